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

TRUTH = {"diffuse": [0.1, 0.06, 0.02], "f0": [0.9, 0.6, 0.3], "alpha": 0.2}
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
                              "f0[2]", "alpha"]
    assert list(df.columns) == ["value", "stderr", "lower", "upper", "status", "at_bound"]
    assert df.loc["alpha", "value"] == pytest.approx(0.2, rel=1e-4)
    assert df.loc["alpha", "lower"] == 0.001 and df.loc["alpha", "upper"] == 1.0
    assert (df["status"] == "free").all() and not df["at_bound"].any()
    html = result._repr_html_()
    assert html.count("<tr>") == 1 + 7  # the header and one row per scalar
    assert "converged" in html and "rmse" in html and "cost" in html
    assert re.search(r"<td>alpha</td><td>0\.(2000|1999)\d* ± 0\.0*\d\d</td>", html)


def test_dataframe_marks_fixed_and_at_bound_scalars(samples_csv):
    r = brdffit.fit(samples_csv, "ggx", fixed={"f0": 0.5}, throw=False)
    df = r.to_dataframe()
    assert (df.loc[["f0[0]", "f0[1]", "f0[2]"], "status"] == "fixed").all()
    assert df.loc[["f0[0]", "f0[1]", "f0[2]"], "stderr"].isna().all()


def test_value_with_error_keeps_the_digits_the_error_supports():
    from brdffit.fitting.result import value_with_error

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
                "max_steps", "multistart", "edm_tol", "covariance", "model"):
        assert key in opts, key
    assert opts["loss"] == "log" and opts["solver"] == "lm" and opts["rtol"] == 1e-8
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
