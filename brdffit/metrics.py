r"""The error metrics of a fit, by name: the one table their names and meanings come from.

A fit's ``result.metrics`` (:mod:`brdffit.fitting.statistics` computes them), its summary and
report, the titles of the diagnostic figures, the comparison of models and the JSON all use
these names, in this order, with these meanings. Every metric runs over the ``N`` residuals the
fit used (a cell's RGB channels with non-zero weight), ``f̂`` the fitted and ``f`` the measured
``f_r``, ``Δ`` their difference:

.. math::

    \mathrm{rmse} &= \sqrt{\tfrac1N \textstyle\sum r^2}
        \quad\text{(the residual the fit minimised, weighted)}\\
    \mathrm{rmse\_cosine} &= \sqrt{\tfrac1N \textstyle\sum (\Delta f \cos\theta_i\cos\theta_o)^2}
        \quad\text{(Ngan et al. 2005)}\\
    \mathrm{rmse\_log} &= \sqrt{\tfrac1N \textstyle\sum
        \bigl(\ln(1 + \hat f\cos\theta_i) - \ln(1 + f\cos\theta_i)\bigr)^2}
        \quad\text{(Löw et al. 2012)}\\
    \mathrm{rel\_error} &= \tfrac1N \textstyle\sum |\Delta f| / \max(f, 10^{-3})

``rmse_log`` is what the figures state (:data:`FIGURE_METRIC`): like the default ``log`` loss it
is close to a relative error on the bright cells (``f cosθi ≫ 1``: the specular peak) and to an
absolute error of the reflected radiance on dark ones, so a dark diffuse floor fitted within a
few per cent does not dominate it. It is not the RMS of ``ln(f̂/f)`` (every cell's relative
error), which dark cells dominate and which is larger: the slice figure's ratio panel shows
that per cell.

NumPy only (no JAX): the batch table and the command line read the names without importing
the fitter; :func:`values` is the NumPy twin of the fitter's sums, for figures of a model
without a fit result.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: The floor of the measured value in ``rel_error`` (BRDF units, 1/sr).
RELATIVE_FLOOR = 1e-3


@dataclasses.dataclass(frozen=True)
class Metric:
    """One error metric: its ``name`` (the key of ``result.metrics``), a short ``label`` for
    people, its ``formula`` in one line, and what it means (``description``)."""

    name: str
    label: str
    formula: str
    description: str


#: Name → :class:`Metric`, in the order every listing uses.
METRICS = {m.name: m for m in (
    Metric("rmse", "RMS residual of the fitted loss", "√(Σ r² / N)",
           "the residual the fit minimised (weighted); compares fits with the same loss only"),
    Metric("rmse_cosine", "cosine-weighted RMS error", "√(Σ (Δf_r cosθi cosθo)² / N)",
           "error of the reflected radiance under unit irradiance, 1/sr (Ngan et al. 2005)"),
    Metric("rmse_log", "RMS log error", "√(Σ (Δ ln(1 + f_r cosθi))² / N)",
           "relative on the bright cells, absolute on dark ones (Löw et al. 2012)"),
    Metric("rel_error", "mean relative error", "Σ |Δf_r| / max(f_r, 0.001) / N",
           "typical error as a fraction of the measured value (0.1: 10 %)"),
)}

#: The metric the titles of the diagnostic figures state.
FIGURE_METRIC = "rmse_log"


def metric_text(name: str, value: float) -> str:
    """``"rmse_log 0.2957"``: a metric as every listing writes it (4 significant digits)."""
    return f"{name} {float(value):.4g}"


def metrics_text(metrics: dict) -> str:
    """``"rmse 0.1087, rmse_cosine 1.251, ..."``: the metrics of ``metrics`` in table order
    (names the table does not know last)."""
    names = [n for n in METRICS if n in metrics] + [n for n in metrics if n not in METRICS]
    return ", ".join(metric_text(n, metrics[n]) for n in names)


def values(fitted, measured, cos_i, cos_o) -> dict:
    """``rmse_cosine``, ``rmse_log`` and ``rel_error`` of ``fitted`` against ``measured``
    (``f_r`` ``(n, 3)``) at cells with the cosines ``cos_i``, ``cos_o`` ``(n,)``, every
    residual counted once (unit weights); NaN for no cells. ``rmse`` needs the fit's loss and
    weights, so it is not here."""
    f, m = np.asarray(fitted, float), np.asarray(measured, float)
    ci, co = np.asarray(cos_i, float)[:, None], np.asarray(cos_o, float)[:, None]
    if f.size == 0:
        return dict.fromkeys(("rmse_cosine", "rmse_log", "rel_error"), float("nan"))
    diff = f - m
    return {
        "rmse_cosine": float(np.sqrt(np.mean((diff * ci * co) ** 2))),
        "rmse_log": float(np.sqrt(np.mean((np.log1p(f * ci) - np.log1p(m * ci)) ** 2))),
        "rel_error": float(np.mean(np.abs(diff) / np.maximum(np.abs(m), RELATIVE_FLOOR))),
    }
