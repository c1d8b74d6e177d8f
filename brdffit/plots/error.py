r"""The error a diagnostic figure's title states, and the per-cell ratio its slice shows.

The title states the fit's own ``rmse_log`` (:data:`brdffit.metrics.FIGURE_METRIC`, defined
with every other metric in :mod:`brdffit.metrics`): a figure of a fit result takes the value
from ``result.metrics`` (:func:`result_error`), so the figure, the summary, the report and the
JSON show one number. A figure of a model and parameters without a result computes the same
formula (:func:`brdffit.metrics.values`) over at most 100 000 valid measurements above the
horizon within the default cutoff (θi, θo ≤ :data:`brdffit.config.DEFAULT_CUTOFF`, the cells a
fit uses unless told otherwise; :func:`error_pairs`, seeded); over the cells a default fit used
(no ``subsample``) that is the fit's value.

The slice's ratio panel shows every cell's relative error instead, the log ratio

.. math::

    \ln\frac{f_\text{fit}(n,c) + \varepsilon}{f_\text{meas}(n,c) + \varepsilon}

with ``ε = 1e-3`` BRDF units (about one quantum of the MERL encoding, 1/1500), so that
near-black cells do not dominate. Its RMS over the cells (:func:`rms_log_error`) is a different
and larger figure than ``rmse_log``: dark cells count with their full relative error there,
while ``ln(1 + f cosθi)`` compresses them. Titles do not state it.
"""

from __future__ import annotations

import numpy as np

from ..config import DEFAULT_CUTOFF
from ..metrics import FIGURE_METRIC, metric_text, values
from ._eval import evaluate_model, is_table, sample_view

#: Floor added to both sides of the ratio (BRDF units).
EPS = 1e-3


def _table_pairs(table, idx):
    from data_formats.merl import cell_angles
    from data_formats.rusinkiewicz import dirs_from_half_diff

    i, j, k = np.unravel_index(idx, np.shape(table.valid))
    wi, wo = dirs_from_half_diff(*cell_angles(i, j, k, np.shape(table.valid)))
    rgb = np.asarray(table.rgb, float)[i, j, k]
    return np.asarray(wi, float), np.asarray(wo, float), rgb


def error_pairs(data, *, max_samples: int = 100_000, seed: int = 0, cutoff=DEFAULT_CUTOFF):
    """``(wi, wo, rgb)``: at most ``max_samples`` valid measurements above the horizon with
    θi, θo at most ``cutoff`` degrees (``None``: every one), seeded."""
    rng = np.random.default_rng(seed)
    if is_table(data):
        idx = np.flatnonzero(np.asarray(data.valid, bool))
        if idx.size > max_samples:
            idx = np.sort(rng.choice(idx, max_samples, replace=False))
        wi, wo, rgb = _table_pairs(data, idx)
    else:
        data = sample_view(data)
        ok = np.flatnonzero(np.asarray(data.valid, bool))
        if ok.size > max_samples:
            ok = np.sort(rng.choice(ok, max_samples, replace=False))
        wi, wo, rgb = data.wi[ok], data.wo[ok], np.asarray(data.rgb, float)[ok]
    keep = (wi[:, 2] > 0) & (wo[:, 2] > 0) & np.all(np.isfinite(rgb), axis=-1)
    if cutoff is not None:
        keep &= np.minimum(wi[:, 2], wo[:, 2]) >= np.cos(np.radians(float(cutoff)))
    return wi[keep], wo[keep], rgb[keep]


def log_ratio(fitted, measured, eps: float = EPS):
    """``ln((fitted + ε) / (measured + ε))`` elementwise, negative values clipped to zero first."""
    f = np.clip(np.asarray(fitted, float), 0.0, None)
    m = np.clip(np.asarray(measured, float), 0.0, None)
    return np.log((f + eps) / (m + eps))


def rms_log_error(data, model, params, *, max_samples: int = 100_000, seed: int = 0) -> float:
    """The RMS of the log ratio (module docstring) of ``model(params)`` against ``data`` at the
    measurements of :func:`error_pairs` (NaN if there are none): every cell's relative error,
    not the ``rmse_log`` of the titles."""
    wi, wo, rgb = error_pairs(data, max_samples=max_samples, seed=seed)
    if len(rgb) == 0:
        return float("nan")
    fitted = evaluate_model(model, params, wi, wo)
    return float(np.sqrt(np.mean(log_ratio(fitted, rgb) ** 2)))


def model_metrics(data, model, params, *, max_samples: int = 100_000, seed: int = 0) -> dict:
    """:func:`brdffit.metrics.values` of ``model(params)`` against ``data`` at the measurements
    of :func:`error_pairs` (NaN if there are none)."""
    wi, wo, rgb = error_pairs(data, max_samples=max_samples, seed=seed)
    fitted = evaluate_model(model, params, wi, wo) if len(rgb) else rgb
    return values(fitted, rgb, wi[:, 2], wo[:, 2])


def model_error(data, model, params) -> str:
    """The title text for a model without a fit result: :data:`FIGURE_METRIC` over ``data``."""
    return format_error(model_metrics(data, model, params)[FIGURE_METRIC])


def result_error(result) -> str:
    """The title text for a fit result: its own :data:`FIGURE_METRIC` (``"rmse_log 0.2957"``),
    and ``"fit NOT converged"`` after it for a failed fit."""
    text = format_error(result.metrics[FIGURE_METRIC])
    return text if result.success else f"{text} (fit NOT converged)"


def format_error(value: float) -> str:
    """The title text for a value of :data:`FIGURE_METRIC` (:func:`brdffit.metrics.metric_text`)."""
    return metric_text(FIGURE_METRIC, value)
