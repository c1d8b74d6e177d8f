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
* **KHR_materials_sheen** ("Implementation Notes"): ``f = f_sheen + f · sheenAlbedoScaling``
  with ``f_sheen = sheenColor D_S / ((1 + Λ(N·V) + Λ(N·L)) 4 |N·L| |N·V|)``, the Charlie NDF
  ``D_S = (2 + 1/α)(1 − (N·H)²)^{1/(2α)} / 2π`` at ``α = sheenRoughnessFactor²``, Λ the
  extension's ``lambdaSheen`` (the fitted ``l(x)`` of Estevez & Kulla 2017), and
  ``sheenAlbedoScaling = min(1 − max₃(sheenColor) E(N·V), 1 − max₃(sheenColor) E(N·L))``,
  clamped at 0 (as Filament does: the lobe's ``E`` exceeds 1 near grazing at low roughness).
  The extension leaves ``E``, the sheen lobe's directional albedo, to a table; here it is that
  integral itself, computed for the file's roughness (:func:`sheen_albedo_curve`: 257 values of
  ``cos θ`` from 10⁻⁴ to 1, spaced evenly in ``√cos θ``, 128 × 128 nodes over ``ωo``, linear
  interpolation between them).
* **KHR_materials_clearcoat** ("Implementation"): ``coated = mix(f, clearcoat_brdf,
  clearcoatFactor (0.04 + 0.96 (1 − |N·V|)⁵))`` with ``clearcoat_brdf`` the specular BRDF at
  ``α = clearcoatRoughnessFactor²`` (the geometric normal: brdffit writes no coat normal map),
  on top of the sheen.

Any other extension that changes reflection is refused with ``ValueError`` rather than
evaluated without it. brdffit writes none of them.
"""

from __future__ import annotations

import functools

import numpy as np

#: Extensions this module evaluates; others listed in a material are refused.
EVALUATED = {"KHR_materials_ior", "KHR_materials_specular", "KHR_materials_clearcoat",
             "KHR_materials_sheen"}

#: ``KHR_materials_sheen``'s ``l(x)`` coefficients: ``mix(at α = 1, at α = 0, (1 − α)²)``.
_SHEEN_L = ((21.5473, 25.3245), (3.82987, 3.32435), (0.19823, 0.16801), (-1.97760, -1.27393),
            (-4.32054, -4.85967))


def _sheen_l(x, alpha):
    t = (1.0 - alpha) ** 2
    a, b, c, d, e = (lo * (1 - t) + hi * t for lo, hi in _SHEEN_L)
    return a / (1.0 + b * np.power(x, c)) + d * x + e


def _lambda_sheen(cos_theta, alpha):
    c = np.abs(cos_theta)
    return np.where(c < 0.5, np.exp(_sheen_l(c, alpha)),
                    np.exp(2.0 * _sheen_l(0.5, alpha) - _sheen_l(1.0 - c, alpha)))


def _sheen_brdf(alpha, L, V, H):
    """The sheen lobe with ``sheenColor = 1``, ``(n,)``."""
    NL, NV, NH = L[..., 2], V[..., 2], H[..., 2]
    sin2h = np.maximum(1.0 - NH**2, 0.0)
    D = (2.0 + 1.0 / alpha) * sin2h ** (0.5 / alpha) / (2 * np.pi) * (NH > 0)
    den = (1.0 + _lambda_sheen(NV, alpha) + _lambda_sheen(NL, alpha)) * 4 * np.abs(NL * NV)
    return np.where((NL > 0) & (NV > 0), D / np.where(den > 0, den, np.inf), 0.0)


@functools.lru_cache(maxsize=16)
def sheen_albedo_curve(roughness: float, n_mu: int = 257, n_quad: int = 128):
    """``(μ, E(μ))``: the directional albedo of the sheen lobe (``sheenColor = 1``) at ``n_mu``
    values of ``cos θ`` from 10⁻⁴ to 1 (evenly spaced in ``√cos θ``), by Gauss–Legendre nodes in ``cos θo`` and midpoint nodes
    in ``φo`` (``n_quad`` each)."""
    alpha = roughness**2
    x, w = np.polynomial.legendre.leggauss(n_quad)
    co, wc = (x + 1) / 2, w / 2
    phi = (np.arange(n_quad) + 0.5) * 2 * np.pi / n_quad
    so = np.sqrt(1 - co**2)
    V = np.stack(np.broadcast_arrays(so[:, None] * np.cos(phi), so[:, None] * np.sin(phi),
                                     co[:, None]), -1).reshape(-1, 3)
    weight = (wc * co)[:, None].repeat(n_quad, 1).ravel() * (2 * np.pi / n_quad)
    mu = np.linspace(1e-2, 1.0, n_mu) ** 2  # denser towards grazing, where E changes fastest
    E = np.empty(n_mu)
    for k, m in enumerate(mu):
        L = np.array([np.sqrt(1 - m * m), 0.0, m])
        H = L + V
        H /= np.linalg.norm(H, axis=-1, keepdims=True)
        E[k] = np.sum(weight * _sheen_brdf(alpha, np.broadcast_to(L, V.shape), V, H))
    mu.flags.writeable = E.flags.writeable = False  # cached: one integral per roughness
    return mu, E


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
    sheen = ext.get("KHR_materials_sheen")
    if sheen is not None:
        color = np.asarray(sheen.get("sheenColorFactor", [0.0, 0.0, 0.0]), float)
        roughness = float(sheen.get("sheenRoughnessFactor", 0.0))
        if color.max() > 0.0:
            alpha = roughness**2
            mu, E = sheen_albedo_curve(roughness)
            scaling = np.minimum(1 - color.max() * np.interp(np.abs(V[:, 2]), mu, E),
                                 1 - color.max() * np.interp(np.abs(L[:, 2]), mu, E))
            f = (color * _sheen_brdf(alpha, L, V, H)[:, None]
                 + f * np.maximum(scaling, 0.0)[:, None])
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
