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

import jax.numpy as jnp
import numpy as np

from ..terms._math import cos_theta, dot, half_vector
from ..terms.diffuse import lambert
from ..terms.fresnel import f0_from_ior, schlick_weight
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX
from .registry import Model, Param, Reading, register
from .starts import gltf_pbr as gltf_pbr_start

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


#: A dielectric's index of refraction stays at or below this: ``f0`` 0.25, beyond diamond's 2.42
#: (0.17). A free ``ior`` up to 5 let fabrics and metals end at 5 (``f0`` 0.44, a Fresnel
#: curve no dielectric has) with ``metallic`` between 0.1 and 0.6.
DIELECTRIC_IOR_MAX = 3.0
#: The metal reading (:func:`metal_reason`): no diffuse albedo above this in any channel ...
BLACK_ALBEDO = 0.02
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
