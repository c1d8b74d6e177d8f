"""RGL ``.bsdf`` materials as a first-class input: fitted, described, drawn, batched, written.

The files are virtual measurements of registered models (:func:`brdffit.cli.synth.
synthesize_material`, small tables so that each fit compiles and runs in seconds). The input
formats are tested over their one registry, :data:`brdffit.io.READERS`: a new format that lacks
a reader, a help text or an error mapping fails here.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit.cli import main
from brdffit.io import READERS, InputFormatError, read_path
from test_hostile import _one_line_error

ROOT = Path(__file__).resolve().parent.parent
#: Small tables: 6 θi slices (9 φi slices when anisotropic), 12 x 12 nodes per slice.
SMALL = dict(resolution=12, n_theta_i=6, n_phi_i=9, vndf_shape=(16, 16))
ISO = {"diffuse": [0.1, 0.2, 0.3], "f0": [0.8, 0.6, 0.4], "alpha": 0.15}
#: A brushed lobe whose axes are turned 30° from the file's x axis.
ANISO = {"diffuse": [0.1, 0.1, 0.1], "f0": [0.8, 0.6, 0.4], "alpha_x": 0.08, "alpha_y": 0.3,
         "frame_angle": float(np.radians(30.0))}


def _write(path, model, truth, **sizes):
    from data_formats.rgl import write_rgl

    from brdffit.cli.synth import synthesize_material

    material = synthesize_material(brdffit.get_model(model), truth, name=path.stem,
                                   **{**SMALL, **sizes})
    write_rgl(path, material)
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    import jax

    folder = tmp_path_factory.mktemp("rgl")
    with jax.enable_x64(True):
        return {"iso": _write(folder / "iso.bsdf", "ggx", ISO),
                "aniso": _write(folder / "brushed.bsdf", "ggx-aniso", ANISO)}


def _assert_params(params, truth, rtol):
    for name, value in truth.items():
        np.testing.assert_allclose(params[name], value, rtol=rtol, atol=1e-6, err_msg=name)


# -- one registry of input formats ---------------------------------------------------------------
@pytest.mark.parametrize("command", ["fit", "info", "plot", "batch", "synth"])
def test_every_registered_format_is_in_every_help_text(command, capsys):
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for suffix in READERS:
        assert suffix in text, (command, suffix)


@pytest.mark.parametrize("suffix", list(READERS))
def test_each_format_is_read_by_its_own_reader(suffix, tmp_path):
    """A malformed file of each suffix reaches its reader (the format's own error, not an
    unknown format), and a batch takes it as an input, not as a list of paths."""
    from brdffit.batch import inputs

    bad = tmp_path / f"bad{suffix}"
    bad.write_bytes(b"\x00\x01 not a measurement \xff" * 3)
    with pytest.raises(Exception) as caught:
        read_path(bad)
    assert not isinstance(caught.value, InputFormatError), caught.value
    empty = tmp_path / f"empty{suffix}"
    empty.write_bytes(b"")
    assert inputs.expand([str(empty)]) == [str(empty)]


@pytest.mark.parametrize("command", ["info", "fit", "plot"])
@pytest.mark.parametrize("suffix", list(READERS))
def test_malformed_file_of_each_format_is_one_line_exit_2(suffix, command, tmp_path, capsys):
    bad = tmp_path / f"bad{suffix}"
    bad.write_bytes(b"\x00\x01 not a measurement \xff" * 3)
    extra = {"fit": ["-m", "ggx"], "plot": ["-o", str(tmp_path / "f.png")]}.get(command, [])
    assert main([command, str(bad), *extra]) == 2
    _one_line_error(capsys.readouterr().err, str(bad))
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]


def test_unknown_suffix_message_lists_every_format(tmp_path):
    with pytest.raises(InputFormatError) as caught:
        read_path(tmp_path / "x.txt")
    for suffix, (kind, _, _) in READERS.items():
        assert f"{suffix} ({kind})" in str(caught.value)


@pytest.mark.parametrize("how", ["truncated", "absurd shape", "empty"])
def test_hostile_bsdf_through_the_cli_is_one_line_exit_2(files, tmp_path, capsys, how):
    raw = files["aniso"].read_bytes()
    bad = tmp_path / "hostile.bsdf"
    if how == "truncated":
        bad.write_bytes(raw[: len(raw) // 3])
    elif how == "absurd shape":  # every uint64 that reads as a dimension of 12 becomes 2^40
        bad.write_bytes(raw.replace(np.uint64(12).tobytes(), np.uint64(1 << 40).tobytes()))
    else:
        bad.write_bytes(b"")
    out = tmp_path / "r.json"
    assert main(["fit", str(bad), "-m", "ggx-aniso", "--out", str(out)]) == 2
    _one_line_error(capsys.readouterr().err, str(bad))
    assert not out.exists()


# -- fitting -------------------------------------------------------------------------------------
def test_isotropic_ggx_recovered_through_the_api(files):
    res = brdffit.fit(str(files["iso"]), "ggx")
    assert res.success, res.summary()
    _assert_params(res.params, ISO, 1e-4)
    assert res.provenance["input"]["path"].endswith("iso.bsdf")


def test_turned_anisotropic_ggx_recovered_through_the_api(files):
    """The lobe's axes are 30° from the file's x axis: the start reads them off the data and
    the fit ends on the truth, the angle included."""
    res = brdffit.fit(files["aniso"], "ggx-aniso")
    assert res.success, res.summary()
    _assert_params(res.params, ANISO, 1e-4)


def test_an_isotropic_lobe_in_an_anisotropic_file_fits_ggx_aniso(tmp_path):
    """With ``α_x = α_y`` the frame angle does nothing: the fit ends on the widths and colours,
    calls ``frame_angle`` not identified and succeeds. The optimality test over every scalar
    failed along that direction alone (``ω`` 1.4e-5 at a cost of 5e-13: the model step
    ``g²/(2 JᵀJ)`` of two vanishing numbers), and the fit was called stalled."""
    import jax

    truth = {**ISO, "alpha_x": 0.15, "alpha_y": 0.15, "frame_angle": 0.0}
    del truth["alpha"]
    with jax.enable_x64(True):
        path = _write(tmp_path / "iso-in-aniso.bsdf", "ggx-aniso", truth)
    res = brdffit.fit(path, "ggx-aniso", throw=False)
    assert res.success and res.status == "successful", res.summary()
    assert res.not_identified == ["frame_angle"] and np.isnan(res.stderr["frame_angle"])
    assert "identify" in res.message and res.optimality > 1e-9  # says why, keeps the figure
    del truth["frame_angle"]
    _assert_params(res.params, truth, 1e-4)


def test_turned_anisotropic_ggx_recovered_through_the_cli(files, tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(files["aniso"]), "-m", "ggx-aniso", "--out", str(out), "-q"]) == 0
    assert "frame_angle" in capsys.readouterr().out
    saved = brdffit.FitResult.from_json(out)
    _assert_params(saved.params, ANISO, 1e-4)


@pytest.mark.parametrize("turn_deg", [30.0, -60.0, 80.0])
def test_start_reads_widths_and_axes_off_the_data(turn_deg):
    """The start's anisotropy: the widths and the axis of α_x, in the labelling with
    |φ_t| ≤ 45° (a turn of -60° is the same lobe as +30° with the widths swapped)."""
    from brdffit.fitting.start import measure
    from brdffit.models.evaluate import evaluate_model

    from data_formats.rgl import synthesize_rgl  # noqa: F401  (the pattern comes from a file)
    from brdffit.cli.synth import synthesize_material

    truth = {**ANISO, "frame_angle": float(np.radians(turn_deg))}
    model = brdffit.get_model("ggx-aniso")
    s = synthesize_material(model, truth, **SMALL).to_samples()
    rgb = evaluate_model(model, truth, s.wi, s.wo)
    feat = measure(rgb, s.wi, s.wo, np.asarray(s.valid, bool))
    turn = (turn_deg + 45.0) % 90.0 - 45.0
    swapped = abs(((turn_deg - turn) / 90.0) % 2) == 1
    ax, ay = (0.3, 0.08) if swapped else (0.08, 0.3)
    assert np.degrees(feat.frame_angle) == pytest.approx(turn, abs=2.0)
    assert feat.alpha_x == pytest.approx(ax, rel=0.15) and feat.alpha_y == pytest.approx(ay, rel=0.15)


def test_start_reads_the_axes_of_an_aps_gaussian_lobe():
    """The same reading starts ``aps-gaussian`` (its hook maps the GGX widths to σ): the
    axes of a lobe turned by 30°, the widths within the solver's reach."""
    from brdffit.cli.synth import synthesize_material
    from brdffit.fitting.start import guess, measure
    from brdffit.models.evaluate import evaluate_model

    s = synthesize_material(brdffit.get_model("ggx-aniso"), ANISO, **SMALL).to_samples()
    truth = {"diffuse": [0.1] * 3, "f0": [0.8, 0.6, 0.4], "sigma_x": 0.12, "sigma_y": 0.4,
             "frame_angle": float(np.radians(30.0))}
    rgb = evaluate_model("aps-gaussian", truth, s.wi, s.wo)
    start = guess(brdffit.get_model("aps-gaussian"),
                  measure(rgb, s.wi, s.wo, np.asarray(s.valid, bool)))
    assert np.degrees(start["frame_angle"]) == pytest.approx(30.0, abs=3.0)
    for name in ("sigma_x", "sigma_y"):
        assert 1 / 1.6 < start[name] / truth[name] < 1.6, (name, start[name])


@pytest.mark.parametrize("turn_deg", [0.0, 30.0])
def test_models_without_a_frame_start_from_the_widths_along_the_files_axes(turn_deg):
    """A model whose tangent is the file's x (Mitsuba's anisotropic rough conductor, Disney)
    starts from the lobe's widths along the file's axes, not from one isotropic width: the
    widths of a lobe along its own axes at 0°, the diagonal of the turned slope covariance at
    30°."""
    from brdffit.cli.synth import synthesize_material
    from brdffit.fitting.start import guess, measure
    from brdffit.models.evaluate import evaluate_model

    truth = {**ANISO, "alpha_x": 0.3, "alpha_y": 0.08, "frame_angle": float(np.radians(turn_deg))}
    s = synthesize_material(brdffit.get_model("ggx-aniso"), truth, **SMALL).to_samples()
    rgb = evaluate_model("ggx-aniso", truth, s.wi, s.wo)
    feat = measure(rgb, s.wi, s.wo, np.asarray(s.valid, bool))
    c, si = np.cos(truth["frame_angle"]), np.sin(truth["frame_angle"])
    wx = np.sqrt(c * c * 0.3 ** 2 + si * si * 0.08 ** 2)
    wy = np.sqrt(si * si * 0.3 ** 2 + c * c * 0.08 ** 2)
    conductor = guess(brdffit.get_model("mitsuba-roughconductor-aniso"), feat)
    assert conductor["alpha_u"] == pytest.approx(wx, rel=0.2)
    assert conductor["alpha_v"] == pytest.approx(wy, rel=0.2)
    disney = guess(brdffit.get_model("disney"), feat)
    aspect2 = 1.0 - 0.9 * disney["anisotropic"]  # α_y/α_x of Disney's lobe
    assert aspect2 == pytest.approx(wy / wx, rel=0.25) and disney["anisotropic"] > 0.3
    assert disney["roughness"] ** 2 == pytest.approx(np.sqrt(wx * wy), rel=0.2)


def _pairs_in_a_plane(n: int):
    """``(wi, wo)`` above the horizon at ``n`` random Rusinkiewicz angles with ``φh = 0``, as a
    MERL table lays them out: every half vector in the x–z plane."""
    from data_formats.rusinkiewicz import dirs_from_half_diff

    rng = np.random.default_rng(3)
    th, td, pd = (rng.uniform(0, 1.4, n) ** 2, rng.uniform(0, 1.5, n),
                  rng.uniform(0, np.pi, n))
    wi, wo = (np.asarray(w, float) for w in dirs_from_half_diff(th, td, pd))
    keep = (wi[:, 2] > 0.05) & (wo[:, 2] > 0.05)
    return wi[keep], wo[keep]


def test_half_vectors_in_one_plane_read_as_isotropic():
    """A MERL table's half vectors all lie in the x–z plane: the anisotropy is not determined,
    and the start keeps one width and the file's frame."""
    from brdffit.fitting.start import anisotropy, measure
    from brdffit.models.evaluate import evaluate_model

    wi, wo = _pairs_in_a_plane(4000)
    rgb = evaluate_model("ggx", ISO, wi, wo)
    excess = (rgb - 0.1 / np.pi).mean(axis=1)
    assert anisotropy(excess, wi, wo, float(excess.max())) is None
    feat = measure(rgb, wi, wo, np.ones(len(wi), bool))
    assert feat.alpha_x == feat.alpha_y == feat.alpha and feat.frame_angle == 0.0
    assert not feat.axes and feat.isotropic


def test_on_half_vectors_in_one_plane_the_frame_angle_is_held_at_zero():
    """Such a table samples one azimuth of the half vector: an anisotropic model's
    ``frame_angle`` is held at 0 (the tangent on the data's x), listed as fixed and said in
    the message; a start or a fixed value the user gives for it is kept."""
    from data_formats import SampleSet

    from brdffit.models.evaluate import evaluate_model

    wi, wo = _pairs_in_a_plane(3000)
    truth = {**ANISO, "frame_angle": 0.0}
    table = SampleSet(wi, wo, evaluate_model("ggx-aniso", truth, wi, wo),
                      np.ones(len(wi), bool), name="plane")
    res = brdffit.fit(table, "ggx-aniso", throw=False)
    assert "frame_angle" in res.fixed and res.params["frame_angle"] == 0.0
    assert "frame_angle held at 0" in res.message
    started = brdffit.fit(table, "ggx-aniso", throw=False, init={"frame_angle": 0.2})
    assert "frame_angle" in started.free and "held" not in started.message


@pytest.mark.parametrize("name,widths", [
    ("ggx-aniso", {"alpha_x": 0.08, "alpha_y": 0.3}),
    ("aps-gaussian", {"sigma_x": 0.12, "sigma_y": 0.4}),
    ("aps-satin", {"sigma_flats": 0.12, "sigma_ends": 0.35}),
    ("aps-vgroove", {"tilt": 0.3, "sigma": 0.1}),
])
def test_frame_angle_turns_the_lobe(name, widths):
    """An anisotropic model at ``frame_angle`` φ is the unturned lobe seen in a frame turned by
    φ, and a lobe with equal widths does not depend on it (a satin's and a V-groove's
    parameters never make them isotropic)."""
    from brdffit.models.evaluate import evaluate_model

    rng = np.random.default_rng(0)
    wi, wo = (rng.normal(size=(64, 3)) for _ in range(2))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    wi, wo = (w / np.linalg.norm(w, axis=1, keepdims=True) for w in (wi, wo))
    phi = 0.7
    c, s = np.cos(phi), np.sin(phi)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])  # the frame's tangent at azimuth φ
    base = {"diffuse": [0.1, 0.1, 0.1], "f0": [0.8, 0.6, 0.4], **widths}
    np.testing.assert_allclose(
        evaluate_model(name, {**base, "frame_angle": phi}, wi @ turn.T, wo @ turn.T),
        evaluate_model(name, {**base, "frame_angle": 0.0}, wi, wo), rtol=1e-9)
    if name in ("aps-satin", "aps-vgroove"):
        return
    first, second = list(widths)
    iso = {**base, second: widths[first]}
    np.testing.assert_allclose(evaluate_model(name, {**iso, "frame_angle": phi}, wi, wo),
                               evaluate_model(name, iso, wi, wo), rtol=1e-6)


#: A satin and V-grooves, each turned by -70° from the file's x axis in the tests below.
TURNED_APS = {
    "aps-satin": {"diffuse": [0.1] * 3, "f0": [0.6, 0.5, 0.4], "sigma_flats": 0.12,
                  "sigma_ends": 0.35, "w_flats": 0.7},
    "aps-vgroove": {"diffuse": [0.1] * 3, "f0": [0.6, 0.5, 0.4], "tilt": 0.3, "sigma": 0.1},
}


@pytest.mark.parametrize("name", list(TURNED_APS))
def test_a_turned_satin_and_v_grooves_are_recovered(name, tmp_path, few_programs_held):
    """The start puts the satin's tangent on the lobe's narrow axis (its fibres' slopes spread
    along x only) and the grooves' on the wide one (they split the lobe along x), a quarter
    turn from the features' own labelling here; the fit then ends on the truth, the turn
    included."""
    import jax

    from brdffit.fitting.start import guess, measure

    truth = {**TURNED_APS[name], "frame_angle": float(np.radians(-70.0))}
    with jax.enable_x64(True):
        path = _write(tmp_path / f"{name}.bsdf", name, truth)
    s = read_path(path).to_samples()  # the file's own values: what the fit's start reads
    feat = measure(s.rgb, s.wi, s.wo, np.asarray(s.valid, bool))
    start = guess(brdffit.get_model(name), feat)
    assert np.degrees(feat.frame_angle) == pytest.approx(20.0, abs=2.0)  # the other labelling
    assert np.degrees(start["frame_angle"]) == pytest.approx(-70.0, abs=2.0)
    res = brdffit.fit(path, name, throw=False)
    assert res.success, res.summary()
    _assert_params(res.params, truth, 1e-4)


# -- info, plot, synth, batch ------------------------------------------------------------------
def test_info_describes_the_material(files, capsys):
    assert main(["info", str(files["aniso"])]) == 0
    text = capsys.readouterr().out
    assert text.startswith("RGL material 'brushed' (")
    assert "anisotropic" in text and "6 theta_i slices" in text and "9 phi_i slices" in text
    assert "reflectance 12x12 per slice" in text and "3 (RGB)" in text
    assert "synthesized virtual measurement brushed" in text and "direction pairs" in text
    assert main(["info", str(files["iso"]), "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["format"] == "RGL material" and figures["isotropic"] is True
    assert figures["phi_i_slices"] == 1 and figures["table_resolution"] == [12, 12]
    assert figures["channels"] == "rgb" and figures["samples_read"]["valid"] > 0


def test_plot_draws_the_polar_lobe_for_a_material(files, tmp_path, capsys):
    result = tmp_path / "fit.json"
    brdffit.fit(files["aniso"], "ggx-aniso").to_json(result)
    out = tmp_path / "fig.png"
    assert main(["plot", str(files["aniso"]), "--fit", str(result), "-o", str(out), "-q"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["fig-albedo.png", "fig-peaks.png", "fig-polar.png", "fig-slice.png",
                     "fig-spheres.png", "fit.json"]
    assert (tmp_path / "fig-polar.png").stat().st_size > 10_000


def test_polar_lobe_shows_the_turn(files):
    """The measured lobe at normal incidence is longest along the bitangent of the turned frame
    (α_y is the wider width): azimuth 30° + 90°."""
    from data_formats.rgl import read_rgl

    from brdffit.plots import lobe_maps

    phi_e, th_e, meas, fit = lobe_maps(read_rgl(files["aniso"]), "ggx-aniso", ANISO, (0.0,))
    assert fit is not None and meas.shape == fit.shape
    ring = np.nanargmin(np.abs(0.5 * (th_e[1:] + th_e[:-1]) - 10.0))  # θo ≈ 10°
    phi_c = np.degrees(0.5 * (phi_e[1:] + phi_e[:-1]))
    brightest = phi_c[np.nanargmax(meas[0, ring])] % 180.0
    assert brightest == pytest.approx(120.0, abs=5.0)
    np.testing.assert_allclose(fit[0, ring], meas[0, ring], rtol=0.1)


def test_figure_names_add_the_polar_view_for_self_evaluating_inputs(files):
    from data_formats.rgl import read_rgl

    from brdffit.plots import figure_names

    assert figure_names("x.bsdf")[-1] == "polar" and figure_names(read_rgl(files["iso"]))[-1] == "polar"
    assert "polar" not in figure_names("x.binary") + figure_names("x.csv")


def test_synth_writes_a_virtual_measurement_of_any_model(tmp_path, capsys):
    from data_formats.rgl import read_rgl

    from brdffit.models.evaluate import evaluate_model

    out = tmp_path / "m.bsdf"
    assert main(["synth", "--model", "ggx-aniso", "--param", "alpha_x=0.1", "--param",
                 "alpha_y=0.25", "--param", "frame_angle=0.4", "-o", str(out)]) == 0
    material = read_rgl(out)
    assert not material.isotropic and material.name == "m"
    rng = np.random.default_rng(1)
    t, p = rng.uniform(0, 1.2, (2, 200)), rng.uniform(0, 2 * np.pi, (2, 200))
    wi, wo = (np.stack([np.sin(t[k]) * np.cos(p[k]), np.sin(t[k]) * np.sin(p[k]), np.cos(t[k])],
                       axis=-1) for k in range(2))
    truth = evaluate_model("ggx-aniso", {"alpha_x": 0.1, "alpha_y": 0.25, "frame_angle": 0.4},
                           wi, wo)
    got = material.eval(wi, wo)
    # agreement in the median (interpolation error is largest in the sharp peak)
    assert np.median(np.abs(got - truth) / truth) < 0.05
    assert main(["synth", "--model", "ggx", "-o", str(tmp_path / "m.txt")]) == 2
    _one_line_error(capsys.readouterr().err, ".bsdf")


def test_batch_fits_a_material(files, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    run = subprocess.run([sys.executable, str(ROOT / "cli.py"), "batch", str(files["iso"]),
                          "--model", "ggx", "--outdir", str(tmp_path / "out"), "--workers", "1"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    import pandas as pd

    table = pd.read_csv(tmp_path / "out" / "results.csv")
    assert table["material"].tolist() == ["iso"] and table["success"].all()
    np.testing.assert_allclose(table["p_alpha"], ISO["alpha"], rtol=1e-4)


def test_synth_renders_a_fit_result_as_a_material(files, tmp_path, capsys):
    """``synth --fit RESULT.json``: the fitted model and its parameters, written as a .bsdf
    (with synth's own table sizes) that evaluates as the model."""
    from data_formats.rgl import read_rgl

    from brdffit.models.evaluate import evaluate_model

    result = tmp_path / "fit.json"
    brdffit.fit(files["iso"], "ggx").to_json(result)
    out = tmp_path / "refit.bsdf"
    assert main(["synth", "--fit", str(result), "-o", str(out)]) == 0
    assert "ggx: diffuse=(0.1, 0.2, 0.3)" in capsys.readouterr().out
    s = read_rgl(files["iso"]).to_samples()
    ok = np.asarray(s.valid, bool)
    wi, wo = s.wi[ok], s.wo[ok]
    got, truth = read_rgl(out).eval(wi, wo), evaluate_model("ggx", ISO, wi, wo)
    assert np.median(np.abs(got - truth) / truth) < 0.02
    assert main(["synth", "-o", str(tmp_path / "x.bsdf")]) == 2
    _one_line_error(capsys.readouterr().err, "--model", "--fit")


def test_synth_writes_every_registered_format():
    from brdffit.cli.synth import WRITERS
    from brdffit.io import INPUT_SUFFIXES

    assert set(WRITERS) == set(INPUT_SUFFIXES.values())


def test_slice_of_a_material_is_evaluated_not_binned(files):
    """A material evaluates itself, so its image slice has no holes (the file's pattern is
    sparse at φd = 90°: binned, most cells would be empty)."""
    from data_formats.rgl import read_rgl

    from brdffit.plots import slice_data

    meas, valid, fit = slice_data(read_rgl(files["aniso"]), "ggx-aniso", ANISO)
    assert valid.mean() > 0.95 and fit.shape == meas.shape
    # the truth against the file between its nodes: the 12 x 12 tables' interpolation error
    assert np.median(np.abs(np.log(fit[valid].sum(-1) / meas[valid].sum(-1)))) < 0.15
