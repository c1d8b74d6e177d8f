r"""Data-driven starting points of the built-in models: their ``Model.start`` hooks.

The fitter reads a few features off the data (:class:`brdffit.fitting.start.Features`): the
diffuse albedo ``ρ_d``, a GGX roughness ``α`` from the width of the specular peak and a Schlick
``F0`` from its height. Each hook here maps them onto one family's parameters. The maps are
conventions, not formulas of the sources: a start for the solver, which the fitter then moves
inside the parameters' bounds.

* **metallic-roughness models** (``disney``, ``mitsuba-principled``, ``gltf-pbr``): all three
  write ``α = roughness²``, so ``roughness = √α``; data whose mean ``F0`` exceeds
  :data:`METAL_F0` read as a metal (colour from ``F0``, ``metallic`` 0.9), others as a
  dielectric (colour from ``ρ_d``, ``metallic`` 0.1); Disney's and Mitsuba's ``specular`` is
  the dielectric ``F0 = 0.08 specular``. On anisotropic data Disney's and Mitsuba's
  ``roughness`` and ``anisotropic`` take the lobe's widths along the data's axes
  (:func:`principled_anisotropy`).
* **glTF** (``gltf-pbr``, ``gltf-pbr-clearcoat``): a dielectric starts at ``metallic`` 0 with
  its diffuse colour and the ``ior`` of its ``F0`` (``KHR_materials_ior``:
  ``ior = (1 + √F0)/(1 − √F0)``, so a plastic's 5 % gives 1.58), ``specular`` 1; a metal at
  ``metallic`` 1 with the colour of its ``F0``. The dielectric start matters: the fit does not
  leave the basin it starts in, and the core model's metallic reading of a shiny plastic (a
  black metal) is a worse optimum once the dielectric can reach its ``F0``.
* **Mitsuba's rough conductor**: ``α`` as measured; when anisotropic, ``alpha_u`` and
  ``alpha_v`` are the lobe's widths along the data's ``x`` and ``y`` (its tangent is the
  data's ``x``: :meth:`~brdffit.fitting.start.Features.axis_widths`); the tint form's ``specular_reflectance`` is ``F0`` (its Fresnel is 1), the
  complex-IOR form takes ``η = 1`` and the ``k`` whose normal-incidence reflectance
  ``((η − 1)² + k²)/((η + 1)² + k²) = k²/(4 + k²)`` is ``F0``: ``k = 2 √(F0/(1 − F0))``.

* **the APS anisotropic Gaussian** (``aps-gaussian``): its widths from the lobe's measured
  principal widths ``α_x, α_y`` and its ``frame_angle`` from their axes (the features'
  anisotropy, :class:`brdffit.fitting.start.Features`). ``p = exp(−s²/σ²)`` in the slope ``s``
  falls to half at ``s² = σ² ln 2``, GGX at ``s² = α²(√2 − 1)``: equal half widths give
  ``σ = α √((√2 − 1)/ln 2)`` (:data:`GAUSSIAN_PER_GGX`).

* **the APS satin and V-grooves** (``aps-satin``, ``aps-vgroove``): their ``frame_angle``
  from the lobe's axes, the satin's tangent on the narrow axis (its fibres' slopes spread
  along ``x`` only), the grooves' on the wide one (the grooves split the lobe along ``x``);
  on anisotropic data their widths from the lobe's (:func:`aps_satin`, :func:`aps_vgroove`).

``two-lobe-ggx`` starts from a fitted ``ggx`` instead (``Model.refines``,
:func:`two_lobes_from_one`): with the blend at 0 (or 1) it is the one-lobe fit, so the two-lobe
fit cannot end above it.
"""

from __future__ import annotations

import numpy as np

#: A mean ``F0`` above this reads as a metal (dielectrics have ``F0`` of about 0.02 to 0.08).
METAL_F0 = 0.25


def metallic_roughness(features, metal: bool | None = None) -> dict:
    """``base_color``, ``metallic`` and ``roughness`` (module docstring); ``metal`` forces one
    reading of the data (``None``: decided by :data:`METAL_F0`)."""
    if metal is None:
        metal = float(np.mean(features.f0)) > METAL_F0
    return {
        "base_color": np.clip(features.f0 if metal else features.diffuse, 0.02, 0.98),
        "metallic": 0.9 if metal else 0.1,
        "roughness": float(np.clip(np.sqrt(features.alpha), 0.05, 0.95)),
    }


#: The ``ior`` range of the glTF start: ``F0`` from 1 % to 25 %.
GLTF_IOR_RANGE = (1.22, 3.0)


def gltf_pbr(features, metal: bool | None = None) -> dict:
    """The start of ``gltf-pbr`` (module docstring); ``metal`` forces one reading (``None``:
    decided by :data:`METAL_F0`)."""
    if metal is None:
        metal = float(np.mean(features.f0)) > METAL_F0
    f0 = float(np.clip(np.mean(features.f0), 0.0, 0.99))
    ior = float(np.clip((1 + np.sqrt(f0)) / (1 - np.sqrt(f0)), *GLTF_IOR_RANGE))
    return {**metallic_roughness(features, metal), "metallic": 1.0 if metal else 0.0,
            "ior": 1.5 if metal else ior, "specular": 1.0}


def gltf_pbr_sheen(features) -> dict:
    """The start of ``gltf-pbr-sheen``: :func:`gltf_pbr` and a faint grey sheen (0.1; at 0 its
    roughness would do nothing) of medium roughness."""
    return {**gltf_pbr(features), "sheen_color": 0.1, "sheen_roughness": 0.5}


def specular_level(features) -> float:
    """Disney's and Mitsuba's ``specular``: the dielectric ``F0 = 0.08 specular``."""
    return float(np.clip(np.mean(features.f0) / 0.08, 0.05, 0.95))


def principled(features) -> dict:
    """The start of ``disney`` and ``mitsuba-principled``: :func:`metallic_roughness` and
    :func:`specular_level`, and on anisotropic data :func:`principled_anisotropy`; the lobes
    the features say nothing about keep their defaults."""
    out = {**metallic_roughness(features), "specular": specular_level(features)}
    if not features.isotropic:
        out.update(principled_anisotropy(features))
    return out


def principled_anisotropy(features) -> dict:
    r"""``roughness`` and ``anisotropic`` of the Disney/Mitsuba principled lobe whose widths
    along the data's axes (:meth:`~brdffit.fitting.start.Features.axis_widths`, ``w_x``,
    ``w_y``) the data show: the lobe's tangent is the data's ``x`` (Burley 2012, addenda:
    ``α_x = r²/aspect``, ``α_y = r² aspect``, ``aspect = √(1 − 0.9 anisotropic)``), so
    ``r² = √(w_x w_y)`` and ``anisotropic = (1 − w_y/w_x)/0.9``, clipped to ``[0, 1]``: a lobe
    wider along ``y`` than ``x`` is one these models cannot turn to, and starts isotropic."""
    wx, wy = features.axis_widths()
    return {"roughness": float(np.clip((wx * wy) ** 0.25, 0.05, 0.95)),
            "anisotropic": float(np.clip((1.0 - wy / wx) / 0.9, 0.0, 1.0))}


def rough_conductor(features, anisotropic: bool = False, fresnel: str = "ior") -> dict:
    """The start of Mitsuba's ``roughconductor`` variants (module docstring)."""
    alpha = float(features.alpha)
    if anisotropic:  # the tangent is the data's x: the lobe's widths along the data's axes
        out = (dict(zip(("alpha_u", "alpha_v"), features.axis_widths()))
               if not features.isotropic else {"alpha_u": alpha, "alpha_v": alpha})
    else:
        out = {"alpha": alpha}
    f0 = np.clip(np.asarray(features.f0, float), 0.01, 0.95)
    if fresnel == "tint":
        out["specular_reflectance"] = f0
    else:
        out["eta"] = np.ones(3)
        out["k"] = 2.0 * np.sqrt(f0 / (1.0 - f0))
    return out


#: ``σ/α`` of an APS Gaussian with the half width of a GGX lobe (module docstring).
GAUSSIAN_PER_GGX = float(np.sqrt((np.sqrt(2.0) - 1.0) / np.log(2.0)))


def aps_gaussian(features, bounds=(0.0, np.inf)) -> dict:
    """The start of ``aps-gaussian`` (module docstring), its widths clipped to ``bounds``."""
    return {"diffuse": features.diffuse, "f0": features.f0,
            "sigma_x": float(np.clip(GAUSSIAN_PER_GGX * features.alpha_x, *bounds)),
            "sigma_y": float(np.clip(GAUSSIAN_PER_GGX * features.alpha_y, *bounds)),
            "frame_angle": features.frame_angle}


def oriented(features, wide_x: bool) -> float:
    """The ``frame_angle`` that puts a model's tangent ``x`` on the lobe's wide axis
    (``wide_x``) or its narrow one: the features' angle (the axis of ``α_x``, ``|φ| ≤ π/4``), or a
    quarter turn from it, wrapped into ``[−π/2, π/2]``; 0 for an isotropic lobe."""
    if features.isotropic:
        return 0.0
    angle = float(features.frame_angle)
    if (features.alpha_x > features.alpha_y) != wide_x:
        angle += np.pi / 2 if angle <= 0 else -np.pi / 2
    return angle


def _narrow_wide(features) -> tuple[float, float]:
    return min(features.alpha_x, features.alpha_y), max(features.alpha_x, features.alpha_y)


def aps_satin(features, bounds=(0.0, np.inf)) -> dict:
    """The start of ``aps-satin``: its fibres' slopes spread along the tangent ``x`` only
    (cylindrical Gaussians, ``σ_y = ∞``), so ``x`` goes on the lobe's narrow axis
    (:func:`oriented`), with ``sigma_flats`` the narrow width as :func:`aps_gaussian` maps it and
    ``sigma_ends`` three times that (the ratio of the paper's 0.1 and 0.3). An isotropic lobe
    keeps the defaults' widths."""
    out = {"diffuse": features.diffuse, "f0": features.f0,
           "frame_angle": oriented(features, wide_x=False)}
    if not features.isotropic:
        narrow = GAUSSIAN_PER_GGX * _narrow_wide(features)[0]
        out.update(sigma_flats=float(np.clip(narrow, *bounds)),
                   sigma_ends=float(np.clip(3.0 * narrow, *bounds)))
    return out


def aps_vgroove(features, bounds=(0.0, np.inf), tilt_max: float = np.inf) -> dict:
    """The start of ``aps-vgroove``: grooves along ``y`` split the lobe along ``x``, so ``x``
    goes on the lobe's wide axis (:func:`oriented`); each facet's ``sigma`` is the narrow width
    (mapped as :func:`aps_gaussian` maps it), and the ``tilt`` the slope that widens the other
    axis beyond it, ``atan √(w² − n²)``. An isotropic lobe keeps the defaults' shape."""
    out = {"diffuse": features.diffuse, "f0": features.f0,
           "frame_angle": oriented(features, wide_x=True)}
    if not features.isotropic:
        narrow, wide = _narrow_wide(features)
        out.update(sigma=float(np.clip(GAUSSIAN_PER_GGX * narrow, *bounds)),
                   tilt=float(np.clip(np.arctan(np.sqrt(wide * wide - narrow * narrow)),
                                      0.0, tilt_max)))
    return out


#: The second lobe of :func:`two_lobes_from_one` starts this factor wider (or narrower) than the
#: fitted one: about the ratio of the haze to the peak width on glossy materials.
SECOND_LOBE_WIDTH = 4.0


def two_lobes_from_one(params) -> list[dict]:
    """Starts of ``two-lobe-ggx`` from a fitted ``ggx`` (``params``): the fitted lobe with blend
    ``m = 0`` beside a broad lobe ``SECOND_LOBE_WIDTH`` times wider, and with ``m = 1`` beside a
    sharp lobe as many times narrower; each is the ``ggx`` fit exactly, and the solver then
    blends in the second lobe where the data ask for it."""
    alpha = float(params["alpha"])
    same = {"diffuse": params["diffuse"], "f0": params["f0"], "grazing": params["grazing"]}
    return [
        {**same, "alpha_1": alpha, "alpha_2": min(1.0, SECOND_LOBE_WIDTH * alpha), "mix": 0.0},
        {**same, "alpha_1": max(1e-3, alpha / SECOND_LOBE_WIDTH), "alpha_2": alpha, "mix": 1.0},
    ]
