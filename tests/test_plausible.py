"""Fits that are materials: ``F90 ≥ F0`` by construction, and a plausibility verdict in every
result (:mod:`brdffit.fitting.plausibility`), shown in the summary, the JSON, ``to_dataframe``,
the batch table and a warning line of ``brdffit fit``.
"""

import json

import numpy as np
import pytest

import brdffit
import realistic
from brdffit.batch.table import frame, result_row
from brdffit.cli import main
from brdffit.fitting import LOSSES, plausibility
from brdffit.fitting.plausibility import assess, verdict_record
from brdffit.models.albedo import CHECK_ANGLES, CHECK_GRID, albedo

N_CELLS = 20_000
#: The registered models whose Schlick term has a free grazing reflectance.
GRAZING_MODELS = ("ggx", "beckmann", "gtr", "blinn-phong", "two-lobe-ggx", "ggx-aniso")
PLAUSIBLE = {"diffuse": [0.2, 0.15, 0.1], "f0": [0.04, 0.04, 0.04], "alpha": 0.2, "grazing": 1.0}


@pytest.fixture(scope="module")
def cells():
    return {name: realistic.merl_cells(name, N_CELLS) for name in realistic.names()}


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    """A noiseless ``ggx`` sample list of a plausible plastic (CSV, 1,200 pairs)."""
    from brdffit.cli.synth import synthesize_samples

    s = synthesize_samples(brdffit.get_model("ggx"), PLAUSIBLE, 1200, seed=5, name="plastic")
    path = tmp_path_factory.mktemp("plausible") / "plastic.csv"
    rows = np.column_stack([s.wi, s.wo, s.rgb])
    path.write_text("wix,wiy,wiz,wox,woy,woz,r,g,b\n" + "\n".join(
        ",".join(f"{v:.17g}" for v in row) for row in rows) + "\n")
    return path


def _checks(record) -> dict:
    return {c["name"]: c for c in record["checks"]}


# -- F90 ≥ F0 by construction ----------------------------------------------------------------------
@pytest.mark.parametrize("name", GRAZING_MODELS)
def test_every_value_the_bounds_allow_gives_f90_at_least_f0(name):
    """The grazing reflectance is ``F0 + (1 − F0) t``: over the whole box of ``f0`` and
    ``grazing`` it lies in ``[F0, 1]``, and the model's Schlick term at grazing incidence is it."""
    model = brdffit.get_model(name)
    rng = np.random.default_rng(1)
    for f0, t in zip(rng.uniform(0, 1, (200, 3)), rng.uniform(0, 1, 200)):
        f90 = model.derived_values({"f0": f0, "grazing": t})["f90"]
        assert np.all(f90 >= f0 - 1e-15) and np.all(f90 <= 1 + 1e-15)
    assert "f90" not in model.names and "grazing" in model.names


def test_f90_is_no_parameter_and_says_what_to_use_instead():
    with pytest.raises(brdffit.BrdffitError, match="'f90' is derived .* 'grazing' instead"):
        brdffit.get_model("ggx").param("f90")


@pytest.mark.parametrize("name", realistic.names())
def test_no_default_fit_of_a_real_material_ends_with_f90_below_f0(cells, name):
    """The embedded real materials: ``ggx`` and ``beckmann``, default options. With a free
    scalar ``F90`` on ``[0, 1]`` the grazing reflectance of brass, nickel, ss440 and the
    phenolic ended on 0, below ``F0``."""
    for model in ("ggx", "beckmann"):
        res = brdffit.fit(cells[name], model, throw=False)
        f90 = np.asarray(res.derived.get("f90", res.params.get("f90")), float)
        assert np.all(f90 >= np.asarray(res.params["f0"]) - 1e-12), (model, f90, res.params)
        assert _checks(res.plausibility)["f90"]["passed"] is True


# -- the verdict -----------------------------------------------------------------------------------
def test_the_verdict_passes_a_plausible_material_and_names_what_is_wrong_with_others():
    good = verdict_record(assess("ggx", PLAUSIBLE, {"rel_error": 0.2, "rmse_log": 0.01}))
    assert good["plausible"] and all(c["passed"] for c in good["checks"])
    assert [c["name"] for c in good["checks"]] == ["energy", "f90", "diffuse_bound",
                                                   "metal_dielectric", "error"]
    assert 0.2 < _checks(good)["energy"]["value"] < 1.0
    # white diffuse under a metal's F0: reflects more than it receives, on the bound, neither
    # metal nor dielectric, and off by a hundred times the data
    bad = verdict_record(assess("ggx", {"diffuse": [1.0, 1.0, 1.0], "f0": [0.9, 0.6, 0.3],
                                        "alpha": 0.05, "grazing": 1.0}, {"rel_error": 143.0}))
    assert not bad["plausible"]
    failed = {c["name"] for c in bad["checks"] if not c["passed"]}
    assert failed == {"energy", "diffuse_bound", "metal_dielectric", "error"}
    assert _checks(bad)["energy"]["value"] > 1.3
    assert "more light than it receives" in _checks(bad)["energy"]["meaning"]


def test_a_black_metal_is_flagged():
    """``gltf-pbr`` with metallic ≈ 1 and a base colour of 0.001: a dielectric fitted as a
    metal (issue's green acrylic)."""
    black = {"base_color": [0.001, 0.002, 0.001], "metallic": 0.98, "roughness": 0.2}
    checks = _checks(verdict_record(assess("gltf-pbr", black, {})))
    assert checks["dark_metal"]["passed"] is False
    gold = {"base_color": [1.0, 0.78, 0.34], "metallic": 1.0, "roughness": 0.3}
    assert _checks(verdict_record(assess("gltf-pbr", gold, {})))["dark_metal"]["passed"] is True


def test_a_gltf_dielectric_with_a_metals_ior_is_flagged():
    """``ior`` 5 (F0 0.44) on a mostly dielectric glTF material: the flat Fresnel curve of a
    metal read as a dielectric (the realistic brass and chrome-steel fits); a plastic's ior, or
    the same ior on a metal, passes."""
    base = {"base_color": [0.25, 0.12, 0.03], "roughness": 0.1, "specular": 0.03}
    bad = _checks(verdict_record(assess("gltf-pbr", {**base, "metallic": 0.23, "ior": 5.0}, {})))
    assert bad["metal_dielectric"]["passed"] is False
    assert bad["metal_dielectric"]["value"] == pytest.approx((4 / 6) ** 2)
    assert "ior 5" in bad["metal_dielectric"]["meaning"]
    for ok in ({**base, "metallic": 0.0, "ior": 1.6}, {**base, "metallic": 0.9, "ior": 5.0},
               {**base, "metallic": 0.0, "ior": 2.42}):
        assert _checks(verdict_record(assess("gltf-pbr", ok, {})))["metal_dielectric"]["passed"]


@pytest.mark.parametrize("alpha", [0.002, 0.02, 0.2, 0.5, 1.0])
def test_the_energy_checks_coarse_grid_agrees_with_the_figures_grid(alpha):
    """The check's 64 × 32 grid against the albedo figure's 64 × 128 (whose accuracy
    :mod:`brdffit.plots.albedo` states), a metal ``ggx`` lobe at every checked angle."""
    p = {"diffuse": 0.0, "f0": [1.0, 0.5, 0.1], "alpha": alpha, "grazing": 1.0}
    coarse = albedo("ggx", p, CHECK_ANGLES, n_u=CHECK_GRID[0], n_phi=CHECK_GRID[1])
    fine = albedo("ggx", p, CHECK_ANGLES)
    np.testing.assert_allclose(coarse, fine, atol=1e-3)
    assert np.all(fine <= 1.0 + 1e-3)  # a single-scattering lobe loses energy, never gains it


def test_converged_but_implausible_is_in_the_result_summary_json_and_dataframe(samples):
    """A Lambertian albedo held at 1 on a plastic: the fit converges, and every output says
    the material is implausible."""
    res = brdffit.fit(str(samples), "ggx", fixed={"diffuse": 1.0}, energy="free")
    assert res.success and res.plausible is False
    assert {"energy", "diffuse_bound"} <= set(res.to_dataframe().attrs["implausible"])
    text = res.summary()
    assert "plausibility: IMPLAUSIBLE material" in text and "diffuse_bound:" in text
    assert "f90 = (" in text and "(derived from the parameters)" in text
    assert "[[Plausibility]]" in res.report() and "IMPLAUSIBLE" in res._repr_html_()
    d = json.loads(res.to_json())
    assert d["plausibility"]["plausible"] is False and len(d["derived"]["f90"]) == 3
    back = brdffit.FitResult.from_json(res.to_json())
    assert back.plausibility == res.plausibility and back.derived == res.derived


def test_a_plausible_fit_says_so_everywhere(samples):
    res = brdffit.fit(str(samples), "ggx")
    assert res.success and res.plausible is True, res.plausibility
    assert "plausibility: plausible (energy, f90, diffuse_bound" in res.summary()
    df = res.to_dataframe()
    assert df.attrs == {"plausible": True, "implausible": []}
    np.testing.assert_allclose(df.loc[["f90[0]", "f90[1]", "f90[2]"], "value"], 1.0, atol=1e-6)
    assert set(df.loc[["f90[0]", "f90[1]", "f90[2]"], "status"]) == {"derived"}
    row = result_row(res)
    assert row["plausible"] is True and row["implausible"] == "" and 0 < row["albedo_max"] < 1
    table = frame([{"material": "plastic", "model": "ggx", "skipped": False, **row}])
    for column in ("plausible", "implausible", "albedo_max", "p_grazing", "se_grazing",
                   "p_f90[0]", "p_f90[2]"):
        assert column in table.columns, column


def test_a_result_file_from_before_the_verdict_still_reads(samples):
    res = brdffit.fit(str(samples), "ggx")
    d = json.loads(res.to_json())
    del d["plausibility"], d["derived"]
    old = brdffit.FitResult.from_dict(d)
    assert old.plausibility == {} and old.plausible is None
    assert "plausibility: not assessed" in old.summary()
    with pytest.raises(ValueError, match="needs 'plausible' and 'checks'"):
        brdffit.FitResult.from_dict({**d, "plausibility": {"checks": []}})


def test_the_command_line_warns_and_keeps_exit_0(samples, capsys, tmp_path):
    out = tmp_path / "r.json"
    code = main(["fit", str(samples), "--model", "ggx", "--fix", "diffuse=1", "--energy", "free",
                 "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0
    lines = [line for line in captured.err.splitlines() if "implausible material" in line]
    assert len(lines) == 1 and lines[0].startswith("brdffit fit: warning: the ggx fit of plastic")
    assert "diffuse_bound (diffuse at 1" in lines[0] and "energy (" in lines[0]
    assert "IMPLAUSIBLE" in captured.out
    assert json.loads(out.read_text())["plausibility"]["plausible"] is False
    assert main(["fit", str(samples), "--model", "ggx"]) == 0
    assert "implausible" not in capsys.readouterr().err


def test_the_cosine_loss_on_a_polished_metal_is_loudly_implausible(cells):
    """Ngan 2005's protocol (``configs/ngan2005.toml``: cosine loss, 80° cutoff) on ss440: the
    peak's absolute residuals outweigh the diffuse signal, the diffuse albedo ends on 1 and
    the fit is off by tens of times the data, yet it converges. The verdict names all three
    and the cause; the ``log`` loss gives a plausible material on the same cells."""
    from brdffit.config import load_config

    preset = load_config(realistic.DATA.parent.parent / "configs" / "ngan2005.toml")
    res = brdffit.fit(cells["ss440"], "ggx", loss=preset.loss, cutoff=preset.cutoff,
                      energy="free")
    assert res.success and res.plausible is False
    checks = _checks(res.plausibility)
    assert {n for n, c in checks.items() if c["passed"] is False} == {
        "energy", "diffuse_bound", "error"}
    assert f"with the {preset.loss} loss (absolute errors)" in checks["diffuse_bound"]["meaning"]
    assert "fit with the log loss" in checks["diffuse_bound"]["meaning"]
    log = brdffit.fit(cells["ss440"], "ggx", cutoff=preset.cutoff)
    assert log.success and log.plausible is True, log.plausibility
    held = brdffit.fit(cells["ss440"], "ggx", loss=preset.loss, cutoff=preset.cutoff)
    assert held.success and _checks(held.plausibility)["energy"]["passed"] is True
    assert "energy held: the unconstrained optimum's directional albedo was 1.06" in held.message


@pytest.mark.parametrize("name", sorted(LOSSES))
def test_a_white_diffuse_names_the_absolute_losses_as_its_cause(name):
    """A diffuse term on its bound 1 blames the loss where the loss weighs absolute errors (its
    registry entry says so, :attr:`Loss.absolute`), for the plain and the robust variant."""
    for label in (name, f"{name}+huber(0.1)"):
        check = plausibility.white_diffuse({"diffuse": np.ones(3)}, label)
        assert check["passed"] is False
        assert ("absolute errors" in check["meaning"]) == LOSSES[name].absolute, label
    assert LOSSES["log"].absolute is False and LOSSES["relative"].absolute is False
    assert LOSSES["cosine-in"].absolute and LOSSES["linear"].absolute
