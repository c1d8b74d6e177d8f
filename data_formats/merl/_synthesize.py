"""Synthetic tables: a NumPy BRDF evaluated at every cell's lower corner."""

from __future__ import annotations

import numpy as np

from ._grid import MERL_SHAPE, above_horizon, cell_directions, shape_key
from ._scale import check_storable
from ._table import MERLTable


def synthesize(fn, name: str = "", shape=MERL_SHAPE) -> MERLTable:
    """A table from a NumPy BRDF ``fn(wi, wo) -> rgb``, evaluated at every cell's lower corner.

    ``fn`` receives the read-only grids of :func:`cell_directions` (each ``(*shape, 3)``) and
    must return ``(*shape, 3)`` (or something that broadcasts to it). Cells whose corner is not
    strictly above the horizon (:func:`above_horizon`) are marked missing, as in the real
    database, and ``fn``'s values there are ignored (NaN is fine). Values are snapped to the
    file grid, so writing the table and reading it back gives it exactly.
    """
    shape = shape_key(shape)
    wi, wo = cell_directions(shape)
    rgb = np.broadcast_to(np.asarray(fn(wi, wo), dtype=np.float64), shape + (3,))
    valid = np.array(above_horizon(shape))
    check_storable(rgb, valid, lambda count, cell: (
        f"synthesize: fn returned {count} negative or non-finite values above the horizon "
        f"(first: cell {cell}, wi={wi[cell].tolist()}, wo={wo[cell].tolist()}: "
        f"{rgb[cell].tolist()}); a BRDF must be finite and >= 0"
    ))
    return MERLTable.from_rgb(rgb, valid, name=name)
