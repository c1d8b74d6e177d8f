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

**The literature's metrics** (:data:`LITERATURE_METRICS`, :func:`literature_values`) score any
set of model values against a measurement on given cells, independently of how (or whether) the
model was fitted: what the leaderboard (:mod:`brdffit.compare`) ranks fits and published fits
by. Each exists twice: per cell (every cell counts once, as a fit over MERL cells counts them)
and solid-angle weighted (suffix ``_sa``: each cell counts by the share of ``dωi dωo`` it
stands for, :func:`solid_angle_weight`, so the result approximates an integral over pairs of
directions and no longer depends on how densely the layout samples the peak). With weights
``w`` (1 per cell, or the solid angle) over the cells ``C`` of each metric's domain:

.. math::

    \mathrm{log\_rms} &= \sqrt{\textstyle\sum_C w\,\tfrac13\sum_c
        \bigl(\ln(1 + \hat f\cos\theta_i) - \ln(1 + f\cos\theta_i)\bigr)^2 / \sum_C w}
        \quad\text{(Löw et al. 2012's E2 error, every cell above the horizon)}\\
    \mathrm{log\_rms\_80} &= \text{the same over } \theta_i, \theta_o \le 80°\\
    \mathrm{cos\_rms} &= \sqrt{\textstyle\sum_C w\,\tfrac13\sum_c
        \bigl((\hat f - f)\cos\theta_i\bigr)^2 / \sum_C w}
        \quad\text{(Löw et al. 2012's E1 error, every cell above the horizon)}\\
    \mathrm{ngan\_rms\_80} &= \sqrt{\textstyle\sum_C w\,\tfrac13\sum_c
        \bigl((\hat f - f)\cos\theta_i\bigr)^2 / \sum_C w}, \quad \theta_i, \theta_o \le 80°
        \quad\text{(Ngan et al. 2005)}\\
    \mathrm{peak\_rel} &= \textstyle\sum_C w\,\tfrac13\sum_c |\hat f - f| / \max(f, 10^{-3})
        \,/ \sum_C w, \quad \theta_h \le 2°,\ \theta_i, \theta_o \le 80°

The two residual forms are those of the BSDF benchmark project's transcriptions of the papers'
losses (``bsdfbenchmark/bbm``, ``include/loss/cosine_weighted_log.h``: ``lowLog_error``,
``log(1 + f cosθi)``; ``include/loss/cosine_weighted_l2.h``: ``nganL2_error``, ``(Δf cosθi)²``
with ``sinθi sinθo`` sample weights, i.e. the solid angle of a spherical grid). ``peak_rel`` is
the mean relative error of the cells within 2° of the mirror direction (the highlight's
centre, 14 rows of the MERL ``θh`` warp), the part of a glossy material that a renderer shows
most and that the metrics above weigh little.
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


# -- the literature's metrics ------------------------------------------------------------------

#: The angle (degrees) the ``_80`` metrics keep: θi and θo at most this (Ngan et al. 2005).
LITERATURE_CUTOFF = 80.0
#: The half-vector angle (degrees) of the cells ``peak_rel`` averages over.
PEAK_THETA_H = 2.0

#: Name → :class:`Metric` of :func:`literature_values`, in the order every table lists them.
LITERATURE_METRICS = {m.name: m for m in (
    Metric("log_rms", "RMS log error (Löw 2012), per cell", "√(Σ (Δ ln(1 + f_r cosθi))² / N)",
           "Löw et al. 2012's log metric over every cell above the horizon"),
    Metric("log_rms_sa", "RMS log error (Löw 2012), solid-angle weighted",
           "√(Σ Ω (Δ ln(1 + f_r cosθi))² / Σ Ω)",
           "the log metric as an integral over direction pairs"),
    Metric("log_rms_80", "RMS log error, θ ≤ 80°, per cell", "log_rms over θi, θo ≤ 80°",
           "the log metric where renderers and measurements are trustworthy"),
    Metric("log_rms_80_sa", "RMS log error, θ ≤ 80°, solid-angle weighted",
           "log_rms_sa over θi, θo ≤ 80°", "the same, as an integral over direction pairs"),
    Metric("cos_rms", "cosθi-weighted RMS (Löw 2012 E1), per cell",
           "√(Σ (Δf_r cosθi)² / N)", "Löw et al. 2012's L2 error (E1) over every cell above the "
           "horizon, 1/sr"),
    Metric("cos_rms_sa", "cosθi-weighted RMS (Löw 2012 E1), solid-angle weighted",
           "√(Σ Ω (Δf_r cosθi)² / Σ Ω)", "E1 as an integral over direction pairs (bbm's lowL2), "
           "1/sr"),
    Metric("ngan_rms_80", "cosθi-weighted RMS (Ngan 2005), θ ≤ 80°, per cell",
           "√(Σ (Δf_r cosθi)² / N), θi, θo ≤ 80°", "Ngan et al. 2005's error, 1/sr"),
    Metric("ngan_rms_80_sa", "cosθi-weighted RMS (Ngan 2005), θ ≤ 80°, solid-angle weighted",
           "√(Σ Ω (Δf_r cosθi)² / Σ Ω), θi, θo ≤ 80°",
           "Ngan's error as an integral over direction pairs (bbm's nganL2), 1/sr"),
    Metric("peak_rel", "relative error in the peak (θh ≤ 2°), per cell",
           "Σ |Δf_r| / max(f_r, 0.001) / N, θh ≤ 2°, θi, θo ≤ 80°",
           "how far the highlight's centre is off, as a fraction (0.1: 10 %)"),
    Metric("peak_rel_sa", "relative error in the peak (θh ≤ 2°), solid-angle weighted",
           "Σ Ω |Δf_r| / max(f_r, 0.001) / Σ Ω, θh ≤ 2°, θi, θo ≤ 80°",
           "the same, each cell by its solid angle"),
)}


def _angles(wi, wo):
    """``(θh, θd)`` of direction pairs ``(n, 3)`` (Rusinkiewicz 1998), radians."""
    h = wi + wo
    norm = np.linalg.norm(h, axis=1)
    h = h / np.where(norm > 0, norm, 1.0)[:, None]
    theta_h = np.arccos(np.clip(h[:, 2], -1.0, 1.0))
    theta_d = np.arccos(np.clip(np.sum(wi * h, axis=1), -1.0, 1.0))
    return theta_h, theta_d


def solid_angle_weight(wi, wo, weight=None) -> np.ndarray:
    r"""``(n,)``: the share of ``dωi dωo`` each direction pair stands for, up to one constant.

    In the Rusinkiewicz angles the measure of direction pairs is (with ``φh`` integrated, the
    BRDF being isotropic)

    .. math:: d\omega_i\, d\omega_o = 4\,\sin\theta_h \,\sin\theta_d \cos\theta_d\;
              d\theta_h\, d\theta_d\, d\phi_d\, d\phi_h ,

    so a sample that stands for the share ``weight`` of the angle domain ``(θh, θd, φd)``
    (``SampleSet.weight``; ``None``: every sample the same share) stands for
    ``weight · sinθh sinθd cosθd`` of the pairs of directions, the density taken at the sample's
    own angles. A MERL cell's sample is its lower corner, so the row ``θh = 0`` and the column
    ``θd = 0`` weigh nothing: they hold a negligible share of the pairs (``10⁻⁸`` and
    ``3·10⁻⁴``). NumPy; the weights are not normalised.
    """
    wi, wo = np.asarray(wi, float), np.asarray(wo, float)
    theta_h, theta_d = _angles(wi, wo)
    w = np.sin(theta_h) * np.sin(theta_d) * np.cos(theta_d)
    return w if weight is None else w * np.asarray(weight, float)


def _weighted_mean(values, w) -> float:
    total = float(np.sum(w))
    return float(np.sum(w * values) / total) if total > 0 else float("nan")


def literature_values(fitted, measured, wi, wo, weight=None) -> dict:
    """Every metric of :data:`LITERATURE_METRICS` of ``fitted`` against ``measured`` (``f_r``,
    ``(n, 3)``) at the cells ``wi``, ``wo`` (``(n, 3)``, all above the horizon and valid: the
    caller selects them), ``weight`` the cells' share of the angle domain
    (``SampleSet.weight`` or ``None``) from which the solid angle comes
    (:func:`solid_angle_weight`). A metric whose domain holds no cell is NaN.
    """
    f, m = np.asarray(fitted, float), np.asarray(measured, float)
    wi, wo = np.asarray(wi, float), np.asarray(wo, float)
    ci, co = wi[:, 2], wo[:, 2]
    theta_h, _ = _angles(wi, wo)
    omega = solid_angle_weight(wi, wo, weight)
    ones = np.ones(len(f))
    inside = np.minimum(ci, co) >= np.cos(np.radians(LITERATURE_CUTOFF))
    peak = inside & (theta_h <= np.radians(PEAK_THETA_H))
    log_sq = np.mean((np.log1p(f * ci[:, None]) - np.log1p(m * ci[:, None])) ** 2, axis=1)
    cos_sq = np.mean(((f - m) * ci[:, None]) ** 2, axis=1)
    rel = np.mean(np.abs(f - m) / np.maximum(np.abs(m), RELATIVE_FLOOR), axis=1)
    out = {}
    for suffix, w in (("", ones), ("_sa", omega)):
        out[f"log_rms{suffix}"] = np.sqrt(_weighted_mean(log_sq, w))
        out[f"log_rms_80{suffix}"] = np.sqrt(_weighted_mean(log_sq[inside], w[inside]))
        out[f"cos_rms{suffix}"] = np.sqrt(_weighted_mean(cos_sq, w))
        out[f"ngan_rms_80{suffix}"] = np.sqrt(_weighted_mean(cos_sq[inside], w[inside]))
        out[f"peak_rel{suffix}"] = _weighted_mean(rel[peak], w[peak])
    return {name: float(out[name]) for name in LITERATURE_METRICS}
