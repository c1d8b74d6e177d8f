"""A glTF 2.0 asset a viewer opens: a sphere carrying the fitted material.

The document (glTF 2.0 Specification §3, ``glTF.schema.json``) holds one material, one sphere
mesh, one node and one scene (``scene: 0``), so any viewer shows the material as it opens the
file:

* the material's ``pbrMetallicRoughness`` holds ``baseColorFactor`` (linear RGB plus alpha 1),
  ``metallicFactor`` and ``roughnessFactor`` (§3.9.2); a fitted ``ior`` other than the core's
  1.5 goes into ``KHR_materials_ior``, a ``specular`` weight below 1 into
  ``KHR_materials_specular`` (``specularFactor``, ``specularColorFactor`` white), a clear coat
  into ``KHR_materials_clearcoat`` (``clearcoatFactor``, ``clearcoatRoughnessFactor``); each
  extension used is listed in ``extensionsUsed`` (not ``extensionsRequired``: a viewer without
  it still shows the core material);
* the mesh is a UV sphere of radius 1 (:func:`sphere`): ``POSITION`` (with the ``min``/``max``
  the specification requires), ``NORMAL`` (unit length) and ``uint16`` indices, counter-clockwise
  seen from outside, one triangle per segment at each pole (no degenerate triangle);
* the binary data live in one buffer: a base64 ``data:`` URI in a ``.gltf`` (one file, nothing
  beside it), the binary chunk of a ``.glb`` (§4.4, :func:`glb_bytes`).

The Khronos validator (npm ``gltf-validator``) reports no error and no warning on either form
(``tests/test_export_faithful.py``). Strings (the material's ``name``, the ``generator``) are
escaped by the JSON writer; one that UTF-8 cannot carry (a lone surrogate) is refused.
"""

from __future__ import annotations

import base64
import json
import struct

import numpy as np

from ._text import unicode_text

#: The core material's index of refraction (``f0 = 0.04``), ``KHR_materials_ior``'s default.
CORE_IOR = 1.5
#: Segments around (``φ``) and rings from pole to pole (``θ``) of the sphere.
SPHERE_SEGMENTS, SPHERE_RINGS = 48, 24
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
FLOAT, UNSIGNED_SHORT = 5126, 5123


def sphere(segments: int = SPHERE_SEGMENTS, rings: int = SPHERE_RINGS):
    """``(positions (n, 3) float32, indices (m,) uint16)`` of a unit UV sphere; its normals are
    its positions. A pole is one vertex; each pole fan has one triangle per segment."""
    theta = np.pi * np.arange(1, rings) / rings                     # inner rings
    phi = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.sin(theta)[:, None] * np.cos(phi), np.cos(theta)[:, None] + 0 * phi,
                     np.sin(theta)[:, None] * np.sin(phi)], -1).reshape(-1, 3)
    top, bottom = len(ring), len(ring) + 1
    pos = np.concatenate([ring, [[0, 1, 0], [0, -1, 0]]]).astype(np.float32)
    pos /= np.linalg.norm(pos, axis=1, keepdims=True)
    s = np.arange(segments)
    t = (s + 1) % segments
    tris = [np.stack([np.full(segments, top), t, s], 1)]            # y up, outward-facing CCW
    for r in range(rings - 2):
        a, b = r * segments + s, r * segments + t
        c, d = a + segments, b + segments
        tris += [np.stack([a, b, c], 1), np.stack([b, d, c], 1)]
    last = (rings - 2) * segments
    tris.append(np.stack([np.full(segments, bottom), last + s, last + t], 1))
    return pos, np.concatenate(tris).astype(np.uint16).ravel()


def _material(params, name: str) -> dict:
    base = [float(x) for x in np.broadcast_to(np.asarray(params["base_color"], float), (3,))]
    material = {
        "name": unicode_text(name, "material name"),
        "pbrMetallicRoughness": {"baseColorFactor": base + [1.0],
                                 "metallicFactor": float(params["metallic"]),
                                 "roughnessFactor": float(params["roughness"])},
        "doubleSided": False,
    }
    ext = {}
    ior = float(params.get("ior", CORE_IOR))
    if ior != CORE_IOR:
        ext["KHR_materials_ior"] = {"ior": ior}
    specular = float(params.get("specular", 1.0))
    if specular != 1.0:
        ext["KHR_materials_specular"] = {"specularFactor": specular,
                                         "specularColorFactor": [1.0, 1.0, 1.0]}
    sheen = [float(x) for x in np.broadcast_to(np.asarray(params.get("sheen_color", 0.0), float),
                                                (3,))]
    if max(sheen) > 0.0:
        ext["KHR_materials_sheen"] = {"sheenColorFactor": sheen,
                                      "sheenRoughnessFactor": float(params["sheen_roughness"])}
    if float(params.get("clearcoat", 0.0)) > 0.0:
        ext["KHR_materials_clearcoat"] = {
            "clearcoatFactor": float(params["clearcoat"]),
            "clearcoatRoughnessFactor": float(params["clearcoat_roughness"])}
    if ext:
        material["extensions"] = ext
    return material


def gltf_document(params, *, name: str = "brdffit-material", generator: str = "brdffit",
                  uri: bool = True) -> dict:
    """The glTF JSON (a dict; ``json.dumps`` it) for complete ``gltf-pbr`` (or
    ``gltf-pbr-clearcoat``, ``gltf-pbr-sheen``) parameters, the sphere's buffer as a ``data:`` URI (``uri=False``:
    no URI, the buffer is a GLB's binary chunk, :func:`glb_bytes`)."""
    material = _material(params, name)
    pos, idx = sphere()
    blob = pos.tobytes() + idx.tobytes()
    blob += b"\0" * (-len(blob) % 4)
    buffer = {"byteLength": len(blob)}
    if uri:
        buffer["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    doc = {
        "asset": {"version": "2.0", "generator": unicode_text(generator, "generator")},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "sphere"}],
        "meshes": [{"name": "sphere", "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]}],
        "materials": [material],
        "buffers": [buffer],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes, "byteStride": 12,
             "target": ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": idx.nbytes,
             "target": ELEMENT_ARRAY_BUFFER},
        ],
        "accessors": [
            {"bufferView": 0, "byteOffset": 0, "componentType": FLOAT, "count": len(pos),
             "type": "VEC3", "min": [float(v) for v in pos.min(0)],
             "max": [float(v) for v in pos.max(0)]},
            {"bufferView": 0, "byteOffset": 0, "componentType": FLOAT, "count": len(pos),
             "type": "VEC3"},
            {"bufferView": 1, "byteOffset": 0, "componentType": UNSIGNED_SHORT,
             "count": len(idx), "type": "SCALAR"},
        ],
    }
    used = sorted(material.get("extensions", {}))
    if used:
        doc["extensionsUsed"] = used
    return doc


def glb_bytes(document: dict) -> bytes:
    """The binary glTF (§4.4) of ``document`` (made with ``uri=False``): a 12-byte header, the
    JSON chunk padded with spaces and the sphere's ``BIN`` chunk padded with zeros."""
    doc = dict(document)
    doc["buffers"] = [{"byteLength": doc["buffers"][0]["byteLength"]}]
    pos, idx = sphere()
    blob = pos.tobytes() + idx.tobytes()
    blob += b"\0" * (-len(blob) % 4)
    text = json.dumps(doc, allow_nan=False, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    return (struct.pack("<III", 0x46546C67, 2, total)
            + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(blob), 0x004E4942) + blob)


def params_from_gltf(document: dict, index: int = 0) -> dict:
    """Inverse of :func:`gltf_document`: the ``gltf-pbr`` parameters of material ``index``
    (with ``clearcoat`` and ``clearcoat_roughness`` where the coat extension is present,
    ``sheen_color`` and ``sheen_roughness`` where the sheen's is), with the specifications'
    defaults for absent fields."""
    material = document["materials"][index]
    pbr = material.get("pbrMetallicRoughness", {})
    ext = material.get("extensions", {})
    out = {
        "base_color": np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])[:3], float),
        "metallic": float(pbr.get("metallicFactor", 1.0)),
        "roughness": float(pbr.get("roughnessFactor", 1.0)),
        "ior": float(ext.get("KHR_materials_ior", {}).get("ior", CORE_IOR)),
        "specular": float(ext.get("KHR_materials_specular", {}).get("specularFactor", 1.0)),
    }
    if "KHR_materials_sheen" in ext:
        sheen = ext["KHR_materials_sheen"]
        out["sheen_color"] = np.asarray(sheen.get("sheenColorFactor", [0.0, 0.0, 0.0]), float)
        out["sheen_roughness"] = float(sheen.get("sheenRoughnessFactor", 0.0))
    if "KHR_materials_clearcoat" in ext:
        coat = ext["KHR_materials_clearcoat"]
        out["clearcoat"] = float(coat.get("clearcoatFactor", 0.0))
        out["clearcoat_roughness"] = float(coat.get("clearcoatRoughnessFactor", 0.0))
    return out
