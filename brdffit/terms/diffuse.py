"""Diffuse (subsurface) BRDF terms. Each returns ``f_r`` without the cosine factor.

Every term takes its parameters explicitly, directions ``wi``, ``wo`` of shape ``(..., 3)``, and
returns RGB ``(..., 3)`` (an RGB ``albedo`` of shape ``(3,)`` broadcasts against the batch; scalar
parameters such as roughness broadcast against the batch shape ``(...)``). Every term is zero
unless both directions are above the horizon (the ``χ⁺(n·l) χ⁺(n·v)`` of RTR eqs. 9.66, 9.68).
"""

from __future__ import annotations

import jax.numpy as jnp

from ._math import chi_plus, cos_theta, dot, half_vector, safe_div
from .fresnel import schlick_weight


def _visible(wi, wo):
    """``χ⁺(n·l) χ⁺(n·v)`` with a trailing axis, ready to multiply an RGB term."""
    return (chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo)))[..., None]


def lambert(albedo, wi, wo):
    r"""Lambertian diffuse ``f = ρ_ss/π``, RTR eq. 9.61, zero unless both directions are above the horizon.

    ``albedo`` (RGB ``(3,)``) broadcasts to ``(..., 3)``.
    """
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    return (albedo / jnp.pi) * vis[..., None]


def disney_retro(roughness, wi, wo):
    r"""Burley's diffuse shape with retro-reflection, the scalar :math:`f_d` of RTR eq. 9.67.

    .. math::

        f_d = (1 + (F_{D90} - 1)(1 - \mathbf n\cdot\mathbf l)^5)
              (1 + (F_{D90} - 1)(1 - \mathbf n\cdot\mathbf v)^5),\qquad
        F_{D90} = 0.5 + 2\,\text{roughness}\,(\mathbf h\cdot\mathbf l)^2

    Burley 2012 §5.3 (``cos θ_d = h·l``); RTR writes ``roughness`` as ``√α``. Returns ``(...)``.
    """
    cos_d = dot(wi, half_vector(wi, wo))
    fd90 = 0.5 + 2.0 * roughness * cos_d**2
    return (1.0 + (fd90 - 1.0) * schlick_weight(cos_theta(wi))) * (
        1.0 + (fd90 - 1.0) * schlick_weight(cos_theta(wo))
    )


def disney_subsurface(roughness, wi, wo):
    r"""Burley's Hanrahan–Krueger-inspired subsurface shape, ``1.25 f_ss`` of RTR eqs. 9.66/9.67.

    .. math::

        1.25\left[\left(\frac{1}{\mathbf n\cdot\mathbf l + \mathbf n\cdot\mathbf v} - 0.5\right)
            F_{SS} + 0.5\right],\qquad
        F_{SS} = (1 + (F_{SS90} - 1)(1 - \mathbf n\cdot\mathbf l)^5)
                 (1 + (F_{SS90} - 1)(1 - \mathbf n\cdot\mathbf v)^5),\qquad
        F_{SS90} = \text{roughness}\,(\mathbf h\cdot\mathbf l)^2

    .. warning:: RTR eq. 9.67 prints the denominator as the *product* ``(n·l)(n·v)``. This code
       follows Burley's reference implementation (BRDF Explorer ``disney.brdf``) and the
       Hanrahan–Krueger single-scattering term it imitates, both of which use the *sum*
       ``n·l + n·v``; the product would diverge at grazing angles. Returns ``(...)``.
    """
    cos_d = dot(wi, half_vector(wi, wo))
    ci, co = cos_theta(wi), cos_theta(wo)
    fss90 = roughness * cos_d**2
    fss = (1.0 + (fss90 - 1.0) * schlick_weight(ci)) * (1.0 + (fss90 - 1.0) * schlick_weight(co))
    inv_sum = safe_div(1.0, jnp.maximum(ci, 0.0) + jnp.maximum(co, 0.0))
    return 1.25 * ((inv_sum - 0.5) * fss + 0.5)


def disney_diffuse(base_color, roughness, subsurface, wi, wo):
    r"""Disney diffuse with the subsurface blend, RTR eq. 9.66 (Burley 2012 §5.3).

    .. math::

        f_\text{diff} = \chi^+(\mathbf n\cdot\mathbf l)\chi^+(\mathbf n\cdot\mathbf v)
            \frac{\rho_{ss}}{\pi}\left((1 - k_{ss}) f_d + 1.25\,k_{ss} f_{ss}\right)

    with ``ρ_ss = base_color`` (RGB), ``k_ss = subsurface`` and the shapes of
    :func:`disney_retro` and :func:`disney_subsurface`. Reciprocal: both shapes are symmetric in
    ``l, v`` (``h·l = h·v``). Not energy conserving: at ``roughness = 1`` the retro-reflection
    raises the directional albedo above 1 at grazing incidence (Burley: "up to 2.5").
    """
    shape = (1.0 - subsurface) * disney_retro(roughness, wi, wo) + subsurface * disney_subsurface(
        roughness, wi, wo
    )
    return (base_color / jnp.pi) * (shape[..., None] * _visible(wi, wo))


def shirley_coupled(albedo, f0, wi, wo):
    r"""Shirley et al.'s coupled diffuse for a Schlick-Fresnel mirror surface, RTR eq. 9.64.

    .. math::

        f_\text{diff} = \frac{21}{20\pi}(1 - F_0)\,\rho_{ss}
            \left(1 - (1 - (\mathbf n\cdot\mathbf l)^+)^5\right)
            \left(1 - (1 - (\mathbf n\cdot\mathbf v)^+)^5\right)

    Reciprocal and energy conserving: its directional albedo is exactly
    ``(1 - F0) ρ_ss (1 - (1 - n·l)^5) ≤ 1``. ``albedo`` and ``f0`` are RGB or scalar.
    """
    wl = 1.0 - schlick_weight(cos_theta(wi))
    wv = 1.0 - schlick_weight(cos_theta(wo))
    shape = (wl * wv)[..., None] * _visible(wi, wo)
    return (21.0 / (20.0 * jnp.pi)) * (1.0 - f0) * albedo * shape


def oren_nayar(albedo, sigma, wi, wo):
    r"""Oren–Nayar diffuse, the "qualitative model" of Oren & Nayar 1994 (SIGGRAPH, eq. 30).

    .. math::

        f = \frac{\rho}{\pi}\left(A + B\,\max(0, \cos(\phi_i - \phi_o))\sin\alpha\tan\beta\right),
        \quad A = 1 - \frac{0.5\,\sigma^2}{\sigma^2 + 0.33},\quad
        B = \frac{0.45\,\sigma^2}{\sigma^2 + 0.09}

    with ``α = max(θ_i, θ_o)``, ``β = min(θ_i, θ_o)`` and ``σ`` (radians) the standard deviation of
    the facet slope angle; ``σ = 0`` is Lambert. The seed texts only name the model (RTR §9.9.4);
    this follows the 1994 paper's qualitative form (the one pbrt implements), without the
    inter-reflection term of its full model.

    Computed without angles: since ``{sin α, sin β} = {sin θ_i, sin θ_o}``,
    ``cos(φ_i - φ_o) sin α tan β = (l_xy · v_xy) / max(cos θ_i, cos θ_o)``, which is smooth and
    has finite gradients at the pole. Reciprocal. Not guaranteed energy conserving.
    """
    s2 = sigma**2
    a = 1.0 - 0.5 * s2 / (s2 + 0.33)
    b = 0.45 * s2 / (s2 + 0.09)
    azim = jnp.maximum(0.0, wi[..., 0] * wo[..., 0] + wi[..., 1] * wo[..., 1])
    term = safe_div(azim, jnp.maximum(cos_theta(wi), cos_theta(wo)))
    return (albedo / jnp.pi) * ((a + b * term)[..., None] * _visible(wi, wo))


def hammon(albedo, alpha_g, f0, wi, wo):
    r"""Hammon's GGX rough-surface diffuse (two-bounce fit), RTR eqs. 9.68/9.69.

    .. math::

        f_\text{diff} = \chi^+(\mathbf n\cdot\mathbf l)\chi^+(\mathbf n\cdot\mathbf v)
            \frac{\rho_{ss}}{\pi}\left((1 - \alpha_g) f_\text{smooth} + \alpha_g f_\text{rough}
            + \rho_{ss} f_\text{multi}\right)

        f_\text{smooth} = \tfrac{21}{20}(1 - F_0)(1 - (1 - \mathbf n\cdot\mathbf l)^5)
                                       (1 - (1 - \mathbf n\cdot\mathbf v)^5),\quad
        f_\text{rough} = k_f(0.9 - 0.4 k_f)\frac{0.5 + \mathbf n\cdot\mathbf h}{\mathbf n\cdot\mathbf h},

        k_f = 0.5 + 0.5\,\mathbf l\cdot\mathbf v,\quad f_\text{multi} = 0.3641\,\alpha_g

    ``alpha_g`` is the GGX roughness of the matching specular lobe, ``f0`` its normal-incidence
    Fresnel reflectance (RGB or scalar). Reciprocal (symmetric in ``l, v``).
    """
    ci, co = cos_theta(wi), cos_theta(wo)
    f_smooth = 1.05 * (1.0 - f0) * ((1.0 - schlick_weight(ci)) * (1.0 - schlick_weight(co)))[..., None]
    k_facing = 0.5 + 0.5 * dot(wi, wo)
    n_h = cos_theta(half_vector(wi, wo))
    f_rough = k_facing * (0.9 - 0.4 * k_facing) * safe_div(0.5 + n_h, n_h)
    ag = jnp.asarray(alpha_g)
    f_multi = (0.3641 * ag)[..., None]
    mix = (1.0 - ag)[..., None] * f_smooth + (ag * f_rough)[..., None] + albedo * f_multi
    return (albedo / jnp.pi) * mix * _visible(wi, wo)
