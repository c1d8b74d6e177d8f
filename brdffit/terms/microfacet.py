"""The microfacet specular lobe, composed from any NDF, G2 form and Fresnel term."""

from __future__ import annotations

from ._math import chi_plus, cos_theta, dot, half_vector, safe_div
from .masking import G2_height_correlated


def microfacet_specular(ndf, fresnel, wi, wo, *, g2=G2_height_correlated):
    r"""Cook–Torrance microfacet specular BRDF, RTR eq. 9.34.

    .. math::

        f_\text{spec}(\mathbf l, \mathbf v) =
            \frac{F(\mathbf h, \mathbf l)\,G_2(\mathbf l, \mathbf v, \mathbf h)\,D(\mathbf h)}
                 {4\,|\mathbf n\cdot\mathbf l|\,|\mathbf n\cdot\mathbf v|}

    Args:
        ndf: an NDF object (:mod:`brdffit.terms.ndf`) giving ``D`` and ``Lambda``.
        fresnel: a function of ``h·l`` returning reflectance, e.g.
            ``functools.partial(brdffit.terms.fresnel.schlick, f0)``; RGB gives an RGB lobe.
        wi, wo: unit directions ``(..., 3)``.
        g2: a masking-shadowing form from :mod:`brdffit.terms.masking` (height-correlated by
            default).

    Returns ``(..., 3)`` (or the Fresnel's trailing shape); zero unless both directions are above
    the horizon.
    """
    wm = half_vector(wi, wo)
    ci, co = cos_theta(wi), cos_theta(wo)
    vis = chi_plus(ci) * chi_plus(co)
    geom = safe_div(g2(ndf, wi, wo, wm) * ndf.D(wm), 4.0 * ci * co) * vis
    return fresnel(dot(wi, wm)) * geom[..., None]
