r"""The glTF 2.0 metallic-roughness BRDF, exactly as the specification's Appendix B defines it.

glTF 2.0 Specification, Appendix B "BRDF Implementation": §B.2.2 (the metal/dielectric mixing
graph), §B.3.1 "Specular BRDF", §B.3.2 "Diffuse BRDF", §B.3.3 "Fresnel", §B.3.4 "Metal BRDF and
Dielectric BRDF" (the "full code" listing). With ``V`` the view, ``L`` the light,
``H = normalize(L + V)``, ``α = roughness²`` and ``w = (1 − |V·H|)^5``:

.. math::

    \text{specular\_brdf} = \frac{G\,D}{4\,|N\cdot L|\,|N\cdot V|},\qquad
    D = \frac{\alpha^2\,\chi^+(N\cdot H)}{\pi((N\cdot H)^2(\alpha^2 - 1) + 1)^2}

    G = \frac{2\,|N\cdot L|\,|N\cdot V|\,\chi^+(H\cdot L)\,\chi^+(H\cdot V)}
        {|N\cdot V|\sqrt{\alpha^2 + (1 - \alpha^2)(N\cdot L)^2}
         + |N\cdot L|\sqrt{\alpha^2 + (1 - \alpha^2)(N\cdot V)^2}}

    \text{dielectric\_brdf} = \operatorname{mix}\!\left(\frac{C}{\pi},\ \text{specular\_brdf},\
        0.04 + 0.96\,w\right),\qquad
    \text{metal\_brdf} = (C + (1 - C)\,w)\ \text{specular\_brdf}

    f_r = \operatorname{mix}(\text{dielectric\_brdf},\ \text{metal\_brdf},\ \text{metallic})

``D`` is GGX (RTR eq. 9.41) and ``G`` is the height-correlated Smith form (RTR eq. 9.31 with
GGX's Λ, eq. 9.42; the spec cites Heitz 2014): the same function, rearranged, as
:func:`brdffit.terms.masking.G2_height_correlated` with :class:`brdffit.terms.ndf.GGX`, which is
what the code uses. ``C`` is ``baseColorFactor`` (linear RGB), ``metallic`` ``metallicFactor``,
``roughness`` ``roughnessFactor``; ``ior = 1.5`` gives the fixed ``f0 = 0.04``. Not energy
conserving (the spec's §B.3.5 says so: ``fresnel_mix`` is not), but reciprocal.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..terms._math import dot, half_vector
from ..terms.diffuse import lambert
from ..terms.fresnel import schlick_weight
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX
from .registry import Model, Param, register
from .starts import metallic_roughness

#: ``f0`` of the dielectric part: ``((1 − ior)/(1 + ior))²`` at the fixed ``ior = 1.5``.
DIELECTRIC_F0 = 0.04


def _unit_fresnel(cos_d):
    return jnp.ones_like(cos_d)[..., None]


def gltf_pbr(p, wi, wo):
    """The glTF metallic-roughness BRDF (module docstring), RGB ``(..., 3)``, zero below the horizon."""
    base = jnp.broadcast_to(jnp.asarray(p["base_color"]), (3,))
    metallic = jnp.asarray(p["metallic"])[..., None]
    spec = microfacet_specular(GGX(p["roughness"] ** 2), _unit_fresnel, wi, wo)  # (..., 1)
    w = schlick_weight(jnp.abs(dot(wo, half_vector(wi, wo))))[..., None]
    f_diel = DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * w
    dielectric_brdf = (1.0 - f_diel) * lambert(base, wi, wo) + f_diel * spec
    metal_brdf = (base + (1.0 - base) * w) * spec
    return (1.0 - metallic) * dielectric_brdf + metallic * metal_brdf


GLTF_PBR = register(Model(
    name="gltf-pbr",
    description="glTF 2.0 metallic-roughness BRDF (spec Appendix B): GGX, height-correlated "
    "Smith G, Schlick Fresnel mixing of Lambert and specular, F0 = mix(0.04, base, metallic)",
    params=(
        Param("base_color", (3,), 0.0, 1.0, 0.5, "baseColorFactor, linear RGB", per_channel=True),
        Param("metallic", (), 0.0, 1.0, 0.0, "metallicFactor: 0 dielectric, 1 metal"),
        Param("roughness", (), 0.02, 1.0, 0.5, "roughnessFactor; α = roughness²", log=True),
    ),
    fn=gltf_pbr,
    start=metallic_roughness,
    reference="glTF 2.0 Specification Appendix B §B.3.1-§B.3.4; RTR eqs. 9.16, 9.31, 9.41, 9.42",
))
