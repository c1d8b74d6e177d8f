"""Beckmann distribution, isotropic and anisotropic, with the exact and the rational Smith Λ."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.scipy.special import erfc

from .._math import cos2_sin2_phi, safe_sqrt, tan2_theta
from .base import NDF, clamp_alpha

_INV_SQRT_PI = 0.5641895835477563


@jax.custom_jvp
def beckmann_lambda_exact(inv_a):
    r"""Smith Λ of Beckmann, RTR eq. 9.38, as a function of ``u = 1/a = α tan θ`` (eq. 9.37).

    .. math::  \Lambda(a) = \tfrac12\left(\frac{e^{-a^2}}{a\sqrt\pi} - \operatorname{erfc}(a)\right),
        \qquad \frac{d\Lambda}{du} = \frac{e^{-1/u^2}}{2\sqrt\pi}

    the same as 9.38 with ``erf(a) − 1 = −erfc(a)`` (no cancellation at large ``a``). Using
    ``u = 1/a`` keeps the normal direction (``a = ∞``, ``Λ = 0``) finite, values and gradients.
    The derivative (``dΛ/da = −e^{−a²}/(2√π a²)`` times ``da/du = −a²``) is the JVP rule: one
    ``exp`` the value already has, where differentiating ``erfc`` and ``1/u`` costs a fit's
    tangent pass more than the rest of the model.
    """
    return _lambda_and_slope(inv_a)[0]


def _lambda_and_slope(inv_a):
    """``(Λ, dΛ/du)`` of :func:`beckmann_lambda_exact`, sharing ``e^{−a²}``; both 0 at the
    normal (``u ≤ 1e-6``)."""
    ok = inv_a > 1e-6
    a = 1.0 / jnp.where(ok, inv_a, 1.0)
    e = jnp.exp(-a * a)
    lam = 0.5 * (e * inv_a * _INV_SQRT_PI - erfc(a))
    return jnp.where(ok, lam, 0.0), jnp.where(ok, (0.5 * _INV_SQRT_PI) * e, 0.0)


@beckmann_lambda_exact.defjvp
def _beckmann_lambda_exact_jvp(primals, tangents):
    (inv_a,), (du,) = primals, tangents
    lam, slope = _lambda_and_slope(inv_a)
    return lam, slope * du


def beckmann_lambda_rational(inv_a):
    r"""Walter et al.'s rational approximation of Beckmann's Λ, RTR eq. 9.39.

    .. math::  \Lambda(a) \approx \frac{1 - 1.259a + 0.396a^2}{3.535a + 2.181a^2}\ (a < 1.6),
        \quad 0\ (a \ge 1.6)

    written with ``1/a`` (numerator and denominator times ``1/a²``), which removes the pole
    at ``a = 0``: ``((1/a)² − 1.259/a + 0.396) / (3.535/a + 2.181)``.
    """
    lam = (inv_a * inv_a - 1.259 * inv_a + 0.396) / (3.535 * inv_a + 2.181)
    return jnp.where(inv_a > 1.0 / 1.6, lam, 0.0)


class Beckmann(NDF):
    r"""Beckmann NDF with roughness ``alpha_x``, ``alpha_y`` (``alpha_y`` defaults to ``alpha_x``).

    .. math::

        D(\mathbf m) = \frac{\chi^+(\mathbf n\cdot\mathbf m)}{\pi\alpha_x\alpha_y(\mathbf n\cdot\mathbf m)^4}
            \exp\left(-\frac{m_x^2/\alpha_x^2 + m_y^2/\alpha_y^2}{(\mathbf n\cdot\mathbf m)^2}\right)

    RTR eq. 9.52 (anisotropic); with ``alpha_x = alpha_y = alpha_b`` it is RTR eq. 9.35.
    ``D`` is evaluated in log space, so tiny ``α`` and grazing ``m`` give 0, not ``0 · inf``.

    ``Lambda``: the exact erf form, RTR eq. 9.38, or with ``lambda_approx=True`` the rational
    approximation, RTR eq. 9.39; both of ``a`` from eq. 9.37, or eq. 9.51 when anisotropic.
    """

    alpha_x: jax.Array
    alpha_y: jax.Array
    lambda_approx: bool = eqx.field(static=True)
    isotropic: bool = eqx.field(static=True)

    def __init__(self, alpha_x, alpha_y=None, *, lambda_approx=False):
        self.alpha_x = clamp_alpha(alpha_x)
        self.alpha_y = self.alpha_x if alpha_y is None else clamp_alpha(alpha_y)
        self.lambda_approx = bool(lambda_approx)
        self.isotropic = alpha_y is None

    def D(self, wm):  # noqa: N802
        ax, ay = self.alpha_x, self.alpha_y
        mz = wm[..., 2]
        up = mz > 0
        mz2 = jnp.where(up, mz * mz, 1.0)
        slope2 = ((wm[..., 0] / ax) ** 2 + (wm[..., 1] / ay) ** 2) / mz2
        log_d = -slope2 - 2.0 * jnp.log(mz2) - jnp.log(jnp.pi * ax * ay)
        return jnp.where(up, jnp.exp(log_d), 0.0)

    def inv_a(self, w):
        """``1/a = α tan θ`` with ``α² = α_x² cos²φ + α_y² sin²φ`` (RTR eqs. 9.37, 9.51; the
        isotropic form skips the azimuth, and ``tan θ`` is then free of ``α``)."""
        if self.isotropic:
            return self.alpha_x * safe_sqrt(tan2_theta(w))
        c2, s2 = cos2_sin2_phi(w)
        alpha2 = self.alpha_x**2 * c2 + self.alpha_y**2 * s2
        return safe_sqrt(alpha2 * tan2_theta(w))

    def Lambda(self, w):  # noqa: N802
        f = beckmann_lambda_rational if self.lambda_approx else beckmann_lambda_exact
        return f(self.inv_a(w))
