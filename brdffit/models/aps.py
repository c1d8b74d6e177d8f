"""The paper's distributions as registered models of the APS 2000 generator.

The registered models (``aps-gaussian`` eq. 34, ``aps-velvet`` eq. 35, ``aps-satin`` §6.3,
``aps-vgroove`` §6.2) each take RGB ``f0`` and ``diffuse`` (ρ_d) plus the distribution's shape
parameters; the BRDF itself is :func:`brdffit.terms.aps.brdf.aps_brdf`, in its three stages.
The anisotropic ones (Gaussian, satin, V-grooves) also take their tangent's azimuth
``frame_angle`` (:mod:`brdffit.models.frame`), which their starts read off the data.

The registered models declare the stages (``Model.stages``) so that
:func:`brdffit.models.evaluate.evaluate_model` (fitted tables, figures) builds the tables once
and compiles stages 2 and 3 as separate programs. Compiled as one program, XLA's CPU backend
re-derives the table lookups in each of the ~16 gather fusions feeding the RGB output, which
makes it markedly slower than the two programs (``benchmarks/bench_aps.py`` times both), with
the same results to rounding (``tests/test_aps.py``).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..terms.aps.brdf import aps_combine, aps_per_pair, aps_prepare
from ..terms.aps.distributions import AnisotropicGaussian, Velvet, satin, v_groove
from ..terms.aps.specular import CORRELATED, UNCORRELATED
from ..terms.aps.tables import Resolution
from .frame import FRAME_ANGLE, rotated, rotated_stages
from .registry import Model, Param, register
from .starts import aps_gaussian, aps_satin, aps_vgroove


F0 = Param(
    "f0", (3,), 0.0, 1.0, 0.05, "normal-incidence reflectance f0 (RGB), Schlick (APS eq. 31)",
    per_channel=True,
)
DIFFUSE = Param(
    "diffuse", (3,), 0.0, 1.0, 0.5, "diffuse albedo ρ_d (RGB) of the coupled term (APS eq. 30)",
    per_channel=True,
)
SIGMA_BOUNDS = (0.08, 1.0)
#: The V-grooves' largest facet tilt (rad).
VGROOVE_TILT_MAX = 1.2

#: Table sizes of the registered models (call :func:`~brdffit.terms.aps.aps_brdf` with others).
#: Isotropic tables are 1-D (33 elevations) and cheap; anisotropic ones are 2-D (17 elevations ×
#: 24 azimuths for g, 11 × 16 for R), sized so that building them costs little beside one
#: evaluation over a MERL grid (``benchmarks/bench_aps.py``). Measured visibility P(k) (eq. 25)
#: against much finer tables (65 × 96, doubled quadratures) at 4000 random directions:
#: anisotropic Gaussian σ = 0.1/0.3 within 0.35 % above 10° elevation and 2.3 % between 2° and
#: 10° (bilinear interpolation in φ dominates); σ = 0.2/0.5: 0.5 % / 1.8 %; velvet σ = 0.5:
#: 0.3 % / 0.02 %; p = GGX(α = 0.1) against Smith's closed-form G1: 0.02 % / 0.04 %.
ISO_RESOLUTION = Resolution()
ANISO_RESOLUTION = Resolution(
    n_u=17, n_phi=24, n_psi=16, n_beta=8, n_theta=40, n_phi_q=64, r_grid=(11, 16), r_quad=(32, 48)
)


def _dt(p, *names):
    dtype = jnp.result_type(*(p[n] for n in names))
    return dtype, {n: jnp.asarray(p[n], dtype) for n in names}


def _staged(make, shadowing, resolution):
    """``(fn, stages)`` of a registered APS model; ``make(params) -> (dist, f0, diffuse, dtype)``."""

    def prepare(p):
        dist, f0, diffuse, dtype = make(p)
        return aps_prepare(dist, f0, diffuse, dtype=dtype, shadowing=shadowing, resolution=resolution)

    def per_pair(state, wi, wo):
        return aps_per_pair(state, wi, wo, shadowing)

    def fn(p, wi, wo):
        state = prepare(p)
        return aps_combine(state, per_pair(state, wi, wo))

    return {"fn": fn, "stages": (prepare, per_pair, aps_combine)}


def _in_frame(staged):
    """A :func:`_staged` model turned by its ``frame_angle`` (:mod:`brdffit.models.frame`)."""
    return {"fn": rotated(staged["fn"]), "stages": rotated_stages(staged["stages"])}


def _gaussian(p):
    dtype, q = _dt(p, "sigma_x", "sigma_y", "f0", "diffuse")
    return AnisotropicGaussian(q["sigma_x"], q["sigma_y"]), q["f0"], q["diffuse"], dtype


def _velvet(p):
    dtype, q = _dt(p, "sigma", "f0", "diffuse")
    return Velvet(q["sigma"]), q["f0"], q["diffuse"], dtype


def _satin(p):
    dtype, q = _dt(p, "sigma_flats", "sigma_ends", "w_flats", "f0", "diffuse")
    dist = satin(q["sigma_flats"], q["sigma_ends"], q["w_flats"], dtype=dtype)
    return dist, q["f0"], q["diffuse"], dtype


def _vgroove(p):
    dtype, q = _dt(p, "tilt", "sigma", "f0", "diffuse")
    return v_groove(q["tilt"], q["sigma"], dtype=dtype), q["f0"], q["diffuse"], dtype


APS_GAUSSIAN = register(Model(
    name="aps-gaussian",
    description="APS 2000 generator, anisotropic Gaussian p(h) (eq. 34), coupled diffuse (eq. 30)",
    params=(
        DIFFUSE, F0,
        Param("sigma_x", (), *SIGMA_BOUNDS, 0.2, "slope width along the tangent x (eq. 34)", log=True),
        Param("sigma_y", (), *SIGMA_BOUNDS, 0.2, "slope width along the bitangent y (eq. 34)", log=True),
        FRAME_ANGLE,
    ),
    **_in_frame(_staged(_gaussian, UNCORRELATED, ANISO_RESOLUTION)), isotropic=False,
    start=lambda features: aps_gaussian(features, SIGMA_BOUNDS), reference="APS 2000 eqs. 26, 25, 18, 30, 31, 34",
))

APS_VELVET = register(Model(
    name="aps-velvet",
    description="APS 2000 generator, velvet inverse-Gaussian p(h) (eq. 35), correlated shadowing (eq. 14)",
    params=(
        DIFFUSE, F0,
        Param("sigma", (), 0.1, 2.0, 0.5, "width σ of the inverse Gaussian exp(-cot²θ/σ²)", log=True),
    ),
    **_staged(_velvet, CORRELATED, ISO_RESOLUTION), isotropic=True, reference="APS 2000 eqs. 14, 25, 18, 30, 31, 35, §6.4",
))

APS_SATIN = register(Model(
    name="aps-satin",
    description="APS 2000 satin: 0.7/0.3 mixture of cylindrical Gaussians (§6.3), coupled diffuse",
    params=(
        DIFFUSE, F0,
        Param("sigma_flats", (), *SIGMA_BOUNDS, 0.1, "σ_x of the flat fiber parts (σ_y = ∞)", log=True),
        Param("sigma_ends", (), *SIGMA_BOUNDS, 0.3, "σ_x of the bent fiber ends (σ_y = ∞)", log=True),
        Param("w_flats", (), 0.0, 1.0, 0.7, "area fraction of the flat parts"),
        FRAME_ANGLE,
    ),
    **_in_frame(_staged(_satin, UNCORRELATED, ANISO_RESOLUTION)), isotropic=False,
    start=lambda features: aps_satin(features, SIGMA_BOUNDS), reference="APS 2000 §6.3, eqs. 26, 30, 34",
))

APS_VGROOVE = register(Model(
    name="aps-vgroove",
    description="APS 2000 V-grooves along y: two narrow Gaussians about tilted facet normals (§6.2)",
    params=(
        DIFFUSE, F0,
        Param("tilt", (), 0.0, VGROOVE_TILT_MAX, float(np.radians(20.0)), "facet tilt from n (rad); grooves along y"),
        Param("sigma", (), *SIGMA_BOUNDS, 0.1, "width of each facet Gaussian", log=True),
        FRAME_ANGLE,
    ),
    **_in_frame(_staged(_vgroove, UNCORRELATED, ANISO_RESOLUTION)), isotropic=False,
    start=lambda features: aps_vgroove(features, SIGMA_BOUNDS, VGROOVE_TILT_MAX),
    reference="APS 2000 §6.2, eqs. 26, 30",
))
