"""Registered energy-conserving GGX variants: ``ggx-ms`` (RTR 9.56–9.60) and ``ggx-coupled`` (RTR 9.65).

Both read the precomputed GGX albedo table of :mod:`brdffit.terms.energy.albedo_table` (built
on first use, a few seconds, then cached).
"""

from __future__ import annotations

from functools import partial

from ..terms.diffuse import lambert
from ..terms.energy.albedo_table import albedo_table
from ..terms.energy.coupled_diffuse import coupled_diffuse
from ..terms.energy.multiscatter import multiscatter_specular
from ..terms.fresnel import schlick
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX
from .registry import Model, register
from .standard import ALPHA, DIFFUSE, F0


def _ggx_ms(p, wi, wo):
    return lambert(p["diffuse"], wi, wo) + multiscatter_specular(GGX, p["alpha"], p["f0"], wi, wo)


def _ggx_coupled(p, wi, wo):
    spec = microfacet_specular(GGX(p["alpha"]), partial(schlick, p["f0"]), wi, wo)
    return spec + coupled_diffuse(albedo_table(GGX), p["alpha"], p["f0"], p["diffuse"], wi, wo)


GGX_MS = register(Model(
    name="ggx-ms",
    description="Lambert + GGX specular with the Imageworks/Kulla-Conty multiple-scattering term",
    params=(DIFFUSE, F0, ALPHA),
    fn=_ggx_ms,
    reference="RTR eqs. 9.34, 9.41, 9.31, 9.16, 9.56-9.60, 9.61",
))

GGX_COUPLED = register(Model(
    name="ggx-coupled",
    description="GGX specular + Kelemen/Ashikhmin-Shirley coupled diffuse (energy-conserving)",
    params=(DIFFUSE, F0, ALPHA),
    fn=_ggx_coupled,
    reference="RTR eqs. 9.34, 9.41, 9.31, 9.16, 9.65",
))
