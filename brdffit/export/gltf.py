"""A glTF 2.0 document holding one metallic-roughness material from a ``gltf-pbr`` fit.

The document is the smallest valid glTF 2.0 asset that carries a material: the required
``asset`` object (``version: "2.0"``) and a ``materials`` array with one material whose
``pbrMetallicRoughness`` holds ``baseColorFactor`` (linear RGB plus alpha 1), ``metallicFactor``
and ``roughnessFactor`` (glTF 2.0 Specification §3.9.2 "Metallic-Roughness Material", schema
``material.pbrMetallicRoughness.schema.json``). A viewer applies it to a mesh by index 0.
Strings (the material's ``name``, the ``generator``) are escaped by the JSON writer; one that
UTF-8 cannot carry (a lone surrogate) is refused.
"""

from __future__ import annotations

import numpy as np

from ._text import unicode_text


def gltf_document(params, *, name: str = "brdffit-material", generator: str = "brdffit") -> dict:
    """The glTF JSON (a dict; ``json.dumps`` it) for complete ``gltf-pbr`` parameters."""
    base = [float(x) for x in np.broadcast_to(np.asarray(params["base_color"], float), (3,))]
    material = {
        "name": unicode_text(name, "material name"),
        "pbrMetallicRoughness": {
            "baseColorFactor": base + [1.0],
            "metallicFactor": float(params["metallic"]),
            "roughnessFactor": float(params["roughness"]),
        },
        "doubleSided": False,
    }
    return {"asset": {"version": "2.0", "generator": unicode_text(generator, "generator")},
            "materials": [material]}


def params_from_gltf(document: dict, index: int = 0) -> dict:
    """Inverse of :func:`gltf_document`: the ``gltf-pbr`` parameters of material ``index``,
    with the specification's defaults (factor 1) for absent fields."""
    pbr = document["materials"][index].get("pbrMetallicRoughness", {})
    return {
        "base_color": np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])[:3], float),
        "metallic": float(pbr.get("metallicFactor", 1.0)),
        "roughness": float(pbr.get("roughnessFactor", 1.0)),
    }
