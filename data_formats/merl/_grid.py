"""The MERL grid: cell indices of half/difference angles, cell corners and their directions.

Cell ``(i, j, k)`` covers ``theta_h`` in ``[(i/n)^2, ((i+1)/n)^2) * 90 deg`` (warped to put
samples near the specular peak), ``theta_d`` in ``[j, j+1) * 90/n_td deg`` and the folded
``phi_d`` in ``[k, k+1) * 180/n_pd deg``; the value stands for the cell's *lower corner*. The
index arithmetic is ``BRDFRead.cpp``'s, operation for operation.
"""

from __future__ import annotations

import functools

import numpy as np

from ..rusinkiewicz import dirs_from_half_diff, fold_phi_d

N_TH, N_TD, N_PD = 90, 90, 180
MERL_SHAPE = (N_TH, N_TD, N_PD)
#: A direction is above the horizon when ``cos(theta) > HORIZON_EPS`` (see ``above_horizon``).
HORIZON_EPS = 1e-9


def _u_theta_h(theta_h, n_th: int):
    """Warped ``theta_h`` coordinate, ``BRDFRead.cpp``'s ``sqrt(theta_h/(pi/2)*90*90)``."""
    th = np.maximum(np.asarray(theta_h, dtype=np.float64), 0.0)  # theta_h <= 0 -> cell 0
    return np.sqrt(th / (np.pi / 2) * n_th * n_th)


def _v_theta_d(theta_d, n_td: int):
    """Linear ``theta_d`` coordinate, ``BRDFRead.cpp``'s ``theta_diff / (M_PI * 0.5) * 90``."""
    return np.asarray(theta_d, dtype=np.float64) / (np.pi / 2) * n_td


def _w_phi_d(phi_d_folded, n_pd: int):
    """Linear coordinate of a folded ``phi_d``, ``BRDFRead.cpp``'s ``phi_diff / M_PI * 180``."""
    return phi_d_folded / np.pi * n_pd


def grid_coords(theta_h, theta_d, phi_d, shape):
    """Continuous cell coordinates ``(u, v, w)``; ``floor`` of each is the MERL cell index.

    The same floating-point operations, in the same order, as ``BRDFRead.cpp``, so that the
    nearest cell agrees with the database reader to the last bit.
    """
    n_th, n_td, n_pd = shape
    return _u_theta_h(theta_h, n_th), _v_theta_d(theta_d, n_td), _w_phi_d(fold_phi_d(phi_d), n_pd)


def clamped_floor(x, n: int):
    """``floor(x)`` clamped to ``[0, n-1]``; NaN maps to 0 (callers mask it)."""
    return np.fmin(np.fmax(x, 0.0), n - 1).astype(np.intp)


def merl_index(theta_h, theta_d, phi_d, shape=MERL_SHAPE):
    """Cell ``(i, j, k)`` holding ``(theta_h, theta_d, phi_d)``, exactly as the database reader.

    ``i = floor(sqrt(theta_h / (pi/2)) * n_th)`` computed as ``BRDFRead.cpp`` does
    (``sqrt(theta_h/(pi/2)*90*90)``), ``j = floor(theta_d / (pi/2) * n_td)``,
    ``k = floor(phi_d / pi * n_pd)`` after folding ``phi_d`` into ``[0, pi)``; each clamped to
    its range. So ``theta_h`` = 0, 1, 45, 90 deg fall in cells 0, 9, 63, 89. The one departure:
    ``phi_d = pi`` folds to cell 0 (its reciprocal twin), where the database clamps it to 179
    (see :func:`~data_formats.rusinkiewicz.fold_phi_d`). Arrays broadcast; returns ``intp``.
    """
    theta_h, theta_d, phi_d = np.broadcast_arrays(theta_h, theta_d, phi_d)
    u, v, w = grid_coords(theta_h, theta_d, phi_d, shape)
    return clamped_floor(u, shape[0]), clamped_floor(v, shape[1]), clamped_floor(w, shape[2])


def _smallest_in_cell(coord, naive):
    """Per cell ``c``, the smallest double ``x >= 0`` with ``floor(coord(x)) == c``.

    Starts at the closed-form corner ``naive[c]`` and steps by one ulp until the reader's own
    arithmetic agrees (a few steps at most): the closed form rounds to either side.
    """
    target = np.arange(len(naive))
    x = np.asarray(naive, dtype=np.float64).copy()
    for _ in range(1000):
        low = np.floor(coord(x)) < target
        if not low.any():
            break
        x = np.where(low, np.nextafter(x, np.inf), x)
    for _ in range(1000):
        prev = np.nextafter(x, -np.inf)
        down = (target > 0) & (np.floor(coord(prev)) == target)
        if not down.any():
            break
        x = np.where(down, prev, x)
    return x


@functools.lru_cache(maxsize=8)
def _corner_axes(shape):
    """Float lower corners along each axis: ``(theta_h[n_th], theta_d[n_td], phi_d[n_pd])``."""
    n_th, n_td, n_pd = shape
    th = _smallest_in_cell(lambda x: _u_theta_h(x, n_th),
                           (np.arange(n_th) / n_th) ** 2 * (np.pi / 2))
    td = _smallest_in_cell(lambda x: _v_theta_d(x, n_td), np.arange(n_td) / n_td * (np.pi / 2))
    pd = _smallest_in_cell(lambda x: _w_phi_d(x, n_pd), np.arange(n_pd) / n_pd * np.pi)
    for a in (th, td, pd):
        a.flags.writeable = False
    return th, td, pd


def cell_angles(i, j, k, shape=MERL_SHAPE):
    """Lower-corner angles ``(theta_h, theta_d, phi_d)`` of cells ``(i, j, k)`` (radians).

    The corner is ``((i/n_th)^2 * 90 deg, j * 90/n_td deg, k * 180/n_pd deg)``, taken as the
    smallest double that :func:`merl_index` puts in the cell (within a few ulps of the closed
    form, which itself can round into the cell below), so ``merl_index(*cell_angles(i, j, k))``
    is ``(i, j, k)`` for every cell. Indices broadcast.
    """
    th, td, pd = _corner_axes(shape_key(shape))
    return th[np.asarray(i)], td[np.asarray(j)], pd[np.asarray(k)]


def shape_key(shape) -> tuple[int, int, int]:
    """A grid shape as a hashable ``(n_th, n_td, n_pd)`` of ints (one cache entry per grid)."""
    n_th, n_td, n_pd = (int(n) for n in shape)
    return n_th, n_td, n_pd


def cell_directions(shape=MERL_SHAPE):
    """Direction pairs ``(wi, wo)`` of every cell's lower corner, each ``(n_th, n_td, n_pd, 3)``.

    ``phi_h = 0`` (the half vector lies in the ``xz`` plane). Cached per shape (the two most
    recent) and returned read-only (2 x 35 MB for the database grid): copy before modifying.
    Cells with ``theta_d = 0`` have ``wi = wo`` for every ``k`` (``phi_d`` is undefined there).
    """
    return _cell_directions(shape_key(shape))


@functools.lru_cache(maxsize=2)
def _cell_directions(shape):
    th, td, pd = _corner_axes(shape)
    wi, wo = dirs_from_half_diff(th[:, None, None], td[None, :, None], pd[None, None, :])
    wi.flags.writeable = False
    wo.flags.writeable = False
    return wi, wo


def above_horizon(shape=MERL_SHAPE):
    """``(n_th, n_td, n_pd)`` bool: both corner directions strictly above the horizon.

    "Strictly" means ``cos(theta) > HORIZON_EPS`` for ``wi`` and ``wo``: corners that lie on the
    horizon mathematically (e.g. ``theta_h + theta_d = 90 deg`` at ``phi_d = 0``) compute to
    ``cos ~ +-1e-17`` and are excluded rather than left to rounding. Read-only, cached.
    """
    return _above_horizon(shape_key(shape))


@functools.lru_cache(maxsize=2)
def _above_horizon(shape):
    wi, wo = _cell_directions(shape)
    mask = (wi[..., 2] > HORIZON_EPS) & (wo[..., 2] > HORIZON_EPS)
    mask.flags.writeable = False
    return mask


def theta_h_weights(shape=MERL_SHAPE):
    r"""``(n_th,)``: the width in ``theta_h`` of each cell row, relative to the mean width.

    Row ``i`` covers ``theta_h`` in ``[(i/n)^2, ((i+1)/n)^2) * 90 deg``, so its width is
    ``(2i + 1)/n^2 * 90 deg`` and, relative to the mean ``90 deg / n``,

    .. math:: w_i = \frac{2i + 1}{n}, \qquad \frac1n \sum_{i<n} w_i = 1 .

    The ``theta_d`` and ``phi_d`` rows are evenly spaced, so ``w_i`` is each cell's share of
    the angle domain ``(theta_h, theta_d, phi_d)`` against the average cell: weighting each
    cell's squared residual by it undoes the warp, which puts ``n^2/(2i+1)`` times the average
    density of cells near the specular peak (cell 0 stands for 1/90 of an average cell, cell 89
    for 179/90). Read-only, cached.
    """
    return _theta_h_weights(shape_key(shape)[0])


@functools.lru_cache(maxsize=4)
def _theta_h_weights(n_th):
    w = (2.0 * np.arange(n_th) + 1.0) / n_th
    w.flags.writeable = False
    return w
