"""The MERL binary BRDF format (Matusik et al. 2003): read, write, index, look up, synthesize.

NumPy only. Facts implemented here (``../shared/reference/merl-format.md``, Burley 2012 §3.1):

* Header: three little-endian ``int32`` ``n_th, n_td, n_pd`` (90, 90, 180 in the database).
  Body: ``3 * n_th * n_td * n_pd`` little-endian ``float64``, the red block, then green, then
  blue; within a block the flat index is ``(i_th * n_td + i_td) * n_pd + i_pd``. The file size is
  exactly ``12 + 8 * 3 * n_th * n_td * n_pd`` (34,992,012 bytes for the database).
* ``BRDF = stored * SCALE[channel]``; a negative stored value marks a cell without measurement.
  In memory a :class:`MERLTable` keeps the BRDF (scales applied) channel-last, a per-cell
  ``valid`` mask (a cell is valid when all three stored values are ``>= 0``), and ``0.0`` in the
  rgb of missing cells (never data; writers store ``-1`` there).
* Cell ``(i, j, k)`` covers ``theta_h`` in ``[(i/n)^2, ((i+1)/n)^2) * 90 deg`` (warped to put
  samples near the specular peak), ``theta_d`` in ``[j, j+1) * 90/n_td deg`` and the folded
  ``phi_d`` in ``[k, k+1) * 180/n_pd deg``; the value stands for the cell's *lower corner*.
  The cells are therefore not equal shares of the angle domain: row ``i`` is ``(2i+1)/n`` times
  the average width in ``theta_h`` (:func:`theta_h_weights`, carried by
  :meth:`MERLTable.to_samples` as ``SampleSet.weight``).

Angles and directions follow :mod:`data_formats.rusinkiewicz` (``z`` is the normal, ``phi_h = 0``).

One module per idea, every public name re-exported here: ``_grid`` (cell indices, corners,
directions, the horizon), ``_scale`` (stored values and what a file can carry), ``_table``
(:class:`MERLTable`), ``_binary`` (:func:`read_merl`, :func:`write_merl`, header checks),
``_lookup`` (nearest and trilinear lookups on threads), ``_synthesize`` (:func:`synthesize`).
"""

from ._binary import MAX_CELLS, MAX_DIM, MERLFormatError, expected_file_size, read_merl, write_merl
from ._grid import (
    HORIZON_EPS,
    MERL_SHAPE,
    N_PD,
    N_TD,
    N_TH,
    above_horizon,
    cell_angles,
    cell_directions,
    merl_index,
    theta_h_weights,
)
from ._lookup import lookup_linear, lookup_linear_angles, lookup_nearest, lookup_nearest_angles
from ._scale import SCALE, snap_to_file
from ._synthesize import synthesize
from ._table import MERLTable

__all__ = [
    "N_TH", "N_TD", "N_PD", "MERL_SHAPE", "SCALE", "MAX_DIM", "MAX_CELLS", "HORIZON_EPS",
    "MERLFormatError", "MERLTable", "read_merl", "write_merl", "expected_file_size", "snap_to_file",
    "merl_index", "cell_angles", "cell_directions", "above_horizon", "theta_h_weights",
    "lookup_nearest", "lookup_linear", "lookup_nearest_angles", "lookup_linear_angles",
    "synthesize",
]
