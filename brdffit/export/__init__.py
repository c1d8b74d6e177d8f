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
``gltf-pbr``                             glTF 2.0 ``materials[0].pbrMetallicRoughness``
  ``base_color`` (RGB, linear)           ``baseColorFactor`` ``[r, g, b, 1]``
  ``metallic``                           ``metallicFactor``
  ``roughness``                          ``roughnessFactor`` (``α = roughness²``)
=======================================  ======================================================

Targets: the registry :data:`TARGETS` (name -> :class:`Target`), the one list the command line
(``brdffit export --to``, its help), the error messages and the tests read: ``"mitsuba-dict"``
(a dict for ``mitsuba.load_dict``; written to a file as JSON), ``"mitsuba-xml"`` (a ``<bsdf>``
element to paste into a ``<scene>``), ``"gltf"`` (a glTF 2.0 JSON document with one material).
To add one: a function writing the payload (a module of this package for a format of its own)
and a :class:`Target` entry in :data:`TARGETS`; ``tests/test_one_owner.py`` runs every entry.

Every file is well-formed whatever the data: the table's name goes into the provenance note
(the XML's leading comment, the glTF material's ``extras.brdffit``) as a Python string literal
(:func:`brdffit.export._text.literal`), never as markup; XML attribute values are escaped; the
JSON is strict. A parameter that is not finite is refused (:class:`NotExportable`): no format
here can carry NaN or infinity.
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
        payload: ``payload(model, params, note)``: the dict or text for complete ``params`` of
            a native model; ``note(comment=...)`` gives the provenance line.
        others: more native models a message suggests (``"for metals also ..."``).
    """

    name: str
    description: str
    renderer: str
    native: str
    is_native: Callable[[str], bool]
    payload: Callable
    others: str = ""


def _is_mitsuba(name: str) -> bool:
    from .mitsuba import is_mitsuba_model

    return is_mitsuba_model(name)


def _mitsuba_dict(model, params, note):
    from .mitsuba import mitsuba_dict

    return mitsuba_dict(model, params)


def _mitsuba_xml(model, params, note):
    from .mitsuba import mitsuba_xml

    return xml_comment(note(comment=True)) + "\n" + mitsuba_xml(model, params)


def _gltf(model, params, note):
    from .gltf import gltf_document

    doc = gltf_document(params)
    doc["materials"][0]["extras"] = {"brdffit": note(comment=False)}
    return doc


_MITSUBA_METALS = "for metals also mitsuba-roughconductor"

#: The export targets, by name: the single list of what can be exported.
TARGETS: dict[str, Target] = {t.name: t for t in (
    Target("mitsuba-xml", "a <bsdf> element for a Mitsuba 3 scene", "Mitsuba",
           "mitsuba-principled", _is_mitsuba, _mitsuba_xml, _MITSUBA_METALS),
    Target("mitsuba-dict", "JSON of the dict mitsuba.load_dict takes", "Mitsuba",
           "mitsuba-principled", _is_mitsuba, _mitsuba_dict, _MITSUBA_METALS),
    Target("gltf", "a glTF 2.0 document with one metallic-roughness material", "glTF",
           "gltf-pbr", lambda name: name == "gltf-pbr", _gltf),
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
    """

    target: str
    payload: object
    model_name: str
    params: dict
    approximation: object = None

    def text(self) -> str:
        """The file contents: JSON for the dict targets, the XML element for ``mitsuba-xml``."""
        if isinstance(self.payload, str):
            return self.payload
        return json.dumps(self.payload, indent=2, allow_nan=False) + "\n"


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


def export(result, to: str, *, approximate: bool = False, **approx_options) -> Exported:
    """Export a :class:`~brdffit.fitting.FitResult` (or ``(model_name, params)``) to ``to``.

    ``to`` is a name in :data:`TARGETS`. Raises :class:`NoExactCounterpart` when the model is
    not the target's BSDF and ``approximate`` is false; with ``approximate=True`` it fits the
    target's ``native`` model to the fitted model (options passed to
    :func:`~brdffit.export.approximate.approximate`).
    Raises :class:`NotExportable` for a parameter that is not finite.
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
    if not target.is_native(model.name):
        if not approximate:
            raise _no_counterpart(model.name, target)
        from .approximate import approximate as fit_native

        approx = fit_native(model, model.complete(params), target.native, **approx_options)
        model, params = get_model(approx.model_name), approx.params
        _check_finite(model.name, params)
    full = model.complete(params)
    note = functools.partial(_note, model.name, name, source, approx)
    return Exported(to, target.payload(model, full, note), model.name, full, approx)


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
