"""The renderer-native Mitsuba models against Mitsuba 3 itself (``scalar_rgb`` variant).

Each native model is exported with :func:`brdffit.export.export`, loaded with
``mitsuba.load_dict`` and evaluated with ``BSDF.eval`` at 12,000 direction pairs (a tenth of
them grazing, cos θ down to 1e-3, 15 % near the mirror direction) for several parameter sets; ``eval`` is ``f_r · cos θo`` with
``wo`` Mitsuba's outgoing argument, which is compared with brdffit's model × cos θo. Mitsuba
computes in float32, brdffit in float64 from the same float32-rounded directions: the maximum
relative error where Mitsuba's value exceeds 1e-6 must be ≤ 1e-4, and brdffit must give (almost)
nothing where Mitsuba gives 0. The exported XML is loaded as a scene fragment and must give the
same BSDF as the dict.

Skipped, with the reason, where ``mitsuba`` cannot be imported (``pip install -e ".[mitsuba]"``;
``.ci/run`` installs it).
"""

from __future__ import annotations

import numpy as np
import pytest

import brdffit
from brdffit.export import export
from brdffit.models.evaluate import evaluate_model

mi = pytest.importorskip("mitsuba", reason="mitsuba (scalar_rgb) not installed: pip install -e '.[mitsuba]'")
mi.set_variant("scalar_rgb")

N_PAIRS = 12000
MAX_REL = 1e-4
FLOOR = 1e-6

GOLD = dict(eta=[0.143, 0.374, 1.442], k=[3.983, 2.385, 1.603])
#: (model, label, parameters): rough and shiny, metal and dielectric, anisotropic where supported.
CASES = [
    ("mitsuba-roughconductor", "rough-gold", dict(alpha=0.5, **GOLD)),
    ("mitsuba-roughconductor", "shiny-gold", dict(alpha=0.02, **GOLD)),
    ("mitsuba-roughconductor", "dielectric-k0", dict(alpha=0.15, eta=[1.5, 1.6, 1.7], k=[0.0] * 3)),
    ("mitsuba-roughconductor-aniso", "brushed", dict(alpha_u=0.03, alpha_v=0.35, **GOLD)),
    ("mitsuba-roughconductor-beckmann", "rough", dict(alpha=0.4, **GOLD)),
    ("mitsuba-roughconductor-beckmann", "shiny", dict(alpha=0.03, eta=[1.66, 0.88, 0.52], k=[9.2, 6.3, 4.8])),
    ("mitsuba-roughconductor-tint", "tint", dict(alpha=0.1, specular_reflectance=[0.9, 0.5, 0.2])),
    ("mitsuba-roughconductor-beckmann-aniso-tint", "factory-built",
     dict(alpha_u=0.2, alpha_v=0.04, specular_reflectance=[0.3, 0.6, 0.9])),
    ("mitsuba-principled", "rough-plastic", dict(base_color=[0.6, 0.3, 0.1], roughness=0.8)),
    ("mitsuba-principled", "shiny-metal",
     dict(base_color=[0.95, 0.64, 0.54], roughness=0.1, metallic=1.0)),
    ("mitsuba-principled", "everything-anisotropic",
     dict(base_color=[0.8, 0.3, 0.1], roughness=0.3, metallic=0.3, specular=0.6, spec_tint=0.4,
          anisotropic=0.5, sheen=0.3, sheen_tint=0.2, clearcoat=0.6, clearcoat_gloss=0.3,
          flatness=0.3)),
    # clearcoat_gloss 0.5 (clearcoat α = 0.05): towards gloss 1 (α = 0.001) Mitsuba's float32
    # GTR1 loses digits near the peak, 1 + (α² − 1) cos²θh being a difference of nearly equal
    # numbers (measured: 4.8e-4 relative at gloss 0.9), which is its rounding, not the formula.
    ("mitsuba-principled", "shiny-coated-anisotropic",
     dict(base_color=[0.1, 0.4, 0.2], roughness=0.08, anisotropic=0.9, specular=1.0,
          clearcoat=1.0, clearcoat_gloss=0.5, sheen=1.0)),
]


def direction_pairs(n=N_PAIRS, seed=0):
    """``n`` pairs of float32-representable unit directions: 10 % grazing, 15 % near the mirror."""
    rng = np.random.default_rng(seed)

    def hemi():
        z = np.sqrt(rng.uniform(0.0, 1.0, n))
        z[: n // 10] = rng.uniform(1e-3, 0.05, n // 10)
        phi = rng.uniform(0.0, 2 * np.pi, n)
        r = np.sqrt(1 - z**2)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1).astype(np.float32).astype(float)

    wi, wo = hemi(), hemi()
    # A quarter near the mirror direction (the peak of a shiny lobe), perturbed by 0.3°-6°.
    k, m = n // 10, n // 4
    spread = np.geomspace(0.005, 0.1, m - k)[:, None]
    wo[k:m] = wi[k:m] * [-1, -1, 1] + spread * rng.normal(0, 1, (m - k, 3))
    wo[k:m, 2] = np.abs(wo[k:m, 2]) + 1e-3
    wo[k:m] /= np.linalg.norm(wo[k:m], axis=1, keepdims=True)
    return wi, wo.astype(np.float32).astype(float)


def mitsuba_eval(bsdf, wi, wo):
    si, ctx = mi.SurfaceInteraction3f(), mi.BSDFContext()
    out = np.empty((len(wi), 3))
    for j, (a, b) in enumerate(zip(wi, wo)):
        si.wi = mi.Vector3f(*a)
        out[j] = bsdf.eval(ctx, si, mi.Vector3f(*b))
    return out


def max_relative_error(name, params, bsdf, wi, wo):
    ref = mitsuba_eval(bsdf, wi, wo)
    got = evaluate_model(brdffit.get_model(name), params, wi, wo) * wo[:, 2:3]
    big = ref > FLOOR
    assert big.sum() > 0.1 * big.size, "the comparison must see the lobe"
    assert np.all(got[~big] < 2 * FLOOR), "brdffit reflects where Mitsuba does not"
    return float(np.max(np.abs(got[big] - ref[big]) / ref[big]))


@pytest.mark.parametrize("name,label,params", CASES, ids=[f"{n}-{lab}" for n, lab, _ in CASES])
def test_native_model_matches_mitsuba_eval(name, label, params):
    wi, wo = direction_pairs()
    bsdf = mi.load_dict(export((name, params), "mitsuba-dict").payload)
    err = max_relative_error(name, params, bsdf, wi, wo)
    assert err <= MAX_REL, (name, label, err)


def test_the_comparison_detects_a_wrong_parameter():
    """The test has teeth: a 1 % change of one parameter is far outside the tolerance."""
    wi, wo = direction_pairs(2000)
    name, _, params = CASES[0]
    bsdf = mi.load_dict(export((name, dict(params, alpha=0.505)), "mitsuba-dict").payload)
    assert max_relative_error(name, params, bsdf, wi, wo) > 1e-3


@pytest.mark.parametrize("name,label,params", [CASES[3], CASES[10]], ids=["roughconductor", "principled"])
def test_exported_xml_loads_as_a_scene_fragment_and_equals_the_dict(name, label, params):
    xml = export((name, params), "mitsuba-xml", fragment=True, error=False).payload
    assert xml.lstrip().startswith("<!--") and "<bsdf " in xml and "<scene" not in xml
    scene = mi.load_string(f'<scene version="3.0.0">{xml}'
                           '<shape type="sphere"><ref id="brdffit-material"/></shape></scene>')
    from_xml = scene.shapes()[0].bsdf()
    from_dict = mi.load_dict(export((name, params), "mitsuba-dict").payload)
    wi, wo = direction_pairs(500, seed=3)
    np.testing.assert_array_equal(mitsuba_eval(from_xml, wi, wo), mitsuba_eval(from_dict, wi, wo))


# --- the rendered sphere against brdffit's own lit sphere ------------------------------------


def _lit_sphere_rmse(name, params, image):
    """Relative RMSE of a Mitsuba render against :func:`brdffit.plots.sphere.render_sphere` of
    ``name`` with ``params`` (same light, unit irradiance), 4×4 supersampled and box-averaged
    per pixel as Mitsuba's box filter integrates."""
    from brdffit.plots.sphere import render_sphere

    size = image.shape[0]
    ref = render_sphere(lambda wi, wo: evaluate_model(name, params, wi, wo), size=4 * size)
    ref = ref.reshape(size, 4, size, 4, 3).mean(axis=(1, 3))
    return float(np.sqrt(np.mean((image - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


@pytest.mark.parametrize("name,label,params", [CASES[0], CASES[8]], ids=["conductor", "principled"])
def test_mitsuba_sphere_matches_brdffit_lit_sphere(name, label, params):
    from brdffit.export.render import render_mitsuba

    image = render_mitsuba(export((name, params), "mitsuba-dict").payload, size=64, spp=16,
                           environment=0.0)
    rmse = _lit_sphere_rmse(name, params, image)
    # measured 0.018-0.025 (pixel jitter at 16 spp, the silhouette's partial pixels)
    assert rmse < 0.04, rmse
    wrong = (dict(params, alpha=0.6) if "alpha" in params
             else dict(params, base_color=0.85 * np.asarray(params["base_color"])))
    assert _lit_sphere_rmse(name, wrong, image) > 3 * rmse  # the comparison sees the material


def test_cli_render_writes_the_sphere(tmp_path):
    from data_formats import SampleSet

    from brdffit.cli import main

    name, _, truth = CASES[0]
    wi, wo = direction_pairs(6000, seed=5)
    data = SampleSet(wi, wo, evaluate_model(name, truth, wi, wo), np.ones(len(wi), bool), name="gold")
    brdffit.fit(data, name, subsample=5000).to_json(tmp_path / "gold.json")  # as test_export.py
    out = tmp_path / "sphere.png"
    assert main(["render", str(tmp_path / "gold.json"), "-o", str(out), "--size", "32", "--spp", "4"]) == 0
    import matplotlib.image

    img = matplotlib.image.imread(out)
    assert img.shape[:2] == (32, 32) and img[8:24, 8:24].mean() > 0.05  # a lit sphere, not black
