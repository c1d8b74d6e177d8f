"""The command line as people use it: flags where they type them, names in any case, tables that
line up, a demo that reruns, a batch folder whose table holds every result, a clean Ctrl-C.

The batch tests run their jobs on one in-process cluster (worker threads in this process,
reached over TCP by ``--scheduler``), so the compiled programs are shared with the other fits of
this module; one test starts ``brdffit batch`` as a real process to interrupt it.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import brdffit
from brdffit.cli import build_parser, main

ROOT = Path(__file__).resolve().parent.parent


def _one_error_line(capsys, argv, message, code=2):
    assert main(argv) == code
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    """A small sample list of a known ggx material."""
    path = tmp_path_factory.mktemp("usability") / "paint.csv"
    assert main(["synth", "--model", "ggx", "--param", "alpha=0.2", "--param", "f0=0.9,0.6,0.3",
                 "--samples", "400", "--seed", "1", "-o", str(path), "--quiet"]) == 0
    return path


# -- global flags before the command -----------------------------------------------------------
@pytest.mark.parametrize("argv, quiet, debug", [
    (["--quiet", "fit", "x.csv"], True, False),
    (["-q", "--debug", "fit", "x.csv"], True, True),
    (["fit", "x.csv", "--quiet"], True, False),
    (["--debug", "fit", "x.csv", "-q"], True, True),  # before and after combine
    (["fit", "x.csv"], False, False),
])
def test_global_flags_are_accepted_before_the_command(argv, quiet, debug):
    """``brdffit --quiet fit ...`` was exit 2 (the flags existed only after the command); a
    command line without the flag after the command keeps the one given before it."""
    args = build_parser().parse_args(argv)
    assert (args.quiet, args.debug) == (quiet, debug)


def test_a_global_flag_before_the_command_runs_it(capsys, tmp_path, samples):
    out = tmp_path / "copy.csv"
    assert main(["--quiet", "synth", "--model", "ggx", "--samples", "50", "-o", str(out)]) == 0
    assert out.is_file()
    assert main(["--quiet", "info", str(samples)]) == 0
    assert "sample list 'paint'" in capsys.readouterr().out


# -- registry names in any case ----------------------------------------------------------------
def test_registry_names_ignore_case_and_errors_list_the_canonical_names():
    from brdffit.config import find_config
    from brdffit.errors import UnknownNameError
    from brdffit.export import export
    from brdffit.fitting import get_loss

    assert brdffit.get_model("GGX").name == "ggx"
    assert brdffit.get_model("Mitsuba-RoughConductor-Beckmann").name == \
        "mitsuba-roughconductor-beckmann"  # built on demand by a factory
    assert get_loss("LOG+Huber").label == get_loss("log+huber").label
    assert find_config("GGX").name == "ggx.toml"
    gltf = brdffit.get_model("gltf-pbr")
    assert export(("gltf-pbr", gltf.defaults()), "GLTF").text() == \
        export(("gltf-pbr", gltf.defaults()), "gltf").text()
    with pytest.raises(UnknownNameError) as err:
        brdffit.get_model("GGXX")
    assert "valid choices: " in str(err.value) and ", ggx, " in str(err.value)
    assert "GGX" not in str(err.value).split("valid choices: ")[1].split(".")[0]


def test_model_and_option_names_ignore_case_in_fit_and_on_the_command_line(capsys, samples):
    """``--model GGX`` was an unknown model; ``brdffit.fit(t, "GGX")`` too."""
    result = brdffit.fit(str(samples), "GGX", loss="Cosine", solver="LM", covariance="GN",
                         throw=False)
    assert (result.model_name, result.loss) == ("ggx", "cosine")
    assert main(["fit", str(samples), "--model", "GGX", "--loss", "COSINE", "--solver", "LM",
                 "--covariance", "GN", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert (printed["model_name"], printed["loss"]) == ("ggx", "cosine")
    _one_error_line(capsys, ["fit", str(samples), "--model", "GGX,ggx"], "distinct model names")


# -- tables sized to their content -------------------------------------------------------------
def _fake(name, cost):
    return SimpleNamespace(model_name=name, success=True, cost=cost, loss="cosine",
                           metrics={"rmse_log": 0.123456, "rmse_cosine": 0.0123456},
                           free=list(range(11)), wall_time=12.5)


def _starts(line: str) -> list[int]:
    """Where each column of a layout begins (a blank followed by a non-blank)."""
    return [i for i in range(len(line)) if line[i] != " " and (i == 0 or line[i - 1] == " ")]


def test_the_model_comparison_lines_up_whatever_the_names():
    """``--model two-lobe-ggx,mitsuba-principled``: names longer than 14 characters shifted
    every column after them."""
    from brdffit.cli.fitting import comparison

    lines = comparison([_fake("two-lobe-ggx", 0.5), _fake("mitsuba-principled", 12345.678)])
    head, rule, *rows, note = lines.split("\n")
    assert set(rule) == {"-"} and len(rule) == len(head)
    ends = [i + len(w) for i, w in zip(_starts(head), head.split())]
    for row in rows:
        cells = row.split()
        # left-aligned columns start with their heading; right-aligned ones end with it
        assert row.index(cells[1]) == head.index("model")
        assert row.index(cells[2], row.index(cells[1]) + len(cells[1])) == head.index("converged")
        row_ends = [i + len(w) for i, w in zip(_starts(row), cells)]
        assert row_ends[3:] == ends[3:], (head, row)
    assert note.startswith("(same cells")


def test_the_posterior_summary_lines_up_with_long_parameter_names():
    """``brdffit fit --mcmc`` of disney: ``base_color[0]`` (13 characters) shifted its row of
    the posterior table (a 10-character name column)."""
    from brdffit.posterior.result import PosteriorResult

    names = ["alpha", "base_color[0]", "f0"]
    diagnostics = SimpleNamespace(tau=dict.fromkeys(names, 12.3), ess=dict.fromkeys(names, 1234.0),
                                  acceptance=0.3, acceptance_min=0.2, acceptance_max=0.4,
                                  too_short=False, messages=[])
    post = SimpleNamespace(
        settings=dict(loss="cosine", nwalkers=32, nsteps=100, burn=20, thin=1, n_cells=1000),
        diagnostics=diagnostics, model_name="disney", table="t", wall_time=1.0,
        noise=dict(mode="fixed", sigma=0.01), names=[*names, "specular_tint"],
        x_ls=[0.1, 0.5, 0.04, 0.2], stderr_ls={"alpha": 0.001}, sampled=names,
        percentiles=dict.fromkeys(names, (0.1, 0.2, 0.3)), fixed=["specular_tint"],
        interval_meaning="p16–p84: 68 % credible intervals on 1000 cells")
    head, *rows = PosteriorResult.summary(post).split("\n")[1:6]
    ends = [i + len(w) for i, w in zip(_starts(head), head.split())]
    for row in rows[:3]:
        assert row.index("=") == rows[0].index("=")
        cells = row.split()
        assert [i + len(w) for i, w in zip(_starts(row), cells)][-3:] == ends[-3:], (head, row)
    assert rows[3].index("=") == rows[0].index("=")  # the fixed parameter's line too


def test_columns_are_as_wide_as_their_widest_cell():
    from brdffit._columns import columns

    lines = columns([("name", "value"), ("a-very-long-parameter-name", "1"), ("b", "12345")],
                    "<>", indent="  ", rule=True)
    assert lines == ["  name                        value",
                     "  " + "-" * 33,
                     "  a-very-long-parameter-name      1",
                     "  b                           12345"]
    with pytest.raises(ValueError):
        columns([("a", "b")], "<")


# -- the demo reruns ---------------------------------------------------------------------------
def test_the_demo_reruns_and_never_overwrites_what_it_did_not_write(capsys, tmp_path):
    """``brdffit demo; brdffit demo`` was exit 2: its own folder "already exists"."""
    outdir = tmp_path / "brdffit-demo"
    argv = ["demo", "--outdir", str(outdir), "--subsample", "5000", "--quiet"]
    outdir.mkdir()
    (outdir / "result.json").write_text("mine\n")  # a user's file where the demo writes
    _one_error_line(capsys, argv, "result.json: already exists and is not what an earlier "
                    "demo wrote; pass --force")
    assert (outdir / "result.json").read_text() == "mine\n"
    (outdir / "result.json").unlink()
    (outdir / "notes.txt").write_text("my notes\n")  # a user's file beside the demo's
    assert main(argv) in (0, 1)
    first = {p.name: p.read_bytes() for p in outdir.iterdir()}
    assert main(argv) in (0, 1)  # the rerun replaces what the demo wrote
    capsys.readouterr()
    assert sorted(p.name for p in outdir.iterdir()) == sorted(first)
    assert (outdir / "notes.txt").read_text() == "my notes\n"
    # a file of the demo's that was changed since is the user's now
    figure = outdir / "demo-slice.png"
    figure.write_bytes(figure.read_bytes() + b"edited")
    _one_error_line(capsys, argv, "demo-slice.png: already exists and is not what an earlier "
                    "demo wrote; pass --force")
    assert figure.read_bytes().endswith(b"edited")
    assert main(argv + ["--force"]) in (0, 1)
    assert not figure.read_bytes().endswith(b"edited")


# -- a batch folder's table holds every result in it -------------------------------------------
@pytest.fixture(scope="module")
def scheduler():
    """The address of an in-process cluster (one worker thread) for ``--scheduler``."""
    distributed = pytest.importorskip("distributed")

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  protocol="tcp://", host="127.0.0.1", dashboard_address=None,
                                  silence_logs=40) as cluster:
        yield cluster.scheduler_address


def _batch(capsys, samples, outdir, model, scheduler, *more):
    code = main(["batch", str(samples), "-m", model, "-o", str(outdir), "--subsample", "200",
                 "--scheduler", scheduler, "-q", *more])
    return code, capsys.readouterr()


def test_a_batch_merges_its_rows_into_the_folders_table(capsys, tmp_path, samples, scheduler):
    """``batch L --model ggx -o R; batch L --model beckmann -o R`` left only the beckmann
    rows in R/results.parquet."""
    outdir = tmp_path / "R"
    code, _ = _batch(capsys, samples, outdir, "ggx", scheduler)
    assert code == 0
    code, out = _batch(capsys, samples, outdir, "beckmann", scheduler)
    assert code == 0
    table = pd.read_parquet(outdir / "results.parquet")
    assert list(zip(table.material, table.model)) == [("paint", "ggx"), ("paint", "beckmann")]
    assert pd.read_csv(outdir / "results.csv")["model"].tolist() == ["ggx", "beckmann"]
    assert "the table holds 2 results: 1 from this run, 1 kept from earlier runs" in out.out
    assert np.isfinite(table["p_alpha"]).all()
    # a rerun of the same material × model replaces its row, in place
    code, out = _batch(capsys, samples, outdir, "ggx", scheduler, "--force")
    assert code == 0
    again = pd.read_parquet(outdir / "results.parquet")
    assert list(zip(again.material, again.model)) == [("paint", "ggx"), ("paint", "beckmann")]
    assert again.loc[1].equals(table.loc[1])  # the beckmann row is kept as it was
    assert "1 replacing an earlier result of the same material and model" in out.out


@pytest.mark.parametrize("make, message", [
    (lambda d: d.joinpath("results.parquet").write_bytes(b"PAR1 not really parquet"),
     "not a table of brdffit batch results"),
    (lambda d: pd.DataFrame({"x": [1, 2]}).to_parquet(d / "results.parquet"),
     "no column material, model, success, outcome"),
    (lambda d: pd.DataFrame({"material": ["a", "a"], "model": ["ggx", "ggx"],
                             "success": [True, True], "outcome": ["converged"] * 2}
                            ).to_parquet(d / "results.parquet"), "holds a × ggx more than once"),
    (lambda d: d.joinpath("results.csv").write_text("material,model\na,ggx\n"),
     "exists without results.parquet"),
])
def test_a_table_that_is_not_a_batch_table_stops_the_batch(capsys, tmp_path, samples, scheduler,
                                                           make, message):
    """Rows of a foreign or corrupt table were silently dropped (the table was replaced)."""
    outdir = tmp_path / "R"
    outdir.mkdir()
    make(outdir)
    before = {p.name: p.read_bytes() for p in outdir.iterdir()}
    _one_error_line(capsys, ["batch", str(samples), "-m", "ggx", "-o", str(outdir),
                             "--scheduler", scheduler, "-q"], message)
    assert {p.name: p.read_bytes() for p in outdir.iterdir()} == before  # nothing ran


# -- a clean stop, and a dashboard whose port is taken -----------------------------------------
def _busy_port():
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen()
    return sock, sock.getsockname()[1]


def test_a_dashboard_port_in_use_is_one_line_with_the_link(capsys):
    """Dask's raw "Port 8787 is already in use ... Hosting the HTTP server on port N instead"
    warning reached the user; the link to the dashboard was never printed."""
    from brdffit.batch import runner

    sock, port = _busy_port()
    with sock, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with runner.open_client(workers=1, dashboard=f"127.0.0.1:{port}") as (client, _):
            served = client.scheduler_info()["services"]["dashboard"]
    assert not [w for w in caught if "already in use" in str(w.message)], caught
    err = capsys.readouterr().err
    assert served != port
    assert err == f"Dask dashboard: http://127.0.0.1:{served}/status (port {port} is in use)\n"


def test_ctrl_c_on_a_batch_is_one_line_and_nothing_else(tmp_path, samples):
    """Ctrl-C (SIGINT to the process group) while the workers run: exit 130 and the one line
    "interrupted": no leaked-semaphore warning, no port warning, no traceback."""
    sock, port = _busy_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmp_path)}
    with sock:
        proc = subprocess.Popen(
            [sys.executable, str(ROOT / "cli.py"), "batch", str(samples), "-m", "ggx",
             "--workers", "1", "-o", str(tmp_path / "out"), f"--dashboard=127.0.0.1:{port}"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
            start_new_session=True)
        try:
            first = proc.stderr.readline()  # the cluster and its worker are up
            if first.startswith("Dask dashboard:"):
                os.killpg(proc.pid, signal.SIGINT)
            out, rest = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    assert first.startswith("Dask dashboard: http://127.0.0.1:"), first + rest
    assert f"(port {port} is in use)" in first
    assert proc.returncode == 130, first + rest
    assert rest == "brdffit batch: interrupted\n", rest
