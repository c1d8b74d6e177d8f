r"""The closest renderer-native parameters for a model that has no exact counterpart.

The fitted model is sampled at direction pairs drawn in half/difference angles (Rusinkiewicz
1998) as a MERL table samples them — ``θh = (π/2) u²`` (Burley 2012 §3.1's warp, which resolves
narrow peaks), ``θd`` and ``φd`` uniform, and ``φh`` uniform too, so that anisotropic models are
seen in every azimuth — keeping pairs with both directions within ``cutoff`` of the normal. The
native model is then *fitted* to those values with :func:`brdffit.fit`, with the same loss,
metrics and result type as a fit to measurements: the approximation's error is that fit's
``metrics`` (``rmse_log``, ``rel_error``, ...), against the fitted model instead of the data.

The target model is fitted to the source model, not mapped parameter by parameter: a mapping
(say Disney's ``specular`` onto glTF's core material) has nowhere to put what the target cannot
hold, and lands on whatever the formulas share (a shiny plastic mapped to the core glTF model
lost its colour to ``metallic``); a fit finds the target material closest to what the source
renders, and says how close. Noise-free data make the fit deterministic; three starts (a
dielectric and a metal reading of the data-driven features, and the fitter's own data-driven
start with its scan) guard against the metallic/dielectric ambiguity and the principled model's
local minima, and the lowest cost wins. A glTF target reads ``metallic`` as 0 or 1 in its own
fit (``Model.reading``), from the fitter's start alone.
"""

from __future__ import annotations

import numpy as np

from data_formats import SampleSet
from data_formats.rusinkiewicz import dirs_from_half_diff

#: Parameters of the native targets held at the renderer's defaults (0) unless freed with
#: ``free=`` or the source model has a parameter of the same name that is not 0 (a Disney
#: source's clear coat: then it starts from the source's value and is fitted): the tints trade off against ``metallic`` and ``specular`` (as in the presets), and
#: the extra lobes (sheen, clearcoat, fake subsurface) would otherwise be spent imitating
#: whatever the source model's lobe shape lacks, slowly (measured: 200 steps without converging
#: for a ``ggx`` source, against about 10 with them held).
HELD = {
    "mitsuba-principled": {"spec_tint": 0.0, "sheen_tint": 0.0, "sheen": 0.0, "clearcoat": 0.0,
                           "clearcoat_gloss": 0.0, "flatness": 0.0},
}


def sample_pairs(n: int = 60000, *, cutoff: float = 80.0, seed: int = 0):
    """``(wi, wo)`` ``(m, 3)``, ``m ≤ n``: the half-vector-warped pairs of the module docstring."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.0, 1.0, (4, n))
    wi, wo = dirs_from_half_diff(0.5 * np.pi * u[0] ** 2, 0.5 * np.pi * u[1],
                                 2 * np.pi * u[2] - np.pi, 2 * np.pi * u[3])
    c = np.cos(np.radians(cutoff))
    keep = (wi[:, 2] > c) & (wo[:, 2] > c)
    return wi[keep], wo[keep]


def _starts(native, features) -> list[dict]:
    """Two of the starting points for ``native`` from data-driven features: the dielectric and the
    metal reading (:func:`brdffit.models.starts.metallic_roughness`); none for a model with a
    :class:`~brdffit.models.registry.Reading` (the glTF models), whose fit decides between the
    two readings itself and would fit a blend from a start that names ``metallic``."""
    from ..models.starts import gltf_pbr, metallic_roughness

    if native.reading is not None:
        return []
    starts = []
    for metal in (False, True):
        reading = (gltf_pbr(features, metal) if native.name.startswith("gltf-pbr")
                   else {**metallic_roughness(features, metal), "specular": 0.5})
        p = {**reading, "alpha": features.alpha,
             "alpha_u": features.alpha, "alpha_v": features.alpha,
             "specular_reflectance": np.clip(features.f0, 0.02, 0.98)}
        starts.append({k: v for k, v in p.items() if k in native.names})
    return starts


def approximate(model, params, native, *, n: int = 40000, cutoff: float = 80.0, seed: int = 0,
                loss: str = "log", free=(), subsample: int | None = 20000, pairs=None):
    """Fit the native model ``native`` to ``model`` with ``params``; returns its ``FitResult``.

    ``result.params`` are the closest native parameters (in the loss's sense), ``result.metrics``
    the approximation's error, ``result.table`` names the approximated model. ``free`` names
    parameters of :data:`HELD` to fit as well (e.g. ``("clearcoat", "clearcoat_gloss")`` for a
    coated source). ``subsample`` cells of the ``≈ 0.6 n`` pairs kept are fitted (all if fewer).
    ``pairs``: ``(wi, wo)`` or ``(wi, wo, weight)`` to sample the source model at instead, e.g.
    the cells of the measurement the source was fitted to with their weights, so that the
    approximation weighs directions as the fit did (a MERL table crowds its cells near the
    specular peak and weighs them down by ``θh``; unweighted, the peak would buy its fit with
    the diffuse colour).
    """
    from ..fitting import fit, measure
    from ..models import get_model
    from ..models.evaluate import evaluate_model

    model, native = get_model(model), get_model(native)
    wi, wo, *weight = sample_pairs(n, cutoff=cutoff, seed=seed) if pairs is None else pairs
    rgb = evaluate_model(model, params, wi, wo)
    data = SampleSet(wi, wo, rgb, np.ones(len(rgb), bool), name=f"{model.name} fit",
                     weight=weight[0] if weight else None)
    shared = {k: params[k] for k in HELD.get(native.name, {}) if k in params
              and float(np.max(np.asarray(params[k], float))) > 0.0}
    held = {k: v for k, v in HELD.get(native.name, {}).items() if k not in free and k not in shared}
    if model.isotropic and "anisotropic" in native.names:
        held["anisotropic"] = 0.0
    best = None
    starts = _starts(native, measure(rgb, wi, wo, np.ones(len(rgb), bool))) + [{}]
    for init in starts:
        init = {**{k: v for k, v in init.items() if k not in held}, **shared}
        res = fit(data, native, loss=loss, init=init, fixed=held or None, throw=False,
                  subsample=subsample if subsample and subsample < len(rgb) else None, seed=seed)
        if best is None or res.cost < best.cost:
            best = res
    return best
