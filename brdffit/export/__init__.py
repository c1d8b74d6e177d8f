r"""Export fitted materials to renderers: Mitsuba 3 (``load_dict`` dictionary, XML) and glTF 2.0.

A result exports **exactly** only when its model *is* the target's BSDF: the renderer-native
models (:mod:`brdffit.models.mitsuba_principled`, :mod:`~brdffit.models.mitsuba_roughconductor`,
:mod:`~brdffit.models.gltf_pbr`) evaluate the renderer's own formula, term for term, so the
exported material renders what was fitted (``tests/test_export_mitsuba.py`` checks that in
Mitsuba itself, to float32 precision). Any other model (``ggx``, ``disney``, ...) raises
:class:`NoExactCounterpart`, naming the native model to fit instead, unless
``approximate=True``: then the native model is fitted *to the fitted model*
(:func:`brdffit.export.approximate.approximate`) and that fit's metrics are the approximation's
error.

Parameter mapping (the one place it is written down)
-----------------------------------------------------

=======================================  ======================================================
brdffit model / parameter                target
=======================================  ======================================================
``mitsuba-principled``                   Mitsuba ``<bsdf type="principled">``
  ``base_color`` (RGB)                   ``base_color`` as ``rgb``
  ``roughness``, ``anisotropic``,        same names, ``float``
  ``metallic``, ``specular``,
  ``spec_tint``, ``sheen``,
  ``sheen_tint``, ``flatness``,
  ``clearcoat``, ``clearcoat_gloss``
  (not a parameter)                      ``spec_trans = 0`` (reflection only)
``mitsuba-roughconductor[-beckmann]``    Mitsuba ``<bsdf type="roughconductor">``,
``[-aniso][-tint]``                      ``distribution`` = ``ggx`` / ``beckmann``
  ``alpha``                              ``alpha`` (isotropic variants)
  ``alpha_u``, ``alpha_v``               ``alpha_u`` (tangent), ``alpha_v`` (bitangent)
  ``eta``, ``k`` (RGB)                   ``eta``, ``k`` as ``rgb``
  ``specular_reflectance`` (``-tint``)   ``specular_reflectance`` as ``rgb``; ``eta = 0``,
                                         ``k = 1`` (Mitsuba's defaults: ``F = 1``)
``gltf-pbr``, ``gltf-pbr-clearcoat``,    glTF 2.0 ``materials[0].pbrMetallicRoughness``
``gltf-pbr-sheen``
  ``base_color`` (RGB, linear)           ``baseColorFactor`` ``[r, g, b, 1]``
  ``metallic``                           ``metallicFactor``
  ``roughness``                          ``roughnessFactor`` (``α = roughness²``)
  ``ior`` (when not 1.5)                 ``KHR_materials_ior`` ``ior``
  ``specular`` (when below 1)            ``KHR_materials_specular`` ``specularFactor``
                                         (``specularColorFactor`` white)
  ``clearcoat``                          ``KHR_materials_clearcoat`` ``clearcoatFactor``
  ``clearcoat_roughness``                ``KHR_materials_clearcoat``
                                         ``clearcoatRoughnessFactor``
  ``sheen_color`` (RGB, linear; when     ``KHR_materials_sheen`` ``sheenColorFactor``
  above 0)
  ``sheen_roughness``                    ``KHR_materials_sheen`` ``sheenRoughnessFactor``
=======================================  ======================================================

Targets: the registry :data:`TARGETS` (name -> :class:`Target`), the one list the command line
(``brdffit export --to``, its help), the error messages and the tests read: ``"mitsuba-dict"``
(a dict for ``mitsuba.load_dict``; written to a file as JSON), ``"mitsuba-xml"`` (a Mitsuba 3
scene file holding the ``<bsdf>``, or the bare element with ``fragment=True``), ``"gltf"`` (a
glTF 2.0 asset: a sphere with the material in a scene; binary ``.glb`` through
:meth:`Exported.data`). To add one: a function writing the payload (a module of this package
for a format of its own) and a :class:`Target` entry in :data:`TARGETS` (with ``evaluate``, the
renderer's evaluation, for its error to be measured); ``tests/test_one_owner.py`` runs every
entry.

Every file is well-formed whatever the data: the table's name goes into the provenance note
(the XML's leading comment, the glTF material's ``extras.brdffit``) as a Python string literal
(:func:`brdffit.export._text.literal`), never as markup; XML attribute values are escaped; the
JSON is strict. A parameter that is not finite is refused (:class:`NotExportable`): no format
here can carry NaN or infinity.

Every export measures what it renders (:mod:`brdffit.export.faithful`): the written material
evaluated by the target renderer's own formulas (Mitsuba 3's ``BSDF.eval`` on the file as
written; the glTF specification's reference BRDF on the document) against the measured table,
beside the fit's error on the same cells: :attr:`Exported.error`, printed by ``brdffit
export``, and kept in the file where the format has room for it (the XML's closing comment,
the glTF material's ``extras.brdffit_error``). The files are complete: the XML is a
``<scene version="3.0.0">`` that ``mitsuba.load_file`` opens (``fragment=True``: the bare
``<bsdf>``), the glTF a sphere with the material in a scene (:mod:`brdffit.export.gltf`),
``.glb`` on request (:meth:`Exported.data`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import warnings
from collections.abc import Callable

import numpy as np

from .._lazy import lazy_exports
from ..errors import BrdffitError, UnknownNameError, canonical_name
from ..metrics import metric_text, metrics_text
from ._text import literal, xml_comment

__all__ = ["TARGETS", "Target", "ApproximationWarning", "Exported", "NoExactCounterpart",
           "NotExportable", "export", "export_payload", "gltf_document", "mitsuba_dict",
           "mitsuba_xml", "params_from_gltf", "render_merl"]

# The writers import the models (and JAX) when first used, so that the command line reads the
# registry without them.
__getattr__, __dir__ = lazy_exports(__name__, globals(), {
    "gltf_document": ".gltf", "params_from_gltf": ".gltf",
    "mitsuba_dict": ".mitsuba", "mitsuba_xml": ".mitsuba"})


@dataclasses.dataclass(frozen=True)
class Target:
    """An export target: what ``brdffit export --to NAME`` and :func:`export` write.

    Attributes:
        name: the target's name (``--to``; names ignore case).
        description: what the file is, for the command line's help.
        renderer: the renderer as messages name it (``"Mitsuba"``, ``"glTF"``).
        native: the model to fit for an exact export (and to approximate with).
        is_native: ``is_native(model_name)``: is the model the target's own BSDF?
        payload: ``payload(model, params, note, fragment)``: the dict or text for complete
            ``params`` of a native model; ``note(comment=...)`` gives the provenance line;
            ``fragment`` asks for the bare element where the format has one.
        others: more native models a message suggests (``"for metals also ..."``).
        layers: ``(source parameter, native model)`` pairs: an approximation also fits that
            native model where the source model's parameter of that name is above 0 (a coat,
            a sheen), and keeps the lowest cost.
        evaluate: ``evaluate(exported, wi, wo) -> (f_r, renderer name)``: the written material
            as the target renderer computes it (:mod:`brdffit.export.faithful`); ``None``: the
            export's error is not measured.
    """

    name: str
    description: str
    renderer: str
    native: str
    is_native: Callable[[str], bool]
    payload: Callable
    others: str = ""
    layers: tuple[tuple[str, str], ...] = ()
    evaluate: Callable | None = None


def _is_mitsuba(name: str) -> bool:
    from .mitsuba import is_mitsuba_model

    return is_mitsuba_model(name)


def _mitsuba_dict(model, params, note, fragment=False):
    from .mitsuba import mitsuba_dict

    return mitsuba_dict(model, params)


def _mitsuba_xml(model, params, note, fragment=False):
    from .mitsuba import mitsuba_xml

    return xml_comment(note(comment=True)) + "\n" + mitsuba_xml(model, params, fragment=fragment)


def _gltf(model, params, note, fragment=False):
    from .gltf import gltf_document

    doc = gltf_document(params)
    doc["materials"][0]["extras"] = {"brdffit": note(comment=False)}
    return doc


def _in_mitsuba(exported, wi, wo):
    from .faithful import mitsuba_bsdf, mitsuba_brdf, mitsuba_version

    return mitsuba_brdf(mitsuba_bsdf(exported), wi, wo), f"Mitsuba {mitsuba_version()} BSDF.eval"


def _in_gltf(exported, wi, wo):
    from .gltf_reference import document_brdf

    return document_brdf(exported.payload, wi, wo), "glTF reference BRDF"


_GLTF_MODELS = ("gltf-pbr", "gltf-pbr-clearcoat", "gltf-pbr-sheen")


_MITSUBA_METALS = "for metals also mitsuba-roughconductor"

#: The export targets, by name: the single list of what can be exported.
TARGETS: dict[str, Target] = {t.name: t for t in (
    Target("mitsuba-xml", "a <bsdf> element for a Mitsuba 3 scene", "Mitsuba",
           "mitsuba-principled", _is_mitsuba, _mitsuba_xml, _MITSUBA_METALS,
           evaluate=_in_mitsuba),
    Target("mitsuba-dict", "JSON of the dict mitsuba.load_dict takes", "Mitsuba",
           "mitsuba-principled", _is_mitsuba, _mitsuba_dict, _MITSUBA_METALS,
           evaluate=_in_mitsuba),
    Target("gltf", "a glTF 2.0 sphere with the material (.glb: binary glTF)", "glTF",
           "gltf-pbr", lambda name: name in _GLTF_MODELS, _gltf,
           "with a coat gltf-pbr-clearcoat, for fabrics gltf-pbr-sheen",
           layers=(("clearcoat", "gltf-pbr-clearcoat"), ("sheen", "gltf-pbr-sheen")),
           evaluate=_in_gltf),
)}


class NoExactCounterpart(BrdffitError):
    """The model of a result is not the target renderer's BSDF (see :func:`export`)."""


class NotExportable(BrdffitError):
    """A parameter that no target format can carry (NaN, infinity)."""


class ApproximationWarning(UserWarning):
    """An export that went through ``approximate=True``; the message carries its error."""


@dataclasses.dataclass
class Exported:
    """An exported material.

    Attributes:
        target: the name of a :data:`TARGETS` entry.
        payload: the dict (``mitsuba-dict``, ``gltf``) or XML text (``mitsuba-xml``).
        model_name, params: the native model and parameters written.
        approximation: the ``FitResult`` of the native model fitted to the source model when
            ``approximate=True`` was needed, else ``None``; its ``metrics`` are the error.
        error: the :class:`~brdffit.export.faithful.ExportError` (the export as the renderer
            evaluates it, beside the fit), or ``None`` when it could not be measured
            (``error_note`` says why).
    """

    target: str
    payload: object
    model_name: str
    params: dict
    approximation: object = None
    error: object = None
    error_note: str = ""

    def text(self) -> str:
        """The file contents: JSON for the dict targets, the XML for ``mitsuba-xml``."""
        if isinstance(self.payload, str):
            return self.payload
        return json.dumps(self.payload, indent=2, allow_nan=False) + "\n"

    def data(self, suffix: str = "") -> bytes:
        """The file's bytes: :meth:`text` in UTF-8, or for ``suffix`` ``".glb"`` of a glTF
        export the binary glTF (:func:`brdffit.export.gltf.glb_bytes`)."""
        if self.target == "gltf" and suffix.lower() == ".glb":
            from .gltf import glb_bytes

            doc = dict(self.payload)
            doc["buffers"] = [{"byteLength": doc["buffers"][0]["byteLength"]}]
            return glb_bytes(doc)
        return self.text().encode("utf-8")


def _note(native, fitted, source, approx, *, comment: bool) -> str:
    """The provenance line, with the table's name written as a literal (:mod:`._text`)."""
    src = literal(source, comment=comment)
    if approx is None:
        return f"brdffit: {native} fit of {src}, exact"
    m = approx.metrics
    return (f"brdffit: {native} approximating a {fitted} fit of {src}; approximation error "
            f"{metric_text('rmse_log', m['rmse_log'])}, {metric_text('rel_error', m['rel_error'])}")


def _check_finite(name, params) -> None:
    for key, value in params.items():
        if not np.all(np.isfinite(np.asarray(value, float))):
            raise NotExportable(f"parameter {key!r} of the {name} result is {value!r}, not a "
                                f"finite number: there is no material to export; fit again")


def _no_counterpart(name, target: Target):
    also = f"; {target.others}" if target.others else ""
    return NoExactCounterpart(
        f"model {name!r} has no exact counterpart in {target.renderer} ({target.name}): its "
        f"formula is not the renderer's. Fit the native model instead (brdffit fit TABLE "
        f"--model {target.native}{also}) or pass --approximate (approximate=True) to fit "
        f"{target.native} to the fitted {name} and report that approximation's error")


def _approximate(model, params, target: Target, data, approx_options):
    """The native model fitted to ``model`` (and, for a source with a layer the target has a
    model for, a coat or a sheen, that model too: ``Target.layers``; the lowest cost wins),
    sampled at the cells of ``data`` where there are data."""
    from .approximate import approximate as fit_native

    natives = [target.native] + [native for name, native in target.layers
                                 if float(np.max(params.get(name, 0.0))) > 0.0]
    if data is not None and "pairs" not in approx_options:
        from .faithful import cells

        wi, wo, _, w = cells(data, approx_options.get("n", 40000), approx_options.get("seed", 1),
                             weights=True)
        approx_options = {**approx_options, "pairs": (wi, wo, w)}
    fits = [fit_native(model, params, native, **approx_options) for native in natives]
    return min(fits, key=lambda r: r.cost)


def _measured(result, data):
    """The data to measure the export against: ``data``, else the file the result's provenance
    names (``None`` where there is none: then the fit stands in)."""
    if data is not None or isinstance(result, tuple) or not getattr(result, "provenance", None):
        return data
    from ..plots import result_data

    try:
        return result_data(result)
    except BrdffitError:
        return None


def _with_error(out: Exported, source, data, error_cells) -> Exported:
    """``out`` with its :class:`~.faithful.ExportError`, kept in the file where it has room."""
    from .faithful import export_error

    evaluate = TARGETS[out.target].evaluate
    if evaluate is None:
        return dataclasses.replace(out, error_note="not measured: the target has no evaluator")
    try:
        err = export_error(out, source, data, evaluate=evaluate, n=error_cells)
    except ImportError as exc:  # Mitsuba is an optional extra
        return dataclasses.replace(out, error_note=f"not measured: {exc}")
    payload = out.payload
    if out.target == "gltf":
        payload["materials"][0]["extras"]["brdffit_error"] = err.to_dict()
    elif isinstance(payload, str):
        payload = payload + xml_comment(err.text()) + "\n"
    return dataclasses.replace(out, payload=payload, error=err)


def export(result, to: str, *, approximate: bool = False, data=None, error: bool = True,
           fragment: bool = False, error_cells: int | None = None,
           **approx_options) -> Exported:
    """Export a :class:`~brdffit.fitting.FitResult` (or ``(model_name, params)``) to ``to``.

    ``to`` is a name in :data:`TARGETS`. Raises :class:`NoExactCounterpart` when the model is
    not the target's BSDF and ``approximate`` is false; with ``approximate=True`` it fits the
    target's ``native`` model to the fitted model (options passed to
    :func:`~brdffit.export.approximate.approximate`; a source with a clear coat or a sheen also
    tries the target's model for that layer, ``Target.layers``), sampled at the measured cells where the data are at hand (seed
    1: other cells than the error's) and at MERL-warped pairs otherwise. Raises :class:`NotExportable` for a parameter that is not finite.

    With ``error`` (the default) the export's error is measured in the target renderer
    (:func:`brdffit.export.faithful.export_error`) on ``error_cells`` cells of ``data``, by
    default the table the result's provenance names, else against the fitted model.
    ``fragment=True`` writes the bare ``<bsdf>`` element for ``mitsuba-xml``.
    """
    from ..models import get_model

    to = canonical_name(to, TARGETS) or to  # names ignore case: "GLTF" is "gltf"
    if to not in TARGETS:
        raise UnknownNameError("export target", to, TARGETS)
    name, params = (result if isinstance(result, tuple) else (result.model_name, result.params))
    model = get_model(name)
    source = getattr(result, "table", "") or "data"
    _check_finite(name, params)
    target, approx = TARGETS[to], None
    if not target.is_native(model.name) and not approximate:
        raise _no_counterpart(model.name, target)
    measured = _measured(result, data) if error or approximate else None
    if not target.is_native(model.name):
        approx = _approximate(model, model.complete(params), target, measured, approx_options)
        model, params = get_model(approx.model_name), approx.params
        _check_finite(model.name, params)
    full = model.complete(params)
    note = functools.partial(_note, model.name, name, source, approx)
    extra = {"fragment": True} if fragment else {}
    out = Exported(to, target.payload(model, full, note, **extra), model.name, full, approx)
    if not error:
        return out
    from .faithful import ERROR_CELLS

    return _with_error(out, (name, get_model(name).complete(
        result[1] if isinstance(result, tuple) else result.params)),
        measured, error_cells or ERROR_CELLS)


def export_payload(result, to: str, *, approximate: bool = False, **approx_options):
    """:func:`export`'s payload alone (what :meth:`brdffit.FitResult.export` returns); an
    approximation is reported as an :class:`ApproximationWarning` carrying its metrics."""
    out = export(result, to, approximate=approximate, **approx_options)
    if out.approximation is not None:
        m = out.approximation.metrics
        source = result[0] if isinstance(result, tuple) else result.model_name
        warnings.warn(ApproximationWarning(
            f"{out.model_name} approximates {source}: "
            + metrics_text(m)), stacklevel=3)
    return out.payload


def render_merl(result, name: str | None = None, shape=None):
    """The fitted model of ``result`` on a whole MERL grid (cell corners), as a ``MERLTable``.

    Cells below the horizon are missing, as in the database (``data_formats.merl.synthesize``);
    write it with ``data_formats.merl.write_merl`` for a fitted ``.binary``.
    """
    from data_formats.merl import MERL_SHAPE, synthesize

    from ..models.evaluate import evaluate_model

    fitted = result.model
    return synthesize(lambda wi, wo: evaluate_model(fitted.model, fitted.params, wi, wo),
                      name=name or f"{result.model_name}-fit", shape=shape or MERL_SHAPE)
