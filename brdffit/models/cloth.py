r"""Cloth BRDFs (RTR §9.10.2) and their registered models ``cloth-velvet`` and ``cloth-sheen``.

* :func:`velvet_cloth`: the cloth BRDF of *The Order: 1886*, RTR eq. 9.74, with the generalized
  velvet NDF (RTR eq. 9.73, :class:`brdffit.terms.ndf.sheen.GeneralizedVelvet`): no masking term and
  the modified denominator ``4(n·l + n·v − (n·l)(n·v))``, plus the Fresnel-weighted Lambert
  diffuse of RTR eq. 9.63.
* :func:`sheen_lobe_imageworks`: the Imageworks sheen (RTR eq. 9.75) as a microfacet lobe with
  height-correlated Smith G2 (from the numerical Λ) and ``F = 1``, scaled by a sheen color,
  added to Lambert.

The Disney sheen (RTR eq. 9.72) is :func:`brdffit.models.disney.sheen_lobe`, part of ``disney``.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..terms._math import chi_plus, cos_theta, dot, half_vector, safe_div
from ..terms.diffuse import lambert
from ..terms.fresnel import schlick
from ..terms.microfacet import microfacet_specular
from ..terms.ndf.sheen import GeneralizedVelvet, ImageworksSheen
from .registry import Model, Param, register


def velvet_cloth(ndf, f0, albedo, wi, wo):
    r"""RTR eq. 9.74, RGB ``(..., 3)``:

    .. math:: f = (1 - F(\mathbf h,\mathbf l))\frac{\rho_{ss}}{\pi}
              + \frac{F(\mathbf h,\mathbf l)\,D(\mathbf h)}{4(\mathbf n\cdot\mathbf l
              + \mathbf n\cdot\mathbf v - (\mathbf n\cdot\mathbf l)(\mathbf n\cdot\mathbf v))}

    ``F`` is Schlick's (RTR eq. 9.16) with RGB ``f0``; ``ndf`` gives ``D`` (RTR eq. 9.73).
    """
    h = half_vector(wi, wo)
    ci, co = cos_theta(wi), cos_theta(wo)
    vis = chi_plus(ci) * chi_plus(co)
    f = schlick(jnp.asarray(f0), dot(wi, h))
    spec = safe_div(ndf.D(h), 4.0 * (ci + co - ci * co)) * vis
    return (1.0 - f) * lambert(albedo, wi, wo) + f * spec[..., None]


def sheen_lobe_imageworks(ndf, color, wi, wo):
    """Imageworks sheen: ``color ×`` the microfacet lobe (RTR eq. 9.34) of the sheen NDF (eq. 9.75), F = 1."""
    return jnp.asarray(color) * microfacet_specular(ndf, lambda c: jnp.ones_like(c)[..., None], wi, wo)


DIFFUSE = Param("diffuse", (3,), 0.0, 1.0, 0.3, "subsurface albedo ρ_ss (RGB)", per_channel=True)

CLOTH_VELVET = register(Model(
    name="cloth-velvet",
    description="cloth of The Order: 1886: generalized velvet NDF, no masking, Fresnel-weighted Lambert",
    params=(
        DIFFUSE,
        Param("f0", (3,), 0.0, 1.0, 0.04, "sheen/specular reflectance F0 (RGB), Schlick",
              per_channel=True),
        Param("alpha", (), 0.05, 1.0, 0.4, "width α of the inverted Gaussian (RTR 9.73)", log=True),
        Param("k_amp", (), 0.0, 10.0, 4.0, "amplitude k_amp of the inverted Gaussian (RTR 9.73)"),
    ),
    fn=lambda p, wi, wo: velvet_cloth(GeneralizedVelvet(p["alpha"], p["k_amp"]), p["f0"], p["diffuse"], wi, wo),
    reference="RTR eqs. 9.73, 9.74, 9.16, 9.63",
))

CLOTH_SHEEN = register(Model(
    name="cloth-sheen",
    description="Lambert + Imageworks sheen lobe (RTR 9.75 NDF, Smith G2 from the numerical Λ)",
    params=(
        DIFFUSE,
        Param("sheen", (3,), 0.0, 1.0, 0.5, "sheen color (RGB) scaling the F = 1 sheen lobe",
              per_channel=True),
        Param("alpha", (), 0.1, 1.0, 0.4, "sheen roughness α (RTR 9.75)", log=True),
    ),
    fn=lambda p, wi, wo: lambert(p["diffuse"], wi, wo)
    + sheen_lobe_imageworks(ImageworksSheen(p["alpha"]), p["sheen"], wi, wo),
    reference="RTR eqs. 9.75, 9.34, 9.31, 9.61; Estevez & Kulla 2017",
))
