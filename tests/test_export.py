"""Export without a renderer: glTF documents, the spec's BRDF, errors, approximation, CLI.

The glTF test evaluates the glTF 2.0 Specification's Appendix B BRDF written out here in NumPy
from the specification's own formulas (its height-correlated ``G`` form, ``fresnel_mix`` and
``conductor_fresnel``), independent of brdffit's pieces, with the factors read back from the
exported JSON text. Recovery from synthetic tables for the renderer-native models is here too
(the model-library tests of ``tests/test_models.py`` cover reciprocity, energy, gradients).
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

import brdffit
from brdffit.cli import main
from brdffit.export import TARGETS, ApproximationWarning, NoExactCounterpart, export
from brdffit.export.approximate import approximate
from brdffit.models.evaluate import evaluate_model
from data_formats.merl import read_merl, synthesize, write_merl

SHAPE = (45, 45, 90)  # a quarter-resolution MERL grid: 182k cells
#: Every fit here uses this many cells: the fitter compiles once per model and shape.
CELLS = 5000


def _pairs(n, seed=0):
    rng = np.random.default_rng(seed)

    def hemi():
        z = rng.uniform(0.02, 1.0, n)
        phi = rng.uniform(0, 2 * np.pi, n)
        r = np.sqrt(1 - z**2)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)

    return hemi(), hemi()


# --- the glTF 2.0 specification, Appendix B, written out independently ----------------------


def spec_brdf(base_color, metallic, roughness, L, V):
    """glTF 2.0 Appendix B "full code" listing, with §B.3.1's D and height-correlated G."""
    a2 = roughness**4  # α = roughness²
    H = (L + V) / np.linalg.norm(L + V, axis=-1, keepdims=True)
    NL, NV, NH = L[:, 2], V[:, 2], H[:, 2]
    HL, HV = np.sum(H * L, -1), np.sum(H * V, -1)
    D = a2 * (NH > 0) / (np.pi * (NH**2 * (a2 - 1) + 1) ** 2)
    G = (2 * abs(NL) * abs(NV) * (HL > 0) * (HV > 0)
         / (abs(NV) * np.sqrt(a2 + (1 - a2) * NL**2) + abs(NL) * np.sqrt(a2 + (1 - a2) * NV**2)))
    specular_brdf = (D * G / (4 * abs(NV) * abs(NL)))[:, None]
    fresnel_w = ((1 - abs(np.sum(V * H, -1))) ** 5)[:, None]
    diffuse_brdf = base_color / np.pi
    dielectric_fresnel = 0.04 + (1 - 0.04) * fresnel_w
    dielectric_brdf = diffuse_brdf + (specular_brdf - diffuse_brdf) * dielectric_fresnel  # mix
    metal_brdf = (base_color + (1 - base_color) * fresnel_w) * specular_brdf
    return dielectric_brdf + (metal_brdf - dielectric_brdf) * metallic  # mix(…, metallic)


GLTF_CASES = [
    dict(base_color=[0.7, 0.3, 0.1], metallic=0.3, roughness=0.35),
    dict(base_color=[0.95, 0.64, 0.54], metallic=1.0, roughness=0.1),
    dict(base_color=[0.2, 0.5, 0.8], metallic=0.0, roughness=0.9),
]


@pytest.mark.parametrize("params", GLTF_CASES, ids=["mixed", "metal", "rough-dielectric"])
def test_gltf_round_trip_through_the_spec_brdf(params):
    doc = json.loads(export(("gltf-pbr", params), "gltf").text())
    pbr = doc["materials"][0]["pbrMetallicRoughness"]
    L, V = _pairs(4000)
    ref = spec_brdf(np.asarray(pbr["baseColorFactor"][:3]), pbr["metallicFactor"],
                    pbr["roughnessFactor"], L, V)
    got = evaluate_model("gltf-pbr", params, L, V)
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-14)


def test_the_spec_oracle_has_teeth():
    L, V = _pairs(500)
    p = GLTF_CASES[0]
    off = spec_brdf(np.asarray(p["base_color"]), p["metallic"], p["roughness"] * 1.01, L, V)
    assert np.max(np.abs(evaluate_model("gltf-pbr", p, L, V) / off - 1)) > 1e-3


def test_gltf_document_is_valid_gltf_2_json():
    """Structure checks transcribed from the glTF 2.0 JSON schema (``glTF.schema.json``,
    ``asset.schema.json``, ``material.schema.json``, ``material.pbrMetallicRoughness.schema.json``);
    the Khronos validator's verdict is in ``tests/test_export_faithful.py``."""
    doc = json.loads(export(("gltf-pbr", GLTF_CASES[0]), "gltf").text())
    assert set(doc) <= {"asset", "materials", "extensionsUsed", "extras", "scene", "scenes",
                        "nodes", "meshes", "buffers", "bufferViews", "accessors"}
    assert re.fullmatch(r"[0-9]+\.[0-9]+", doc["asset"]["version"]) and doc["asset"]["version"] == "2.0"
    assert isinstance(doc["asset"].get("generator", ""), str)
    (material,) = doc["materials"]
    assert set(material) <= {"name", "pbrMetallicRoughness", "doubleSided", "extras",
                             "alphaMode", "emissiveFactor", "extensions"}
    assert isinstance(material["doubleSided"], bool) and isinstance(material["name"], str)
    assert "extensions" not in material  # the core material: ior 1.5, specular 1
    pbr = material["pbrMetallicRoughness"]
    assert set(pbr) == {"baseColorFactor", "metallicFactor", "roughnessFactor"}
    assert len(pbr["baseColorFactor"]) == 4 and pbr["baseColorFactor"][3] == 1.0
    for v in [*pbr["baseColorFactor"], pbr["metallicFactor"], pbr["roughnessFactor"]]:
        assert isinstance(v, float) and 0.0 <= v <= 1.0


# --- no silent approximation ------------------------------------------------------------------


@pytest.mark.parametrize("model,target,native", [
    ("ggx", "mitsuba-dict", "mitsuba-principled"),
    ("disney", "mitsuba-xml", "mitsuba-principled"),
    ("gltf-pbr", "mitsuba-dict", "mitsuba-principled"),
    ("mitsuba-principled", "gltf", "gltf-pbr"),
])
def test_no_exact_counterpart_names_the_native_model(model, target, native):
    with pytest.raises(NoExactCounterpart, match=rf"{model}.*no exact counterpart.*{native}.*approximate"):
        export((model, {}), target)
    assert TARGETS[target].native == native


def test_unknown_target_lists_the_valid_ones():
    with pytest.raises(brdffit.UnknownNameError, match="gltf.*mitsuba-dict.*mitsuba-xml"):
        export(("gltf-pbr", {}), "usd")


@pytest.mark.parametrize("truth", GLTF_CASES[1:], ids=["metal", "dielectric"])
def test_approximating_a_native_model_by_itself_recovers_it(truth):
    """The approximation machinery is exact where it can be: gltf-pbr fitted to gltf-pbr, a
    metal and a dielectric (``metallic`` is read as 0 or 1, so a blend is not recovered: the
    fit's own test, :func:`test_native_model_recovered_from_a_synthetic_table`, starts it)."""
    res = approximate("gltf-pbr", truth, "gltf-pbr", n=10000, subsample=CELLS)
    assert res.success and res.metrics["rel_error"] < 1e-8
    assert res.params["metallic"] == truth["metallic"]
    np.testing.assert_allclose(res.params["base_color"], truth["base_color"], rtol=1e-6)
    assert res.params["roughness"] == pytest.approx(truth["roughness"], rel=1e-6)


# --- recovery, FitResult.export and the command line -----------------------------------------


def _table(tmp_path, name, truth):
    path = tmp_path / f"{name}.binary"
    write_merl(path, synthesize(lambda wi, wo: evaluate_model(name, truth, wi, wo), name=name,
                                shape=SHAPE))
    return read_merl(path)


RECOVERY = {
    # off the extensions' defaults (specular 1 is its upper bound): ior and specular recovered too
    "gltf-pbr": dict(GLTF_CASES[0], ior=1.7, specular=0.8),
    "mitsuba-roughconductor": dict(alpha=0.15, eta=[0.143, 0.374, 1.442], k=[3.983, 2.385, 1.603]),
}


#: mitsuba-principled with every lobe on, the preset's unidentifiable tints (and anisotropy, on
#: an isotropic grid) held; the fitter's data-driven start does not know this model, so the
#: start is given (the approximation's dielectric start would do, too).
PRINCIPLED = dict(base_color=[0.6, 0.3, 0.15], roughness=0.35, metallic=0.2, specular=0.6,
                  sheen=0.5, flatness=0.3, clearcoat=0.4, clearcoat_gloss=0.5)
PRINCIPLED_START = dict(base_color=0.4, roughness=0.3, metallic=0.1, specular=0.5, sheen=0.2,
                        flatness=0.1, clearcoat=0.2, clearcoat_gloss=0.3)
PRINCIPLED_HELD = dict(anisotropic=0.0, spec_tint=0.0, sheen_tint=0.0)
RECOVERY["mitsuba-principled"] = dict(PRINCIPLED, **PRINCIPLED_HELD)


@pytest.mark.parametrize("name", sorted(RECOVERY))
def test_native_model_recovered_from_a_synthetic_table(tmp_path, name):
    truth = RECOVERY[name]
    start, held = (PRINCIPLED_START, PRINCIPLED_HELD) if name == "mitsuba-principled" else (None, None)
    if name == "gltf-pbr":  # a blend (metallic 0.3): started, metallic is fitted, not read
        start = {"metallic": 0.5}
    res = brdffit.fit(_table(tmp_path, name, truth), name, subsample=CELLS, init=start, fixed=held)
    model = brdffit.get_model(name)
    x = model.flatten(truth)
    assert res.success and res.cost < 1e-12 and not res.at_bound
    np.testing.assert_allclose(res.x, x, rtol=1e-6)


@pytest.fixture(scope="module")
def ggx_result(tmp_path_factory):
    """A ggx fit (Lambert + Schlick GGX: no exact counterpart in any renderer), written to disk."""
    tmp = tmp_path_factory.mktemp("ggx")
    truth = dict(diffuse=[0.02] * 3, f0=[0.9, 0.6, 0.3], alpha=0.08)
    res = brdffit.fit(_table(tmp, "ggx", truth), "ggx", subsample=CELLS)
    path = tmp / "ggx.json"
    res.to_json(path)
    return res, path


def test_result_export_refuses_then_approximates_with_a_warning(ggx_result):
    res, _ = ggx_result
    with pytest.raises(NoExactCounterpart, match="gltf-pbr"):
        res.export("gltf")
    with pytest.warns(ApproximationWarning, match="gltf-pbr approximates ggx: .*rmse_log"):
        doc = res.export("gltf", approximate=True, n=10000, subsample=CELLS)
    pbr = doc["materials"][0]["pbrMetallicRoughness"]
    assert pbr["metallicFactor"] > 0.8  # a metal stays a metal
    assert "approximation error rmse_log" in doc["materials"][0]["extras"]["brdffit"]


def test_cli_export_exact_and_refusal(tmp_path, ggx_result, capsys):
    res = brdffit.fit(_table(tmp_path, "gltf-pbr", GLTF_CASES[1]), "gltf-pbr", subsample=CELLS)
    res.to_json(tmp_path / "r.json")
    assert main(["export", str(tmp_path / "r.json"), "--to", "gltf", "-o", str(tmp_path / "m.gltf")]) == 0
    doc = json.loads((tmp_path / "m.gltf").read_text())
    assert doc["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] == pytest.approx(0.1, rel=1e-6)
    assert "exact" in doc["materials"][0]["extras"]["brdffit"]
    _, ggx_path = ggx_result
    code = main(["export", str(ggx_path), "--to", "mitsuba-xml", "-o", str(tmp_path / "m.xml")])
    err = capsys.readouterr().err
    assert code == 2 and "mitsuba-principled" in err and "--approximate" in err
    assert not (tmp_path / "m.xml").exists()
