"""Mitsuba 3 materials from renderer-native fits: the ``load_dict`` dictionary and the XML element.

Only the models whose formula is Mitsuba's own are written (:data:`MITSUBA_MODELS`); the
parameter mapping is the table in :mod:`brdffit.export`. Values are written with full float64
precision (Mitsuba reads them as float32). Every attribute value of the XML is escaped
(:func:`brdffit.export._text.xml_attribute`), so the element is well-formed XML; a ``bsdf_id``
holding a character XML cannot carry is refused.

The XML is a file ``mitsuba.load_file`` accepts as it is: a ``<scene version="3.0.0">`` holding
the ``<bsdf>`` (with ``id`` :data:`BSDF_ID`), which a scene can also ``<include>``; on request
(``fragment=True``, ``brdffit export --fragment``) the bare ``<bsdf>`` element to paste inside a
``<scene>``.
"""

from __future__ import annotations

import numpy as np

from ..models.mitsuba_roughconductor import variant_of
from ._text import xml_attribute

#: The ``id`` of the exported ``<bsdf>``: shapes ``<ref id="brdffit-material"/>`` it.
BSDF_ID = "brdffit-material"
#: The scene format version written (Mitsuba 3 requires the attribute on the root element).
SCENE_VERSION = "3.0.0"

#: Principled parameters, written under the same names (``spec_trans`` is added as 0).
PRINCIPLED_SCALARS = ("roughness", "anisotropic", "metallic", "specular", "spec_tint", "sheen",
                      "sheen_tint", "flatness", "clearcoat", "clearcoat_gloss")


def is_mitsuba_model(name: str) -> bool:
    """True for the models that have an exact Mitsuba counterpart."""
    return name == "mitsuba-principled" or variant_of(name) is not None


def _rgb(v) -> dict:
    return {"type": "rgb", "value": [float(x) for x in np.broadcast_to(np.asarray(v, float), (3,))]}


def _principled(params) -> dict:
    d = {"type": "principled", "base_color": _rgb(params["base_color"])}
    d.update({k: float(params[k]) for k in PRINCIPLED_SCALARS})
    d["spec_trans"] = 0.0
    return d


def _roughconductor(options, params) -> dict:
    d = {"type": "roughconductor", "distribution": options["distribution"]}
    if options["anisotropic"]:
        d["alpha_u"], d["alpha_v"] = float(params["alpha_u"]), float(params["alpha_v"])
    else:
        d["alpha"] = float(params["alpha"])
    if options["fresnel"] == "tint":
        d["eta"], d["k"] = _rgb(0.0), _rgb(1.0)
        d["specular_reflectance"] = _rgb(params["specular_reflectance"])
    else:
        d["eta"], d["k"] = _rgb(params["eta"]), _rgb(params["k"])
    return d


def mitsuba_dict(model, params) -> dict:
    """What ``mitsuba.load_dict`` takes for ``model`` (a native :class:`Model`) with ``params``.

    ``params`` must be complete (``model.complete(...)``). Raises ``ValueError`` for a model
    without a Mitsuba counterpart (:func:`brdffit.export.export` turns that into advice).
    """
    if model.name == "mitsuba-principled":
        return _principled(params)
    options = variant_of(model.name)
    if options is None:
        raise ValueError(f"model {model.name!r} has no Mitsuba counterpart")
    return _roughconductor(options, params)


def _xml_value(name, value) -> str:
    key = xml_attribute(name, "property name")
    if isinstance(value, dict):  # an RGB texture
        text = ", ".join(repr(float(x)) for x in value["value"])
        return f'<rgb name={key} value="{text}"/>'
    if isinstance(value, str):
        return f"<string name={key} value={xml_attribute(value, name)}/>"
    return f'<float name={key} value="{float(value)!r}"/>'


def mitsuba_xml(model, params, *, bsdf_id: str = BSDF_ID, fragment: bool = False) -> str:
    """A Mitsuba 3 scene file holding the material's ``<bsdf>`` (``fragment=True``: the
    ``<bsdf>`` element alone, to paste inside a ``<scene>``).

    The same values as :func:`mitsuba_dict`, each as ``<float>``, ``<rgb>`` or ``<string>``; the
    element carries ``id=bsdf_id`` (escaped; ``ValueError`` for a character XML cannot hold) so
    shapes can ``<ref id="..."/>`` it.
    """
    d = mitsuba_dict(model, params)
    lines = [f"<bsdf type={xml_attribute(d['type'], 'type')} id={xml_attribute(bsdf_id, 'id')}>"]
    lines += [f"    {_xml_value(k, v)}" for k, v in d.items() if k != "type"]
    lines.append("</bsdf>")
    if not fragment:
        lines = [f'<scene version="{SCENE_VERSION}">'] + [f"    {x}" for x in lines] + ["</scene>"]
    return "\n".join(lines) + "\n"
