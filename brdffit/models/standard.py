"""The standard registered models: one microfacet specular lobe (or two) plus Lambert, every
lobe with the generalized Schlick Fresnel term (RTR eq. 9.18: RGB ``F0``; the grazing value
``F90 = F0 + (1 − F0) t`` per channel, with a scalar rise ``t`` named ``grazing``:
:func:`brdffit.terms.fresnel.f90_from_rise`, so that ``F0 ≤ F90 ≤ 1`` for every value the
bounds allow).

Every entry is a short ``fn(params, wi, wo)`` built from the pieces in
:mod:`brdffit.terms.ndf`, :mod:`brdffit.terms.masking`, :mod:`brdffit.terms.fresnel` and
:mod:`brdffit.terms.diffuse`, and a parameter list.
"""

from __future__ import annotations

from functools import partial

from ..terms.diffuse import lambert
from ..terms.fresnel import f90_from_rise, schlick
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX, GTR, Beckmann, BlinnPhong
from .frame import FRAME_ANGLE, rotated
from .registry import Model, Param, PerPass, register
from .starts import two_lobes_from_one

#: Bounds shared by the single-lobe models. Roughness ``alpha`` spans decades (polished metals
#: near 0.005, paints near 0.3), so it is fitted in log space.
ALPHA_BOUNDS = (1e-3, 1.0)

DIFFUSE = Param(
    "diffuse", (3,), 0.0, 1.0, 0.2, "Lambertian diffuse albedo ρ_d (RGB); f_d = ρ_d/π", per_channel=True
)
F0 = Param(
    "f0", (3,), 0.0, 1.0, 0.04, "specular reflectance at normal incidence F0 (RGB), Schlick",
    per_channel=True,
)
ALPHA = Param("alpha", (), *ALPHA_BOUNDS, 0.1, "microfacet roughness α", log=True)
#: The grazing rise ``t`` of the generalized Schlick term (RTR eq. 9.18), ``F90 = F0 + (1 − F0) t``
#: per channel (:func:`~brdffit.terms.fresnel.f90_from_rise`). Measured materials rarely
#: reflect everything at grazing angles: with ``F90 = 1`` forced, one lobe follows the grazing
#: cells by being broad, 1.5–23× rougher than the published Cook–Torrance fits, whose free
#: specular scale had this degree of freedom. A free scalar ``F90`` on ``[0, 1]`` (the form
#: before this one) ended on 0 for the sharp dielectrics and metals, below ``F0``: a
#: reflectance that falls towards grazing incidence, which no surface has and no renderer
#: shows. ``t`` keeps the freedom where it is physical (``F0 ≤ F90 ≤ 1``). The start, 1, is
#: plain Schlick (fix it there for plain Schlick: ``fixed={"grazing": 1}``); results report
#: the ``F90`` it gives (:func:`grazing_f90`, the models' ``derived``).
GRAZING = Param(
    "grazing", (), 0.0, 1.0, 1.0,
    "grazing rise t of the Schlick F: F90 = F0 + (1 - F0) t per channel (1: plain Schlick)",
)


def grazing_f90(p) -> dict:
    """f90 = f0 + (1 - f0) * grazing per channel: fix, start or bound 'grazing' instead (1 is
    plain Schlick, 0 no rise at grazing incidence)."""
    return {"f90": f90_from_rise(p["f0"], p["grazing"])}


def _single_lobe(ndf_from_params):
    """``fn(p, wi, wo)`` for Lambert + one microfacet lobe with the given NDF and the
    generalized Schlick ``F`` (``F0`` RGB, rise ``t`` scalar)."""

    def fn(p, wi, wo):
        return lobe_with(ndf_from_params(p), p, wi, wo)

    return fn


def lobe_with(ndf, p, wi, wo):
    return lambert(p["diffuse"], wi, wo) + microfacet_specular(
        ndf, _fresnel(p), wi, wo
    )


def _fresnel(p):
    """The generalized Schlick ``F`` of ``p``: ``F0`` and ``F90 = F0 + (1 − F0) t``."""
    return partial(schlick, p["f0"], f90=f90_from_rise(p["f0"], p["grazing"]))


def _gtr_table(p):
    return GTR(p["alpha"], p["gamma"]).lambda_table()


def _gtr_with_table(p, table, wi, wo):
    return lobe_with(GTR(p["alpha"], p["gamma"], table=table), p, wi, wo)


GGX_MODEL = register(
    Model(
        name="ggx",
        description=(
            "Lambert + GGX/Trowbridge-Reitz specular, height-correlated Smith G2, "
            "generalized Schlick F (F0, F90 = F0 + (1 - F0) grazing)"
        ),
        params=(DIFFUSE, F0, ALPHA, GRAZING),
        fn=_single_lobe(lambda p: GGX(p["alpha"])),
        derived=grazing_f90,
        reference="RTR eqs. 9.34, 9.41, 9.42, 9.31, 9.18, 9.61",
    )
)

GGX_ANISO_MODEL = register(
    Model(
        name="ggx-aniso",
        description=(
            "Lambert + anisotropic GGX specular (α_x along the tangent, α_y along the "
            "bitangent; the tangent at azimuth frame_angle)"
        ),
        params=(
            DIFFUSE,
            F0,
            Param("alpha_x", (), *ALPHA_BOUNDS, 0.1, "roughness along the tangent x", log=True),
            Param("alpha_y", (), *ALPHA_BOUNDS, 0.1, "roughness along the bitangent y", log=True),
            GRAZING,
            FRAME_ANGLE,
        ),
        fn=rotated(_single_lobe(lambda p: GGX(p["alpha_x"], p["alpha_y"]))),
        derived=grazing_f90,
        isotropic=False,
        reference="RTR eqs. 9.34, 9.53, 9.42 with 9.51, 9.18",
    )
)


def _two_lobe_ggx(p, wi, wo):
    """Two GGX lobes blended, ``f = ρ_d/π + (1 − m) f_s(α₁) + m f_s(α₂)``, each ``f_s`` the full
    microfacet lobe of RTR eq. 9.34 (its own height-correlated ``G2``) with the same generalized
    Schlick ``F`` (``F0``, ``F90 = F0 + (1 − F0) t``): the "mix of two GGX NDFs ... a second roughness value and a
    blend amount" that RTR §9.8.1 describes at Imageworks, for the measured materials whose peak and haze one lobe cannot both
    follow (Ngan et al. 2005). A convex blend of two energy-conserving lobes conserves energy, and
    ``m = 0`` (or ``m = 1``) is ``ggx`` exactly, so the fit starts from the ``ggx`` optimum
    (``refines``) and descends from there. Two lobes each with its own Schlick ``F0`` would not
    contain ``ggx``: a lobe with ``F0 = 0`` still reflects ``(1 − cos θd)⁵`` at grazing angles."""
    fresnel = _fresnel(p)
    sharp = microfacet_specular(GGX(p["alpha_1"]), fresnel, wi, wo)
    broad = microfacet_specular(GGX(p["alpha_2"]), fresnel, wi, wo)
    m = p["mix"]
    return lambert(p["diffuse"], wi, wo) + (1.0 - m) * sharp + m * broad


TWO_LOBE_GGX_MODEL = register(
    Model(
        name="two-lobe-ggx",
        description=(
            "Lambert + a blend of a sharp and a broad GGX lobe with one generalized Schlick F "
            "(RTR §9.8.1, Imageworks; Ngan et al. 2005)"
        ),
        params=(
            DIFFUSE,
            F0,
            Param("alpha_1", (), *ALPHA_BOUNDS, 0.05, "roughness of the sharp lobe", log=True),
            Param("alpha_2", (), *ALPHA_BOUNDS, 0.3, "roughness of the broad lobe", log=True),
            Param("mix", (), 0.0, 1.0, 0.2, "blend amount m: weight of the broad lobe"),
            GRAZING,
        ),
        fn=_two_lobe_ggx,
        derived=grazing_f90,
        reference="RTR §9.8.1 (Imageworks' mix of two GGX lobes), eq. 9.34 twice; Ngan et al. 2005",
        refines=("ggx", two_lobes_from_one),
    )
)


BECKMANN_MODEL = register(
    Model(
        name="beckmann",
        description=(
            "Lambert + Beckmann specular, exact erf Smith Λ, height-correlated G2, "
            "generalized Schlick F (F0, F90 = F0 + (1 - F0) grazing)"
        ),
        params=(DIFFUSE, F0, ALPHA, GRAZING),
        fn=_single_lobe(lambda p: Beckmann(p["alpha"])),
        derived=grazing_f90,
        reference="RTR eqs. 9.34, 9.35, 9.38, 9.31, 9.18, 9.61",
    )
)

#: GTR's tail exponent: γ = 1 is Berry's (clearcoat) tail, 2 is GGX, large γ approaches
#: Beckmann; Burley 2012 §5.4 found γ between 1 and 2 for MERL, the bounds leave room either side.
GAMMA = Param("gamma", (), 0.3, 10.0, 2.0, "GTR tail exponent γ (2 = GGX, smaller = longer tail)", log=True)

GTR_MODEL = register(
    Model(
        name="gtr",
        description="Lambert + generalized Trowbridge-Reitz specular (free tail γ), numerical Smith Λ",
        params=(DIFFUSE, F0, ALPHA, GAMMA, GRAZING),
        fn=_single_lobe(lambda p: GTR(p["alpha"], p["gamma"])),
        derived=grazing_f90,
        reference="Burley 2012 App. B eq. 1; RTR eqs. 9.34, 9.46, 9.47, 9.23/9.24, 9.31, 9.18",
        per_pass=PerPass(build=_gtr_table, apply=_gtr_with_table, uses=("alpha", "gamma")),
    )
)

BLINN_PHONG_MODEL = register(
    Model(
        name="blinn-phong",
        description=(
            "Lambert + Blinn-Phong specular; alpha is the Beckmann-equivalent roughness, "
            "exponent α_p = 2α⁻² − 2 (Walter 2007), Beckmann Smith Λ"
        ),
        params=(DIFFUSE, F0, ALPHA, GRAZING),
        fn=_single_lobe(lambda p: BlinnPhong.from_beckmann_alpha(p["alpha"])),
        derived=grazing_f90,
        reference="RTR eqs. 9.34, 9.40 (α_p = 2α_b⁻² − 2, p. 340), 9.38, 9.31, 9.18, 9.61",
    )
)
