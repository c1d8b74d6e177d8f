r"""Mitsuba 3's ``principled`` BSDF (its reflection part), term for term, as a fit target.

Follows ``src/bsdfs/principled.cpp`` (``Principled::eval``) and ``src/bsdfs/principledhelpers.h``
(``calc_dist_params``, ``principled_fresnel``, ``calc_schlick``, ``schlick_weight``,
``GTR1Isotropic``, ``clearcoat_G``), with ``include/mitsuba/render/microfacet.h`` for the GGX
lobe and ``fresnel.h`` for the dielectric Fresnel, Mitsuba 3.9. ``eval`` returns ``f_r · cos θo``;
the model returns ``f_r``. With ``h = normalize(i + o)``, ``c_d = i·h = o·h``, the Schlick
weight ``w(x) = (1 − x)^5`` (clamped) and ``brdf = 1 − metallic`` (``spec_trans = 0``):

.. math::

    f_r = \underbrace{\frac{F_p\,D\,G}{4\cos\theta_i\cos\theta_o}}_\text{main specular}
        + \underbrace{\tfrac14\,\text{clearcoat}\;F_{cc}\,D_{cc}\,G_{cc}}_\text{clearcoat}
        + \underbrace{\text{brdf}\;\frac{C}{\pi}\,\operatorname{lerp}(f_\text{diff} + f_\text{retro},
              f_{ss}, \text{flatness})}_\text{diffuse}
        + \underbrace{\text{sheen}\,(1 - \text{metallic})\,w(c_d)\,C_\text{sheen}}_\text{sheen}

* ``D``, ``G``: anisotropic GGX with ``α_x = max(0.001, r²/a)``, ``α_y = max(0.001, r² a)``,
  ``a = sqrt(1 − 0.9 anisotropic)``, ``r = roughness`` (``calc_dist_params``), and Mitsuba's
  separable Smith ``G = G1(i) G1(o)`` (RTR eq. 9.27).
* ``F_p`` (``principled_fresnel``, front side):
  ``(1 − m)(1 − t) F_diel(c_d; η) + m · Schlick(C; c_d) + (1 − m) t · Schlick(C_tint R0(η); c_d)``
  with ``m = metallic``, ``t = spec_tint``, the *exact* dielectric Fresnel ``F_diel`` of
  :func:`brdffit.terms.fresnel.dielectric`, ``η = 2/(1 − sqrt(0.08 specular)) − 1`` (the
  constructor's mapping of ``specular``), ``R0(η) = ((η − 1)/(η + 1))²`` and
  ``C_tint = C / lum(C)`` (white if ``lum = 0``), ``lum`` Rec. 709 luminance (0.212671,
  0.715160, 0.072169), Mitsuba's
  ``luminance`` in RGB mode. Mitsuba skips the lobe where ``F_diel = 0``; so does this code.
* Diffuse: ``F_i = w(cos θi)``, ``F_o = w(cos θo)``, ``f_diff = (1 − F_i/2)(1 − F_o/2)``,
  ``R_r = 2 r c_d²``, ``f_retro = R_r (F_o + F_i + F_o F_i (R_r − 1))``, and Mitsuba's fake
  subsurface ``f_ss = 1.25 (F_ss (1/(cos θi + cos θo) − 0.5) + 0.5)``,
  ``F_ss = lerp(1, R_r/2, F_o) lerp(1, R_r/2, F_i)`` (Burley 2012 §5.3).
* Sheen: ``C_sheen = lerp(1, C_tint, sheen_tint)``, no 1/π (Burley 2014 addenda).
* Clearcoat: GTR1 ``D_cc = (α² − 1)/(π ln α² (1 + (α² − 1) cos²θh))`` (Burley 2012 App. B eq. 4)
  with ``α = lerp(0.1, 0.001, clearcoat_gloss)``, ``G_cc`` separable GGX Smith with α = 0.25,
  ``F_cc = Schlick(0.04; c_d)``.

.. warning:: Mitsuba's clearcoat is **not** divided by ``4 cos θi cos θo``: ``eval`` adds
   ``0.25 clearcoat F D G · |cos θo|``, so the lobe's ``f_r`` is ``0.25 clearcoat F D G``
   (Burley's reference shader divides through its ``smithG_GGX``). This model follows Mitsuba;
   the lobe is therefore dimmer than ``disney``'s away from grazing.

Differences from :mod:`brdffit.models.disney` (Burley's reference): the dielectric specular uses
the exact Fresnel of ``η`` (not Schlick with F0 = 0.08 specular), the masking is separable GGX
(same), the luminance is Rec. 709, the clearcoat as warned above, Mitsuba's defaults
(``clearcoat_gloss = 0``, ``sheen_tint = 0``, ``base_color = 0.5``), and ``flatness`` replaces
``subsurface``. Transmission (``spec_trans``) and the back side are not modelled: a reflectance
measurement cannot identify them; the export writes ``spec_trans = 0``.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..terms._math import chi_plus, cos_theta, dot, half_vector, safe_div
from ..terms.fresnel import dielectric, schlick, schlick_weight
from ..terms.masking import G2_separable
from ..terms.ndf import GGX
from .disney import BASE_COLOR_MIN
from .registry import Model, Param, register
from .starts import principled

#: Mitsuba's ``luminance()`` in RGB mode (Rec. 709 / sRGB Y).
LUMINANCE = (0.212671, 0.715160, 0.072169)
#: ``calc_dist_params`` clamps both α at this.
ALPHA_FLOOR = 1e-3
#: Clearcoat: Schlick F0, and the α of its separable GGX masking (``clearcoat_G``).
CLEARCOAT_R0 = 0.04
CLEARCOAT_G_ALPHA = 0.25


def _col(x):
    return jnp.asarray(x)[..., None]


def eta_from_specular(specular):
    r"""Mitsuba's ``η = 2/(1 − sqrt(0.08·specular)) − 1`` (the inverse of ``F0 = 0.08 specular``)."""
    return 2.0 / (1.0 - jnp.sqrt(0.08 * specular)) - 1.0


def dist_alphas(roughness, anisotropic):
    r"""``calc_dist_params``: ``(max(0.001, r²/a), max(0.001, r² a))``, ``a = sqrt(1 − 0.9 anisotropic)``."""
    r2 = roughness**2
    aspect = jnp.sqrt(1.0 - 0.9 * anisotropic)
    return jnp.maximum(ALPHA_FLOOR, r2 / aspect), jnp.maximum(ALPHA_FLOOR, r2 * aspect)


def tint(base_color):
    """``C / lum(C)`` where ``lum > 0``, else white (``principled_fresnel``, sheen tint).

    Discontinuous at black, as Burley's: the fit's lower bound of ``base_color`` is therefore
    :data:`~brdffit.models.disney.BASE_COLOR_MIN` (the reason is in
    :func:`brdffit.models.disney.tint_color`; black-oxidized-steel, full table: 200 steps along
    ``base_color → 0`` at a fixed hue with a bound of 0).
    """
    w = LUMINANCE
    lum = w[0] * base_color[..., 0] + w[1] * base_color[..., 1] + w[2] * base_color[..., 2]
    return safe_div(base_color, lum[..., None], fill=1.0)


def principled_fresnel(base_color, metallic, spec_tint, eta, cos_d):
    """``F_p`` of the main lobe, front side (``principled_fresnel`` with ``eta > 1``): ``(..., 3)``."""
    f_diel = dielectric(eta, cos_d)  # (..., 1)
    r0 = ((eta - 1.0) / (eta + 1.0)) ** 2
    metal = metallic * schlick(base_color, cos_d)
    tinted = (1.0 - metallic) * spec_tint * schlick(tint(base_color) * r0, cos_d)
    return (1.0 - metallic) * (1.0 - spec_tint) * f_diel + metal + tinted, f_diel


def main_specular(p, wi, wo, wm):
    """``F_p D G / (4 cos θi cos θo)``, zero where ``F_diel = 0`` (``spec_reflect_active``)."""
    ax, ay = dist_alphas(p["roughness"], p["anisotropic"])
    ndf = GGX(ax, ay)
    cos_d = dot(wi, wm)
    fresnel, f_diel = principled_fresnel(p["base_color"], p["metallic"], p["spec_tint"],
                                         eta_from_specular(p["specular"]), cos_d)
    geom = safe_div(ndf.D(wm) * G2_separable(ndf, wi, wo, wm), 4.0 * cos_theta(wi) * cos_theta(wo))
    return fresnel * (geom[..., None] * (f_diel > 0.0))


def gtr1(alpha, cos_h):
    """``GTR1Isotropic::eval``, zero where ``D cos θh ≤ 1e-20``."""
    a2 = alpha**2
    d = (a2 - 1.0) / (jnp.pi * jnp.log(a2) * (1.0 + (a2 - 1.0) * cos_h**2))
    return jnp.where(d * cos_h > 1e-20, d, 0.0)


def clearcoat(p, wi, wo, wm):
    """``0.25 clearcoat F_cc D_cc G_cc`` (no ``4 cos θi cos θo``: see the module's warning)."""
    alpha = 0.1 + (0.001 - 0.1) * p["clearcoat_gloss"]
    g = G2_separable(GGX(CLEARCOAT_G_ALPHA), wi, wo, wm)
    f = schlick(jnp.asarray(CLEARCOAT_R0), dot(wi, wm))[..., 0]
    return _col(0.25 * p["clearcoat"] * f * gtr1(alpha, cos_theta(wm)) * g)


def diffuse_and_sheen(p, wi, wo, wm):
    """``(1 − m) C/π lerp(f_diff + f_retro, f_ss, flatness) + sheen (1 − m) w(c_d) C_sheen``."""
    ci, co = cos_theta(wi), cos_theta(wo)
    fi, fo = schlick_weight(ci), schlick_weight(co)
    cos_d = dot(wm, wo)
    rr = 2.0 * p["roughness"] * cos_d**2
    f_diff = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo)
    f_retro = rr * (fo + fi + fo * fi * (rr - 1.0))
    fss90 = 0.5 * rr
    fss = (1.0 + (fss90 - 1.0) * fo) * (1.0 + (fss90 - 1.0) * fi)
    f_ss = 1.25 * (fss * (safe_div(1.0, jnp.maximum(ci, 0.0) + jnp.maximum(co, 0.0)) - 0.5) + 0.5)
    shape = f_diff + f_retro + p["flatness"] * (f_ss - f_diff - f_retro)
    base, m = p["base_color"], p["metallic"]
    diffuse = (1.0 - m) * base / jnp.pi * shape[..., None]
    c_sheen = 1.0 + p["sheen_tint"] * (tint(base) - 1.0)
    sheen = p["sheen"] * (1.0 - m) * schlick_weight(cos_d)[..., None] * c_sheen
    return diffuse + sheen


def mitsuba_principled(p, wi, wo):
    """The whole reflection ``f_r`` of the principled BSDF (see the module docstring): ``(..., 3)``."""
    p = dict(p, base_color=jnp.broadcast_to(jnp.asarray(p["base_color"]), (3,)))
    wm = half_vector(wi, wo)
    vis = (chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo)))[..., None]
    total = main_specular(p, wi, wo, wm) + clearcoat(p, wi, wo, wm) + diffuse_and_sheen(p, wi, wo, wm)
    return total * vis


def _unit(name, default, description):
    return Param(name, (), 0.0, 1.0, default, f"{description} (Mitsuba {name})")


PRINCIPLED_PARAMS = (
    # log-scaled, not scanned: the tint base_color / lum(base_color) has a derivative of
    # ~1/lum near the bound, base_color / lum = O(1) in log base_color
    Param("base_color", (3,), BASE_COLOR_MIN, 1.0, 0.5,
          "surface color, linear RGB (Mitsuba base_color)", log=True, scan=False),
    Param("roughness", (), 0.032, 1.0, 0.5, "roughness; α = roughness² ≥ 0.001 (Mitsuba roughness)",
          log=True),
    _unit("anisotropic", 0.0, "anisotropy, aspect = sqrt(1 − 0.9 anisotropic)"),
    _unit("metallic", 0.0, "0 dielectric, 1 metal (Schlick of base_color), no diffuse"),
    Param("specular", (), 1e-3, 1.0, 0.5, "dielectric IOR via η = 2/(1 − sqrt(0.08 specular)) − 1 "
          "(Mitsuba specular)"),
    _unit("spec_tint", 0.0, "fraction of the dielectric reflection tinted towards base_color"),
    _unit("sheen", 0.0, "strength of the grazing sheen lobe"),
    _unit("sheen_tint", 0.0, "tints sheen towards the base color's hue"),
    _unit("flatness", 0.0, "blend from diffuse + retro-reflection to the fake subsurface"),
    _unit("clearcoat", 0.0, "strength of the GTR1 clearcoat lobe, scale 0.25 clearcoat"),
    _unit("clearcoat_gloss", 0.0, "clearcoat α = lerp(0.1, 0.001, gloss)"),
)

MITSUBA_PRINCIPLED = register(Model(
    name="mitsuba-principled",
    description="Mitsuba 3 principled BSDF (reflection): exact dielectric + Schlick metallic "
    "Fresnel, anisotropic GGX with separable Smith G, retro-reflective diffuse, sheen, clearcoat",
    params=PRINCIPLED_PARAMS,
    fn=mitsuba_principled,
    isotropic=False,
    start=principled,
    reference="Mitsuba 3 src/bsdfs/principled.cpp, principledhelpers.h, "
    "include/mitsuba/render/microfacet.h, fresnel.h; Burley 2012 §5, App. B eq. 4",
))
