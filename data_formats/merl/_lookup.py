"""Nearest-cell and trilinear lookups of a table, in chunks on a few threads.

``table`` below is a :class:`~data_formats.merl.MERLTable` (any object with its ``rgb``,
``valid``, ``shape`` and ``gather_grid()``); this module does not import the type, which imports
these functions.
"""

from __future__ import annotations

import concurrent.futures
import os

import numpy as np

from ..rusinkiewicz import half_diff_from_dirs
from ._grid import clamped_floor, grid_coords, merl_index

#: Lookups run in chunks of this many pairs so that every temporary stays in cache.
_CHUNK = 32768
#: Worker threads for lookups of more than one chunk (the cores this process may use, at most 8).
_THREADS = min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def _over_chunks(run, n: int) -> None:
    """Call ``run(slice)`` on consecutive chunks of ``range(n)``, on up to :data:`_THREADS` threads.

    The kernels are gathers and elementwise NumPy work, which release the GIL, and their
    random reads of the table are bound by memory latency: a second core nearly halves the time.
    Each chunk writes its own slice of the output, so the threads share nothing else.
    """
    slices = [slice(s, s + _CHUNK) for s in range(0, n, _CHUNK)]
    if len(slices) < 2 or _THREADS < 2:
        for sl in slices:
            run(sl)
        return
    with concurrent.futures.ThreadPoolExecutor(min(_THREADS, len(slices))) as pool:
        for future in [pool.submit(run, sl) for sl in slices]:
            future.result()


def _nan_angles(theta_h, theta_d, phi_d):
    """True where any angle is NaN (a NaN direction); such lookups return NaN."""
    return np.isnan(theta_h) | np.isnan(theta_d) | np.isnan(phi_d)


def _by_angles(kernel, prepared, shape, theta_h, theta_d, phi_d):
    """Run ``kernel(prepared, shape, th, td, pd) -> (n, 3)`` over broadcast angles, in chunks."""
    angles = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                   for a in (theta_h, theta_d, phi_d)))
    batch = angles[0].shape
    th, td, pd = (a.reshape(-1) for a in angles)
    out = np.empty((th.size, 3))

    def run(sl):
        out[sl] = kernel(prepared, shape, th[sl], td[sl], pd[sl])

    _over_chunks(run, th.size)
    return out.reshape(batch + (3,))


def _by_dirs(kernel, prepared, shape, wi, wo):
    """Run ``kernel`` over direction pairs ``(..., 3)``, converting each chunk to angles."""
    wi, wo = np.broadcast_arrays(np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64))
    if wi.ndim == 0 or wi.shape[-1] != 3:
        raise ValueError(f"lookup: expected directions of shape (..., 3), got {wi.shape}")
    batch = wi.shape[:-1]
    wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
    out = np.empty((len(wi), 3))

    def run(sl):
        out[sl] = kernel(prepared, shape, *half_diff_from_dirs(wi[sl], wo[sl]))

    _over_chunks(run, len(wi))
    return out.reshape(batch + (3,))


def _nearest_kernel(prepared, shape, th, td, pd):
    """Nearest-cell rgb ``(n, 3)`` for flat angle arrays; NaN for missing cells/NaN angles."""
    rgb, valid = prepared
    n_th, n_td, n_pd = shape
    i, j, k = merl_index(th, td, pd, shape)
    flat = (i * n_td + j) * n_pd + k
    out = np.take(rgb, flat, axis=0)
    missing = ~np.take(valid, flat) | _nan_angles(th, td, pd)
    if missing.any():
        out[missing] = np.nan
    return out


def _nearest_prepared(table):
    return table.rgb.reshape(-1, 3), table.valid.reshape(-1)


def lookup_nearest_angles(table, theta_h, theta_d, phi_d):
    """BRDF ``(..., 3)`` of the cell :func:`merl_index` picks for broadcast angles; NaN where
    that cell is missing or an angle is NaN."""
    return _by_angles(_nearest_kernel, _nearest_prepared(table), table.shape,
                      theta_h, theta_d, phi_d)


def lookup_nearest(table, wi, wo):
    """The database reader's lookup (``lookup_brdf_val``): the BRDF of the cell holding the
    pair's half/difference angles, for direction pairs ``(..., 3)``; returns ``(..., 3)``.

    Missing cells give NaN (never the stored ``-1 * SCALE``). Like the database reader it does
    not test the horizon: a pair below it gets whatever its cell holds. Directions are not
    renormalised. Note that a cell's own corner direction (:func:`cell_directions`) sits on
    the cell's lower boundary, so rounding in the direction -> angle conversion puts about half
    of them in the cell below; look up ``cell_angles`` with :func:`lookup_nearest_angles` for
    exact cells.
    """
    return _by_dirs(_nearest_kernel, _nearest_prepared(table), table.shape, wi, wo)


def _axis_weights(x, n: int):
    """Lower cell, upper cell and upper weight along a clamped axis of continuous coordinate ``x``.

    Past the last sample (``x >= n - 1``) both cells are the last one: the value is held.
    """
    lo = clamped_floor(x, n)
    return lo, np.minimum(lo + 1, n - 1), np.clip(x - lo, 0.0, 1.0)


def gather_grid(rgb, valid):
    """The gather array of the linear lookup, for a table's ``rgb`` and ``valid`` arrays.

    ``(n_th * n_td * (n_pd + 1), 4)`` float64 rows ``(r, g, b, valid)`` (rgb zeroed where
    missing) in file order, with ``phi_d`` cell 0 repeated at ``k = n_pd`` (the periodic wrap),
    so a corner is one 32-byte row and ``k + 1`` never needs a modulo. Costs 1.35x the table's
    rgb in memory (47 MB for the database grid). A pure function: the table keeps the array it
    built (:meth:`MERLTable.gather_grid`).
    """
    n_th, n_td, n_pd = valid.shape
    grid = np.empty((n_th, n_td, n_pd + 1, 4))
    grid[:, :, :n_pd, :3] = rgb
    grid[:, :, :n_pd, 3] = valid
    grid[:, :, :n_pd, :3][~valid] = 0.0
    grid[:, :, n_pd] = grid[:, :, 0]
    return grid.reshape(-1, 4)


def _linear_kernel(grid, shape, th, td, pd):
    """Trilinear rgb ``(n, 3)`` for flat angle arrays (see :func:`lookup_linear_angles`)."""
    n_th, n_td, n_pd = shape
    u, v, w = grid_coords(th, td, pd, shape)
    i0, i1, fi = _axis_weights(u, n_th)
    j0, j1, fj = _axis_weights(v, n_td)
    k0 = clamped_floor(w, n_pd)
    fk = np.clip(w - k0, 0.0, 1.0)
    acc = np.zeros((th.size, 4))  # (r, g, b, weight of the valid corners)
    rec = np.empty((th.size, 4))
    for ii, wgt_i in ((i0, 1.0 - fi), (i1, fi)):
        for jj, wgt_j in ((j0, 1.0 - fj), (j1, fj)):
            row = (ii * n_td + jj) * (n_pd + 1) + k0
            wgt_ij = wgt_i * wgt_j
            for dk, wgt_k in ((0, 1.0 - fk), (1, fk)):
                np.take(grid, row + dk, axis=0, out=rec)
                rec *= (wgt_ij * wgt_k)[:, None]
                acc += rec
    ok = acc[:, 3] > 0.0  # False for NaN weights too
    out = acc[:, :3] / np.where(ok, acc[:, 3], 1.0)[:, None]
    out[~ok] = np.nan
    return out


def lookup_linear_angles(table, theta_h, theta_d, phi_d):
    """Trilinear interpolation ``(..., 3)`` in the warped coordinates ``(u, v, w)``.

    With ``u = sqrt(theta_h/(pi/2)) n_th``, ``v = theta_d/(pi/2) n_td``, ``w = phi_d/pi n_pd``
    (``phi_d`` folded), cell ``(i, j, k)`` is the sample at ``(u, v, w) = (i, j, k)``, its lower
    corner, so the result equals the stored value there (bit for bit when the coordinates are
    exactly integral) and is linear along each axis in between. ``phi_d`` is periodic (the fold
    by reciprocity): between the last cell and ``phi_d = pi`` it blends towards cell 0, so the
    result is continuous across ``phi_d = 0 = pi``. Past the last ``theta_h`` or ``theta_d``
    sample it is held constant.

    Missing cells: their weights are dropped and the rest renormalised, so the result is the
    weighted mean of the valid corners among the eight; NaN when no corner with non-zero weight
    is valid (in particular exactly at a missing cell's corner), or where an angle is NaN.
    """
    return _by_angles(_linear_kernel, table.gather_grid(), table.shape, theta_h, theta_d, phi_d)


def lookup_linear(table, wi, wo):
    """Trilinear lookup of direction pairs ``(..., 3)``; see :func:`lookup_linear_angles`."""
    return _by_dirs(_linear_kernel, table.gather_grid(), table.shape, wi, wo)
