r"""The fitted-distribution models of the MERL studies: Löw 2012's ABC models, Bagher 2012's SGD,
and the Student-t distribution of Ribardière et al. 2017; each plus a Lambertian ``ρ_d/π``.

Each model is written as the bbm project implements it (``bsdfbenchmark/bbm``,
``include/bsdfmodel/*.h``), in bbm's conventions, so that the published fits evaluate to bbm's
reference values (:func:`~brdffit.models.published.register_published`;
``tests/test_published_models.py``). ``h`` is the half vector, ``θd`` the angle between ``wi``
and ``h``, ``F_η`` the dielectric Fresnel reflectance with index ``η``
(:func:`~brdffit.terms.fresnel.dielectric`, equal for ``η ≥ 1`` to Cook & Torrance 1982's
``½ ((g − c)/(g + c))² (1 + ((c(g + c) − 1)/(c(g − c) + 1))²)``, ``g² = η² + c² − 1``, which bbm
writes; the bounds keep ``η ≥ 1``).

* ``low-smooth``: Löw et al. 2012 eq. 12, the ABC "smooth surface" model (bbm ``LowSmooth``),
  in the projected directions ``ĩ, õ`` (the ``xy`` parts of ``wi``, ``wo``):

  .. math::  f = \frac{\rho_d}{\pi} + A\,\left(1 + B\,\lVert\tilde i + \tilde o\rVert^2\right)^{-C}
      F_\eta(\cos\theta_d), \qquad \cos\theta_d = \sqrt{1 - \tfrac14\lVert\tilde i - \tilde o\rVert^2}

* ``low-microfacet``: Löw et al. 2012 eq. 15, the microfacet model with the ABC distribution
  ``S`` (:class:`~brdffit.terms.ndf.ABC`) and the V-groove masking of Cook & Torrance 1982 (:func:`~brdffit.terms.masking.G2_vgroove`; bbm
  ``LowMicrofacetFit``: the normalisation ``π`` of the fits in Löw's supplemental material):

  .. math::  f = \frac{\rho_d}{\pi} + A\,\frac{S(\mathbf h)\,G\,F_\eta(\mathbf i\cdot\mathbf h)}
      {\pi\,(\mathbf n\cdot\mathbf i)(\mathbf n\cdot\mathbf o)}, \qquad
      G = \min\!\left(1, \frac{2(\mathbf n\cdot\mathbf h)(\mathbf n\cdot\mathbf i)}{\mathbf i\cdot\mathbf h},
          \frac{2(\mathbf n\cdot\mathbf h)(\mathbf n\cdot\mathbf o)}{\mathbf o\cdot\mathbf h}\right)

* ``sgd``: Bagher et al. 2012, the shifted gamma distribution (:class:`~brdffit.terms.ndf.SGD`),
  their fitted masking ``G1`` (:func:`~brdffit.terms.ndf.bagher_g1`), separable, and their
  modified Schlick Fresnel ``F = F0 + (1 − F0)(1 − c)⁵ − F1 c`` (eq. 12; bbm ``Bagher``), every
  parameter per colour channel as published:

  .. math::  f = \frac{\rho_d}{\pi} + k_s\,\frac{P_{22}(\tan^2\theta_h)}{\pi\cos^4\theta_h}\,
      \frac{G_1(\mathbf i)G_1(\mathbf o)\,F(\mathbf i\cdot\mathbf h)}
      {\pi\,(\mathbf n\cdot\mathbf i)(\mathbf n\cdot\mathbf o)}

  ``k_s`` is bbm's specular ``albedo`` times the NDF's normalisation ``K``: the two only ever
  appear as this product (a fit of both would be singular).

* ``student-t``: the house's single-lobe microfacet model (RTR eq. 9.34: height-correlated
  Smith ``G2``, generalized Schlick ``F0``, ``F90 = F0 + (1 − F0) t``, as ``ggx``) with the Student-t NDF
  (:class:`~brdffit.terms.ndf.StudentT`): ``γ = 2`` is ``ggx``, ``γ → ∞`` is ``beckmann``. No
  published fits of MERL exist for it; bbm's ``Ribardiere`` differs (separable ``G`` with the
  paper's approximate ``Λ``, the Cook–Torrance Fresnel).
"""

from __future__ import annotations

from functools import partial

import jax.numpy as jnp
import numpy as np

from data_formats.published import PublishedFit

from ..terms._math import cos_theta, dot, half_vector, safe_div, safe_sqrt
from ..terms.diffuse import lambert
from ..terms.fresnel import dielectric, ior_from_f0
from ..terms.masking import G2_vgroove
from ..terms.ndf import ABC, SGD, StudentT, bagher_g1
from ..terms.ndf.sgd import theta_of
from .published import PublishedForm, register_published
from .registry import Model, Param, PerPass, register
from .standard import ALPHA, DIFFUSE, F0, GRAZING, grazing_f90, lobe_with

# --- Löw 2012 ------------------------------------------------------------------------------

#: The bounds contain every published value (80 materials, E2): ``A`` 0.078–4513, ``B``
#: 6.6–8.1e6, ``C`` 0.014–2.7, ``η`` 1.054–99.9996 (``lowmicrofacet`` ends at Löw's bound 100).
LOW_A = Param("a", (3,), 1e-3, 1e5, 1.0, "specular scale A (RGB), unnormalised", log=True,
              per_channel=True, scan=False)
LOW_B = Param("b", (), 1.0, 1e8, 1e3, "ABC width B (larger: sharper peak)", log=True)
LOW_C = Param("c", (), 1e-3, 10.0, 1.0, "ABC tail exponent C (smaller: longer tail)", log=True,
              scan=False)
LOW_ETA = Param("eta", (), 1.0, 100.0, 1.5, "index of refraction η of the Fresnel term",
                log=True, scan=False)


def _within(param, value):
    """``value`` clipped to ``param``'s bounds (a start hook names values inside them)."""
    return np.clip(value, param.lower, param.upper)


def _vis(wi, wo):
    return (cos_theta(wi) > 0) & (cos_theta(wo) > 0)


def low_smooth(p, wi, wo):
    """Löw 2012 eq. 12 plus Lambert (module docstring)."""
    s, d = wi[..., :2] + wo[..., :2], wi[..., :2] - wo[..., :2]
    dp2 = s[..., 0] ** 2 + s[..., 1] ** 2
    cos_d = safe_sqrt(1.0 - 0.25 * (d[..., 0] ** 2 + d[..., 1] ** 2))
    shape = jnp.exp(-p["c"] * jnp.log1p(p["b"] * dp2))
    spec = p["a"] * (shape * _vis(wi, wo))[..., None] * dielectric(p["eta"], cos_d)
    return lambert(p["diffuse"], wi, wo) + spec


def low_microfacet(p, wi, wo):
    """Löw 2012 eq. 15 with bbm's normalisation ``π`` plus Lambert (module docstring)."""
    wm = half_vector(wi, wo)
    ci, co = cos_theta(wi), cos_theta(wo)
    geom = ABC(p["b"], p["c"]).S(wm) * G2_vgroove(None, wi, wo, wm)
    geom = safe_div(geom, jnp.pi * ci * co) * _vis(wi, wo)
    cos_d = 0.5 * (dot(wi, wm) + dot(wo, wm))  # bbm's reciprocal average of two equal cosines
    return lambert(p["diffuse"], wi, wo) + p["a"] * geom[..., None] * dielectric(p["eta"], cos_d)


def _low_start(features, normalization):
    r"""``B, C`` whose peak matches the measured GGX width near its top (``C = 2``: Löw's smooth
    ``(1 + 4Bθ²)^{-2}``, ``B = 1/(4α²)``; the microfacet ``(1 + Bθ²/2)^{-2}``, ``B = 2/α²``), ``η``
    from the measured ``F0`` and ``A`` from the peak height ``H = A F_η(1)/normalization``."""
    alpha = float(features.alpha)
    f0 = float(np.clip(np.mean(features.f0), 0.01, 0.6))
    eta = float(np.clip(ior_from_f0(f0), 1.1, 20.0))
    b = 1.0 / (4.0 * alpha**2) if normalization == 1.0 else 2.0 / alpha**2
    f_normal = ((eta - 1.0) / (eta + 1.0)) ** 2
    a = normalization * np.asarray(features.height) / f_normal
    return {"diffuse": features.diffuse, "a": _within(LOW_A, a), "b": _within(LOW_B, b), "c": 2.0,
            "eta": eta}


LOW_SMOOTH_MODEL = register(
    Model(
        name="low-smooth",
        description="Lambert + Löw 2012's ABC smooth-surface model (A, B, C), Cook-Torrance Fresnel (η)",
        params=(DIFFUSE, LOW_A, LOW_B, LOW_C, LOW_ETA),
        fn=low_smooth,
        reference="Löw et al. 2012 eqs. 10, 12, 14; bbm include/bsdfmodel/lowsmooth.h",
        start=partial(_low_start, normalization=1.0),
    )
)

LOW_MICROFACET_MODEL = register(
    Model(
        name="low-microfacet",
        description=("Lambert + Löw 2012's microfacet model: ABC distribution (A, B, C), V-groove G, "
                     "Cook-Torrance Fresnel (η)"),
        params=(DIFFUSE, LOW_A, LOW_B, LOW_C, LOW_ETA),
        fn=low_microfacet,
        reference="Löw et al. 2012 eq. 15; Cook & Torrance 1982; bbm include/bsdfmodel/low.h",
        start=partial(_low_start, normalization=float(np.pi)),
    )
)


def _low_params(fit: PublishedFit) -> dict:
    p = fit.params
    return {"diffuse": fit.albedo, "a": p["A"], "b": p["B"], "c": p["C"], "eta": p["eta"]}


register_published(PublishedForm("LowSmooth", "low-smooth", _low_params, "Löw 2012"))
register_published(PublishedForm("LowMicrofacetFit", "low-microfacet", _low_params, "Löw 2012"))

# --- Bagher 2012 -----------------------------------------------------------------------------


def _rgb(name, lower, upper, default, description, log=False):
    return Param(name, (3,), lower, upper, default, description, log=log, per_channel=True,
                 scan=False if log else None)


#: Every parameter per channel (Bagher's fits are). The bounds contain every published value
#: (80 materials): ``k_s`` 1.8e-15–3377, ``α`` 1.6e-5–0.85, ``p`` 2e-14–1.44, ``F0`` 0–8.5,
#: ``F1`` −1–7.5, ``Λ`` 4.5e-8–1.4e7, ``θ0`` −0.66–1.21, ``w`` 0.37–2.4, ``k`` 5.6–856.
SGD_PARAMS = (
    DIFFUSE,
    _rgb("ks", 1e-16, 1e5, 1.0, "specular scale k_s = albedo·K (RGB)", log=True),
    Param("alpha", (3,), 1e-5, 1.0, 0.01, "SGD α (RGB; p = 0: Beckmann with α_b² = α)",
          log=True, per_channel=True),
    _rgb("p", 0.0, 2.0, 0.5, "SGD shift exponent p (RGB; larger: longer tail)"),
    _rgb("f0", 0.0, 10.0, 0.05, "Fresnel F0 of Bagher's modified Schlick (RGB)"),
    _rgb("f1", -2.0, 10.0, 0.0, "Fresnel F1 of Bagher's modified Schlick, F − F1 cos θd (RGB)"),
    _rgb("g_lambda", 1e-8, 1e8, 1e-8, "masking amplitude Λ of G1 (RGB)", log=True),
    _rgb("g_theta0", -1.0, 1.5, 1.2, "angle θ0 (radians) where G1 starts to fall (RGB)"),
    _rgb("g_width", 0.1, 5.0, 1.0, "width w (radians) of G1's fall past θ0 (RGB)", log=True),
    _rgb("g_k", 1.0, 1e3, 10.0, "exponent k of G1's fall (RGB)", log=True),
)


def sgd(p, wi, wo):
    """Bagher 2012's SGD microfacet model plus Lambert (module docstring), per channel."""
    wm = half_vector(wi, wo)
    ci, co = cos_theta(wi), cos_theta(wo)
    ih, oh = dot(wi, wm), dot(wo, wm)
    vis = _vis(wi, wo) & (ih > 0) & (oh > 0)
    d = SGD(p["alpha"], p["p"]).shape(wm[..., None, :])  # (..., 3): one lobe per channel

    def g1(w):
        return bagher_g1(theta_of(w)[..., None], p["g_lambda"], p["g_theta0"], p["g_width"], p["g_k"])

    c = (0.5 * (ih + oh))[..., None]
    fresnel = p["f0"] + (1.0 - p["f0"]) * (1.0 - c) ** 5 - p["f1"] * c
    denom = safe_div(vis, jnp.pi * ci * co)[..., None]
    return lambert(p["diffuse"], wi, wo) + p["ks"] * d * g1(wi) * g1(wo) * fresnel * denom


#: The start's ``p``: near the peak, where ``α + t²/α ≪ 1``, ``P22 ≈ α^{−p}(1 + t²/α²)^{−p}``, a
#: core of width ``α`` whose tail ``e^{−t²/α}`` cuts beyond ``t ≈ √α``; Bagher's fits have ``p``
#: from 0 to 1.4.
SGD_START_P = 1.0


def _sgd_start(features):
    """``p = 1`` and the ``α`` whose core has the measured GGX half width (``(1 + t²/α²)^{−p}``
    halves at ``t² = α²(2^{1/p} − 1)``, GGX at ``α_g²(√2 − 1)``), ``F0`` from the features,
    ``F1 = 0``, the masking term off (``Λ`` at its lower bound) and ``k_s`` from the peak height
    ``H = k_s e^{−α} α^{−p} F0/π²`` (normal incidence)."""
    p = SGD_START_P
    alpha = float(np.clip(features.alpha * np.sqrt((np.sqrt(2.0) - 1.0) / (2.0 ** (1.0 / p) - 1.0)),
                          2e-5, 0.5))
    f0 = np.clip(np.asarray(features.f0, float), 0.02, 0.95)
    ks = np.asarray(features.height) * np.pi**2 * alpha**p * np.exp(alpha) / f0
    return {"diffuse": features.diffuse, "ks": _within(SGD_PARAMS[1], ks),
            "alpha": np.full(3, alpha), "p": p, "f0": f0, "f1": 0.0}


SGD_MODEL = register(
    Model(
        name="sgd",
        description=("Lambert + Bagher 2012's shifted gamma distribution, fitted G1, modified "
                     "Schlick F (F0, F1), every parameter per channel"),
        params=SGD_PARAMS,
        fn=sgd,
        reference="Bagher et al. 2012 eqs. 7, 8, 12 and §5; bbm include/bsdfmodel/bagher.h, ndf/sgd.h",
        start=_sgd_start,
    )
)


def _bagher_params(fit: PublishedFit) -> dict:
    p = fit.params
    eta = np.asarray(p["eta"], float)  # bbm's 2-vector of spectra: (F0, F1)
    return {"diffuse": fit.albedo, "ks": p["albedo"] * p["K"], "alpha": p["alpha"], "p": p["p"],
            "f0": eta[0], "f1": eta[1], "g_lambda": p["Lambda"], "g_theta0": p["theta0"],
            "g_width": np.power(p["c"], -1.0 / p["k"]), "g_k": p["k"]}


register_published(PublishedForm("Bagher", "sgd", _bagher_params, "Bagher 2012"))

# --- Ribardière 2017 -------------------------------------------------------------------------

#: ``γ = 2`` is GGX; the upper bound is Beckmann to about ``t⁴/(2γ)`` relative; below ``1.6``
#: the masking ``Λ`` grows without bound (it diverges at ``3/2``).
STUDENT_GAMMA = Param("gamma", (), 1.6, 1e3, 2.0,
                      "Student-t tail exponent γ (2 = GGX, → ∞ Beckmann, smaller: longer tail)",
                      log=True, scan=False)


def _student_t_table(p):
    return StudentT(p["alpha"], p["gamma"]).lambda_table()


def _student_t_with_table(p, table, wi, wo):
    return lobe_with(StudentT(p["alpha"], p["gamma"], table=table), p, wi, wo)


STUDENT_T_MODEL = register(
    Model(
        name="student-t",
        description=("Lambert + Student-t (STD) specular, free tail γ (2 = GGX, ∞ = Beckmann), "
                     "numerical Smith Λ, height-correlated G2, generalized Schlick F (F0, "
                     "F90 = F0 + (1 - F0) grazing)"),
        params=(DIFFUSE, F0, ALPHA, STUDENT_GAMMA, GRAZING),
        derived=grazing_f90,
        fn=lambda p, wi, wo: lobe_with(StudentT(p["alpha"], p["gamma"]), p, wi, wo),
        reference="Ribardière et al. 2017 eqs. 10, 13-15; RTR eqs. 9.34, 9.23/9.24, 9.31, 9.18",
        per_pass=PerPass(build=_student_t_table, apply=_student_t_with_table,
                         uses=("alpha", "gamma")),
    )
)
