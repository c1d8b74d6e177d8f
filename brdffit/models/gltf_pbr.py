r"""The glTF 2.0 metallic-roughness BRDF with the reflection extensions, as the specifications define it.

glTF 2.0 Specification, Appendix B "BRDF Implementation": §B.2.2 (the metal/dielectric mixing
graph), §B.3.1 "Specular BRDF", §B.3.2 "Diffuse BRDF", §B.3.3 "Fresnel", §B.3.4 "Metal BRDF and
Dielectric BRDF"; with ``KHR_materials_ior`` (the dielectric's ``ior``) and
``KHR_materials_specular`` (its ``specularFactor``, "Implementation" section, with
``specularColorFactor`` white) in ``gltf-pbr``, and ``KHR_materials_clearcoat``
("Implementation": ``fresnel_coat``) in ``gltf-pbr-clearcoat``. With ``V = wo`` the view,
``L = wi`` the light, ``H = normalize(L + V)``, ``α = roughness²``, ``w = (1 − |V·H|)^5``,
``s`` = ``specular`` and ``f0 = ((ior − 1)/(ior + 1))²``:

.. math::

    \text{specular\_brdf} = \frac{G\,D}{4\,|N\cdot L|\,|N\cdot V|},\qquad
    D = \frac{\alpha^2\,\chi^+(N\cdot H)}{\pi((N\cdot H)^2(\alpha^2 - 1) + 1)^2}

    G = \frac{2\,|N\cdot L|\,|N\cdot V|\,\chi^+(H\cdot L)\,\chi^+(H\cdot V)}
        {|N\cdot V|\sqrt{\alpha^2 + (1 - \alpha^2)(N\cdot L)^2}
         + |N\cdot L|\sqrt{\alpha^2 + (1 - \alpha^2)(N\cdot V)^2}}

    F_d = \min(f_0, 1) + (1 - \min(f_0, 1))\,w,\qquad
    \text{dielectric\_brdf} = (1 - s\,F_d)\,\frac{C}{\pi} + s\,F_d\ \text{specular\_brdf}

    \text{metal\_brdf} = (C + (1 - C)\,w)\ \text{specular\_brdf},\qquad
    f_r = \operatorname{mix}(\text{dielectric\_brdf},\ \text{metal\_brdf},\ \text{metallic})

and, with a clear coat of weight ``c`` and roughness ``r_c``,
``f_coated = mix(f_r, specular_brdf(α = r_c²), c (0.04 + 0.96 (1 − |N·V|)^5))`` (the coat's
Fresnel reads ``N·V``, not ``V·H``, as the extension says; so the coated BRDF is not
reciprocal).

``D`` is GGX (RTR eq. 9.41) and ``G`` is the height-correlated Smith form (RTR eq. 9.31 with
GGX's Λ, eq. 9.42; the spec cites Heitz 2014): the same function, rearranged, as
:func:`brdffit.terms.masking.G2_height_correlated` with :class:`brdffit.terms.ndf.GGX`, which is
what the code uses. ``C`` is ``baseColorFactor`` (linear RGB), ``metallic`` ``metallicFactor``,
``roughness`` ``roughnessFactor``. At the extensions' defaults (``ior = 1.5``, ``specular = 1``,
no coat) this is the core material, ``f0 = 0.04``.

Why the extensions are parameters: the core material caps a dielectric's normal-incidence
reflectance at 4 %. Plastics, phenolics, acrylics and paints measure more; without ``ior`` the
only way the core model reaches their peak is ``metallic``, which spends the diffuse colour
(measured on the realistic corpus: black "metals" with the colour lost). With ``ior`` and
``specular`` a dielectric stays a dielectric (metallic 0) with its own colour; the metal part is
untouched by both (as the extensions say). Not energy conserving (§B.3.5), but reciprocal
without the coat.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..terms._math import chi_plus, cos_theta, dot, half_vector, safe_div
from ..terms.diffuse import lambert
from ..terms.fresnel import f0_from_ior, schlick_weight
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX
from ..terms.ndf.sheen import charlie_D, charlie_lambda
from .registry import Model, Param, Reading, register
from .starts import gltf_pbr as gltf_pbr_start
from .starts import gltf_pbr_sheen as gltf_pbr_sheen_start

#: The clear coat's fixed index of refraction (``KHR_materials_clearcoat``): ``f0 = 0.04``.
CLEARCOAT_F0 = 0.04


def _unit_fresnel(cos_d):
    return jnp.ones_like(cos_d)[..., None]


def gltf_pbr(p, wi, wo):
    """The glTF metallic-roughness BRDF with ``ior`` and ``specular`` (module docstring), RGB
    ``(..., 3)``, zero below the horizon."""
    base = jnp.broadcast_to(jnp.asarray(p["base_color"]), (3,))
    metallic = jnp.asarray(p["metallic"])[..., None]
    weight = jnp.asarray(p["specular"])[..., None]
    spec = microfacet_specular(GGX(p["roughness"] ** 2), _unit_fresnel, wi, wo)  # (..., 1)
    w = schlick_weight(jnp.abs(dot(wo, half_vector(wi, wo))))[..., None]
    f0 = jnp.minimum(f0_from_ior(jnp.asarray(p["ior"])), 1.0)[..., None]
    f_diel = f0 + (1.0 - f0) * w
    dielectric_brdf = (1.0 - weight * f_diel) * lambert(base, wi, wo) + weight * f_diel * spec
    metal_brdf = (base + (1.0 - base) * w) * spec
    return (1.0 - metallic) * dielectric_brdf + metallic * metal_brdf


def gltf_pbr_clearcoat(p, wi, wo):
    """:func:`gltf_pbr` under a ``KHR_materials_clearcoat`` coat (module docstring)."""
    material = gltf_pbr(p, wi, wo)
    coat = microfacet_specular(GGX(p["clearcoat_roughness"] ** 2), _unit_fresnel, wi, wo)
    n_v = jnp.abs(cos_theta(wo))
    fresnel = CLEARCOAT_F0 + (1.0 - CLEARCOAT_F0) * schlick_weight(n_v)
    mix = (jnp.asarray(p["clearcoat"]) * fresnel)[..., None]
    return (1.0 - mix) * material + mix * coat


def sheen_lobe(color, roughness, wi, wo):
    r"""``KHR_materials_sheen``'s ``f_sheen`` ("Implementation Notes"), RGB ``(..., 3)``:

    .. math:: f_\text{sheen} = \text{sheenColor}\;
              \frac{D_S(\mathbf h)}{(1 + \Lambda(N\cdot V) + \Lambda(N\cdot L))\,
              4\,|N\cdot L|\,|N\cdot V|}

    with ``F = 1``, the Charlie NDF ``D_S`` at ``α = sheenRoughness²``
    (:func:`~brdffit.terms.ndf.sheen.charlie_D`) and Estevez & Kulla's fitted ``Λ``
    (:func:`~brdffit.terms.ndf.sheen.charlie_lambda`); zero below the horizon."""
    alpha = jnp.asarray(roughness) ** 2
    ci, co = cos_theta(wi), cos_theta(wo)
    d = charlie_D(alpha, half_vector(wi, wo))
    den = (1.0 + charlie_lambda(co, alpha) + charlie_lambda(ci, alpha)) * 4.0 * ci * co
    lobe = safe_div(d, den) * chi_plus(ci) * chi_plus(co)
    return jnp.asarray(color) * lobe[..., None]


#: The sheen's roughness stays at or above this (``α = 0.04``): narrower lobes live within a
#: few degrees of grazing, where neither a measurement nor the albedo table resolves them.
SHEEN_ROUGHNESS_MIN = 0.2
#: The albedo table's nodes: ``cos θ = u²``, ``u`` from 0 to 1 (``E`` changes fastest near
#: grazing incidence) × ``sheenRoughness`` from :data:`SHEEN_ROUGHNESS_MIN` to 1, evenly
#: spaced; and its quadrature over ``ωo``:
#: Gauss–Legendre nodes in ``cos θo`` × midpoint nodes in ``φo``.
SHEEN_TABLE = (65, 33)
SHEEN_QUADRATURE = (96, 128)


@functools.cache
def sheen_albedo_table() -> np.ndarray:
    r"""``E(μ, r)`` ``(65, 33)``: the directional albedo of :func:`sheen_lobe` with
    ``sheenColor = 1``, :math:`E(\mu) = \int f_\text{sheen}\cos\theta_o\,d\omega_o`, at
    incidence ``cos θ = μ`` (``μ = u²``, node 0 at ``μ = 10⁻⁴``) and roughness ``r``
    (:data:`SHEEN_TABLE`), by the quadrature of :data:`SHEEN_QUADRATURE`. The extension leaves
    the table to the implementation ("section 6.2.3 of the Enterprise PBR Shading Model" for
    this visibility); this one integrates the lobe itself, so the albedo scaling conserves
    what the lobe reflects. Built once per process (a second or two)."""
    n_mu, n_r = SHEEN_TABLE
    n_c, n_phi = SHEEN_QUADRATURE
    x, w = np.polynomial.legendre.leggauss(n_c)
    cos_o, w_c = (x + 1) / 2, w / 2
    phi = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    sin_o = np.sqrt(1 - cos_o**2)
    wo = np.stack(np.broadcast_arrays(sin_o[:, None] * np.cos(phi), sin_o[:, None] * np.sin(phi),
                                      cos_o[:, None]), -1).reshape(-1, 3)
    weight = (w_c[:, None] * cos_o[:, None] * np.full(n_phi, 2 * np.pi / n_phi)).ravel()
    mu = np.linspace(0.0, 1.0, n_mu) ** 2
    mu[0] = 1e-4
    wi = np.stack([np.sqrt(1 - mu**2), np.zeros_like(mu), mu], -1)
    roughness = np.linspace(SHEEN_ROUGHNESS_MIN, 1.0, n_r)
    lobe = jax.jit(lambda r: sheen_lobe(1.0, r, jnp.asarray(wi)[:, None, :],
                                        jnp.asarray(wo)[None, :, :])[..., 0] @ weight)
    with jax.ensure_compile_time_eval(), jax.enable_x64(True):  # also when first used in a trace
        return np.stack([np.asarray(lobe(jnp.float64(r))) for r in roughness], 1)


def sheen_albedo(cos_theta_, roughness):
    """``E(|cos θ|, r)`` read off :func:`sheen_albedo_table` by bilinear interpolation in
    ``(√|cos θ|, r)`` (differentiable in both)."""
    table = jnp.asarray(sheen_albedo_table(), jnp.result_type(cos_theta_, roughness))
    n_mu, n_r = SHEEN_TABLE
    i = jnp.sqrt(jnp.clip(jnp.abs(cos_theta_), 1e-12, 1.0)) * (n_mu - 1)
    j = (roughness - SHEEN_ROUGHNESS_MIN) / (1.0 - SHEEN_ROUGHNESS_MIN) * (n_r - 1)
    j = jnp.broadcast_to(jnp.clip(j, 0.0, n_r - 1.0), i.shape)
    return jax.scipy.ndimage.map_coordinates(table, [i, j], order=1, mode="nearest")


#: A dielectric's index of refraction stays at or below this: ``f0`` 0.25, beyond diamond's 2.42
#: (0.17). A free ``ior`` up to 5 let fabrics and metals end at 5 (``f0`` 0.44, a Fresnel
#: curve no dielectric has) with ``metallic`` between 0.1 and 0.6.
DIELECTRIC_IOR_MAX = 3.0
#: The metal reading (:func:`metal_reason`): no diffuse albedo above this in any channel (the
#: MERL metals measure at most 0.007; the dielectrics whose reading needs a high ``ior``,
#: fabrics and pearlescent paints, 0.1 and more) ...
BLACK_ALBEDO = 0.05
#: ... and a dielectric reading whose ``ior`` exceeds this (``f0`` 0.14: a Fresnel curve that
#: rises less than 7× towards grazing, flatter than any common dielectric's).
METAL_IOR = 2.2


def metal_reason(params, features) -> str:
    """Why a material fitted as a glTF dielectric (``metallic`` 0) is a metal, or ``""``.

    A metal has no diffuse term (light that enters a conductor is absorbed) and a flat Fresnel
    curve: its reflectance at normal incidence is already a large fraction of the grazing one.
    A dielectric fit of such data can only follow both with no base colour and an ``ior``
    beyond the dielectrics': the data's diffuse albedo (``features.diffuse``) below
    :data:`BLACK_ALBEDO` in every channel and the dielectric's ``ior`` above :data:`METAL_IOR`.
    On the realistic corpus this reads aluminium, brass, chrome-steel, grease-covered steel,
    nickel, ss440 and tungsten carbide (dielectric ``ior`` 2.25-3) as metals, and keeps black
    dielectrics (obsidian, the black phenolic: ``ior`` 1.45-1.48; a black soft plastic: 2.09)
    dielectrics; hematite (2.15) and two metallic paints (2.06, 2.11) stay dielectric too.
    """
    diffuse = float(np.max(features.diffuse))
    ior = float(np.asarray(params["ior"]))
    if diffuse < BLACK_ALBEDO and ior > METAL_IOR:
        return (f"no diffuse albedo (at most {diffuse:.3f}) and a dielectric reading that needs "
                f"ior {ior:.2f} > {METAL_IOR:g}, a Fresnel curve flatter than a dielectric's")
    return ""


def gltf_pbr_sheen(p, wi, wo):
    """:func:`gltf_pbr` under a ``KHR_materials_sheen`` layer (its albedo-scaling technique):
    ``f = f_sheen + f_base · max(0, min(1 − max₃(sheenColor) E(N·V), 1 − max₃(sheenColor)
    E(N·L)))`` with :func:`sheen_lobe` and :func:`sheen_albedo`. The Estevez–Kulla lobe
    reflects more than 1 near grazing incidence at low roughness (``E`` 1.09 at ``r = 0.2``,
    ``cos θ = 1/64``); there the scaling is clamped at 0, as Filament's implementation of the
    extension clamps it."""
    color = jnp.broadcast_to(jnp.asarray(p["sheen_color"]), (3,))
    roughness = jnp.asarray(p["sheen_roughness"])
    top = jnp.max(color)
    scale = jnp.maximum(jnp.minimum(1.0 - top * sheen_albedo(cos_theta(wo), roughness),
                                    1.0 - top * sheen_albedo(cos_theta(wi), roughness)), 0.0)
    return sheen_lobe(color, roughness, wi, wo) + gltf_pbr(p, wi, wo) * scale[..., None]


#: glTF's ``metallic`` is a reading, 0 or 1, not a blend the fit chooses (:class:`Reading`).
METALLIC = Reading("metallic", 0.0, 1.0, metal_reason, ("a dielectric", "a metal"),
                   other_holds={"ior": 1.5, "specular": 1.0})

#: The parameters of ``gltf-pbr``: the core factors and the two reflection extensions.
GLTF_PARAMS = (
    Param("base_color", (3,), 0.0, 1.0, 0.5, "baseColorFactor, linear RGB", per_channel=True),
    Param("metallic", (), 0.0, 1.0, 0.0, "metallicFactor: 0 dielectric, 1 metal"),
    Param("roughness", (), 0.02, 1.0, 0.5, "roughnessFactor; α = roughness²", log=True),
    Param("ior", (), 1.0, DIELECTRIC_IOR_MAX, 1.5,
          "KHR_materials_ior ior: dielectric f0 = ((ior-1)/(ior+1))²"),
    Param("specular", (), 0.0, 1.0, 1.0, "KHR_materials_specular specularFactor: the dielectric "
          "specular's weight (f0 and f90)"),
)

GLTF_PBR = register(Model(
    name="gltf-pbr",
    description="glTF 2.0 metallic-roughness BRDF (spec Appendix B) with KHR_materials_ior and "
    "KHR_materials_specular: GGX, height-correlated Smith G, Schlick Fresnel mixing of Lambert "
    "and specular, dielectric f0 from the IOR",
    params=GLTF_PARAMS,
    fn=gltf_pbr,
    start=gltf_pbr_start,
    reading=METALLIC,
    reference="glTF 2.0 Specification Appendix B §B.3.1-§B.3.4; KHR_materials_ior; "
    "KHR_materials_specular (Implementation); RTR eqs. 9.16, 9.31, 9.41, 9.42",
))

GLTF_PBR_SHEEN = register(Model(
    name="gltf-pbr-sheen",
    description="gltf-pbr under a KHR_materials_sheen layer (Charlie NDF, Estevez-Kulla "
    "visibility, albedo scaling of the base): fabrics' grazing sheen",
    params=GLTF_PARAMS + (
        Param("sheen_color", (3,), 0.0, 1.0, 0.0, "KHR_materials_sheen sheenColorFactor, "
              "linear RGB (0: no sheen)"),
        Param("sheen_roughness", (), SHEEN_ROUGHNESS_MIN, 1.0, 0.5,
              "sheenRoughnessFactor; the Charlie NDF's α = roughness²"),
    ),
    fn=gltf_pbr_sheen,
    start=gltf_pbr_sheen_start,
    reading=METALLIC,
    reference="glTF 2.0 Specification Appendix B; KHR_materials_ior; KHR_materials_specular; "
    "KHR_materials_sheen (Implementation Notes); Estevez & Kulla 2017",
))

GLTF_PBR_CLEARCOAT = register(Model(
    name="gltf-pbr-clearcoat",
    description="gltf-pbr under a KHR_materials_clearcoat coat (GGX, f0 0.04, Fresnel from N·V)",
    params=GLTF_PARAMS + (
        Param("clearcoat", (), 0.0, 1.0, 0.5, "KHR_materials_clearcoat clearcoatFactor"),
        Param("clearcoat_roughness", (), 0.02, 1.0, 0.1,
              "clearcoatRoughnessFactor; α = roughness²", log=True),
    ),
    fn=gltf_pbr_clearcoat,
    start=gltf_pbr_start,
    reading=METALLIC,
    reference="glTF 2.0 Specification Appendix B; KHR_materials_ior; KHR_materials_specular; "
    "KHR_materials_clearcoat (Implementation)",
))
