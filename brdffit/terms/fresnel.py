"""Fresnel reflectance terms ``F(h, l)`` and conversions between their parameters.

Each reflectance function takes the cosine between the light (or view) direction and the
microfacet normal, ``cos_d = wi · wm``, batched ``(...)``, and its optical parameters, which
broadcast against ``cos_d[..., None]``: an RGB parameter of shape ``(3,)`` gives ``(..., 3)``, a
scalar gives ``(..., 1)``. So every term composes with
:func:`brdffit.terms.microfacet.microfacet_specular` through ``functools.partial(term, params...)``.

Optical constants are *relative*: ``eta = n_t / n_i`` (the medium the light refracts into over
the medium it comes from; ``n_i = 1`` in air) and, for conductors, ``eta + i k``.
"""

from __future__ import annotations

import jax.numpy as jnp

from ._math import safe_div, safe_sqrt


def schlick(f0, cos_d, f90=1.0):
    r"""Schlick's approximation, RTR eq. 9.16, as used by Burley 2012 §5.5; with ``f90`` the
    generalized form of RTR eq. 9.18 (exponent ``1/p = 5``).

    .. math:: F(\mathbf h, \mathbf l) \approx F_0 + (F_{90} - F_0)(1 - (\mathbf h\cdot\mathbf l)^+)^5

    ``F90 = 1`` (the default) is eq. 9.16: every material reflects everything at grazing
    incidence. A free ``F90 < 1`` decouples the grazing reflectance from the normal one, the
    second degree of freedom that the Cook–Torrance fits of measured materials get from a free
    specular scale ``k_s`` and a free ``F0`` (``k_s F(F0)`` is this form with ``F90 = k_s``);
    ``0 ≤ F0, F90 ≤ 1`` keeps ``0 ≤ F ≤ 1``.

    ``f0`` and ``f90`` broadcast against ``cos_d[..., None]`` (RGB ``f0`` of shape ``(3,)`` gives
    ``(..., 3)``); a scalar ``f0`` with scalar output is obtained by passing ``f0[..., None]``.
    """
    m = jnp.clip(1.0 - cos_d, 0.0, 1.0)[..., None]
    return f0 + (f90 - f0) * m**5


def f90_from_rise(f0, rise):
    r"""The grazing reflectance ``F90`` of a rise ``t`` from ``F0`` towards 1, per channel:

    .. math:: F_{90} = F_0 + (1 - F_0)\,t, \qquad 0 \le t \le 1

    The parameterization of the generalized Schlick term (RTR eq. 9.18) by which a fit can
    only return a physical surface: for every ``0 ≤ F0 ≤ 1`` and ``0 ≤ t ≤ 1`` it gives
    ``F0 ≤ F90 ≤ 1`` in every channel, so the reflectance never falls towards grazing
    incidence. ``t = 1`` is plain Schlick (eq. 9.16, what every renderer uses), ``t = 0`` a
    reflectance without a grazing rise, ``F = F0`` at every angle. A scalar ``t`` keeps
    :func:`schlick`'s channel ``c`` a function of ``F0[c]`` alone:
    ``F = F0 + (1 − F0) t (1 − cos θd)^5``.

    A free scalar ``F90`` on ``[0, 1]``, the form this replaces, lets a fit end with ``F90 < F0``
    (a metal's reflectance that falls to 0 at grazing incidence), which no surface does and
    no renderer shows.
    """
    return f0 + (1.0 - f0) * rise


def schlick_weight(cos_d):
    r"""The Schlick shape ``(1 - cos)^5`` alone, clamped to ``[0, 1]`` (Burley 2012 §5.3, §5.5).

    Burley's diffuse retro-reflection and sheen use it as a blending weight,
    ``lerp(a, b, (1 - cos)^5)``. Batch shape ``(...)``, no trailing axis.
    """
    return jnp.clip(1.0 - cos_d, 0.0, 1.0) ** 5


def dielectric(eta, cos_d):
    r"""Exact unpolarised Fresnel reflectance of a dielectric interface (Fresnel's equations).

    .. math::

        r_\parallel = \frac{\eta\cos\theta_i - \cos\theta_t}{\eta\cos\theta_i + \cos\theta_t},\quad
        r_\perp = \frac{\cos\theta_i - \eta\cos\theta_t}{\cos\theta_i + \eta\cos\theta_t},\quad
        F = \tfrac12\left(r_\parallel^2 + r_\perp^2\right)

    with Snell's law :math:`\sin^2\theta_t = \sin^2\theta_i/\eta^2` (RTR §9.5, whose eq. 9.16
    approximates this; the form is pbrt-v4's ``FrDielectric``).

    Args:
        eta: relative index of refraction ``n_t / n_i`` (scalar or RGB), ``> 0``.
        cos_d: cosine of the incidence angle ``(...)``. A negative cosine means the light arrives
            from the other side (inside the medium): the code then uses ``1/eta`` and ``|cos_d|``,
            pbrt's convention.

    Total internal reflection (``sin^2 θ_t ≥ 1``, only possible when the effective ``eta < 1``)
    gives exactly 1, with zero (finite) gradients. Normal incidence gives
    ``((eta - 1)/(eta + 1))^2`` (:func:`f0_from_ior`), grazing incidence gives 1.
    """
    c = jnp.clip(cos_d, -1.0, 1.0)[..., None]
    eta = jnp.where(c < 0, 1.0 / eta, eta)
    c = jnp.abs(c)
    sin2_t = safe_div(1.0 - c**2, eta**2)
    tir = sin2_t >= 1.0
    cos_t = safe_sqrt(1.0 - sin2_t)
    r_par = safe_div(eta * c - cos_t, eta * c + cos_t, fill=1.0)
    r_perp = safe_div(c - eta * cos_t, c + eta * cos_t, fill=1.0)
    return jnp.where(tir, 1.0, 0.5 * (r_par**2 + r_perp**2))


def conductor(eta, k, cos_d):
    r"""Exact unpolarised Fresnel reflectance of a conductor with complex index ``eta + i k``.

    The complex Fresnel equations (pbrt-v4 ``FrComplex``) written in real arithmetic, after
    pbrt-v3's ``FrConductor`` (the closed form of Lazányi & Szirmay-Kalos 2005):

    .. math::

        a^2 + b^2 = \sqrt{(\eta^2 - k^2 - \sin^2\theta)^2 + 4\eta^2k^2},\quad
        a = \sqrt{\tfrac12(a^2 + b^2 + \eta^2 - k^2 - \sin^2\theta)}

        R_s = \frac{a^2 + b^2 - 2a\cos\theta + \cos^2\theta}{a^2 + b^2 + 2a\cos\theta + \cos^2\theta},
        \quad
        R_p = R_s\,\frac{\cos^2\theta\,(a^2 + b^2) - 2a\cos\theta\sin^2\theta + \sin^4\theta}
                        {\cos^2\theta\,(a^2 + b^2) + 2a\cos\theta\sin^2\theta + \sin^4\theta},
        \quad F = \tfrac12 (R_s + R_p)

    Real arithmetic keeps gradients in ``eta`` and ``k`` finite everywhere (square roots go
    through :func:`~brdffit.terms._math.safe_sqrt`). With ``k = 0`` it equals :func:`dielectric` for
    ``cos_d ≥ 0``. ``eta``, ``k``: per channel (scalar or RGB), ``cos_d`` is clamped to ``[0, 1]``.
    """
    c = jnp.clip(cos_d, 0.0, 1.0)[..., None]
    c2 = c**2
    s2 = 1.0 - c2
    t0 = eta**2 - k**2 - s2
    a2b2 = safe_sqrt(t0**2 + 4.0 * eta**2 * k**2)
    a = safe_sqrt(0.5 * (a2b2 + t0))
    rs = safe_div(a2b2 - 2.0 * a * c + c2, a2b2 + 2.0 * a * c + c2, fill=1.0)
    t1 = c2 * a2b2 + s2**2
    t2 = 2.0 * a * c * s2
    rp = rs * safe_div(t1 - t2, t1 + t2, fill=1.0)
    return 0.5 * (rs + rp)


def f0_from_ior(eta):
    r"""Normal-incidence reflectance of a dielectric, :math:`F_0 = ((\eta - 1)/(\eta + 1))^2` (RTR eq. 9.17)."""
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def ior_from_f0(f0):
    r"""Inverse of :func:`f0_from_ior` on the branch ``eta ≥ 1``: :math:`\eta = (1 + \sqrt{F_0})/(1 - \sqrt{F_0})`.

    Valid for ``0 ≤ f0 < 1`` (``f0 → 1`` gives ``eta → ∞``). Burley's ``specular`` parameter maps
    to ``f0 = 0.08 · specular``, so ``specular = 0.5`` is ``f0 = 0.04``, ``eta = 1.5``.
    """
    s = jnp.sqrt(f0)
    return (1.0 + s) / (1.0 - s)


def f0_from_conductor(eta, k):
    r"""Normal-incidence reflectance of a conductor, :math:`F_0 = ((\eta-1)^2 + k^2)/((\eta+1)^2 + k^2)`.

    The value of :func:`conductor` at ``cos_d = 1``; use it to seed a Schlick fit of a metal.
    """
    return ((eta - 1.0) ** 2 + k**2) / ((eta + 1.0) ** 2 + k**2)
