r"""The glTF 2.0 reference BRDF in plain NumPy, read off a glTF material: what a viewer renders.

A transcription of the specifications, independent of brdffit's model code (it shares nothing
with :mod:`brdffit.models.gltf_pbr` but the conventions), used to measure what an exported file
renders (:mod:`brdffit.export.faithful`). ``V`` is the view (``wo``, towards the viewer), ``L``
the light (``wi``), ``N = z``, ``H = normalize(L + V)``:

* **glTF 2.0 Appendix B** (§B.3.1-§B.3.4): ``α = roughness²``;
  ``D = α² χ⁺(N·H) / (π ((N·H)²(α² − 1) + 1)²)``; the height-correlated
  ``G = 2 |N·L| |N·V| χ⁺(H·L) χ⁺(H·V) / (|N·V| √(α² + (1 − α²)(N·L)²) + |N·L| √(α² + (1 − α²)(N·V)²))``;
  ``specular_brdf = G D / (4 |N·L| |N·V|)``; ``diffuse_brdf = C/π``;
  ``metal_brdf = (C + (1 − C)(1 − |V·H|)⁵) specular_brdf``;
  ``f = mix(dielectric_brdf, metal_brdf, metallic)``.
* **KHR_materials_ior** and **KHR_materials_specular** (its "Implementation" section, with
  ``KHR_materials_ior``'s "interaction"): ``f0 = min(((ior − 1)/(ior + 1))² specularColorFactor,
  1)``, ``fr = f0 + (1 − f0)(1 − |V·H|)⁵`` (RGB) and
  ``dielectric_brdf = (1 − specularFactor · max(fr)) diffuse_brdf + specularFactor · fr ·
  specular_brdf`` (``fresnel_mix`` with ``weight`` and ``f0_color``; without the extensions
  ``ior = 1.5``, both factors 1: Appendix B's ``fresnel_mix``).
* **KHR_materials_clearcoat** ("Implementation"): ``coated = mix(f, clearcoat_brdf,
  clearcoatFactor (0.04 + 0.96 (1 − |N·V|)⁵))`` with ``clearcoat_brdf`` the specular BRDF at
  ``α = clearcoatRoughnessFactor²`` (the geometric normal: brdffit writes no coat normal map).

``KHR_materials_sheen`` is not transcribed (its albedo scaling needs the sheen lobe's
directional albedo, a table the extension leaves to the implementation): a material using it,
or any other extension that changes reflection, is refused with ``ValueError`` rather than
evaluated without it. brdffit writes none of them.
"""

from __future__ import annotations

import numpy as np

#: Extensions this module evaluates; others listed in a material are refused.
EVALUATED = {"KHR_materials_ior", "KHR_materials_specular", "KHR_materials_clearcoat"}


def _specular_brdf(alpha, L, V, H):
    a2 = alpha**2
    NL, NV, NH = L[:, 2], V[:, 2], H[:, 2]
    HL, HV = np.sum(H * L, -1), np.sum(H * V, -1)
    D = a2 * (NH > 0) / (np.pi * (NH**2 * (a2 - 1) + 1) ** 2)
    den = abs(NV) * np.sqrt(a2 + (1 - a2) * NL**2) + abs(NL) * np.sqrt(a2 + (1 - a2) * NV**2)
    G = 2 * abs(NL) * abs(NV) * (HL > 0) * (HV > 0) / np.where(den > 0, den, np.inf)
    return (G * D / np.maximum(4 * abs(NL) * abs(NV), 1e-300))[:, None]


def material_brdf(material: dict, wi, wo) -> np.ndarray:
    """``f_r`` ``(n, 3)`` of the glTF ``material`` (a dict of the document's ``materials``) at
    ``(wi, wo)`` ``(n, 3)``; zero where either direction is below the horizon."""
    ext = material.get("extensions", {})
    other = sorted(set(ext) - EVALUATED)
    if other:
        raise ValueError(f"the glTF reference BRDF does not evaluate {', '.join(other)}")
    pbr = material.get("pbrMetallicRoughness", {})
    C = np.asarray(pbr.get("baseColorFactor", [1.0] * 4)[:3], float)
    metallic = float(pbr.get("metallicFactor", 1.0))
    alpha = float(pbr.get("roughnessFactor", 1.0)) ** 2
    ior = float(ext.get("KHR_materials_ior", {}).get("ior", 1.5))
    spec_ext = ext.get("KHR_materials_specular", {})
    weight = float(spec_ext.get("specularFactor", 1.0))
    f0_color = np.asarray(spec_ext.get("specularColorFactor", [1.0, 1.0, 1.0]), float)

    L, V = np.asarray(wi, float), np.asarray(wo, float)
    H = L + V
    H = H / np.maximum(np.linalg.norm(H, axis=-1, keepdims=True), 1e-300)
    w = ((1 - np.abs(np.sum(V * H, -1))) ** 5)[:, None]
    specular_brdf = _specular_brdf(alpha, L, V, H)
    diffuse_brdf = C / np.pi
    f0 = np.minimum(((ior - 1) / (ior + 1)) ** 2 * f0_color, 1.0)
    fr = f0 + (1 - f0) * w
    dielectric_brdf = ((1 - weight * fr.max(-1, keepdims=True)) * diffuse_brdf
                       + weight * fr * specular_brdf)
    metal_brdf = (C + (1 - C) * w) * specular_brdf
    f = (1 - metallic) * dielectric_brdf + metallic * metal_brdf
    coat = ext.get("KHR_materials_clearcoat")
    if coat is not None:
        cc = float(coat.get("clearcoatFactor", 0.0))
        cc_alpha = float(coat.get("clearcoatRoughnessFactor", 0.0)) ** 2
        fresnel = (0.04 + 0.96 * (1 - np.abs(V[:, 2])) ** 5)[:, None]
        f = f + (_specular_brdf(cc_alpha, L, V, H) - f) * cc * fresnel
    visible = ((L[:, 2] > 0) & (V[:, 2] > 0))[:, None]
    return np.where(visible, f, 0.0)


def document_brdf(document: dict, wi, wo, index: int = 0) -> np.ndarray:
    """:func:`material_brdf` of material ``index`` of a glTF ``document`` (the JSON, a dict)."""
    return material_brdf(document["materials"][index], wi, wo)
