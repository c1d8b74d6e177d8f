r"""Uncertainty and error figures at the optimum.

Both covariance estimates use the Gauss–Newton approximation :math:`H \approx J^\top J` at the
optimum, with ``J`` the Jacobian of the residual with respect to the free physical scalars that
are *not* at a bound (``m`` residuals with non-zero weight, ``p`` such scalars):

* ``"sandwich"`` (the default; Huber 1967, White 1980, with the ``m/(m-p)`` correction):

  .. math:: \mathrm{Cov}(\hat x) \approx \frac{m}{m-p}\,(J^\top J)^{-1}
            \Bigl(\sum_i r_i^2\, J_i^\top J_i\Bigr)(J^\top J)^{-1}

* ``"gn"`` (the classical estimate of ``scipy.optimize.curve_fit``):

  .. math:: \mathrm{Cov}(\hat x) \approx s^2 (J^\top J)^{-1}, \qquad s^2 = \frac{\sum r^2}{m-p}

The classical estimate assumes every residual has the same variance. Under the default ``log``
loss, multiplicative noise is *not* homoscedastic (a residual's spread is ``σ ρcosθ/(1+ρcosθ)``:
``σ`` on the peak, ``~0.01σ`` on a dark diffuse floor), hence the sandwich by default: with 2%
multiplicative noise on ``ggx`` tables the classical estimate's ``|z|`` reached 4.8, the
sandwich's root-mean-square ``z`` stayed within 0.5–1.2 for every parameter.

Delta method: ``J_x = J_u (∂x/∂u)⁻¹``, so the bounds transform cancels and the covariance is in
physical units. Scalars at a bound are held fixed (their ``∂x/∂u`` vanishes), as scipy's
``least_squares`` does with its active set.

Identification (:func:`not_identified`): in the box coordinates ``z`` (:mod:`.transforms`) a
scalar's whole range is one unit, so ``JᵀJ`` there compares the scalars on one scale. A free
scalar off its bounds is **not identified** when

* the curvature of the cost along it, with the other such scalars re-fitted (the Schur
  complement :math:`H_{kk} - H_{k,o} H_{oo}^{+} H_{o,k}` of ``H = JᵀJ`` in ``z``), is at most
  ``RANK_RTOL`` (:mod:`.normal_form`: the rank the solver itself resolves) of the largest
  diagonal entry of ``H`` over all free scalars: the parameter does nothing the others cannot
  do, e.g. a lobe's width when its amplitudes sit on zero, or two scalars that only enter as a
  product; or
* one standard error spans its whole range (:math:`\sigma_z \ge 1`): the data cannot place it
  within its bounds (for a scalar fitted in log space ``z`` is its logarithm scaled by the
  range, so this is a relative standard error of ``ln(hi/lo)``, ≫ 1); or
* its variance is not a positive finite number (the pseudo-inverse dropped its direction).

A relative standard error alone decides nothing for a scalar fitted linearly: a metal's
diffuse albedo of ``1e-6 ± 1e-4`` is well determined (near zero), not unidentified.

Such scalars get no standard error: they are held at their values, like those on a bound, and
the covariance is that of the others.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .data import FitData
from .losses import RELATIVE_FLOOR
from .normal_form import RANK_RTOL


#: What each covariance estimator is, in words and symbols (the summary, the reports and the
#: JSON name it): ``m`` residuals with non-zero weight, ``p`` scalars with a standard error.
ESTIMATORS = {
    "sandwich": ("sandwich (Huber–White): (JᵀJ)⁻¹ (Σ rᵢ² JᵢᵀJᵢ) (JᵀJ)⁻¹ · m/(m − p), J the "
                 "Gauss–Newton Jacobian at the optimum; no common residual variance assumed"),
    "gn": ("Gauss–Newton: s² (JᵀJ)⁻¹, J the Jacobian at the optimum, s² = Σr²/(m − p) the "
           "residual variance, one for all residuals"),
}
#: What every estimator assumes, and what it therefore leaves out.
ESTIMATOR_CAVEAT = ("residuals taken as independent: the model error of a fit to a measured "
                    "BRDF is correlated from cell to cell, so ± understates the uncertainty "
                    "there and does not cover the model error")


def estimator_text(kind: str) -> str:
    """:data:`ESTIMATORS` ``[kind]`` (the kind itself for one not listed)."""
    return ESTIMATORS.get(kind, kind)


#: The length of :func:`cell_metric_sums`.
N_CELL_SUMS = 4


def cell_metric_sums(pred, data: FitData):
    """Sums over one block of cells behind :func:`metrics_from`: ``m`` (residuals with non-zero
    weight), ``Σ (Δρ cosθi cosθo)²``, ``Σ (Δ log(1 + ρ cosθi))²``, ``Σ |Δρ|/max(ρ, 10⁻³)``.

    ``m`` comes first: :func:`brdffit.fitting.normal_form.gram` and the solver's statistical
    test read it there. ``pred`` is the model's ``f_r`` ``(n, 3)`` from the normal form's pass
    (:meth:`brdffit.fitting.problem.Problem.block_sums`), so the figures at the optimum cost no
    pass of their own.
    """
    dt = jnp.promote_types(data.rgb.dtype, jnp.float32)
    pred = pred.astype(dt)
    mask = (data.sqrt_weight > 0).astype(dt)
    diff = (pred - data.rgb) * mask
    ci, co = data.wi[:, 2:3].astype(dt), data.wo[:, 2:3].astype(dt)
    log_diff = jnp.log1p(pred * ci) - jnp.log1p(data.rgb * ci)
    rel = jnp.abs(diff) / jnp.maximum(jnp.abs(data.rgb), RELATIVE_FLOOR)
    return jnp.stack([
        jnp.sum(mask), jnp.sum((diff * ci * co) ** 2), jnp.sum((log_diff * mask) ** 2),
        jnp.sum(rel * mask),
    ])


def metrics_from(sum_r2, sums):
    """Error figures over the cells used (non-zero weight): ``(dict, cost, m)`` from ``Σ r²`` and
    the :func:`cell_metric_sums` of all blocks. The names, their order and their formulas are
    :data:`brdffit.metrics.METRICS`."""
    m = jnp.maximum(sums[0], 1.0)
    return {
        "rmse": jnp.sqrt(sum_r2 / m),
        "rmse_cosine": jnp.sqrt(sums[1] / m),
        "rmse_log": jnp.sqrt(sums[2] / m),
        "rel_error": sums[3] / m,
    }, 0.5 * sum_r2, m


def covariance(jtj_u, meat_u, dxdu, sum_r2: float, m: float, keep: np.ndarray, kind: str):
    """Covariance over the ``keep`` scalars (zero elsewhere), and whether ``JᵀJ`` is regular.

    ``jtj_u``, ``meat_u`` are ``JᵀJ`` and ``Jᵀdiag(r²)J`` in the unconstrained coordinates at the
    optimum; ``J_x = J_u diag(∂x/∂u)⁻¹`` converts them to physical units. ``kind`` is
    ``"sandwich"`` or ``"gn"`` (module docstring).
    """
    jtj_u, meat_u, dxdu = (np.asarray(a, float) for a in (jtj_u, meat_u, dxdu))
    k = np.flatnonzero(keep)
    cov = np.zeros_like(jtj_u)
    if len(k) == 0:
        return cov, True
    d = np.outer(dxdu[k], dxdu[k])
    bread, meat = jtj_u[np.ix_(k, k)] / d, meat_u[np.ix_(k, k)] / d
    scale = np.sqrt(np.clip(np.diag(bread), 1e-300, None))
    corr = bread / np.outer(scale, scale)
    w = np.linalg.eigvalsh(corr)
    regular = bool(w.min() > 1e-12 * max(w.max(), 1e-300))
    inv = np.linalg.pinv(corr, rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    if kind == "gn":
        cov[np.ix_(k, k)] = inv * (sum_r2 / max(m - len(k), 1.0))
    else:
        cov[np.ix_(k, k)] = inv @ meat @ inv * (m / max(m - len(k), 1.0))
    return cov, regular


def correlation(cov, stderr) -> np.ndarray:
    """The correlation matrix ``cov[i, j] / (σ_i σ_j)`` (clipped to [-1, 1]) with ``σ`` the
    standard errors ``stderr``; NaN in every row and column whose ``σ`` is not a positive finite
    number (no standard error: no correlation), 1 on the rest of the diagonal."""
    cov, se = np.asarray(cov, float), np.asarray(stderr, float)
    out = np.full(cov.shape, np.nan)
    k = np.flatnonzero(np.isfinite(se) & (se > 0))
    out[np.ix_(k, k)] = np.clip(cov[np.ix_(k, k)] / np.outer(se[k], se[k]), -1.0, 1.0)
    out[k, k] = 1.0
    return out


def schur_deficient(jtj_z, keep: np.ndarray) -> np.ndarray:
    """Over the free scalars: those of ``keep`` whose Schur complement in ``JᵀJ`` (box
    coordinates, against the other ``keep`` scalars) is at most ``RANK_RTOL`` of the largest
    diagonal entry of ``JᵀJ`` (module docstring); all of ``keep`` when ``JᵀJ`` is zero."""
    h = np.asarray(jtj_z, float)
    keep = np.asarray(keep, bool)
    out = np.zeros(len(keep), bool)
    diag = np.diagonal(h)
    ref = float(np.max(diag)) if diag.size else 0.0
    k = np.flatnonzero(keep)
    if not ref > 0 or not np.all(np.isfinite(h)):
        out[k] = True
        return out
    hk = h[np.ix_(k, k)]
    d = np.sqrt(np.clip(np.diagonal(hk), 0.0, None))
    scale = np.where(d > 0, d, 1.0)
    corr = hk / np.outer(scale, scale)
    for j in range(len(k)):
        o = np.arange(len(k)) != j
        c = corr[o, j]
        explained = c @ np.linalg.pinv(corr[np.ix_(o, o)], rcond=1e-12, hermitian=True) @ c
        schur = hk[j, j] * max(1.0 - explained, 0.0) if o.any() else hk[j, j]
        out[k[j]] = schur <= RANK_RTOL * ref
    return out


def beyond_range(cov_free, dxdz, keep: np.ndarray) -> np.ndarray:
    """Over the free scalars: those of ``keep`` with a standard error of at least their whole
    range, ``σ_x ≥ |∂x/∂z|`` (module docstring), or with none at all (a variance that is not a
    positive finite number: the pseudo-inverse dropped the scalar's direction, so ``± 0``
    would claim a precision the data do not give)."""
    var = np.diagonal(np.asarray(cov_free, float))
    dxdz = np.abs(np.asarray(dxdz, float))
    return np.asarray(keep, bool) & ~((var < dxdz**2) & (var > 0))


def identified_covariance(jtj_z, meat_z, dxdz, sum_r2: float, m: float, interior: np.ndarray,
                          kind: str):
    """``(cov, regular, lost)``: :func:`covariance` over the ``interior`` scalars that are
    identified, and ``lost``, those that are not (module docstring)."""
    lost = schur_deficient(jtj_z, interior)
    for _ in range(len(lost) + 1):
        keep = np.asarray(interior, bool) & ~lost
        cov, regular = covariance(jtj_z, meat_z, dxdz, sum_r2, m, keep, kind)
        wide = beyond_range(cov, dxdz, keep)
        if not wide.any():
            return cov, regular, lost
        lost = lost | wide
    return cov, regular, lost
