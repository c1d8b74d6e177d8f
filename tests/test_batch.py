"""Batches on a real ``dask.distributed.LocalCluster`` of worker processes (``brdffit.fit_many``)
and ``brdffit batch`` end to end in a subprocess.

One cluster (a single-threaded worker process, restarted by its nanny when a test kills it)
serves the module; the tables are small
(16×16×32 MERL-layout grids, ~6 600 valid cells) so each fit takes well under a second once its
program is compiled. The compilation cache goes to a temporary folder shared by the workers and
the command-line subprocesses, so a restarted worker or a new process loads programs instead of
compiling them. The cluster has the scheduler settings of the local clusters ``fit_many`` starts,
except that it never retries a job whose worker died (``allowed-failures = 0``).
"""

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import brdffit
from brdffit.batch import BASE_COLUMNS, BatchInputError, inputs
from brdffit.batch.jobs import options_key

distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parent.parent
SHAPE = (16, 16, 32)
TRUTHS = {  # material -> ggx parameters
    # a grazing rise of 0.5: with plain Schlick this lobe beside this diffuse reflects 1.002
    # at 89°, and the fit's energy constraint would rightly leave the truth
    "shiny": {"diffuse": [0.1, 0.06, 0.02], "f0": [0.9, 0.6, 0.3], "alpha": 0.12, "grazing": 0.5},
    "rough": {"diffuse": [0.3, 0.3, 0.3], "f0": [0.05, 0.05, 0.05], "alpha": 0.4},
}


def _synth(path, truth):
    from data_formats.merl import synthesize, write_merl

    from brdffit.models.evaluate import evaluate_model

    model = brdffit.get_model("ggx")
    write_merl(path, synthesize(lambda wi, wo: np.asarray(evaluate_model(model, truth, wi, wo)),
                                name=path.stem, shape=SHAPE))
    return path


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("batch-data")
    for name, truth in TRUTHS.items():
        _synth(folder / f"{name}.binary", truth)
    (folder / "broken.binary").write_bytes(b"\x10\x00\x00\x00 not a MERL table")
    return folder


@pytest.fixture(scope="module")
def cache_home(tmp_path_factory):
    return tmp_path_factory.mktemp("xdg-cache")


@pytest.fixture(scope="module")
def client(cache_home):
    import dask
    from distributed import Client, LocalCluster

    from brdffit.batch.runner import LOCAL_SCHEDULER

    with dask.config.set({**LOCAL_SCHEDULER, "distributed.scheduler.allowed-failures": 0}):
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40,
                               env={"XDG_CACHE_HOME": str(cache_home)})
    with cluster, Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def first(client, data, tmp_path_factory):
    """The good tables and a malformed one, ggx, written to an outdir: ``(outdir, df, results)``."""
    outdir = tmp_path_factory.mktemp("batch-out")
    paths = [data / "shiny.binary", str(data / "broken.binary"), data / "rough.binary"]
    df, results = brdffit.fit_many(paths, "ggx", client=client, outdir=outdir,
                                   return_results=True)
    return outdir, df, results


def _leftovers(folder):
    """Temporary files of atomic writes (``.NAME.XXXX``) anywhere under ``folder``."""
    return [p for p in Path(folder).rglob(".*")]


def test_table_is_complete_and_recovers_the_parameters(first, data):
    outdir, df, results = first
    assert list(df["material"]) == ["shiny", "broken", "rough"] and set(df["model"]) == {"ggx"}
    assert list(df.columns[: len(BASE_COLUMNS)]) == list(BASE_COLUMNS)
    for col in ("rmse", "rmse_log", "rmse_cosine", "rel_error", "p_alpha", "se_alpha",
                "p_f0[0]", "se_f0[2]", "p_diffuse[1]"):
        assert col in df.columns, col
    good = df.set_index("material").loc[["shiny", "rough"]]
    assert good["success"].all() and (good["outcome"] == "converged").all()
    assert not good["skipped"].any() and (good["steps"] > 0).all()
    for name, truth in TRUTHS.items():
        row = good.loc[name]
        np.testing.assert_allclose(row["p_alpha"], truth["alpha"], rtol=1e-6)
        np.testing.assert_allclose([row[f"p_f0[{i}]"] for i in range(3)], truth["f0"], rtol=1e-6)
        np.testing.assert_allclose([row[f"p_diffuse[{i}]"] for i in range(3)], truth["diffuse"],
                                   rtol=1e-6)
        digest = hashlib.sha256((data / f"{name}.binary").read_bytes()).hexdigest()
        assert row["checksum"] == f"sha256:{digest}"
        assert row["input"] == str(data / f"{name}.binary")
        assert row["brdffit_version"] == brdffit.__version__ and row["result"] == f"{name}/ggx.json"
        assert row["time"] > 0 and row["job_time"] >= row["time"]
        saved = brdffit.FitResult.from_json(outdir / name / "ggx.json")
        np.testing.assert_allclose(saved.params["alpha"], truth["alpha"], rtol=1e-6)
    # One worker ran both fits in turn: the first compiled, the second reused its programs.
    assert good.loc["rough", "time"] < good.loc["shiny", "time"] / 3
    assert results[0].params["alpha"] == pytest.approx(TRUTHS["shiny"]["alpha"], rel=1e-6)
    assert results[1] is None and results[2].model_name == "ggx"


def test_malformed_file_is_recorded_and_the_batch_goes_on(first):
    outdir, df, _ = first
    bad = df.set_index("material").loc["broken"]
    assert not bad["success"] and bad["outcome"] == "error"
    assert "MERLFormatError" in bad["message"] and "broken.binary" in bad["message"]
    assert bad["checksum"].startswith("sha256:") and np.isnan(bad["p_alpha"])
    assert not (outdir / "broken").exists()  # no result, no partial file
    assert df["success"].sum() == 2


def test_table_files_hold_the_table_and_nothing_partial_is_left(first):
    outdir, df, _ = first
    parquet = pd.read_parquet(outdir / "results.parquet")
    pd.testing.assert_frame_equal(parquet, df, check_dtype=False)
    csv = pd.read_csv(outdir / "results.csv")
    assert list(csv.columns) == list(df.columns)
    np.testing.assert_allclose(csv["p_alpha"], df["p_alpha"], rtol=1e-12)
    assert sorted(p.name for p in (outdir / "shiny").iterdir()) == ["ggx.json", "ggx.meta.json"]
    assert _leftovers(outdir) == []


def test_rerun_skips_everything_done_and_force_refits(first, client, data):
    outdir, df, _ = first
    stamp = (outdir / "shiny" / "ggx.json").stat().st_mtime_ns
    (outdir / "shiny" / ".ggx.json.k1ll3d.json").write_text('{"trunc')  # a write cut short
    again = brdffit.fit_many([data / "shiny.binary", data / "rough.binary"], "ggx",
                             scheduler=client.scheduler.address, outdir=outdir)
    assert again["skipped"].all() and again["success"].all()
    pd.testing.assert_series_equal(again["p_alpha"], df["p_alpha"].iloc[[0, 2]].reset_index(
        drop=True))
    assert (outdir / "shiny" / "ggx.json").stat().st_mtime_ns == stamp
    forced = brdffit.fit_many([data / "shiny.binary"], "ggx", client=client, outdir=outdir,
                              force=True)
    assert not forced["skipped"].any() and forced["success"].all()
    assert (outdir / "shiny" / "ggx.json").stat().st_mtime_ns != stamp
    assert _leftovers(outdir) == []


def test_changed_input_or_options_are_refitted(client, data, tmp_path):
    table = tmp_path / "material.binary"
    table.write_bytes((data / "shiny.binary").read_bytes())
    before = brdffit.fit_many([table], "ggx", client=client, outdir=tmp_path / "out")
    table.write_bytes((data / "rough.binary").read_bytes())  # same path, new measurement
    after = brdffit.fit_many([table], "ggx", client=client, outdir=tmp_path / "out")
    assert not before["skipped"].any() and not after["skipped"].any()
    assert before["p_alpha"].iloc[0] == pytest.approx(TRUTHS["shiny"]["alpha"], rel=1e-6)
    assert after["p_alpha"].iloc[0] == pytest.approx(TRUTHS["rough"]["alpha"], rel=1e-6)
    assert options_key("ggx", {"cutoff": 80}) == options_key("ggx", {"cutoff": 80.0})
    assert options_key("ggx", {"cutoff": 80}) != options_key("ggx", {"cutoff": 70})
    assert options_key("ggx", {}) != options_key("beckmann", {})


def test_worker_killed_mid_batch_is_recorded_and_the_rest_completes(client, data, tmp_path):
    class KillsItsWorker:
        """An input whose reading takes the worker process down, as the OOM killer would."""

        name = "killer"

        def to_samples(self):
            os._exit(3)

    paths = [data / "shiny.binary", KillsItsWorker(), data / "rough.binary"]
    df = brdffit.fit_many(paths, "ggx", client=client, outdir=tmp_path)
    assert df["material"].tolist() == ["shiny", "killer", "rough"]
    killed = df.iloc[1]
    assert killed["outcome"] == "worker died" and not killed["success"]
    assert "died" in killed["message"]
    assert df["success"].iloc[[0, 2]].all()
    assert not (tmp_path / "killer").exists() and _leftovers(tmp_path) == []
    assert pd.read_parquet(tmp_path / "results.parquet")["outcome"].tolist()[1] == "worker died"


def test_inputs_globs_lists_and_name_clashes(data, tmp_path):
    listing = tmp_path / "list.txt"
    listing.write_text(f"# materials\n{data / 'rough.binary'}\n\nshiny.binary\n")
    (tmp_path / "shiny.binary").write_bytes((data / "shiny.binary").read_bytes())
    assert inputs.expand([str(data / "*.binary")]) == sorted(
        str(p) for p in data.glob("*.binary"))
    names = [m.name for m in inputs.materials([listing])]
    assert names == ["rough", "shiny"]
    with pytest.raises(BatchInputError, match="both named 'shiny'"):
        inputs.materials([listing, data / "shiny.binary"])
    with pytest.raises(BatchInputError, match="matches no file"):
        inputs.expand([str(tmp_path / "*.nothing")])
    with pytest.raises(BatchInputError, match="line 2: nowhere.binary: no such file"):
        (tmp_path / "bad.txt").write_text("shiny.binary\nnowhere.binary\n")
        inputs.materials([tmp_path / "bad.txt"])


def _cli(*args, cwd, cache_home):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "XDG_CACHE_HOME": str(cache_home)}
    return subprocess.run([sys.executable, str(ROOT / "cli.py"), *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=env, timeout=600)


def test_cli_end_to_end_exit_codes_and_summary(data, first, tmp_path, cache_home):
    """A preset that stops every fit after one step: not converged (and the malformed file an
    error), exit 1; then the default options over the first batch's outdir: all skipped, exit
    0 (the command line and ``fit_many`` give the same options the same key); a usage error 2
    (the other usage errors are checked in-process below)."""
    preset = tmp_path / "one-step.toml"
    preset.write_text("[solver]\nmax_steps = 1\n")
    run = _cli("batch", data / "*.binary", "--model", "ggx", "--config", preset, "--outdir",
               "out", "--workers", "1", cwd=tmp_path, cache_home=cache_home)
    assert run.returncode == 1, run.stderr
    assert "3 fits: 0 succeeded, 3 failed, 0 skipped" in run.stdout
    assert "broken × ggx: error: MERLFormatError" in run.stdout
    assert "shiny × ggx: not converged: The maximum number of steps" in run.stdout
    assert "3 of 3 fits not successful" in run.stderr
    table = pd.read_csv(tmp_path / "out" / "results.csv")
    assert table["material"].tolist() == ["broken", "rough", "shiny"]
    assert table["outcome"].tolist() == ["error", "not converged", "not converged"]
    assert (table["steps"].iloc[1:] == 1).all() and _leftovers(tmp_path / "out") == []

    outdir = first[0]
    rerun = _cli("batch", data / "shiny.binary", data / "rough.binary", "--model", "ggx",
                 "--outdir", outdir, "--workers", "1", cwd=tmp_path, cache_home=cache_home)
    assert rerun.returncode == 0, rerun.stderr
    assert "2 fits: 0 succeeded, 0 failed, 2 skipped" in rerun.stdout
    assert "best model per material" in rerun.stdout and "shiny  ggx (rmse" in rerun.stdout

    usage = _cli("batch", "*.nothing", "--model", "ggx", "--outdir", "o2", cwd=tmp_path,
                 cache_home=cache_home)
    assert usage.returncode == 2 and usage.stdout == ""
    assert usage.stderr.startswith("brdffit batch: error: '*.nothing' matches no file")



@pytest.mark.parametrize("args, message", [
    (["*.nothing", "--model", "ggx", "--outdir", "o2"], "matches no file"),
    (["shiny.binary", "--model", "ggx,nope", "--outdir", "o2"], "unknown model 'nope'"),
    (["shiny.binary", "--model", "ggx", "--outdir", "o2", "--fix", "zz=1"], "'zz'"),
    (["shiny.binary", "--model", "ggx", "--outdir", "shiny.binary"], "not a folder"),
    (["shiny.binary", "--outdir", "o2"], "no model given"),
    (["shiny.binary", "--model", "ggx", "--outdir", "o2", "--workers", "0"], "from 1 to 256"),
    (["shiny.binary", "--model", "ggx", "--outdir", "o2", "--scheduler", "tcp://127.0.0.1:9"],
     "cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"),
])
def test_cli_usage_errors_exit_2_before_any_work(data, args, message, capsys, monkeypatch):
    from brdffit.batch import runner
    from brdffit.cli import main

    monkeypatch.chdir(data)
    monkeypatch.setattr(runner, "CONNECT_TIMEOUT", "1s")
    assert main(["batch", *args]) == 2
    assert message in capsys.readouterr().err
    assert not (data / "o2").exists()


def test_compilation_cache_opt_out_and_unwritable_folder(monkeypatch, tmp_path):
    from brdffit import compilation_cache

    monkeypatch.setattr(compilation_cache, "_decided", compilation_cache._decided)  # restored
    monkeypatch.delenv(compilation_cache.FOLDER_VARIABLE, raising=False)  # the suite's folder
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert compilation_cache.cache_folder() == tmp_path / "brdffit" / "jax"
    monkeypatch.setenv(compilation_cache.OPT_OUT, "1")
    assert compilation_cache.enable() is None and not (tmp_path / "brdffit").exists()
    monkeypatch.delenv(compilation_cache.OPT_OUT)
    (tmp_path / "brdffit").write_text("a file where the folder should be")
    assert compilation_cache.enable() is None


def test_progress_bar_counts_done_failed_skipped(capsys):
    from brdffit.batch.runner import _Bar

    bar = _Bar(3, progress=True)
    for row in ({"success": True}, {"success": False}, {"success": True, "skipped": True}):
        bar.update(row)
    bar.close()
    assert bar.counts == {"done": 1, "failed": 1, "skipped": 1}
    err = capsys.readouterr().err
    assert "3/3" in err and "done=1, failed=1, skipped=1" in err
    quiet = _Bar(3, progress=False)
    quiet.update({"success": True})
    quiet.close()
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("cores, n, expect", [
    (list(range(4)), 2, [[0, 1], [2, 3]]),
    (list(range(5)), 2, [[0, 1, 2], [3, 4]]),
    (list(range(2)), 2, [[0], [1]]),
    (list(range(2)), 3, []),  # more workers than cores: not pinned
])
def test_core_groups_split_the_available_cores(monkeypatch, cores, n, expect):
    from brdffit.batch import pinning

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(cores), raising=False)
    assert pinning.core_groups(n) == expect


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="pinning needs a platform with CPU affinity and at least 2 cores")
def test_local_workers_are_pinned_to_their_own_cores():
    from brdffit.batch.pinning import core_groups
    from brdffit.batch.runner import open_client

    with open_client(workers=2) as (client, _):
        got = client.run(lambda: sorted(os.sched_getaffinity(0)))
    assert sorted(got.values()) == sorted(core_groups(2))
