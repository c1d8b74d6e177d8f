"""The APS 2000 BRDF for any distribution, and the paper's distributions as registered models.

:func:`aps_brdf` is the whole model of APS 2000: specular term (eq. 26 or 14) plus the
energy-conserving diffuse term (eqs. 28–30, or the metal variant), tables built from the
current parameters. The registered models (``aps-gaussian`` eq. 34, ``aps-velvet`` eq. 35,
``aps-satin`` §6.3, ``aps-vgroove`` §6.2) each take RGB ``f0`` and ``diffuse`` (ρ_d) plus the
distribution's shape parameters.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..models.registry import Model, Param, register
from .diffuse import aps_diffuse, aps_diffuse_metal, build_r_table
from .distributions import AnisotropicGaussian, Velvet, satin, v_groove
from .specular import CORRELATED, UNCORRELATED, aps_specular
from .tables import DEFAULT_RESOLUTION, Resolution, build_g_table


def aps_brdf(dist, f0, diffuse, wi, wo, *, shadowing=UNCORRELATED, resolution=DEFAULT_RESOLUTION, metal=False):
    """``ρ = ρ_s + ρ_diffuse`` of APS 2000 for the distribution ``dist``, RGB ``(..., 3)``.

    Args:
        dist: a :class:`~brdffit.aps.distributions.Distribution` (any ``p(h)``).
        f0: Schlick normal reflectance (RGB).
        diffuse: ρ_d (RGB) of eq. 30; ignored (``ρ_d = f0``) when ``metal=True``; ``None``
            leaves the diffuse term out (and its table unbuilt).
        shadowing: ``UNCORRELATED`` (eq. 26) or ``Correlated(width)`` (eq. 14).
        resolution: table and quadrature sizes (:class:`~brdffit.aps.tables.Resolution`).
        metal: use the metal variant of the diffuse term (§5.1).
    """
    f0 = jnp.asarray(f0)
    dtype = jnp.result_type(wi, wo, f0)
    table = build_g_table(dist, dtype, resolution)
    out = aps_specular(dist, table, f0, wi, wo, shadowing)
    if diffuse is None and not metal:
        return out
    rtable = build_r_table(dist, table, dtype, resolution, shadowing)
    if metal:
        return out + aps_diffuse_metal(rtable, f0, wi, wo)
    return out + aps_diffuse(rtable, diffuse, f0, wi, wo)


F0 = Param(
    "f0", (3,), 0.0, 1.0, 0.05, "normal-incidence reflectance f0 (RGB), Schlick (APS eq. 31)",
    per_channel=True,
)
DIFFUSE = Param(
    "diffuse", (3,), 0.0, 1.0, 0.5, "diffuse albedo ρ_d (RGB) of the coupled term (APS eq. 30)",
    per_channel=True,
)
SIGMA_BOUNDS = (0.08, 1.0)

#: Table sizes of the registered models (call :func:`aps_brdf` directly for others). Isotropic
#: tables are 1-D (33 elevations) and cheap; anisotropic ones are 2-D (17 elevations × 24
#: azimuths for g, 11 × 16 for R), sized so that one evaluation with its table builds stays
#: near 0.1 s on a CPU core. Measured visibility P(k) (eq. 25) against much finer tables
#: (65 × 96, doubled quadratures) at 4000 random directions: anisotropic Gaussian σ = 0.1/0.3
#: within 0.35 % above 10° elevation and 2.3 % between 2° and 10° (bilinear interpolation in φ
#: dominates); σ = 0.2/0.5: 0.5 % / 1.8 %; velvet σ = 0.5: 0.3 % / 0.02 %; p = GGX(α = 0.1)
#: against Smith's closed-form G1: 0.02 % / 0.04 %.
ISO_RESOLUTION = Resolution()
ANISO_RESOLUTION = Resolution(
    n_u=17, n_phi=24, n_psi=16, n_beta=8, n_theta=40, n_phi_q=64, r_grid=(11, 16), r_quad=(32, 48)
)


def _dt(p, *names):
    dtype = jnp.result_type(*(p[n] for n in names))
    return dtype, {n: jnp.asarray(p[n], dtype) for n in names}


def _gaussian(p, wi, wo):
    _, q = _dt(p, "sigma_x", "sigma_y", "f0", "diffuse")
    dist = AnisotropicGaussian(q["sigma_x"], q["sigma_y"])
    return aps_brdf(dist, q["f0"], q["diffuse"], wi, wo, resolution=ANISO_RESOLUTION)


def _velvet(p, wi, wo):
    _, q = _dt(p, "sigma", "f0", "diffuse")
    return aps_brdf(Velvet(q["sigma"]), q["f0"], q["diffuse"], wi, wo, shadowing=CORRELATED,
                    resolution=ISO_RESOLUTION)


def _satin(p, wi, wo):
    dtype, q = _dt(p, "sigma_flats", "sigma_ends", "w_flats", "f0", "diffuse")
    dist = satin(q["sigma_flats"], q["sigma_ends"], q["w_flats"], dtype=dtype)
    return aps_brdf(dist, q["f0"], q["diffuse"], wi, wo, resolution=ANISO_RESOLUTION)


def _vgroove(p, wi, wo):
    dtype, q = _dt(p, "tilt", "sigma", "f0", "diffuse")
    dist = v_groove(q["tilt"], q["sigma"], dtype=dtype)
    return aps_brdf(dist, q["f0"], q["diffuse"], wi, wo, resolution=ANISO_RESOLUTION)


APS_GAUSSIAN = register(Model(
    name="aps-gaussian",
    description="APS 2000 generator, anisotropic Gaussian p(h) (eq. 34), coupled diffuse (eq. 30)",
    params=(
        DIFFUSE, F0,
        Param("sigma_x", (), *SIGMA_BOUNDS, 0.2, "slope width along the tangent x (eq. 34)", log=True),
        Param("sigma_y", (), *SIGMA_BOUNDS, 0.2, "slope width along the bitangent y (eq. 34)", log=True),
    ),
    fn=_gaussian, isotropic=False, reference="APS 2000 eqs. 26, 25, 18, 30, 31, 34",
))

APS_VELVET = register(Model(
    name="aps-velvet",
    description="APS 2000 generator, velvet inverse-Gaussian p(h) (eq. 35), correlated shadowing (eq. 14)",
    params=(
        DIFFUSE, F0,
        Param("sigma", (), 0.1, 2.0, 0.5, "width σ of the inverse Gaussian exp(-cot²θ/σ²)", log=True),
    ),
    fn=_velvet, isotropic=True, reference="APS 2000 eqs. 14, 25, 18, 30, 31, 35, §6.4",
))

APS_SATIN = register(Model(
    name="aps-satin",
    description="APS 2000 satin: 0.7/0.3 mixture of cylindrical Gaussians (§6.3), coupled diffuse",
    params=(
        DIFFUSE, F0,
        Param("sigma_flats", (), *SIGMA_BOUNDS, 0.1, "σ_x of the flat fiber parts (σ_y = ∞)", log=True),
        Param("sigma_ends", (), *SIGMA_BOUNDS, 0.3, "σ_x of the bent fiber ends (σ_y = ∞)", log=True),
        Param("w_flats", (), 0.0, 1.0, 0.7, "area fraction of the flat parts"),
    ),
    fn=_satin, isotropic=False, reference="APS 2000 §6.3, eqs. 26, 30, 34",
))

APS_VGROOVE = register(Model(
    name="aps-vgroove",
    description="APS 2000 V-grooves along y: two narrow Gaussians about tilted facet normals (§6.2)",
    params=(
        DIFFUSE, F0,
        Param("tilt", (), 0.0, 1.2, float(np.radians(20.0)), "facet tilt from n (rad); grooves along y"),
        Param("sigma", (), *SIGMA_BOUNDS, 0.1, "width of each facet Gaussian", log=True),
    ),
    fn=_vgroove, isotropic=False, reference="APS 2000 §6.2, eqs. 26, 30",
))
