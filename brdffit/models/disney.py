r"""The Disney "principled" BRDF (Burley 2012 §5 with its 2014 addenda), lobe by lobe.

.. math::

    f = (1 - \text{metallic})\,(f_\text{diffuse} + f_\text{sheen}) + f_\text{specular}
        + f_\text{clearcoat}

Each lobe is its own function of explicit parameters; :func:`disney` composes them and is
registered as the model ``disney``. Where Burley's notes leave a detail out, the code follows his
reference implementation, BRDF Explorer's ``disney.brdf`` (the 2014 revision that goes with the
addenda), and says so in the lobe's docstring.

Parameter names are snake_case versions of Burley's camelCase names: ``base_color`` =
*baseColor*, ``specular_tint`` = *specularTint*, ``sheen_tint`` = *sheenTint*,
``clearcoat_gloss`` = *clearcoatGloss*; ``subsurface``, ``metallic``, ``specular``,
``roughness``, ``anisotropic``, ``sheen``, ``clearcoat`` are unchanged. ``base_color`` is taken
as *linear* RGB (the reference shader converts a display-referred color with ``pow(c, 2.2)``
first; a fit to measured data has no display color to convert).

Conventions: the anisotropy axes are the frame's tangent ``x`` (α_x, the long axis of the
highlight's microfacet slopes) and bitangent ``y``; rotating the frame about ``n`` changes the
result when ``anisotropic > 0``, so the model is declared ``isotropic=False``.
"""

from __future__ import annotations

from functools import partial

import jax.numpy as jnp

from ..terms._math import chi_plus, cos_theta, dot, half_vector, safe_div
from ..terms.diffuse import disney_diffuse
from ..terms.fresnel import schlick, schlick_weight
from ..terms.masking import G2_separable
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX, GTR
from .registry import Model, Param, register
from .starts import principled

#: Luminance weights of the reference implementation's tint (an approximation of Rec. 709 Y).
LUMINANCE = (0.3, 0.6, 0.1)
#: The lower bound of ``base_color`` (each channel): an albedo no measurement resolves, above 0
#: so that :func:`tint_color` is continuous on the whole box (see there).
BASE_COLOR_MIN = 1e-6
#: Clearcoat: fixed IOR 1.5 (polyurethane), so F0 = 0.04 (Burley 2012 §5.4).
CLEARCOAT_F0 = 0.04
#: Clearcoat's ad-hoc masking: GGX Smith G with a fixed α = 0.25 (Burley 2012 §5.6, Addenda).
CLEARCOAT_G_ALPHA = 0.25


def _col(x):
    """A scalar parameter (or a batch of them) with a trailing axis, to scale an RGB term."""
    return jnp.asarray(x)[..., None]


def _rgb(color):
    """``color`` as an RGB array ``(..., 3)``; a scalar means grey."""
    c = jnp.asarray(color)
    return jnp.broadcast_to(c, (3,)) if c.ndim == 0 else c


def tint_color(base_color):
    r"""``base_color`` divided by its luminance (hue and saturation only); white if it is black.

    .. math:: C_\text{tint} = C_\text{base} / (0.3 R + 0.6 G + 0.1 B)

    Burley's *specularTint* and *sheenTint* blend towards this color (BRDF Explorer
    ``disney.brdf``: ``Cdlum > 0 ? Cdlin/Cdlum : vec3(1)``; the notes do not give it).

    The tint keeps the hue of a base color however dark, and turns white only at exactly
    black: it is discontinuous at 0. A material whose specular is colored but whose diffuse is
    nil (a dark paint or wood, measured) is then a limit the model never attains, and a fit
    crawls towards ``base_color → 0`` along a ray of fixed hue until its step limit (fruitwood-241
    and dark-blue-paint from ``../shared/realistic``: 200 steps, not converged). So the fit's
    lower bound of each channel is :data:`BASE_COLOR_MIN`, not 0: on that box the tint is
    continuous, the infimum is attained (on the bound, where the data ask for it), and the
    formula is still exactly the reference's, so a renderer reproduces the fitted BRDF.
    """
    w, base_color = LUMINANCE, _rgb(base_color)
    lum = w[0] * base_color[..., 0] + w[1] * base_color[..., 1] + w[2] * base_color[..., 2]
    return safe_div(base_color, lum[..., None], fill=1.0)


def anisotropic_alphas(roughness, anisotropic):
    r"""``(α_x, α_y)`` from Burley's roughness and anisotropy (Burley 2014 Addenda; RTR eq. 9.54).

    .. math:: \text{aspect} = \sqrt{1 - 0.9\,\text{anisotropic}},\quad
        \alpha_x = \text{roughness}^2/\text{aspect},\quad \alpha_y = \text{roughness}^2\,\text{aspect}

    .. warning:: the reference shader also clamps both at 0.001. This code does not: the
       registry's bound ``roughness ≥ 0.02`` and the NDF's ``ALPHA_MIN`` keep α finite, and a
       clamp inside the bounds would zero the roughness gradient of shiny fits.
    """
    aspect = jnp.sqrt(1.0 - 0.9 * anisotropic)
    alpha = roughness**2
    return alpha / aspect, alpha * aspect


def specular_f0(base_color, metallic, specular, specular_tint):
    r"""Normal-incidence color of the main specular lobe (Burley 2012 §5.4, reference shader).

    .. math:: C_{s0} = \operatorname{lerp}\!\left(0.08\,\text{specular}\,
        \operatorname{lerp}(1, C_\text{tint}, \text{specularTint}),\; C_\text{base},\;
        \text{metallic}\right)

    ``specular ∈ [0, 1]`` maps to F0 ∈ [0, 0.08] (IOR 1 to 1.8; 0.5 is IOR 1.5).
    """
    dielectric = 0.08 * _col(specular) * (1.0 + _col(specular_tint) * (tint_color(base_color) - 1.0))
    return dielectric + _col(metallic) * (base_color - dielectric)


def specular_lobe(base_color, metallic, specular, specular_tint, roughness, anisotropic, wi, wo):
    r"""The primary specular lobe: anisotropic GGX (GTR γ = 2), RTR eq. 9.34.

    ``D``: GTR2 aniso (Burley 2012 App. B eq. 13 = RTR eq. 9.53) with the α_x, α_y of
    :func:`anisotropic_alphas`. ``F``: Schlick (§5.5) from :func:`specular_f0`. ``G``: the 2014
    addenda's revision: Smith G for anisotropic GGX (Heitz 2014) with the *unremapped* α_x, α_y
    (the 2012 remapping ``α_g = (0.5 + roughness/2)^2`` of §5.6 is removed), in the separable
    form the reference shader uses (``smithG_GGX_aniso`` twice: RTR eq. 9.27,
    :func:`~brdffit.terms.masking.G2_separable`), not the height-correlated default of
    :func:`~brdffit.terms.microfacet.microfacet_specular`. Returns ``(..., 3)``.
    """
    ax, ay = anisotropic_alphas(roughness, anisotropic)
    f0 = specular_f0(base_color, metallic, specular, specular_tint)
    return microfacet_specular(GGX(ax, ay), partial(schlick, f0), wi, wo, g2=G2_separable)


def sheen_lobe(base_color, sheen, sheen_tint, wi, wo):
    r"""Sheen, a Schlick-shaped grazing lobe for cloth (Burley 2014 Addenda, "Sheen details").

    .. math:: f_\text{sheen} = \text{sheen}\;\operatorname{lerp}(1, C_\text{tint},
        \text{sheenTint})\;(1 - \mathbf h\cdot\mathbf l)^5

    Not divided by π, as in the reference shader. Zero unless both directions are above the
    horizon. Returns ``(..., 3)``.
    """
    wm = half_vector(wi, wo)
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    color = 1.0 + _col(sheen_tint) * (tint_color(base_color) - 1.0)
    return _col(sheen) * color * (schlick_weight(dot(wi, wm)) * vis)[..., None]


def clearcoat_lobe(clearcoat, clearcoat_gloss, wi, wo):
    r"""Clearcoat: a second, isotropic, achromatic specular lobe (Burley 2012 §5.4, §5.6, Addenda).

    .. math:: f_\text{cc} = \frac{\text{clearcoat}}{4}\,
        \frac{F(\mathbf h,\mathbf l)\,G_2\,D_{\text{GTR}_1}(\mathbf h)}
             {4\,(\mathbf n\cdot\mathbf l)(\mathbf n\cdot\mathbf v)}

    ``D``: GTR with γ = 1 (App. B eq. 4) and ``α = lerp(0.1, 0.001, clearcoatGloss)``; ``F``:
    Schlick with F0 = 0.04 (IOR 1.5); ``G``: the ad-hoc separable GGX Smith G with a fixed
    α = 0.25; overall scale ``[0, 0.25]`` (the ``.25 * clearcoat`` of the reference shader).
    Returns ``(..., 3)`` (three equal channels).
    """
    alpha = 0.1 + (0.001 - 0.1) * jnp.asarray(clearcoat_gloss)
    wm = half_vector(wi, wo)
    ci, co = cos_theta(wi), cos_theta(wo)
    vis = chi_plus(ci) * chi_plus(co)
    g = G2_separable(GGX(CLEARCOAT_G_ALPHA), wi, wo, wm)
    geom = safe_div(g * GTR(alpha, gamma=1.0).D(wm), 4.0 * ci * co) * vis
    lobe = 0.25 * _col(clearcoat) * schlick(CLEARCOAT_F0, dot(wi, wm)) * geom[..., None]
    return jnp.broadcast_to(lobe, lobe.shape[:-1] + (3,))


def disney(p, wi, wo):
    """The whole principled BRDF: the lobes above, blended by ``metallic`` as the reference does.

    ``p`` maps each parameter name of the registered model to its value. Returns RGB ``(..., 3)``.
    """
    base = _rgb(p["base_color"])
    dielectric = disney_diffuse(base, p["roughness"], p["subsurface"], wi, wo) + sheen_lobe(
        base, p["sheen"], p["sheen_tint"], wi, wo
    )
    spec = specular_lobe(
        base, p["metallic"], p["specular"], p["specular_tint"], p["roughness"], p["anisotropic"], wi, wo
    )
    coat = clearcoat_lobe(p["clearcoat"], p["clearcoat_gloss"], wi, wo)
    return (1.0 - _col(p["metallic"])) * dielectric + spec + coat


def _unit(name, default, description, camel):
    return Param(name, (), 0.0, 1.0, default, f"{description} (Burley's {camel})")


DISNEY_PARAMS = (
    Param("base_color", (3,), BASE_COLOR_MIN, 1.0, (0.82, 0.67, 0.16),
          "surface color, linear RGB (baseColor)"),
    _unit("subsurface", 0.0, "blend from retro-reflective diffuse to the subsurface shape", "subsurface"),
    _unit("metallic", 0.0, "0 dielectric, 1 metal: no diffuse, specular tinted by base color", "metallic"),
    _unit("specular", 0.5, "incident specular amount, F0 = 0.08·specular", "specular"),
    _unit("specular_tint", 0.0, "tints incident specular towards the base color's hue", "specularTint"),
    Param("roughness", (), 0.02, 1.0, 0.5, "roughness; α = roughness² (Burley's roughness)",
          log=True),
    _unit("anisotropic", 0.0, "anisotropy, aspect = sqrt(1 - 0.9·anisotropic)", "anisotropic"),
    _unit("sheen", 0.0, "extra grazing Schlick-shaped lobe for cloth", "sheen"),
    _unit("sheen_tint", 0.5, "tints sheen towards the base color's hue", "sheenTint"),
    _unit("clearcoat", 0.0, "strength of the GTR1 clearcoat lobe, scale 0.25·clearcoat", "clearcoat"),
    _unit("clearcoat_gloss", 1.0, "clearcoat α = lerp(0.1, 0.001, gloss)", "clearcoatGloss"),
)

DISNEY_MODEL = register(
    Model(
        name="disney",
        description="Disney principled BRDF (Burley 2012 + 2014 addenda): diffuse with retro-"
        "reflection and subsurface, sheen, anisotropic GGX specular, GTR1 clearcoat",
        params=DISNEY_PARAMS,
        fn=disney,
        isotropic=False,
        start=principled,
        reference="Burley 2012 §5, App. B eqs. 4, 13, Addenda; RTR eqs. 9.27, 9.34, 9.54, 9.66, "
        "9.67; BRDF Explorer disney.brdf",
    )
)
