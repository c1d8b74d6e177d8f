"""The leaderboard (``brdffit.compare``, ``brdffit compare``, ``brdffit batch --compare``), the
literature's metrics and losses, and published fits read as results.

The published forms of the literature's models are registered by their own modules; here a
test-only form (``TestGGX`` → ``ggx``) stands for them, so that these tests do not depend on
which of the literature's models are registered.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import brdffit
from brdffit.cli import main
from brdffit.metrics import LITERATURE_METRICS, literature_values, solid_angle_weight

SHAPE = (16, 16, 32)
TRUTH = {"diffuse": [0.1, 0.06, 0.02], "f0": [0.9, 0.6, 0.3], "alpha": 0.12, "grazing": 1.0}
#: A published line of the test-only class: off the truth (roughness 0.2), so a fit beats it.
LINE = ("{name} = Aggregate(Lambertian(albedo = [0.1, 0.06, 0.02]), "
        "TestGGX(ks = [0.9, 0.6, 0.3], roughness = {alpha}))")


@pytest.fixture
def test_form(monkeypatch):
    """A published form for the bbm class ``TestGGX``: ``ggx`` with the albedo as its diffuse
    colour, ``ks`` as ``f0`` and ``roughness`` as ``alpha``."""
    from brdffit.models import published as pub

    form = pub.PublishedForm(
        "TestGGX", "ggx", lambda fit: {"diffuse": fit.albedo, "f0": fit.params["ks"],
                                       "alpha": fit.params["roughness"], "grazing": 1.0},
        study="Test 2099")
    monkeypatch.setitem(pub._FORMS, "TestGGX", form)
    return form


def _synth(path: Path, model="ggx", params=TRUTH) -> Path:
    from data_formats.merl import synthesize, write_merl

    from brdffit.models.evaluate import evaluate_model

    import jax

    with jax.enable_x64(True):
        table = synthesize(lambda wi, wo: np.asarray(evaluate_model(model, params, wi, wo)),
                           name=path.stem, shape=SHAPE)
    write_merl(path, table)
    return path


@pytest.fixture(scope="module")
def shiny(tmp_path_factory) -> Path:
    return _synth(tmp_path_factory.mktemp("compare") / "shiny.binary")


@pytest.fixture
def fits_dir(tmp_path) -> Path:
    """A folder of published fits: ``test_ggx_E2.fit`` (shiny and another material) and a file
    of a class no model stands for."""
    folder = tmp_path / "fits"
    folder.mkdir()
    (folder / "test_ggx_E2.fit").write_text(
        "# a test-only published file\n" + LINE.format(name="shiny", alpha=0.2) + "\n"
        + LINE.format(name="other", alpha=0.3) + "\n")
    (folder / "unknown_model.fit").write_text(
        "shiny = Aggregate(Lambertian(albedo = [0.1, 0.1, 0.1]), NoSuchModel(x = 1.0))\n")
    return folder


# -- the metrics, against a plain NumPy transcription -------------------------------------------

def _numpy_metrics(f, m, wi, wo, weight):
    """The literature's metrics written out from their definitions, with the angles from
    :func:`data_formats.rusinkiewicz.half_diff_from_dirs` (independent of brdffit.metrics)."""
    from data_formats.rusinkiewicz import half_diff_from_dirs

    th, td, _ = half_diff_from_dirs(wi, wo)
    omega = np.sin(th) * np.sin(td) * np.cos(td) * weight
    ci = wi[:, 2]
    inside = (np.degrees(np.arccos(wi[:, 2])) <= 80) & (np.degrees(np.arccos(wo[:, 2])) <= 80)
    peak = inside & (np.degrees(th) <= 2.0)
    out = {}
    for suffix, w in (("", np.ones(len(f))), ("_sa", omega)):
        def mean(per_cell, keep):
            return np.sum(w[keep] * per_cell[keep]) / np.sum(w[keep])
        every = np.ones(len(f), bool)
        logsq = ((np.log(1 + f * ci[:, None]) - np.log(1 + m * ci[:, None])) ** 2).mean(1)
        cossq = (((f - m) * ci[:, None]) ** 2).mean(1)
        rel = (np.abs(f - m) / np.maximum(m, 1e-3)).mean(1)
        out["log_rms" + suffix] = math.sqrt(mean(logsq, every))
        out["log_rms_80" + suffix] = math.sqrt(mean(logsq, inside))
        out["cos_rms" + suffix] = math.sqrt(mean(cossq, every))
        out["ngan_rms_80" + suffix] = math.sqrt(mean(cossq, inside))
        out["peak_rel" + suffix] = mean(rel, peak)
    return out


def test_literature_metrics_match_numpy():
    rng = np.random.default_rng(1)
    n = 4000
    th = np.concatenate([rng.uniform(0, np.radians(3), n // 2), rng.uniform(0, np.pi / 2, n // 2)])
    ph = rng.uniform(0, 2 * np.pi, n)
    wi = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    wo = wi * [-1, -1, 1] + rng.normal(0, 0.02, (n, 3))
    wo /= np.linalg.norm(wo, axis=1)[:, None]
    keep = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    wi, wo = wi[keep], wo[keep]
    m = rng.lognormal(0, 2, (len(wi), 3))
    f = m * rng.lognormal(0, 0.3, m.shape)
    weight = rng.uniform(0.5, 2, len(wi))
    got = literature_values(f, m, wi, wo, weight)
    want = _numpy_metrics(f, m, wi, wo, weight)
    assert set(got) == set(LITERATURE_METRICS) == set(want)
    for name in LITERATURE_METRICS:
        assert got[name] == pytest.approx(want[name], rel=1e-10), name
    assert literature_values(m, m, wi, wo)["log_rms_sa"] == 0.0


def test_solid_angle_weights_integrate_to_the_pairs_of_directions():
    """Over the MERL grid, Σ (solid-angle weight × cell volume in (θh, θd, φd)) × 4 × 2π (φh)
    × 2 (φd folded) is the measure of all pairs of directions above the horizon, (2π)²."""
    from data_formats.merl import MERL_SHAPE, MERLTable

    s = MERLTable.from_rgb(np.zeros(MERL_SHAPE + (3,))).to_samples()
    ok = s.valid
    w = solid_angle_weight(s.wi[ok], s.wo[ok], s.weight[ok])
    n_th, n_td, n_pd = MERL_SHAPE
    volume = (np.pi / 2 / n_th) * (np.pi / 2 / n_td) * (np.pi / n_pd)
    assert np.sum(w) * volume * 4 * 2 * np.pi * 2 == pytest.approx((2 * np.pi) ** 2, rel=0.02)


def test_cosine_in_loss_and_solid_angle_weighting_recover_the_truth(shiny):
    # energy="free": the truth (plain Schlick beside a diffuse term) reflects 1.002 at 89°
    r = brdffit.fit(shiny, "ggx", loss="cosine-in", weighting="solid-angle", cutoff=80,
                    energy="free")
    assert r.success and r.loss == "cosine-in"
    assert r.params["alpha"] == pytest.approx(0.12, rel=1e-6)
    assert r.provenance["options"]["weighting"] == "solid-angle"


def test_the_default_fit_uses_the_cells_within_80_degrees(shiny):
    """The default cells (``brdffit.config.DEFAULT_CUTOFF``): θi, θo ≤ 80°, where a fit is best
    in the metrics over those angles (``benchmarks/bench_compare.py``); ``cutoff=None`` given
    explicitly, or 90, keeps every cell above the horizon."""
    from brdffit.io import read_path

    s = read_path(shiny).to_samples()
    inside = s.valid & (np.minimum(s.wi[:, 2], s.wo[:, 2]) >= np.cos(np.radians(80)))
    r = brdffit.fit(shiny, "ggx")
    assert r.provenance["options"]["cutoff"] == 80.0 and r.n_cells == int(inside.sum())
    assert brdffit.fit(shiny, "ggx", cutoff=None).n_cells == int(s.valid.sum())
    assert brdffit.fit(shiny, "ggx", cutoff=90).n_cells == int(s.valid.sum())


@pytest.mark.parametrize("preset, loss, weighting, cutoff", [
    ("ngan2005", "cosine-in", "solid-angle", 80.0),
    ("low2012-e1", "cosine-in", "solid-angle", 90.0),
    ("low2012-e2", "log", "solid-angle", 90.0),
    ("bagher2012", "cosine-in", "solid-angle", 80.0),
])
def test_protocol_presets_say_what_they_reproduce(preset, loss, weighting, cutoff):
    from brdffit.config import find_config, load_config

    opts = load_config(preset)
    assert (opts.loss, opts.weighting, opts.cutoff) == (loss, weighting, cutoff)
    text = find_config(preset).read_text()
    assert "reproduce" in text and "does not reproduce" in text or "NOT a transcription" in text


# -- published fits as results ----------------------------------------------------------------

def test_a_fit_line_loads_as_a_result_of_its_model(test_form, fits_dir, shiny):
    results = brdffit.load_published(fits_dir / "test_ggx_E2.fit")
    assert [r.table for r in results] == ["shiny", "other"]
    r = results[0]
    assert isinstance(r, brdffit.FitResult) and r.model_name == "ggx"
    assert r.params["alpha"] == 0.2 and r.params["f0"] == [0.9, 0.6, 0.3]
    assert r.source == "published: Test 2099 E2" and r.status == "published"
    assert r.free == [] and set(r.fixed) == set(r.names) and math.isnan(r.cost)
    where = r.provenance["published"]
    assert (where["line"], where["bbm_class"], where["material"]) == (2, "TestGGX", "shiny")
    assert "published: Test 2099 E2" in r.summary() and "not fitted" in r.summary()
    f = np.asarray(r.model(np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]])))
    assert f.shape == (1, 3) and np.all(f > 0)
    back = brdffit.FitResult.from_json(r.to_json())  # JSON round trip, marked as published
    assert back.status == "published" and back.message == r.source
    table = r.render_merl(shape=(4, 4, 8))  # rendered (and exported) like a fit
    assert table.shape == (4, 4, 8) and np.all(np.isfinite(table.rgb[table.valid]))
    assert [x.table for x in brdffit.load_published(fits_dir / "test_ggx_E2.fit", "other")] \
        == ["other"]


def test_a_folder_skips_files_without_a_registered_model(test_form, fits_dir):
    with pytest.warns(UserWarning, match="unknown_model.fit"):
        results = brdffit.load_published(fits_dir, "shiny")
    assert [r.source for r in results] == ["published: Test 2099 E2"]
    with pytest.raises(brdffit.UnknownNameError, match="NoSuchModel"):
        brdffit.load_published(fits_dir / "unknown_model.fit")


def test_a_malformed_fit_file_names_its_line(tmp_path, test_form):
    from brdffit.published import PublishedFitError

    bad = tmp_path / "bad.fit"
    bad.write_text("# x\nshiny = Aggregate(Lambertian(albedo = [1, 2, 3]), __import__('os'))\n")
    with pytest.raises(PublishedFitError, match=r"bad.fit:2"):
        brdffit.load_published(bad)


# -- the leaderboard --------------------------------------------------------------------------

def test_a_table_made_from_one_model_ranks_that_model_first(shiny, fits_dir, test_form):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        board = brdffit.compare(shiny, "beckmann,ggx,blinn-phong", published=fits_dir,
                                options={"energy": "free"})  # the truth reflects 1.002 at 89°
    labels = [c.label for c in board.candidates]
    assert labels[0] == "ggx" and set(labels) == {"ggx", "beckmann", "blinn-phong",
                                                  "published: Test 2099 E2 (ggx)"}
    best = board.candidates[0].scores
    assert best["log_rms_sa"] < 1e-9 and best["ngan_rms_80"] < 1e-9
    df = board.frame
    assert list(df["candidate"]) == labels and list(df["rank"]) == [1, 2, 3, 4]
    for name in LITERATURE_METRICS:  # first in every metric, not just the ranking one
        assert df.loc[df["candidate"] == "ggx", f"rank_{name}"].item() == 1, name
    assert df.loc[df["kind"] == "published", "source"].item() == "published: Test 2099 E2"
    # a published fit was not fitted here: its row says so instead of "converged"
    assert df.loc[df["kind"] == "published", "converged"].isna().all()
    assert df.loc[df["kind"] == "fit", "converged"].all()
    pub_line = next(line for line in board.text().splitlines() if "Test 2099" in line)
    assert " published " in pub_line and " yes " not in pub_line
    assert (df["n_cells"] == board.n_cells).all() and "ggx" in board.text()


def test_scores_are_the_metrics_of_the_candidates_values(shiny, test_form, fits_dir):
    """The board's scores are those of :func:`literature_values` on the table's valid cells,
    for a published fit as for a fitted one."""
    from brdffit.io import read_path
    from brdffit.models.evaluate import evaluate_model

    import jax

    board = brdffit.compare(shiny, [], published=fits_dir / "test_ggx_E2.fit")
    (c,) = board.candidates
    s = read_path(shiny).to_samples()
    ok = s.valid
    with jax.enable_x64(True):
        f = np.asarray(evaluate_model("ggx", c.result.params, s.wi[ok], s.wo[ok]))
    want = literature_values(f, s.rgb[ok], s.wi[ok], s.wo[ok], s.weight[ok])
    assert c.scores == pytest.approx(want, rel=1e-12) and board.n_cells == int(ok.sum())


def test_a_model_under_its_own_preset_over_the_common_options(shiny):
    board = brdffit.compare(shiny, "ggx@low2012-e2", options={"cutoff": 70.0, "seed": 3})
    (c,) = board.candidates
    options = c.result.provenance["options"]
    assert (options["loss"], options["weighting"], options["cutoff"]) == (
        "log", "solid-angle", 90.0)  # the preset's cutoff over the common options'
    assert options["seed"] == 3  # and the common options where the preset is silent
    assert c.label == "ggx@low2012-e2" and c.source == "fit (log, solid-angle, θ ≤ 90°)"
    with pytest.raises(TypeError, match="cutof"):
        brdffit.compare(shiny, "ggx", options={"cutof": 80})


def test_compare_refuses_bad_input_before_any_fit(shiny, tmp_path):
    with pytest.raises(brdffit.UnknownNameError, match="ggz"):
        brdffit.compare(shiny, "ggz")
    with pytest.raises(brdffit.UnknownNameError, match="metric"):
        brdffit.compare(shiny, "ggx", rank_by="rmse")
    with pytest.raises(brdffit.ConfigError, match="no preset"):
        brdffit.compare(shiny, "ggx@no-such-preset")
    with pytest.raises(brdffit.ConfigError, match="twice"):
        brdffit.compare(shiny, "ggx,ggx")


# -- the command line -------------------------------------------------------------------------

def test_cli_compare_writes_the_table_and_a_self_contained_report(shiny, fits_dir, test_form,
                                                                  tmp_path, capsys):
    out, csv, report = tmp_path / "b.parquet", tmp_path / "b.csv", tmp_path / "r.html"
    code = main(["compare", str(shiny), "--models", "ggx,beckmann@low2012-e2", "--published",
                 str(fits_dir), "--out", str(out), "--csv", str(csv), "--html", str(report),
                 "--quiet"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "ggx" in captured.out and "beckmann@low2012-e2" in captured.out
    assert "unknown_model.fit" in captured.err  # the skipped file is said, in one line
    df = pd.read_parquet(out)
    assert list(df["candidate"])[0] == "ggx" and len(df) == 3
    assert pd.read_csv(csv)["candidate"].tolist() == df["candidate"].tolist()
    text = report.read_text()
    assert text.startswith("<!DOCTYPE html>") and "published: Test 2099 E2" in text
    srcs = re.findall(r"""(?:src|href)\s*=\s*['"]([^'"]*)""", text)
    assert len(srcs) >= 1 + 2 * 3 and all(s.startswith("data:image/png;base64,") for s in srcs)
    assert "<script" not in text and "<link" not in text and "url(" not in text


def test_cli_compare_json(shiny, capsys):
    assert main(["compare", str(shiny), "-m", "ggx", "--json", "--quiet"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["material"] == "shiny" and doc["rows"][0]["candidate"] == "ggx"


@pytest.mark.parametrize("extra, says", [
    (["--models", "ggz"], "unknown model 'ggz'"),
    (["--models", "ggx", "--published", "MISSING"], "MISSING"),
    (["--models", "ggx", "--published", "BAD"], "bad.fit:1"),
    (["--models", "ggx", "--rank-by", "rmse"], "--rank-by"),
    (["--models", "ggx@nope"], "no preset named 'nope'"),
    ([], "nothing to compare"),
    (["--models", "ggx", "--cutoff", "95"], "--cutoff"),
])
def test_cli_compare_bad_input_is_one_line_and_leaves_nothing(shiny, tmp_path, capsys, extra,
                                                              says):
    bad = tmp_path / "bad.fit"
    bad.write_text("shiny = Aggregate(Lambertian(albedo = [1, 2]), X(a = 1))\n")
    extra = [str(tmp_path / "missing") if a == "MISSING" else str(bad) if a == "BAD" else a
             for a in extra]
    out, report = tmp_path / "b.parquet", tmp_path / "r.html"
    code = main(["compare", str(shiny), *extra, "--out", str(out), "--html", str(report)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert says.replace("MISSING", "missing") in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.fit"]


def test_cli_help_lists_compare(capsys):
    assert main(["--help"]) == 0
    assert re.search(r"^\s+compare\s+rank models", capsys.readouterr().out, re.M)


# -- batch ------------------------------------------------------------------------------------

def test_batch_compare_writes_a_leaderboard_per_material(shiny, fits_dir, test_form, tmp_path,
                                                         capsys):
    pytest.importorskip("distributed")
    rough = _synth(tmp_path / "rough.binary", "beckmann",
                   {"diffuse": [0.3, 0.3, 0.3], "f0": [0.05, 0.05, 0.05], "alpha": 0.4})
    outdir = tmp_path / "out"
    code = main(["batch", str(shiny), str(rough), "--model", "ggx,beckmann", "--outdir",
                 str(outdir), "--workers", "1", "--compare", "--published",
                 str(fits_dir / "test_ggx_E2.fit"), "--quiet"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    board = pd.read_parquet(outdir / "leaderboard.parquet")
    assert set(board["material"]) == {"shiny", "rough"}
    first = board[board["rank"] == 1].set_index("material")["candidate"].to_dict()
    assert first == {"shiny": "ggx", "rough": "beckmann"}
    assert (board["material"] == "shiny").sum() == 3  # two fits and its published fit
    assert (board["material"] == "rough").sum() == 2
    assert "leaderboard" in captured.out and (outdir / "leaderboard.csv").is_file()


def test_batch_published_needs_compare_and_is_checked_first(shiny, tmp_path, capsys):
    outdir = tmp_path / "out"
    assert main(["batch", str(shiny), "--model", "ggx", "--outdir", str(outdir),
                 "--published", str(tmp_path)]) == 2
    assert "--compare" in capsys.readouterr().err and not outdir.exists()
    bad = tmp_path / "bad.fit"
    bad.write_text("shiny = nonsense(\n")
    assert main(["batch", str(shiny), "--model", "ggx", "--outdir", str(outdir), "--compare",
                 "--published", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.fit:1" in err and len(err.strip().splitlines()) == 1 and not outdir.exists()
