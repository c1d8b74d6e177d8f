"""Each concept has one owner: a lookup keeps no state on the caller's table, exporters come from
one registry, no package reaches into another's private names."""

from __future__ import annotations

import numpy as np

from data_formats.merl import MERLTable, synthesize


def _table(shape=(6, 6, 12)):
    return synthesize(lambda wi, wo: np.full(wi.shape[:-1] + (3,), 0.25) + wi[..., 2:3] * 0.5,
                      name="toy", shape=shape)


def test_the_linear_lookup_grid_is_a_pure_function_the_table_keeps():
    from data_formats.merl._lookup import gather_grid

    table = _table()
    grid = table.gather_grid()
    np.testing.assert_array_equal(grid, gather_grid(table.rgb, table.valid))
    assert table.gather_grid() is grid  # built once
    wi = np.array([[0.0, 0.0, 1.0], [0.3, 0.1, 0.9]])
    before = table.lookup(wi, wi[::-1], method="linear")
    assert table.gather_grid() is grid
    other = MERLTable.from_rgb(np.asarray(table.rgb) * 2.0, table.valid)
    np.testing.assert_allclose(other.lookup(wi, wi[::-1], method="linear"), 2.0 * before)
    assert not hasattr(table, "_interp_cache")
