r"""What an exported file renders, measured: the material evaluated by the target renderer's own
formulas against the measurement, beside the fit's own error on the same cells.

* **Mitsuba** (``mitsuba-xml``, ``mitsuba-dict``): the exported file itself is loaded by Mitsuba
  3 (``mitsuba.load_string`` of the XML, ``mitsuba.load_dict`` of the dict; the ``scalar_rgb``
  variant) and evaluated with ``BSDF.eval``, which returns ``f_r cos θ`` with ``θ`` the angle of
  its ``wo`` argument; the cosine is divided out. Mitsuba's ``si.wi`` is brdffit's ``wo`` (the
  viewer), its ``wo`` brdffit's ``wi`` (the light).
* **glTF** (``gltf``): the material of the exported document, read back from its JSON, is
  evaluated by :mod:`brdffit.export.gltf_reference`, the specification's reference BRDF with
  the extensions the file uses.

The cells (:func:`cells`) are a seeded sample of ``n`` cells of the measured table the result
was fitted to (the file its provenance names, read again, or data passed in); without one, of
direction pairs warped as a MERL table samples them (:func:`brdffit.export.approximate.
sample_pairs`) with the fitted model's values standing in for the measurement, which measures
the export against the fit only. On these cells :func:`export_error` gives, for the export and
for the fit, ``rmse_log`` (:data:`brdffit.metrics.METRICS`) and the **peak error**

.. math::

    \mathrm{peak\_log} = \max_{\text{cells, channels}}
        \bigl|\ln(1 + \hat f\cos\theta_i) - \ln(1 + f\cos\theta_i)\bigr|,

the worst cell of the quantity whose RMS is ``rmse_log``. A native export's error equals the
fit's up to the renderer's float32 arithmetic; an approximation's is the price of the target
model.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..metrics import metric_text, values
from ._text import literal

#: Cells the export error is measured on, by default (a seeded sample; all if fewer).
ERROR_CELLS = 20000


@dataclasses.dataclass(frozen=True)
class ExportError:
    """The export's error and the fit's, on the same cells.

    Attributes:
        export, fit: ``{"rmse_log": ..., "peak_log": ..., "rel_error": ...}`` of the material as
            the renderer evaluates it, and of the fitted model.
        renderer: what evaluated the export (``"Mitsuba 3.x BSDF.eval"``, ``"glTF reference BRDF"``).
        against: what the cells hold (``"measured 'name'"``, the name a Python literal safe
            in an XML comment, or ``"the fitted <model>"``).
        cells: how many cells.
    """

    export: dict
    fit: dict
    renderer: str
    against: str
    cells: int

    def text(self) -> str:
        """One line: ``export error (glTF reference BRDF, 20000 cells of measured x): rmse_log
        0.1, peak_log 1.2; fit rmse_log 0.1, peak_log 1.2``."""
        def two(m):
            return ", ".join(metric_text(k, m[k]) for k in ("rmse_log", "peak_log"))
        return (f"export error ({self.renderer}, {self.cells} cells of {self.against}): "
                f"{two(self.export)}; fit {two(self.fit)}")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def errors(fitted, measured, cos_i, cos_o) -> dict:
    """``rmse_log``, ``rel_error`` (:func:`brdffit.metrics.values`) and ``peak_log`` (module
    docstring) of ``fitted`` against ``measured`` ``(n, 3)``."""
    f, m = np.asarray(fitted, float), np.asarray(measured, float)
    out = values(f, m, cos_i, cos_o)
    ci = np.asarray(cos_i, float)[:, None]
    peak = float(np.max(np.abs(np.log1p(f * ci) - np.log1p(m * ci)))) if f.size else np.nan
    return {"rmse_log": out["rmse_log"], "peak_log": peak, "rel_error": out["rel_error"]}


def cells(data, n: int = ERROR_CELLS, seed: int = 0, *, weights: bool = False):
    """``(wi, wo, f_r)`` of ``n`` seeded cells of ``data`` (a table or sample list): valid
    cells with non-zero weight, both directions above the horizon; with ``weights``, their
    weights too (ones where the data have none)."""
    samples = data.to_samples() if hasattr(data, "to_samples") else data
    keep = np.asarray(samples.valid, bool) & (samples.wi[:, 2] > 0) & (samples.wo[:, 2] > 0)
    weight = getattr(samples, "weight", None)
    if weight is not None:
        keep &= np.asarray(weight) > 0
    rows = np.flatnonzero(keep)
    if len(rows) > n:
        rows = np.sort(np.random.default_rng(seed).choice(rows, n, replace=False))
    rgb = np.broadcast_to(np.asarray(samples.rgb, float)[rows].reshape(len(rows), -1),
                          (len(rows), 3))
    if weights:
        w = np.ones(len(rows)) if weight is None else np.asarray(weight, float)[rows]
        return samples.wi[rows], samples.wo[rows], rgb, w
    return samples.wi[rows], samples.wo[rows], rgb


def _mitsuba():
    import mitsuba as mi

    if mi.variant() is None:
        mi.set_variant("scalar_rgb")
    return mi


def mitsuba_bsdf(exported):
    """The Mitsuba BSDF the exported payload loads as (the XML text as written, the dict)."""
    mi = _mitsuba()
    if isinstance(exported.payload, dict):
        return mi.load_dict(exported.payload)
    text = exported.payload
    from .mitsuba import BSDF_ID

    ref = f'<shape type="rectangle"><ref id="{BSDF_ID}"/></shape>'
    if "<scene" in text:  # the file as written, with a shape that references its material
        scene = mi.load_string(text.replace("</scene>", ref + "</scene>"))
    else:  # the fragment, inside a scene as the user pastes it
        scene = mi.load_string(f'<scene version="3.0.0">{text}{ref}</scene>')
    return scene.shapes()[0].bsdf()


def mitsuba_brdf(bsdf, wi, wo) -> np.ndarray:
    """``f_r(wi, wo)`` ``(n, 3)`` from Mitsuba's ``bsdf.eval`` (module docstring), one pair at a
    time in the scalar variant."""
    mi = _mitsuba()
    si, ctx = mi.SurfaceInteraction3f(), mi.BSDFContext()
    out = np.empty((len(wi), 3))
    for j, (a, b) in enumerate(zip(np.asarray(wo, float), np.asarray(wi, float))):
        si.wi = mi.Vector3f(*a)
        out[j] = bsdf.eval(ctx, si, mi.Vector3f(*b))
    return out / np.maximum(np.asarray(wi, float)[:, 2:3], 1e-300)


def mitsuba_version() -> str:
    return _mitsuba().__version__


def export_error(exported, source, data=None, *, evaluate, n: int = ERROR_CELLS, seed: int = 0):
    """The :class:`ExportError` of ``exported`` (an :class:`~brdffit.export.Exported`) for the
    fit ``source`` (``(model_name, params)``) on ``n`` cells of ``data`` (module docstring;
    ``None``: the fitted model on MERL-warped pairs). ``evaluate(exported, wi, wo) -> (f_r,
    renderer name)`` is the target's renderer (:class:`brdffit.export.Target`)."""
    from ..models.evaluate import evaluate_model

    name, params = source
    if data is not None:
        wi, wo, measured = cells(data, n, seed)
        against = f"measured {literal(getattr(data, 'name', '') or 'data', comment=True)}"
    else:
        from .approximate import sample_pairs

        wi, wo = sample_pairs(int(n / 0.6), seed=seed)
        wi, wo = wi[:n], wo[:n]
        measured = np.asarray(evaluate_model(name, params, wi, wo), float)
        against = f"the fitted {name}"
    fitted = np.asarray(evaluate_model(name, params, wi, wo), float)
    rendered, renderer = evaluate(exported, wi, wo)
    ci, co = wi[:, 2], wo[:, 2]
    return ExportError(errors(rendered, measured, ci, co), errors(fitted, measured, ci, co),
                       renderer, against, len(wi))
