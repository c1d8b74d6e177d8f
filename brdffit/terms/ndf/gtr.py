"""Generalized Trowbridge–Reitz (GTR) distribution with free tail exponent ``γ``."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .base import NDF, clamp_alpha
from .ggx import GGX
from .numerical import N_QUAD_TABLE, N_THETA, ProjectedAreaTable, numerical_lambda

#: ``γ`` is clamped to at least this (``γ → 0`` is the uniform NDF ``1/π``).
GAMMA_MIN = 1e-3
#: Below this ``|x|`` :func:`log_exprel` uses its Taylor series.
_SERIES_BELOW = 1e-2


def log_exprel(x):
    r"""``log((eˣ − 1)/x)``, finite with finite gradients everywhere (``0`` at ``x = 0``).

    Taylor series ``log1p(x/2 + x²/6 + x³/24 + x⁴/120)`` for ``|x| < 0.01`` (truncation
    ``< 1.4e-13`` relative), else ``x + log(−expm1(−x)) − log x`` for ``x > 0`` (no overflow)
    and ``log(−expm1(x)) − log(−x)`` for ``x < 0``.
    """
    small = jnp.abs(x) < _SERIES_BELOW
    xs = jnp.where(small, x, 0.0)
    series = jnp.log1p(xs * (0.5 + xs * (1.0 / 6.0 + xs * (1.0 / 24.0 + xs / 120.0))))
    pos = x >= _SERIES_BELOW
    xp = jnp.where(pos, x, 1.0)
    big_pos = xp + jnp.log(-jnp.expm1(-xp)) - jnp.log(xp)
    neg = x <= -_SERIES_BELOW
    xn = jnp.where(neg, x, -1.0)
    big_neg = jnp.log(-jnp.expm1(xn)) - jnp.log(-xn)
    return jnp.where(small, series, jnp.where(pos, big_pos, big_neg))


def gtr_log_normalization(alpha, gamma):
    r"""``log k(α, γ)`` of RTR eq. 9.47 (Burley 2012 App. B eqs. 1, 4), stable at γ = 1, α = 1.

    With ``u = ln α²`` and ``δ = 1 − γ``, eq. 9.47's three cases are one expression,

    .. math::

        k = \frac{(\gamma - 1)(\alpha^2 - 1)}{1 - (\alpha^2)^{1-\gamma}}
          = \frac{\delta\,(e^{u} - 1)}{e^{\delta u} - 1}
          = \frac{\operatorname{exprel}(u)}{\operatorname{exprel}(\delta u)},
        \qquad \operatorname{exprel}(x) = \frac{e^x - 1}{x},

    whose removable singularities are ``exprel(0) = 1``: ``γ = 1`` gives ``(α² − 1)/ln α²``
    (App. B eq. 4) and ``α = 1`` gives 1. Computed as a difference of :func:`log_exprel`, so
    large ``γ`` with tiny ``α`` does not overflow even in float32.
    """
    u = jnp.log(alpha * alpha)
    return log_exprel(u) - log_exprel((1.0 - gamma) * u)


def _is_concrete_two(gamma) -> bool:
    try:
        return bool(np.all(np.asarray(gamma) == 2.0))
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return False


class GTR(NDF):
    r"""GTR NDF (Burley 2012 App. B eq. 1; RTR eqs. 9.46, 9.47), isotropic.

    .. math::  D(\mathbf m) = \frac{k(\alpha,\gamma)\,\chi^+(\mathbf n\cdot\mathbf m)}
        {\pi\,\left(1 + (\mathbf n\cdot\mathbf m)^2(\alpha^2 - 1)\right)^\gamma}

    with ``k`` from :func:`gtr_log_normalization` (App. B eqs. 1, 4, 6, 8 are its cases
    ``γ ≠ 1``, ``γ = 1``, ``3/2``, ``2``). The base is evaluated as ``α² m_z² + m_x² + m_y²``
    (equal for unit ``m``), free of cancellation at the peak, and ``D`` in log space.

    ``Lambda``: GTR is not shape-invariant and has no general closed-form Λ (RTR p. 345).
    When ``γ`` is a concrete 2 (a Python number or a concrete array, not a traced value) this
    is GGX's closed form, RTR eq. 9.42; otherwise it is the numerical Λ of
    :mod:`brdffit.terms.ndf.numerical` (weak white furnace, RTR 9.23/9.24), so inside a fit, where
    ``γ`` is traced, the numerical Λ is used for every ``γ`` including 2 (G1 within 1.0e-7 of
    the closed form there, measured over α ∈ [0.005, 1]; other γ: see that module) and
    ``∂Λ/∂γ`` stays correct.

    ``alpha`` and ``gamma`` are scalars (batch over parameter sets with ``jax.vmap``): each
    ``Lambda`` call builds one θ table from them (``n_theta`` nodes, ``4 · n_quad`` quadrature
    nodes each) and interpolates it for every direction. ``table`` (from :meth:`lambda_table`
    of the same ``α, γ``) skips that build: the fitter builds it once per pass over the table
    instead of once per block of cells (``Model.per_pass``).
    """

    alpha: jax.Array
    gamma: jax.Array
    table: ProjectedAreaTable | None
    closed_form_lambda: bool = eqx.field(static=True)
    n_theta: int = eqx.field(static=True)
    n_quad: int = eqx.field(static=True)

    def __init__(self, alpha, gamma, *, table=None, n_theta=N_THETA, n_quad=N_QUAD_TABLE):
        self.alpha = clamp_alpha(alpha)
        self.gamma = jnp.maximum(jnp.asarray(gamma), GAMMA_MIN)
        self.table = table
        self.closed_form_lambda = _is_concrete_two(gamma)
        self.n_theta, self.n_quad = int(n_theta), int(n_quad)

    def lambda_table(self) -> ProjectedAreaTable:
        """The θ table of the numerical Λ (:class:`ProjectedAreaTable`) of this ``α, γ``."""
        return ProjectedAreaTable.build(self.D, self.alpha, n_theta=self.n_theta,
                                        n_quad=self.n_quad, dtype=jnp.result_type(self.alpha))

    def D(self, wm):  # noqa: N802
        mz = wm[..., 2]
        base = self.alpha**2 * mz * mz + wm[..., 0] ** 2 + wm[..., 1] ** 2
        base = jnp.where(mz > 0, base, 1.0)
        log_d = gtr_log_normalization(self.alpha, self.gamma) - jnp.log(jnp.pi) - self.gamma * jnp.log(base)
        return jnp.where(mz > 0, jnp.exp(log_d), 0.0)

    def Lambda(self, w):  # noqa: N802
        if self.closed_form_lambda:
            return GGX(self.alpha).Lambda(w)
        if self.table is not None:
            return self.table.Lambda(w)
        return numerical_lambda(self.D, w, self.alpha, n_theta=self.n_theta, n_quad=self.n_quad)
