"""``brdffit.fit`` as a notebook user meets it: a path, no x64 set, ``progress=True``, the
result's repr, HTML view and DataFrame, and the provenance in its JSON.

Every fit here is ``ggx`` on the same 1200-sample list (log loss), so they share one compiled
program."""

import io
import json
import re
import os
import pty
import sys
import threading
import time
from pathlib import Path

import jax
import numpy as np
import pytest

import brdffit

TRUTH = {"diffuse": [0.1, 0.06, 0.02], "f0": [0.9, 0.6, 0.3], "alpha": 0.2, "grazing": 0.7}
N_SAMPLES = 1200


def write_sample_list(path, n=N_SAMPLES, seed=3, extra=None, params=TRUTH):
    """A noiseless ``ggx`` sample list of ``n`` random direction pairs as CSV (``extra``:
    more columns, name → values)."""
    from brdffit.cli.synth import synthesize_samples

    s = synthesize_samples(brdffit.get_model("ggx"), params, n, seed=seed, name=path.stem)
    cols = {"wix": s.wi[:, 0], "wiy": s.wi[:, 1], "wiz": s.wi[:, 2],
            "wox": s.wo[:, 0], "woy": s.wo[:, 1], "woz": s.wo[:, 2],
            "r": s.rgb[:, 0], "g": s.rgb[:, 1], "b": s.rgb[:, 2], **(extra or {})}
    lines = [",".join(cols)] + [",".join(f"{v:.17g}" for v in row)
                                for row in np.column_stack(list(cols.values()))]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def samples_csv(tmp_path_factory):
    return write_sample_list(tmp_path_factory.mktemp("api") / "gold.csv")


@pytest.fixture(scope="module")
def result(samples_csv):
    return brdffit.fit(str(samples_csv), "ggx")


def test_a_path_is_read_through_the_cli_reader_dispatch(samples_csv, result):
    assert result.success and result.table == "gold"
    for name, true in TRUTH.items():
        np.testing.assert_allclose(result.params[name], true, rtol=1e-4)
    again = brdffit.fit(Path(samples_csv), "ggx")  # a PathLike too
    np.testing.assert_allclose(again.x, result.x)
    with pytest.raises(brdffit.BrdffitError, match=r"unknown input format '\.txt'"):
        brdffit.fit(str(samples_csv.with_suffix(".txt")), "ggx")
    with pytest.raises(TypeError, match=r"a path \(str or PathLike"):
        brdffit.fit(42, "ggx")


def test_without_x64_the_fit_runs_in_float64_and_leaves_jax_config_alone(samples_csv, result):
    seen = []

    def spy(event, info):
        if event == "setup":
            seen.append(bool(jax.config.jax_enable_x64))

    with jax.enable_x64(False):  # a session that never set jax_enable_x64
        r = brdffit.fit(samples_csv, "ggx", progress=spy)
        assert jax.config.jax_enable_x64 is False  # unchanged after the call
    assert seen == [True]  # float64 for the duration of the call
    assert r.success and r.steps == result.steps
    np.testing.assert_allclose(r.x, result.x, rtol=1e-12)
    assert r.provenance["options"]["precision"] == "float64"


def test_repr_is_one_short_line(result):
    text = repr(result)
    assert "\n" not in text and len(text) < 200
    assert text.startswith("FitResult('ggx' on 'gold': converged") and "alpha=0.2" in text


def test_html_view_and_dataframe_have_one_row_per_scalar(result):
    df = result.to_dataframe()
    assert list(df.index) == ["diffuse[0]", "diffuse[1]", "diffuse[2]", "f0[0]", "f0[1]",
                              "f0[2]", "alpha", "grazing", "f90[0]", "f90[1]", "f90[2]"]
    assert list(df.columns) == ["value", "stderr", "lower", "upper", "status", "at_bound"]
    assert df.loc["alpha", "value"] == pytest.approx(0.2, rel=1e-4)
    assert df.loc["alpha", "lower"] == 0.001 and df.loc["alpha", "upper"] == 1.0
    assert (df["status"][:8] == "free").all() and not df["at_bound"].any()
    assert (df["status"][8:] == "derived").all()  # f90 = f0 + (1 - f0) grazing
    html = result._repr_html_()
    params = html.split("<table class='brdffit-params'>")[1].split("</table>")[0]
    assert params.count("<tr>") == 1 + 8  # the header and one row per scalar
    assert "converged" in html and "rmse" in html and "cost" in html
    assert re.search(r"<td>alpha</td><td>0\.(2000|1999)\d* ± 0\.0*\d\d</td>", html)


def test_value_with_error_keeps_the_digits_the_error_supports():
    from brdffit.fitting import value_with_error

    assert value_with_error(0.0801234, 0.000113) == "0.08012 ± 0.00011"
    assert value_with_error(12345.6, 230.0) == "12350 ± 230"
    assert value_with_error(0.5, float("nan")) == "0.5"


def test_progress_true_draws_a_bar_on_a_pseudo_terminal(samples_csv, monkeypatch):
    import fcntl
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a 100-column window
    tty = os.fdopen(slave, "w", buffering=1)
    chunks = []
    reader = threading.Thread(target=_drain, args=(master, chunks), daemon=True)
    reader.start()
    monkeypatch.setattr(sys, "stderr", tty)
    r = brdffit.fit(samples_csv, "ggx", progress=True)
    tty.flush()
    time.sleep(0.3)  # let the reader take what is buffered before the slave side closes
    tty.close()
    reader.join(timeout=10)
    text = b"".join(chunks).decode(errors="replace")
    assert r.success
    assert "fit ggx" in text and "100%" in text and "1/1" in text and "cost" in text


def _drain(fd, chunks):
    while True:
        try:
            data = os.read(fd, 4096)
        except OSError:  # the slave side closed
            return
        if not data:
            return
        chunks.append(data)


def test_progress_must_be_a_bool_or_a_callable(samples_csv):
    with pytest.raises(TypeError, match=r"progress must be True .* or a callable"):
        brdffit.fit(samples_csv, "ggx", progress="yes")


def test_provenance_is_recorded_and_round_trips_through_json(samples_csv, result, tmp_path):
    import hashlib

    prov = result.provenance
    assert prov["input"]["path"] == str(samples_csv.resolve())
    assert prov["input"]["sha256"] == hashlib.sha256(samples_csv.read_bytes()).hexdigest()
    opts = prov["options"]
    for key in ("loss", "cutoff", "subsample", "seed", "solver", "rtol", "atol", "precision",
                "max_steps", "multistart", "ftol", "covariance", "model"):
        assert key in opts, key
    assert opts["loss"] == "log" and opts["solver"] == "lm" and opts["rtol"] == 1e-14
    assert set(prov["versions"]) >= {"brdffit", "jax", "optimistix"}
    assert prov["versions"]["jax"] == jax.__version__
    assert prov["date"].endswith("+00:00") and prov["date"][:2] == "20"
    path = tmp_path / "r.json"
    result.to_json(path)
    assert json.loads(path.read_text())["provenance"] == json.loads(json.dumps(prov))
    back = brdffit.FitResult.from_json(path)
    assert back.provenance == prov
    np.testing.assert_allclose(back.x, result.x)


def test_unknown_option_names_the_valid_ones(samples_csv):
    with pytest.raises(TypeError, match=r"unknown option\(s\) max_step; valid options: .*max_steps"):
        brdffit.fit(samples_csv, "ggx", max_step=5)


def test_a_fit_options_object_and_keywords_take_one_path(samples_csv, result):
    from brdffit.config import FitOptions

    preset = FitOptions(model="ggx", loss="log", max_steps=2, description="a preset")
    again = brdffit.fit(samples_csv, "ggx", preset, max_steps=200)  # the keyword wins
    np.testing.assert_allclose(again.x, result.x, rtol=1e-12)
    assert again.provenance["options"] == result.provenance["options"]
    with pytest.raises(brdffit.ConfigError, match=r"'multistart' must be an integer in \[0, 1000\]"):
        brdffit.fit(None, "ggx", FitOptions(multistart=-1))  # checked before the input
    with pytest.raises(TypeError, match="FitOptions or a mapping"):
        brdffit.fit(samples_csv, "ggx", "ggx")
    from brdffit.fitting import fit as low_level_fit
    from brdffit.io import read_path

    low = low_level_fit(read_path(samples_csv), "ggx", {"max_steps": 2}, throw=False)
    assert not low.success and low.status == "nonlinear_max_steps_reached"


# -- measurement uncertainties --------------------------------------------------------------
def _noisy_with_sigma(tmp_path, per_channel: bool):
    """The ggx sample list with Gaussian noise of a known, strongly varying σ per sample, and
    that σ in the file (one ``sigma`` column or ``sigma_r/g/b``)."""
    from brdffit.cli.synth import synthesize_samples

    clean = synthesize_samples(brdffit.get_model("ggx"), TRUTH, N_SAMPLES, seed=3)
    rng = np.random.default_rng(11)
    rel = rng.choice([0.005, 0.2], size=(N_SAMPLES, 1))  # good and bad samples, mixed
    level = clean.rgb if per_channel else np.repeat(clean.rgb.mean(1, keepdims=True), 3, 1)
    sigma = rel * level + 1e-4
    rgb = np.clip(clean.rgb + sigma * rng.standard_normal(sigma.shape), 0, None)
    extra = ({"sigma_r": sigma[:, 0], "sigma_g": sigma[:, 1], "sigma_b": sigma[:, 2]}
             if per_channel else {"sigma": sigma[:, 0]})
    path = tmp_path / ("rgb-sigma.csv" if per_channel else "sigma.csv")
    cols = {"wix": clean.wi[:, 0], "wiy": clean.wi[:, 1], "wiz": clean.wi[:, 2],
            "wox": clean.wo[:, 0], "woy": clean.wo[:, 1], "woz": clean.wo[:, 2],
            "r": rgb[:, 0], "g": rgb[:, 1], "b": rgb[:, 2], **extra}
    lines = [",".join(cols)] + [",".join(f"{v:.17g}" for v in row)
                                for row in np.column_stack(list(cols.values()))]
    path.write_text("\n".join(lines) + "\n")
    return path, sigma


def test_sigma_columns_are_read_and_weight_the_residuals(tmp_path):
    from data_formats.samplelist import SampleListFormatError, read_samples

    path, sigma = _noisy_with_sigma(tmp_path, per_channel=True)
    s = read_samples(path)
    np.testing.assert_allclose(s.sigma, sigma, rtol=1e-15)
    one, _ = _noisy_with_sigma(tmp_path, per_channel=False)
    assert read_samples(one).sigma.shape == (N_SAMPLES, 3)
    # energy="free": the bad samples pull the unweighted fit past albedo 1, and the energy
    # constraint would then keep it from the optimum this test compares
    weighted = brdffit.fit(path, "ggx", loss="linear", energy="free")
    plain = brdffit.fit(dataclass_without_sigma(s), "ggx", loss="linear", energy="free")
    # χ²/dof ≈ 1 when the residuals are divided by the σ the noise was drawn with
    dof = 3 * N_SAMPLES - 7
    assert 0.8 < 2 * weighted.cost / dof < 1.2
    # weighting by 1/σ ignores the bad samples: closer to the truth than the unweighted fit
    err_w = abs(weighted.params["alpha"] - TRUTH["alpha"])
    err_p = abs(plain.params["alpha"] - TRUTH["alpha"])
    assert err_w < 0.5 * err_p
    bad = tmp_path / "bad.csv"
    bad.write_text(path.read_text().replace("sigma_b", "sigma_x"))
    with pytest.raises(SampleListFormatError, match="sigma_r, sigma_g, sigma_b"):
        read_samples(bad)


def dataclass_without_sigma(s):
    import dataclasses

    return dataclasses.replace(s, sigma=None)


def test_sigma_enters_the_posterior_likelihood(tmp_path):
    import warnings

    path, _ = _noisy_with_sigma(tmp_path, per_channel=True)
    steps = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a short chain: too short for emcee's 50 τ rule
        post = brdffit.sample_posterior(
            path, "ggx", loss="linear", nwalkers=16, nsteps=40, burn=10, subsample=None,
            progress=lambda event, info: steps.append(info["step"]))
    assert post.noise == {"mode": "measured", "sigma": 1.0, "sigma_ls": post.noise["sigma_ls"]}
    assert 0.8 < post.noise["sigma_ls"] < 1.2  # residuals in units of their own σ
    assert steps == list(range(1, 41))
    df = post.to_dataframe()
    assert list(df.index) == post.sampled and {"p16", "p50", "p84", "tau", "ess"} <= set(df.columns)
    html = post._repr_html_()
    assert html.count("<tr>") == 1 + len(post.sampled) and "acceptance" in html
    assert "\n" not in repr(post) and repr(post).startswith("PosteriorResult('ggx'")


def test_monochrome_sample_list_fits_a_grey_model(tmp_path):
    from brdffit.cli.synth import synthesize_samples
    from data_formats.samplelist import read_samples

    grey = {"diffuse": 0.05, "f0": 0.5, "alpha": 0.2}
    s = synthesize_samples(brdffit.get_model("ggx"), grey, N_SAMPLES, seed=3)
    path = tmp_path / "grey.csv"
    rows = np.column_stack([s.wi, s.wo, s.rgb[:, 0]])
    path.write_text("wix,wiy,wiz,wox,woy,woz,value\n" +
                    "\n".join(",".join(f"{v:.17g}" for v in row) for row in rows) + "\n")
    data = read_samples(path)
    assert data.channels == 1 and np.all(data.rgb == data.rgb[:, :1])
    r = brdffit.fit(path, "ggx")
    assert r.success and r.free == ["diffuse[0]", "f0[0]", "alpha", "grazing"] and r.fixed == []
    assert r.params["f0"] == [r.params["f0"][0]] * 3  # grey
    for name, true in grey.items():
        np.testing.assert_allclose(r.params[name], true, rtol=1e-4)
    inside = np.minimum(s.wi[:, 2], s.wo[:, 2]) >= np.cos(np.radians(80))  # default cells
    assert r.n_cells == int(inside.sum())
    df = r.to_dataframe()
    assert df.loc["f0[2]", "status"] == "= f0[0] (grey)"
    assert df.loc["f0[2]", "stderr"] == df.loc["f0[0]", "stderr"] > 0
    assert "grey fit of monochrome data" in r.summary()
    with pytest.raises(brdffit.BrdffitError, match="base_color mixing the channels"):
        brdffit.fit(path, "disney")


def test_progress_bar_counts_posterior_steps():
    from brdffit.progress import Bar

    out = io.StringIO()
    bar = Bar("posterior", file=out)
    for k in range(1, 6):
        bar("sample-step", {"step": k, "of": 5})
    bar.close()
    assert "posterior" in out.getvalue() and "5/5" in out.getvalue()
