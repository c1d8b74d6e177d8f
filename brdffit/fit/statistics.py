r"""Uncertainty and error figures at the optimum.

Covariance (Gauss–Newton approximation, in physical units): with ``J`` the Jacobian of the
residual with respect to the free physical scalars that are *not* at a bound,

.. math::

    \mathrm{Cov}(\hat x) \approx s^2 (J^\top J)^{-1}, \qquad s^2 = \frac{\sum r^2}{m - p},

``m`` the number of residuals with non-zero weight and ``p`` the number of those scalars. This is
the delta method applied to the unconstrained fit: ``J_x = J_u (∂x/∂u)^{-1}``, so the transform
cancels and ``J`` is differentiated in physical units directly. Scalars at a bound are held
fixed (their ``∂x/∂u`` vanishes), as scipy's ``least_squares`` does with its active set.
The estimate assumes homoscedastic residuals under the chosen loss: for multiplicative noise
use ``log`` or ``relative``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .data import FitData
from .losses import RELATIVE_FLOOR
from .problem import Problem


def metrics_at(problem: Problem, x_free, data: FitData):
    """Error figures over the cells used (mask: non-zero weight): ``(dict, cost, m)``."""
    pred = problem.predict(x_free, data).astype(data.rgb.dtype)
    r = problem.residual_x(x_free, data).astype(data.rgb.dtype)
    mask = (data.sqrt_weight > 0).astype(data.rgb.dtype)
    m = jnp.maximum(jnp.sum(mask), 1.0)
    diff = (pred - data.rgb) * mask

    def rms(a):
        return jnp.sqrt(jnp.sum((a * mask) ** 2) / m)

    ci, co = data.wi[:, 2:3], data.wo[:, 2:3]
    log_diff = jnp.log1p(pred * ci) - jnp.log1p(data.rgb * ci)
    rel = jnp.abs(diff) / jnp.maximum(jnp.abs(data.rgb), RELATIVE_FLOOR)
    return {
        "rmse": jnp.sqrt(jnp.sum(r**2) / m),
        "rmse_cosine": rms(diff * ci * co),
        "rmse_log": rms(log_diff),
        "rel_error": jnp.sum(rel * mask) / m,
    }, 0.5 * jnp.sum(r**2), m


def covariance(jtj_u, dxdu, sum_r2: float, m: float, keep: np.ndarray):
    """``s² (J_xᵀJ_x)⁻¹`` over the ``keep`` scalars (zero elsewhere) and whether it is regular.

    ``jtj_u`` is the Gauss–Newton matrix in the unconstrained coordinates at the optimum (what the
    solver factored); ``J_x = J_u diag(∂x/∂u)⁻¹`` converts it to physical units.
    """
    jtj_u, dxdu = np.asarray(jtj_u, float), np.asarray(dxdu, float)
    k = np.flatnonzero(keep)
    cov = np.zeros_like(jtj_u)
    if len(k) == 0:
        return cov, True
    sub = jtj_u[np.ix_(k, k)] / np.outer(dxdu[k], dxdu[k])
    dof = max(m - len(k), 1.0)
    scale = np.sqrt(np.clip(np.diag(sub), 1e-300, None))
    corr = sub / np.outer(scale, scale)
    w = np.linalg.eigvalsh(corr)
    regular = bool(w.min() > 1e-12 * max(w.max(), 1e-300))
    inv = np.linalg.pinv(corr, rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    cov[np.ix_(k, k)] = inv * (sum_r2 / dof)
    return cov, regular
