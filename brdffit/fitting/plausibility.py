"""Is the fitted material one a renderer can trust? The plausibility verdict of every fit.

Convergence says the solver found an optimum; it does not say that the optimum is a material.
:func:`assess` checks the fitted parameters against what every renderer assumes and what
real surfaces do, and returns a record (:func:`verdict_record`) that
:class:`~brdffit.fitting.FitResult` carries as ``plausibility``:
``{"plausible": bool, "checks": [{"name", "passed", "value", "limit", "meaning"}, ...]}``.
A check a model has no parameters for is left out; ``plausible`` is true when every check
listed passed. The checks (:data:`CHECKS`, in this order):

* ``energy``: the largest directional albedo of any channel over incidence ``0°–89°``
  (:func:`brdffit.models.albedo.max_albedo`) is at most 1 (+ :data:`ENERGY_SLACK` for the
  quadrature): the material reflects no more light than it receives. A Lambert term plus an
  independent specular lobe (the standard models) can exceed it; the fit holds it by default
  (:mod:`brdffit.fitting.constraints`), so this check fails only with ``energy="free"``.
* ``f90``: the grazing reflectance ``F90`` is at least ``F0`` in every channel (models with
  both, as parameters or as the model's ``derived``): a reflectance that falls towards
  grazing incidence is no surface, and plain-Schlick renderers show another material.
* ``diffuse_bound``: no channel of a Lambertian albedo (``diffuse``; a dielectric's
  ``base_color``) ends at 1 (:data:`WHITE`): a surface that scatters all light diffusely.
  The case that made this check: the ``cosine`` loss (Ngan 2005's protocol,
  ``configs/ngan2005.toml``) on a polished metal. Absolute errors let the sharp peak's
  residuals (values of 1e3–1e4) outweigh the whole diffuse signal, so the diffuse term is
  barely determined and takes up the peak's shoulders: on the chrome-steel proxy ``ggx``
  ends with ``diffuse`` (1, 0.96, 1), from the data-driven start and from the ``log`` loss's
  optimum alike (the loss's own optimum, not a start problem), and holding it at 0 raises
  the cost by 0.26 % while ``rel_error`` falls from 114 to 0.67.
* ``dark_metal``: ``metallic`` near 1 (:data:`METALLIC`) with a ``base_color`` darker than a
  dielectric's specular (:data:`DARK`, every channel): a black metal, the mark of a dielectric
  fitted as a metal with its colour traded away.
* ``metal_dielectric``: a metal-like specular (mean ``F0`` above
  :data:`brdffit.models.starts.METAL_F0`) over a strong diffuse term (:data:`STRONG_DIFFUSE`):
  metals have no diffuse term, dielectrics reflect 2–8 % at normal incidence; a metallic
  paint is both, a fit that traded one lobe for the other is neither. In a model with a
  dielectric ``ior`` beside ``metallic`` (``gltf-pbr``, ``KHR_materials_ior``): a mostly
  dielectric material (``metallic`` below 0.5) whose ``ior`` gives a metal's ``F0``
  (``((ior − 1)/(ior + 1))²`` above ``METAL_F0``: ``ior`` above 3; diamond's 2.42 gives 0.17).
  ``KHR_materials_specular`` scales ``F0`` and ``F90`` together, so the ``ior`` sets the ratio
  of the normal to the grazing reflectance: above 3 the Fresnel curve is flatter than any
  dielectric's. The realistic corpus ends there where the measured reflectance barely rises
  towards grazing within 80° (brass and chrome-steel, metallic 0.2–0.35, and beige fabric,
  all at the bound ``ior`` 5): the glTF model has no plausible reading of such data.
* ``error``: the fit's error in the literature's metrics (:data:`brdffit.metrics.METRICS`):
  ``rel_error`` at most :data:`REL_ERROR_LIMIT`; the meaning carries ``rmse_log`` and
  ``rmse_cosine`` beside it. ``rel_error`` counts every cell's error relative to the measured
  value (floored at 1e-3), so dark cells weigh in and good fits of glossy metals reach 1–7
  (the development corpus); ten times the measured value on average is a fit that does not
  describe the material at all.

The thresholds are conventions, stated here once; a failed check is a warning about the
material, never a change of the fit or of its ``success``.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError, UnknownNameError
from ..metrics import metric_text
from ..models.albedo import CHECK_ANGLES, max_albedo
from ..models.registry import get_model
from ..models.starts import METAL_F0
from .losses import get_loss

#: The quadrature's slack on ``ρ ≤ 1`` (its error is below 1e-3 on the check's grid).
ENERGY_SLACK = 0.01
#: A Lambertian albedo at or above this is "white", at its physical bound.
WHITE = 0.999
#: ``metallic`` at or above this reads as a metal.
METALLIC = 0.9
#: A metal's ``base_color`` (its ``F0``) below this in every channel is darker than a
#: dielectric's specular reflectance (2–8 %): no metal is that dark.
DARK = 0.05
#: A diffuse albedo above this (any channel) is a strong diffuse term.
STRONG_DIFFUSE = 0.1
#: ``rel_error`` above this: the fit is on average off by ten times the measured value.
REL_ERROR_LIMIT = 10.0
#: The checks' names, in the order a record lists them.
CHECKS = ("energy", "f90", "diffuse_bound", "dark_metal", "metal_dielectric", "error")


def _check(name, passed, value, limit, meaning) -> dict:
    return {"name": name, "passed": None if passed is None else bool(passed),
            "value": float(value), "limit": float(limit), "meaning": meaning}


def _rgb(value) -> np.ndarray:
    return np.broadcast_to(np.asarray(value, float), (3,))


def energy(model, params, albedo=None) -> dict:
    """The ``energy`` check (module docstring); not assessed (``passed`` None) where the
    parameters are not finite. ``albedo``: ``(ρ_max, θi)`` of :func:`max_albedo` at these
    parameters where the caller has it already (the fit's energy constraint)."""
    if not all(np.all(np.isfinite(np.asarray(v, float))) for v in params.values()):
        return _check("energy", None, math.nan, 1.0, "not assessed: the parameters are not finite")
    rho, theta = max_albedo(model, params) if albedo is None else albedo
    ok = rho <= 1.0 + ENERGY_SLACK
    meaning = (f"largest directional albedo {rho:.3g} (θi = {theta:.0f}°, over 0–"
               f"{CHECK_ANGLES[-1]:.0f}°): " + (
                   "reflects no more light than it receives" if ok else
                   "reflects more light than it receives; no surface does, and a renderer "
                   "brightens it at every bounce"))
    return _check("energy", ok, rho, 1.0, meaning)


def grazing(params, derived) -> dict | None:
    """The ``f90`` check, where the model has ``f0`` and ``f90``."""
    f90 = params.get("f90", derived.get("f90"))
    if "f0" not in params or f90 is None:
        return None
    gap = float(np.min(_rgb(f90) - _rgb(params["f0"])))
    ok = gap >= -1e-9
    meaning = ("F90 ≥ F0 in every channel: the reflectance rises towards grazing incidence"
               if ok else
               "F90 < F0: the reflectance falls towards grazing incidence; no surface does, and "
               "a renderer with plain Schlick (F90 = 1) shows another material")
    return _check("f90", ok, gap, 0.0, meaning)


def _absolute(loss: str) -> bool:
    """Whether the loss labelled ``loss`` weighs absolute errors (:attr:`.losses.Loss.absolute`);
    ``False`` for a label that is not a registered loss's."""
    try:
        return get_loss(loss).absolute
    except (UnknownNameError, ConfigError):
        return False


def white_diffuse(params, loss: str = "") -> dict | None:
    """The ``diffuse_bound`` check: ``diffuse``, or a dielectric's ``base_color``; ``loss``
    (the fit's loss label) names the likely cause."""
    if "diffuse" in params:
        albedo, what = _rgb(params["diffuse"]), "diffuse"
    elif "base_color" in params and float(params.get("metallic", 0.0)) < 0.5:
        albedo, what = _rgb(params["base_color"]), "base_color"
    else:
        return None
    top = float(np.max(albedo))
    ok = top < WHITE
    absolute = _absolute(loss)
    cause = (f"with the {loss} loss (absolute errors) the specular peak's residuals outweigh "
             f"the whole diffuse signal, so the diffuse term is barely determined and takes up "
             f"the peak's shoulders; fit with the log loss, or fix {what}" if absolute else
             f"the loss or the start pushed it there, not the material; fix {what} or try "
             f"another start")
    meaning = (f"{what} below 1: a diffuse term that absorbs some light" if ok else
               f"{what} at 1 (its bound): a surface that scatters all light diffusely; {cause}")
    return _check("diffuse_bound", ok, top, WHITE, meaning)


def black_metal(params) -> dict | None:
    """The ``dark_metal`` check, where the model has ``metallic`` and ``base_color``."""
    if "metallic" not in params or "base_color" not in params:
        return None
    metallic, top = float(params["metallic"]), float(np.max(_rgb(params["base_color"])))
    ok = not (metallic >= METALLIC and top < DARK)
    meaning = ("not a black metal" if ok else
               f"metallic {metallic:.2g} with base_color below {DARK:g}: a black metal, darker "
               f"than any dielectric's specular; a dielectric fitted as a metal, its colour "
               f"traded away")
    return _check("dark_metal", ok, top, DARK, meaning)


def metal_over_diffuse(params) -> dict | None:
    """The ``metal_dielectric`` check, where the model has ``f0`` and ``diffuse`` (or a
    dielectric ``ior`` beside ``metallic``: :func:`metal_ior`)."""
    if "ior" in params and "metallic" in params:
        return metal_ior(params)
    if "f0" not in params or "diffuse" not in params:
        return None
    f0, diffuse = float(np.mean(_rgb(params["f0"]))), float(np.max(_rgb(params["diffuse"])))
    ok = not (f0 > METAL_F0 and diffuse > STRONG_DIFFUSE)
    meaning = ("F0 and the diffuse term agree (a dielectric's F0, or a metal's without a "
               "strong diffuse term)" if ok else
               f"a metal's F0 (mean {f0:.2g} > {METAL_F0:g}) over a strong diffuse term "
               f"({diffuse:.2g} > {STRONG_DIFFUSE:g}): neither metal nor dielectric; a "
               f"metallic paint, or a fit that traded one lobe for the other")
    return _check("metal_dielectric", ok, f0, METAL_F0, meaning)


def metal_ior(params) -> dict:
    """The ``metal_dielectric`` check of a metallic-roughness model with a dielectric ``ior``
    (module docstring)."""
    from ..terms.fresnel import f0_from_ior

    ior, metallic = float(params["ior"]), float(params["metallic"])
    f0 = float(f0_from_ior(ior))
    ok = not (metallic < 0.5 and f0 > METAL_F0)
    meaning = ("the dielectric's ior gives a dielectric's F0" if ok else
               f"a dielectric (metallic {metallic:.2g}) with ior {ior:.3g}: F0/F90 {f0:.2g} > "
               f"{METAL_F0:g}, a Fresnel curve flatter than any dielectric's (a metal's); the "
               f"data's reflectance barely rises towards grazing, which neither the glTF "
               f"dielectric nor its metal (F90 = 1) follows")
    return _check("metal_dielectric", ok, f0, METAL_F0, meaning)


def fit_error(metrics) -> dict | None:
    """The ``error`` check, from the result's ``metrics``."""
    if "rel_error" not in metrics:
        return None
    rel = float(metrics["rel_error"])
    ok = rel <= REL_ERROR_LIMIT if math.isfinite(rel) else None
    others = ", ".join(metric_text(n, metrics[n]) for n in ("rmse_log", "rmse_cosine")
                       if n in metrics)
    meaning = (f"{metric_text('rel_error', rel)}" + (f" ({others})" if others else "") + ": " + (
        "the fit follows the data" if ok else
        f"the fit is on average off by more than {REL_ERROR_LIMIT:g} times the measured "
        f"value: the model or the loss does not describe this material"))
    return _check("error", ok, rel, REL_ERROR_LIMIT, meaning)


def assess(model, params, metrics, loss: str = "", albedo=None) -> list[dict]:
    """Every check that applies to ``model`` (a registered name or a ``Model``) with the
    fitted ``params`` (name → value), ``metrics`` (the result's) and ``loss`` (its label, for
    the meanings), in :data:`CHECKS` order; ``albedo`` as for :func:`energy`."""
    model = get_model(model)
    params = {k: np.asarray(v, float) for k, v in params.items()}
    try:
        derived = model.derived_values(params)
    except (ValueError, TypeError, FloatingPointError):
        derived = {}
    found = [energy(model, params, albedo), grazing(params, derived), white_diffuse(params, loss),
             black_metal(params), metal_over_diffuse(params), fit_error(metrics)]
    return [c for c in found if c is not None]


def verdict_record(checks: list[dict]) -> dict:
    """The record a result carries: ``plausible`` (every assessed check passed) and the
    ``checks``."""
    return {"plausible": all(c["passed"] is not False for c in checks), "checks": list(checks)}


def failed(record: dict) -> list[dict]:
    """The failed checks of a record (``[]`` for an empty record: a result read from a file
    older than the verdict)."""
    return [c for c in (record or {}).get("checks", []) if c.get("passed") is False]


def summary_lines(record: dict) -> list[str]:
    """The summary's lines: one when plausible, then one per failed check."""
    if not record:
        return ["  plausibility: not assessed (a result older than the verdict)"]
    bad = failed(record)
    names = ", ".join(c["name"] for c in record["checks"])
    if not bad:
        return [f"  plausibility: plausible ({names})"]
    lines = [f"  plausibility: IMPLAUSIBLE material, {len(bad)} of {len(record['checks'])} "
             f"checks failed:"]
    lines += [f"    {c['name']}: {c['meaning']}" for c in bad]
    return lines


def warning_text(record: dict, what: str) -> str | None:
    """One line for the command line's warning, or None when nothing failed: ``what`` (e.g.
    ``"the ggx fit"``) is implausible, and which checks failed."""
    bad = failed(record)
    if not bad:
        return None
    return (f"{what} is an implausible material: "
            + "; ".join(f"{c['name']} ({c['meaning']})" for c in bad))
