"""Beckmann distribution, isotropic and anisotropic, with the exact and the rational Smith Λ."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from .._math import cos2_sin2_phi, safe_sqrt, tan2_theta
from .base import NDF, clamp_alpha

_INV_SQRT_PI = 0.5641895835477563
#: ``D`` is 0 where the squared slope ``tan²θ_m/α²`` exceeds this (``e^{−700} ≈ 1e-304``): a
#: unit ``m`` with ``mz²`` small enough for ``1/mz⁴`` to overflow lies far beyond it.
_MAX_SLOPE2 = 700.0


#: ``erf(a) = (2/√π) Σₙ (−1)ⁿ a²ⁿ⁺¹ / (n! (2n+1))``, its Maclaurin series to ``n = 18`` (the
#: next term is below 1e-17 for ``a ≤ 1``), as Horner coefficients of ``a²``, highest first.
_ERF_SERIES = tuple(
    2.0 / math.sqrt(math.pi) * (-1) ** n / (math.factorial(n) * (2 * n + 1)) for n in range(18, -1, -1)
)

#: ``G(s) = (1 − √π a erfcx(a)) / s`` with ``s = 1/a²`` on ``a ≥ 1``, as the ratio of degree-7
#: polynomials in ``s`` (numerator, denominator; Horner, highest first). ``√π a erfcx(a)`` is a
#: Stieltjes function of ``s`` (Laplace's continued fraction), so rational functions
#: approximate it well on the whole half-line; this one is a least-squares fit of the relative
#: error on Chebyshev nodes of ``s ∈ [0, 1]``, computed with mpmath at 50 digits and reweighted
#: to the relative error eight times: ``|rational/G − 1| < 1e-12`` on ``[0, 1]``
#: (``G(0) = ½``).
_G_NUM = (0.2307325264790818, 47.203728002151436, 297.0521865992943, 515.1189703625669,
          342.03115575297306, 97.60982329884904, 11.890152418589134, 0.4999999999996486)
_G_DEN = (62.46692664765695, 609.1197978483472, 1680.920260414656, 1862.476131436285,
          946.4712796026887, 229.39010426571718, 25.280304835706342, 1.0)


def _horner(coefficients, x):
    """``jnp.polyval(coefficients, x)`` (highest power first) unrolled in Python: the same
    values, where ``jnp.polyval``'s partly unrolled loop took 1.2–1.5× as long on 2e6 values."""
    out = jnp.full_like(x, coefficients[0])
    for c in coefficients[1:]:
        out = out * x + c
    return out


@jax.custom_jvp
def beckmann_lambda_exact(inv_a):
    r"""Smith Λ of Beckmann, RTR eq. 9.38, as a function of ``u = 1/a = α tan θ`` (eq. 9.37).

    .. math::  \Lambda(a) = \tfrac12\left(\frac{e^{-a^2}}{a\sqrt\pi} - \operatorname{erfc}(a)\right),
        \qquad \frac{d\Lambda}{du} = \frac{e^{-1/u^2}}{2\sqrt\pi}

    the same as 9.38 with ``erf(a) − 1 = −erfc(a)``. Using ``u = 1/a`` keeps the normal
    direction (``a = ∞``, ``Λ = 0``) finite, values and gradients. Evaluated with the one
    ``e^{−a²}`` that the derivative also needs, to a relative error below 1e-11:

    * ``a ≤ 1``: ``Λ = ½ (e^{−a²} u/√π − 1 + erf a)``, ``erf`` by its Maclaurin series;
    * ``a > 1``: ``Λ = e^{−a²} u³ G(u²) / (2√π)`` with ``G(s) = (1 − √π a erfcx(a))/s``
      (``erfcx(a) = e^{a²} erfc a``), a rational function of ``s = u²`` (``_G_NUM``,
      ``_G_DEN``): no cancellation however large ``a`` (``Λ ≈ e^{−a²}/(4√π a³)``).

    The derivative (``dΛ/da = −e^{−a²}/(2√π a²)`` times ``da/du = −a²``) is the JVP rule: the
    ``exp`` the value already has, where differentiating ``erfc`` and ``1/u`` costs a fit's
    tangent pass more than the rest of the model.
    """
    return _lambda_and_slope(inv_a)[0]


def _lambda_and_slope(inv_a):
    """``(Λ, dΛ/du)`` of :func:`beckmann_lambda_exact`, sharing ``e^{−a²}``; both 0 at the
    normal (``u ≤ 1e-6``)."""
    ok = inv_a > 1e-6
    u = jnp.where(ok, inv_a, 1.0)
    a = 1.0 / u
    a2 = a * a
    e = jnp.exp(-a2)
    near = 0.5 * (e * u * _INV_SQRT_PI - 1.0 + a * _horner(_ERF_SERIES, jnp.minimum(a2, 1.0)))
    s = u * u
    far = (0.5 * _INV_SQRT_PI) * e * u * s * _horner(_G_NUM, s) / _horner(_G_DEN, s)
    lam = jnp.where(u >= 1.0, near, far)
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
    ``D`` is 0 where ``e^{−tan²θ_m/α²}`` underflows, so tiny ``α`` and grazing ``m`` give 0,
    not ``0 · inf``.

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
        mz2 = jnp.where(mz > 0, mz * mz, 1.0)
        slope2 = ((wm[..., 0] / ax) ** 2 + (wm[..., 1] / ay) ** 2) / mz2
        # exp(−slope²) underflows before 1/mz⁴ can overflow: past this, D is 0 (no 0 · inf)
        up = (mz > 0) & (slope2 < _MAX_SLOPE2)
        d = jnp.exp(-slope2) / (jnp.pi * ax * ay * jnp.where(up, mz2 * mz2, 1.0))
        return jnp.where(up, d, 0.0)

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
