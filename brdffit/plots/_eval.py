"""Evaluating what a figure shows: the fitted model (JAX, chunked) and the measured data (NumPy).

A figure receives a measured MERL table (``data_formats.merl.MERLTable``: ``rgb``
``(n_th, n_td, n_pd, 3)``, ``valid``; :func:`brdffit.io.is_table`), a
:class:`data_formats.SampleSet` of arbitrary direction pairs, or a measurement that evaluates
itself at any direction pair (an RGL material, ``data_formats.rgl.RGLMaterial``: ``eval(wi, wo)``,
what Mitsuba's ``measured`` BSDF renders). All are reduced here to the two things the figures
need:

* :func:`evaluate_model`: ``f_r`` of a fitted model at NumPy directions, compiled once per model
  (parameters are arguments, not constants) and evaluated in fixed-size chunks, the last one
  padded, so that memory stays bounded and every call with any batch size reuses one compilation.
* :func:`measured_lookup`: ``f_r`` of the measurement at arbitrary direction pairs, with ``NaN``
  where there is no data. A table is looked up with ``data_formats.merl.lookup_linear``
  (trilinear in warped θh, θd, φd); a measurement with ``eval`` by that method (so anisotropy is
  seen); a sample set by its nearest sample in the same warped coordinates, within ``max_dist``
  (so sparse goniometric data leaves honest holes).
"""

from __future__ import annotations


import numpy as np

from ..io import is_table  # noqa: F401  (re-exported for the figures)
from ..models.evaluate import evaluate_model  # noqa: F401  (re-exported for the figures)


def sample_view(data):
    """The measured points that the binned figures read: a table or a sample set as it is, any
    other measurement (an RGL material) as its ``to_samples()`` (the file's own measurement
    pattern; a material makes it once and keeps it, so the figures of one material share it)."""
    if is_table(data) or (hasattr(data, "wi") and hasattr(data, "wo")):
        return data
    return data.to_samples()


def data_name(data, fallback: str = "measured") -> str:
    """The material's name for titles: ``data.name``, else the file stem, else ``fallback``."""
    name = getattr(data, "name", "") or ""
    if not name and getattr(data, "path", None):
        from pathlib import Path

        name = Path(data.path).stem
    return name or fallback


def measured_lookup(data, *, max_dist: float = 0.03):
    """A function ``(wi, wo) -> rgb`` ``(..., 3)`` giving the measured ``f_r``, NaN where unknown.

    Tables: ``data_formats.merl.lookup_linear`` (its treatment of missing cells applies; a
    non-finite result stays NaN). A measurement with ``eval(wi, wo)`` (an RGL material): that
    method, NaN below the horizon. Sample sets: the nearest valid sample in the coordinates
    ``(sqrt(θh/(π/2)), θd/(π/2), φd/π)`` (MERL's warp; φd folded to [0, π) and periodic), NaN when
    it is farther than ``max_dist`` in those unit coordinates (0.03 ≈ 2.7° of θd).
    """
    if is_table(data):
        from data_formats.merl import lookup_linear

        def table_lookup(wi, wo):
            wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
            out = np.asarray(lookup_linear(data, wi.reshape(-1, 3), wo.reshape(-1, 3)), float)
            out = np.where(np.isfinite(out), out, np.nan)
            return out.reshape(wi.shape[:-1] + (3,))

        return table_lookup
    if callable(getattr(data, "eval", None)):
        return _evaluated_lookup(data)
    return _nearest_sample_lookup(data, max_dist)


def _evaluated_lookup(data):
    """``data.eval`` at any shape of directions; NaN where it is not finite, and where either
    direction is below the horizon (no measurement there)."""

    def evaluated(wi, wo):
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        a, b = wi.reshape(-1, 3), wo.reshape(-1, 3)
        out = np.asarray(data.eval(a, b), float).reshape(-1, 3)
        out = np.where(np.isfinite(out) & ((a[:, 2] > 0) & (b[:, 2] > 0))[:, None], out, np.nan)
        return out.reshape(wi.shape[:-1] + (3,))

    return evaluated


def warped_coords(wi, wo) -> np.ndarray:
    """``(..., 3)`` unit-cube coordinates ``(sqrt(θh/(π/2)), θd/(π/2), φd/π)``, φd folded."""
    from data_formats.rusinkiewicz import half_diff_from_dirs

    th, td, pd = half_diff_from_dirs(np.asarray(wi, float), np.asarray(wo, float))
    pd = np.mod(pd, np.pi)
    return np.stack(
        [np.sqrt(np.clip(th, 0.0, None) / (np.pi / 2)), td / (np.pi / 2), pd / np.pi], axis=-1
    )


def _nearest_sample_lookup(samples, max_dist: float):
    from scipy.spatial import cKDTree

    ok = np.asarray(samples.valid, bool) & np.all(np.isfinite(samples.rgb), axis=-1)
    if not ok.any():
        return lambda wi, wo: np.full(np.broadcast_shapes(np.shape(wi), np.shape(wo)), np.nan)
    top = [9.0, 9.0, np.nextafter(1.0, 0.0)]  # inside the periodic box of the tree
    pts = np.clip(warped_coords(samples.wi[ok], samples.wo[ok]), 0.0, top)
    tree = cKDTree(pts, boxsize=[10.0, 10.0, 1.0])  # periodic in φd only
    rgb = np.asarray(samples.rgb, float)[ok]

    def sample_lookup(wi, wo):
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        q = np.clip(warped_coords(wi, wo).reshape(-1, 3), 0.0, top)
        dist, idx = tree.query(q, distance_upper_bound=max_dist)
        hit = np.isfinite(dist)
        out = np.full((len(q), 3), np.nan)
        out[hit] = rgb[idx[hit]]
        return out.reshape(wi.shape[:-1] + (3,))

    return sample_lookup
