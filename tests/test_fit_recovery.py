"""Parameter recovery on synthetic MERL-layout tables written to disk and read back.

Every table is the full 90×90×180 grid, made with ``data_formats.merl.synthesize`` from known
parameters, written with ``write_merl`` and read with ``read_merl``. Fits run on a seeded random
subsample of 20,000 cells (the shapes, hence the compilation, are shared by all tables of a
model) from the default data-driven initialization. The truth is the independent reference.
"""

import jax
import numpy as np
import pytest

import brdffit
from brdffit.fitting import Subsample
from data_formats import SampleSet
from data_formats.merl import read_merl, synthesize, write_merl

SUB = Subsample(20000)

#: model -> materials (label, truth). Rough and very shiny, dark and bright, metal and plastic.
CASES = {
    "ggx": [
        ("rough-bright-plastic", {"diffuse": [0.5, 0.4, 0.3], "f0": [0.04] * 3, "alpha": 0.6}),
        ("polished-metal", {"diffuse": [0.01] * 3, "f0": [0.95, 0.64, 0.54], "alpha": 0.005}),
        ("dark-plastic", {"diffuse": [0.02, 0.01, 0.005], "f0": [0.05] * 3, "alpha": 0.1}),
    ],
    "beckmann": [
        ("paint", {"diffuse": [0.3, 0.2, 0.1], "f0": [0.04] * 3, "alpha": 0.3}),
        ("steel", {"diffuse": [0.01] * 3, "f0": [0.9] * 3, "alpha": 0.01}),
    ],
    "blinn-phong": [
        ("plastic", {"diffuse": [0.3, 0.2, 0.1], "f0": [0.04] * 3, "alpha": 0.2}),
        ("brass", {"diffuse": [0.02] * 3, "f0": [0.8, 0.5, 0.3], "alpha": 0.02}),
    ],
    "gtr": [
        ("long-tail", {"diffuse": [0.2] * 3, "f0": [0.05] * 3, "alpha": 0.1, "gamma": 1.2}),
        ("short-tail-metal", {"diffuse": [0.05] * 3, "f0": [0.5] * 3, "alpha": 0.05, "gamma": 3.0}),
    ],
    "two-lobe-ggx": [
        ("coated", {"diffuse": [0.1] * 3, "f0": [0.5, 0.4, 0.3], "alpha_1": 0.02,
                    "alpha_2": 0.3, "mix": 0.2}),
    ],
    "disney": [
        ("everything-on", {"base_color": [0.6, 0.3, 0.15], "subsurface": 0.3, "metallic": 0.2,
                               "specular": 0.6, "specular_tint": 0.3, "roughness": 0.35, "anisotropic": 0.0,
                               "sheen": 0.5, "sheen_tint": 0.5, "clearcoat": 0.4, "clearcoat_gloss": 0.8}),
    ],
}
#: Disney parameters held at the truth: ``specular_tint`` trades off against ``metallic`` and
#: ``specular`` (JᵀJ singular when all are free); ``sheen_tint`` only matters through a small
#: grazing term; ``anisotropic`` needs φh ≠ 0, which a MERL grid (φh = 0) never has.
DISNEY_FIXED = ("specular_tint", "sheen_tint", "anisotropic")


def _evaluator(name):
    model = brdffit.get_model(name)
    return model, jax.jit(lambda p, wi, wo: model.fn(p, wi, wo))


@pytest.fixture(scope="module")
def merl_table(tmp_path_factory):
    """``merl_table(name, label, truth, noise=0.0)``: the table of ``truth``, written to disk
    once per case and read back for each test. Only the files outlive a test: a full table is
    35 MB in memory, and this file's thirteen tables held at once raised a worker's peak."""
    paths = {}

    def table(name, label, truth, noise=0.0):
        key = (name, label, noise)
        if key not in paths:
            model, f = _evaluator(name)
            p = model.unflatten(model.flatten(truth))
            rng = np.random.default_rng(7)

            def fn(wi, wo):
                rgb = np.concatenate([np.asarray(f(p, a, b))[None] for a, b in zip(wi, wo)])
                return rgb * (1.0 + noise * rng.standard_normal(rgb.shape)) if noise else rgb

            path = tmp_path_factory.mktemp("merl") / f"{name}-{label}.binary"
            write_merl(path, synthesize(fn, name=f"{name}-{label}"))
            paths[key] = path
        return read_merl(paths[key])

    return table


def fixed_for(name, truth):
    return {k: truth[k] for k in DISNEY_FIXED} if name == "disney" else None


def truth_at_bound(model, truth):
    """Flat name → ``"lower"``/``"upper"`` for the scalars whose true value is on a bound (an
    ``grazing`` left at its default 1: a table of plain Schlick lobes)."""
    lo, hi = model.flat_bounds()
    x = model.flatten(truth)
    return {n: ("lower" if v == a else "upper")
            for n, v, a, b in zip(model.flat_names(), x, lo, hi) if v in (a, b)}


def rel_errors(model, result, truth):
    """Relative error of each free scalar; absolute where the truth is 0 (an angle of 0)."""
    x = model.flatten(truth)
    idx = [model.flat_names().index(n) for n in result.free]
    scale = np.where(x[idx] != 0, np.abs(x[idx]), 1.0)
    return dict(zip(result.free, np.abs(result.x[idx] - x[idx]) / scale))


@pytest.mark.parametrize(
    "name,label,truth", [(n, lab, t) for n, cases in CASES.items() for lab, t in cases],
    ids=[f"{n}-{lab}" for n, cases in CASES.items() for lab, _ in cases],
)
def test_noise_free_recovery_from_default_init(merl_table, name, label, truth):
    if name not in brdffit.available_models():
        pytest.fail(f"model {name!r} is not registered")
    table = merl_table(name, label, truth)
    model = brdffit.get_model(name)
    res = brdffit.fit(table, name, subsample=SUB, fixed=fixed_for(name, truth))
    errs = rel_errors(model, res, truth)
    assert res.success, res.message
    assert max(errs.values()) <= 1e-3, (res.summary(), errs)
    assert res.cost < 1e-12
    # Only a truth on its bound may be reported there (an exact fit touches the bound with a
    # zero gradient, so it may also end within the tolerance above, just inside)
    on = truth_at_bound(model, truth)
    assert all(on.get(k) == side for k, side in res.at_bound.items()), (res.at_bound, on)


def test_noisy_estimates_within_three_standard_errors(merl_table):
    """2% multiplicative noise: |estimate - truth| ≤ 3 reported standard errors (7 scalars)."""
    name, label = "ggx", "blue-plastic"
    truth = {"diffuse": [0.1, 0.2, 0.3], "f0": [0.05, 0.04, 0.03], "alpha": 0.1}
    table = merl_table(name, label, truth, noise=0.02)
    model = brdffit.get_model(name)
    res = brdffit.fit(table, name, subsample=Subsample(5000))
    se = np.sqrt(np.diag(res.cov))
    z = (res.x - model.flatten(truth)) / se
    assert res.success and np.all(se > 0)
    assert np.all(np.abs(z) <= 3.0), dict(zip(res.names, z.round(2)))
    # the noise is visible in the metrics: relative error about 2% × sqrt(2/π) on average
    assert 0.01 < res.metrics["rel_error"] < 0.03


@pytest.mark.parametrize("start", [0, 1, 2])
def test_several_starting_points_reach_the_same_optimum(merl_table, start):
    name, label, truth = "ggx", "polished-metal", CASES["ggx"][1][1]
    table = merl_table(name, label, truth)
    init = [
        None,
        {"diffuse": 0.3, "f0": 0.1, "alpha": 0.3},
        {"diffuse": 0.05, "f0": 0.5, "alpha": 0.002},
    ][start]
    res = brdffit.fit(table, name, subsample=SUB, init=init)
    errs = rel_errors(brdffit.get_model(name), res, truth)
    assert res.success and max(errs.values()) <= 1e-3, (init, res.summary())


def test_multistart_keeps_the_best(merl_table):
    name, label, truth = "ggx", "rough-bright-plastic", CASES["ggx"][0][1]
    table = merl_table(name, label, truth)
    res = brdffit.fit(table, name, subsample=SUB, multistart=3, seed=5)
    assert len(res.starts) == 4 and res.cost == pytest.approx(min(res.starts), rel=1e-6, abs=1e-20)
    assert max(rel_errors(brdffit.get_model(name), res, truth).values()) <= 1e-3


def test_fixed_parameters_are_honoured_and_others_still_recovered(merl_table):
    name, label, truth = "ggx", "dark-plastic", CASES["ggx"][2][1]
    table = merl_table(name, label, truth)
    res = brdffit.fit(table, name, subsample=SUB, fixed={"alpha": 0.1, "f0[1]": 0.05})
    assert res.params["alpha"] == 0.1 and res.params["f0"][1] == 0.05
    assert res.fixed == ["f0[1]", "alpha"] and res.stderr["alpha"] == 0
    assert max(rel_errors(brdffit.get_model(name), res, truth).values()) <= 1e-3
    # a wrong fixed value is honoured too: the fit moves the others and the cost shows it
    off = brdffit.fit(table, name, subsample=SUB, fixed={"alpha": 0.11}, throw=False)
    assert off.params["alpha"] == 0.11 and off.cost > 1e-4


def test_at_bound_reporting(merl_table):
    """A metal with no diffuse term: the diffuse albedo ends at (or within 2e-6 of) its lower
    bound, and a bound that excludes the optimum pins every channel there, reported as such."""
    name, label = "ggx", "bare-metal"
    truth = {"diffuse": [0.0, 0.0, 0.0], "f0": [0.9, 0.7, 0.5], "alpha": 0.05}
    table = merl_table(name, label, truth)
    res = brdffit.fit(table, name, subsample=SUB)
    assert res.success
    # The table's values carry ~1e-7 relative rounding: the optimum of a channel may sit just
    # inside the bound (measured: 0.9e-6 to 1.0e-6, the at-bound tolerance is 1e-6 of the range)
    assert np.all(np.asarray(res.params["diffuse"]) < 2e-6)
    assert set(res.at_bound) <= {f"diffuse[{i}]" for i in range(3)} | {"grazing"}
    assert res.at_bound.get("grazing", "upper") == "upper"
    assert res.params["grazing"] == pytest.approx(1.0, abs=1e-3)  # the table is plain Schlick
    for key in set(res.at_bound) - {"grazing"}:
        assert res.at_bound[key] == "lower" and np.isnan(res.stderr["diffuse"][int(key[-2])])
    assert abs(res.params["alpha"] / 0.05 - 1) < 1e-3
    # a user bound that excludes the optimum: every channel pinned at it
    pinned = brdffit.fit(table, name, subsample=SUB, bounds={"diffuse": (0.01, 1.0)})
    assert pinned.success
    assert {k: v for k, v in pinned.at_bound.items() if k != "grazing"} == {
        f"diffuse[{i}]": "lower" for i in range(3)}
    assert pinned.at_bound.get("grazing", "upper") == "upper"
    assert all(np.isnan(pinned.stderr["diffuse"]))
    # "at a bound": within 1e-6 of the range (transforms.AT_BOUND_TOL)
    np.testing.assert_allclose(pinned.params["diffuse"], 0.01, rtol=0, atol=1e-6)
    assert "at lower bound" in pinned.summary()
    # a user bound that excludes the truth: alpha pinned at the upper bound (the other scalars
    # then crawl towards a compromise; convergence is not what this checks)
    capped = brdffit.fit(table, name, subsample=SUB, bounds={"alpha": (0.001, 0.03)},
                         throw=False, max_steps=60)
    assert capped.at_bound.get("alpha") == "upper" and capped.params["alpha"] == pytest.approx(0.03)


def test_anisotropic_ggx_from_direction_pairs():
    """MERL tables are isotropic, so ggx-aniso is recovered from gonioreflectometer-style pairs:
    random directions plus pairs clustered around the mirror direction, from an anisotropic
    truth, fitted as a ``SampleSet``."""
    rng = np.random.default_rng(11)
    n = 20000
    wi = rng.normal(size=(n, 3))
    wi[:, 2] = np.abs(wi[:, 2]) + 0.2
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    mirror = wi * np.array([-1.0, -1.0, 1.0])
    wo = np.where(rng.random((n, 1)) < 0.5, mirror + 0.15 * rng.normal(size=(n, 3)),
                  rng.normal(size=(n, 3)))
    wo[:, 2] = np.abs(wo[:, 2]) + 0.05
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    truth = {"diffuse": [0.2, 0.15, 0.1], "f0": [0.6, 0.5, 0.4], "alpha_x": 0.05, "alpha_y": 0.25}
    model, f = _evaluator("ggx-aniso")
    rgb = np.asarray(f(model.unflatten(model.flatten(truth)), wi, wo))
    samples = SampleSet(wi, wo, rgb, np.ones(n, bool), name="aniso-pairs")
    res = brdffit.fit(samples, "ggx-aniso")
    errs = rel_errors(model, res, truth)
    assert res.success and max(errs.values()) <= 1e-3, res.summary()
