"""A NumPy port of Mitsuba 3's ``Marginal2D<Float, Dim, Continuous=true>``, vectorized over points.

Source: ``include/mitsuba/core/distr_2d.h`` (classes ``Distribution2D`` and ``Marginal2D``) and
``include/mitsuba/core/warp.h`` of Mitsuba 3; the warp is the "marginal" construction used by the
RGL material model (Dupuy & Jakob 2018, "An Adaptive Parameterization for Efficient Material
Acquisition and Rendering", ACM TOG 37(6)).

The density is the bilinear interpolant of a ``H x W`` grid of values on the unit square
(``x`` along the last, contiguous axis), node ``(i, j)`` at ``(j/(W-1), i/(H-1))``, optionally
depending on ``Dim`` parameters: the table is ``(n_0, ..., n_{Dim-1}, H, W)`` and a point's table
is the multilinear interpolation, in the parameters, of the ``2^Dim`` surrounding slices
(``Distribution2D::interpolate_weights``: interval found by binary search in each parameter's
sorted node values, weight clamped to ``[0, 1]``).

Construction (``Continuous=true``): per slice, the conditional CDF of each row is the trapezoid
sum ``c[y, x] = sum_{k<=x} (d[y, k] + d[y, k+1]) / (2 (W-1))`` and the marginal CDF
``m[y] = sum_{k<=y} (c[k, W-2] + c[k+1, W-2]) / (2 (H-1))`` (accumulated in double, stored as
float32); with ``normalize`` every table of the slice is divided by the total ``m[H-2]``, so the
bilinear density integrates to 1. ``sample`` inverts the marginal CDF of ``y`` (piecewise
quadratic, ``sample_segment``), then the conditional CDF of ``x`` given ``y``; ``invert`` is its
exact inverse, and ``eval`` the bilinear density. As in Mitsuba, tables are float32 (the CDFs and
normalized values are rounded exactly as Mitsuba rounds them, and kept in float32); the
arithmetic on them here is float64, so results agree with Mitsuba's float32 arithmetic to
float32 rounding.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Marginal2D"]

_EPS = float(np.finfo(np.float32).eps) / 2  # dr::Epsilon<float> = 2^-24
_ONE_MINUS_EPS = float(np.nextafter(np.float32(1), np.float32(0)))


#: Values per block of slices that :class:`Marginal2D` accumulates in float64 at a time: about
#: 8 MiB for each float64 temporary, whatever the table's size.
BUILD_BLOCK_VALUES = 1 << 20


def _slice_blocks(n: int, per_slice: int):
    """``(start, stop)`` of consecutive blocks of the ``n`` slices, each holding at most
    :data:`BUILD_BLOCK_VALUES` values (at least one slice)."""
    step = max(1, BUILD_BLOCK_VALUES // per_slice)
    return [(a, min(n, a + step)) for a in range(0, n, step)]


def _lerp(a, b, t):
    return a + (b - a) * t


class Marginal2D:
    """Mitsuba's ``Marginal2D<Float, Dim, true>`` (module docstring).

    Args:
        data: ``(*param_res, H, W)`` values ``>= 0`` (converted to float32, as Mitsuba stores
            them), ``H, W >= 2``.
        param_values: ``Dim`` sorted 1-D arrays, the node values of each parameter
            (``len(param_values[k]) == param_res[k]``).
        normalize: scale each slice so that its bilinear density integrates to 1.
        enable_sampling: build the CDFs (needed by :meth:`sample` and :meth:`invert`).

    Points are ``(N, 2)`` arrays in ``[0, 1]^2`` (``x`` first); parameters a sequence of ``Dim``
    arrays broadcastable to ``(N,)``.
    """

    def __init__(self, data, param_values=(), normalize: bool = True,
                 enable_sampling: bool = True):
        data = np.asarray(data, dtype=np.float32)
        self.dim = len(param_values)
        if data.ndim != self.dim + 2:
            raise ValueError(f"Marginal2D: data must have {self.dim + 2} dimensions for "
                             f"{self.dim} parameters, got shape {data.shape}")
        self.param_values = [np.asarray(v, dtype=np.float32).astype(np.float64)
                             for v in param_values]
        res = data.shape[:self.dim]
        for k, (v, n) in enumerate(zip(self.param_values, res)):
            if v.shape != (n,) or n < 1:
                raise ValueError(f"Marginal2D: parameter {k} has {v.shape} values for "
                                 f"{n} slices")
        self.h, self.w = data.shape[-2:]
        if self.h < 2 or self.w < 2:
            raise ValueError(f"Marginal2D: resolution must be >= 2, got {data.shape[-2:]}")
        # Distribution2D: strides per parameter (0 where the parameter has one value).
        self.strides, slices = [0] * self.dim, 1
        for k in range(self.dim - 1, -1, -1):
            self.strides[k] = slices if res[k] > 1 else 0
            slices *= res[k]
        self.slices, self.normalized = slices, normalize
        flat = data.reshape(slices, self.h, self.w)
        if enable_sampling:
            self.data, self.cond, self.marg = self._build_cdfs(flat, normalize)
        else:
            self.data, self.cond, self.marg = self._scale_only(flat, normalize), None, None

    def _build_cdfs(self, flat, normalize):
        """``(data, cond, marg)``, float32 as Mitsuba stores them: the (normalized) values
        ``(slices, H·W)``, the rows' conditional CDFs ``(slices, H·(W−1))`` and the marginal
        CDF ``(slices, H−1)``, accumulated in float64 a block of slices at a time
        (:func:`_slice_blocks`), so the build needs about the tables' own bytes beside them."""
        h, w = self.h, self.w
        n = len(flat)
        data = np.empty((n, h * w), np.float32)
        cond = np.empty((n, h * (w - 1)), np.float32)
        marg = np.empty((n, h - 1), np.float32)
        for a, b in _slice_blocks(n, h * w):
            d = flat[a:b].astype(np.float64)
            cond_acc = np.cumsum((0.5 / (w - 1)) * (d[:, :, :-1] + d[:, :, 1:]), axis=2)
            del d
            row_sum = cond_acc[:, :, -1]
            marg_acc = np.cumsum((0.5 / (h - 1)) * (row_sum[:, :-1] + row_sum[:, 1:]), axis=1)
            norm = ((1.0 / marg_acc[:, -1]).astype(np.float32) if normalize
                    else np.ones(b - a, np.float32))
            cond[a:b] = (cond_acc.astype(np.float32) * norm[:, None, None]).reshape(b - a, -1)
            del cond_acc
            marg[a:b] = marg_acc.astype(np.float32) * norm[:, None]
            data[a:b] = (flat[a:b] * norm[:, None, None]).reshape(b - a, -1)
        return data, cond, marg

    def _scale_only(self, flat, normalize):
        """The (normalized) values ``(slices, H·W)``, float32 (:meth:`_build_cdfs`)."""
        out = flat.reshape(len(flat), -1).copy()
        if normalize:
            for a, b in _slice_blocks(len(flat), self.h * self.w):
                d = flat[a:b].astype(np.float64)
                s = (d[:, :-1, :-1] + d[:, :-1, 1:] + d[:, 1:, :-1] + d[:, 1:, 1:]).sum(axis=(1, 2))
                norm = (1.0 / ((0.5 / (self.w - 1)) * (0.5 / (self.h - 1)) * s)).astype(np.float32)
                out[a:b] = (flat[a:b] * norm[:, None, None]).reshape(b - a, -1)
        return out

    # -- parameters ------------------------------------------------------------------------------

    def _corners(self, params, n):
        """``[(slice index (N,), weight (N,))]`` for the ``2^Dim`` slices around each point."""
        corners = [(np.zeros(n, np.int64), np.ones(n))]
        if self.dim == 0:
            return corners
        if len(params) != self.dim:
            raise ValueError(f"Marginal2D: expected {self.dim} parameters, got {len(params)}")
        for k in range(self.dim):
            values = self.param_values[k]
            if len(values) == 1:
                continue  # weights (1, 0): the same slice
            p = np.broadcast_to(np.asarray(params[k], dtype=np.float64), (n,))
            # math::find_interval: binary_search(1, size-1, values[i] < p) - 1
            idx = np.clip(np.searchsorted(values, p, side="left") - 1, 0, len(values) - 2)
            p0, p1 = values[idx], values[idx + 1]
            w1 = np.clip((p - p0) / (p1 - p0), 0.0, 1.0)
            stride = self.strides[k]
            corners = [(s + stride * idx, w * (1 - w1)) for s, w in corners] + \
                      [(s + stride * (idx + 1), w * w1) for s, w in corners]
        return corners

    @staticmethod
    def _lookup(table, corners, index):
        """The parameter-interpolated ``table[slice, index]`` (``index`` (N,) or (N, k))."""
        out = 0.0
        for s, w in corners:
            s = s if np.ndim(index) == 1 else s[:, None]
            ww = w if np.ndim(index) == 1 else w[:, None]
            out = out + table[s, index] * ww
        return out

    def _corner_values(self, corners, offset):
        look = self._lookup
        return (look(self.data, corners, offset), look(self.data, corners, offset + 1),
                look(self.data, corners, offset + self.w),
                look(self.data, corners, offset + self.w + 1))

    # -- the warp --------------------------------------------------------------------------------

    @staticmethod
    def _sample_segment(sample, inv_width, v0, v1):
        non_const = np.abs(v0 - v1) > 1e-4 * (v0 + v1)
        divisor = np.where(non_const, v0 - v1, v0 + v1)
        sample = sample * (2.0 * inv_width)
        sample = np.where(non_const, v0 - np.sqrt(np.maximum(v0 * v0 + sample * (v1 - v0), 0.0)),
                          sample)
        return np.where(divisor != 0, sample / np.where(divisor != 0, divisor, 1.0), sample)

    @staticmethod
    def _invert_segment(sample, width, v0, v1):
        return sample * _lerp(v0, v1, 0.5 * sample) * width

    def _prepare(self, points, params):
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"Marginal2D: points must have shape (N, 2), got {pts.shape}")
        return pts, self._corners(params, len(pts))

    def _cell(self, points, params):
        """The table cell of each position ``(N, 2)`` in ``[0, 1]²`` (clamped): its column and
        row, the position inside it, the parameter corners, and its four corner values
        ``(v00, v10, v01, v11)`` (shared by :meth:`invert` and :meth:`eval`)."""
        p, corners = self._prepare(points, params)
        w, h = self.w, self.h
        p = np.clip(p, 0.0, 1.0) * np.array([w - 1, h - 1], dtype=np.float64)
        px = np.minimum(p[:, 0].astype(np.int64), w - 2)
        py = np.minimum(p[:, 1].astype(np.int64), h - 2)
        x, y = p[:, 0] - px, p[:, 1] - py
        return px, py, x, y, corners, self._corner_values(corners, py * w + px)

    def sample(self, points, params=(), *, guard: bool = True):
        """``Marginal2D::sample_continuous``: uniform ``(N, 2)`` -> ``(positions, pdf)``.

        ``guard=False`` skips Mitsuba's clamp of the input to ``[ε, 1-ε]``, so that the edges
        of the square map exactly onto the edges (the tables' own nodes, :mod:`._material`).
        """
        if self.cond is None:
            raise ValueError("Marginal2D.sample: built with enable_sampling=False")
        u, corners = self._prepare(points, params)
        w, h, n = self.w, self.h, len(u)
        lo, hi = (_EPS, _ONE_MINUS_EPS) if guard else (0.0, 1.0)
        x = np.clip(u[:, 0], lo, hi)
        y = np.clip(u[:, 1], lo, hi)
        marg = sum(self.marg[sl] * wt[:, None] for sl, wt in corners)  # (N, h-1) rows
        if not self.normalized:
            y = y * marg[:, -1]
        row = np.count_nonzero(marg[:, :h - 2] < y[:, None], axis=1)
        y = y - np.where(row > 0, marg[np.arange(n), np.maximum(row - 1, 0)], 0.0)
        rows = self.cond.reshape(self.slices, h, w - 1)
        c0 = sum(rows[sl, row] * wt[:, None] for sl, wt in corners)  # (N, w-1): CDF of row
        c1 = sum(rows[sl, row + 1] * wt[:, None] for sl, wt in corners)  # and of the next
        r0, r1 = c0[:, -1], c1[:, -1]
        y = self._sample_segment(y, h - 1, r0, r1)
        x = x * _lerp(r0, r1, y)
        cond = _lerp(c0, c1, y[:, None])
        col = np.minimum(np.count_nonzero(cond < x[:, None], axis=1), w - 2)
        x = x - np.where(col > 0, cond[np.arange(n), np.maximum(col - 1, 0)], 0.0)
        v00, v10, v01, v11 = self._corner_values(corners, row * w + col)
        c0, c1 = _lerp(v00, v01, y), _lerp(v10, v11, y)
        x = self._sample_segment(x, w - 1, c0, c1)
        pos = np.stack([(col + x) / (w - 1), (row + y) / (h - 1)], axis=1)
        return pos, _lerp(c0, c1, x)

    def invert(self, points, params=()):
        """``Marginal2D::invert_continuous``: positions ``(N, 2)`` -> ``(uniform, pdf)``."""
        if self.cond is None:
            raise ValueError("Marginal2D.invert: built with enable_sampling=False")
        px, py, x, y, corners, (v00, v10, v01, v11) = self._cell(points, params)
        w, h = self.w, self.h
        c0, c1 = _lerp(v00, v01, y), _lerp(v10, v11, y)
        pdf = _lerp(c0, c1, x)
        x = self._invert_segment(x, 1.0 / (w - 1), c0, c1)
        off_c = py * (w - 1)
        prev = np.maximum(px - 1, 0)
        before = _lerp(self._lookup(self.cond, corners, off_c + prev),
                       self._lookup(self.cond, corners, off_c + prev + (w - 1)), y)
        x = x + np.where(px > 0, before, 0.0)
        r0 = self._lookup(self.cond, corners, off_c + (w - 2))
        r1 = self._lookup(self.cond, corners, off_c + 2 * (w - 1) - 1)
        x = x / _lerp(r0, r1, y)
        y = self._invert_segment(y, 1.0 / (h - 1), r0, r1)
        y = y + np.where(py > 0, self._lookup(self.marg, corners, np.maximum(py - 1, 0)), 0.0)
        if not self.normalized:
            y = y / self._lookup(self.marg, corners, np.full(len(px), h - 2))
        return np.stack([x, y], axis=1), pdf

    def eval(self, points, params=()):
        """``Marginal2D::eval``: the (parameter- and bilinearly interpolated) density."""
        _, _, x, y, _, (v00, v10, v01, v11) = self._cell(points, params)
        return _lerp(_lerp(v00, v10, x), _lerp(v01, v11, x), y)
