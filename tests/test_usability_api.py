"""The library as a notebook user meets it: a failed fit hands back its result, the persistent
compilation cache is on without being asked for, and ``fit_many`` keeps its cluster (and so
its workers' compiled programs) from one call to the next.

Fits here are ``ggx`` on small sample lists (log loss), so they share compiled programs with
``tests/test_api.py``; the cache and the cluster are process state, so those cases run in
fresh processes or read the cluster's own identity."""

import os
import pickle
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit.errors import FitError

from test_api import write_sample_list

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def samples_csv(tmp_path_factory):
    return write_sample_list(tmp_path_factory.mktemp("usability") / "gold.csv", n=300)


# -- a failed fit hands back its result ---------------------------------------------------------
def test_a_fit_stopped_by_the_step_limit_raises_with_its_result(samples_csv):
    with pytest.raises(FitError, match="did not converge.*max_steps") as info:
        brdffit.fit(samples_csv, "ggx", max_steps=1)
    res = info.value.result
    assert isinstance(res, brdffit.FitResult)
    assert res.success is False and res.status == "nonlinear_max_steps_reached"
    assert "max_steps" in res.message and np.all(np.isfinite(res.x))
    assert res.provenance["options"]["max_steps"] == 1  # finished as a returned result is
    assert res.provenance["input"]["path"] == str(samples_csv.resolve())
    assert "throw=False" in str(info.value) and ".result" in str(info.value)
    back = brdffit.fit(samples_csv, "ggx", max_steps=1, throw=False)
    assert back.status == res.status and back.success is False
    np.testing.assert_array_equal(back.x, res.x)


def test_the_result_of_a_fit_error_survives_pickling(samples_csv):
    """A Dask worker's exception travels pickled: its result must travel with it."""
    with pytest.raises(FitError) as info:
        brdffit.fit(samples_csv, "ggx", max_steps=1)
    again = pickle.loads(pickle.dumps(info.value))
    assert str(again) == str(info.value)
    assert again.result is not None and again.result.status == info.value.result.status
    assert FitError("no cells").result is None  # a fit that could not start has none


def test_data_that_determine_nothing_raise_with_the_result(samples_csv):
    """The data verdicts (here: all zeros) are failures after the fit ran: result attached."""
    from data_formats import SampleSet

    s = brdffit.io.read_path(samples_csv).to_samples()
    zero = SampleSet(s.wi, s.wo, np.zeros_like(s.rgb), s.valid, name="zero")
    with pytest.raises(FitError, match="is degenerate") as info:
        brdffit.fit(zero, "ggx")
    assert info.value.result.status == "degenerate" and not info.value.result.success
    with pytest.raises(FitError, match="is degenerate") as info:  # the posterior's own fit
        brdffit.sample_posterior(zero, "ggx", nwalkers=8, nsteps=4, burn=0)
    assert info.value.result is not None and info.value.result.status == "degenerate"


# -- the persistent compilation cache is on in the library -------------------------------------
def _fresh(code, tmp_path, **env):
    """Run ``code`` in a fresh Python process whose environment has no cache setting but
    ``env``'s (the suite's own folder and opt-out removed); its stdout lines."""
    full = {k: v for k, v in os.environ.items()
            if k not in ("BRDFFIT_NO_COMPILATION_CACHE", "BRDFFIT_COMPILATION_CACHE_DIR",
                         "JAX_COMPILATION_CACHE_DIR")}
    full.update(PYTHONPATH=str(ROOT), XDG_CACHE_HOME=str(tmp_path / "xdg"), **env)
    out = subprocess.run([sys.executable, "-W", "always", "-c", code], cwd=tmp_path, env=full,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.splitlines(), out.stderr


FIT_AND_SAY_WHERE = (
    "import brdffit, jax\n"
    "r = brdffit.fit({path!r}, 'ggx')\n"
    "print(r.success); print(jax.config.jax_compilation_cache_dir)\n"
)


def _entries(folder):
    return [p for p in Path(folder).rglob("*") if p.is_file() and p.name.endswith("-cache")]


def test_the_first_fit_of_a_fresh_process_fills_the_user_cache_folder(samples_csv, tmp_path):
    (ok, where), _ = _fresh(FIT_AND_SAY_WHERE.format(path=str(samples_csv)), tmp_path)
    folder = tmp_path / "xdg" / "brdffit" / "jax"
    assert ok == "True" and where == str(folder)
    assert _entries(folder), "the first fit wrote no compiled program into the cache"
    assert folder.stat().st_mode & 0o077 == 0  # private: JAX runs what the cache holds


def test_an_unusable_named_folder_warns_once_and_the_fit_goes_on(samples_csv, tmp_path):
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")
    (ok, where), err = _fresh(FIT_AND_SAY_WHERE.format(path=str(samples_csv)), tmp_path,
                              BRDFFIT_COMPILATION_CACHE_DIR=str(blocked / "jax"))
    assert ok == "True" and where == "None"
    assert err.count("CompilationCacheWarning") == 1 and "cannot be used" in err, err
    assert not (tmp_path / "xdg").exists()


def test_the_cache_can_be_turned_off_and_left_to_the_user(tmp_path):
    say = "from brdffit import compilation_cache as cc\n"
    (where,), _ = _fresh(say + "cc.disable(); print(cc.ensure())", tmp_path)
    assert where == "None"
    (where,), _ = _fresh(say + "print(cc.ensure())", tmp_path, BRDFFIT_NO_COMPILATION_CACHE="1")
    assert where == "None"
    own = tmp_path / "mine"
    (where,), _ = _fresh("import jax\n" f"jax.config.update('jax_compilation_cache_dir', {str(own)!r})\n"
                         + say + "print(cc.ensure())", tmp_path)
    assert where == str(own)  # a folder the user chose is theirs
    assert not (tmp_path / "xdg").exists()


def test_the_suite_keeps_the_cache_in_a_temporary_folder(samples_csv):
    from brdffit import compilation_cache as cc

    brdffit.fit(samples_csv, "ggx", max_steps=1, throw=False)
    where = cc.location()
    assert where is not None and where == os.environ["BRDFFIT_COMPILATION_CACHE_DIR"]
    assert not Path(where).is_relative_to(cc.default_folder().parent)


# -- fit_many keeps its cluster for the session --------------------------------------------------
def test_fit_many_runs_twice_on_the_same_workers_and_closes_them_when_interrupted(samples_csv):
    first = brdffit.fit_many([samples_csv], "ggx", workers=1)
    second = brdffit.fit_many([samples_csv], "ggx", workers=1)
    assert first["success"].all() and second["success"].all()
    # the same worker process: its compiled programs (jit caches) were there for call 2
    assert first["worker"].iloc[0] == second["worker"].iloc[0]
    from brdffit.batch import close_session, session_client

    client = session_client()
    try:
        assert client is not None and list(client.run(os.getpid)) == [first["worker"].iloc[0]]
        # the kept cluster is the batch's own: TLS on loopback, no HTTP server
        info = client.scheduler_info()
        assert client.scheduler.address.startswith("tls://127.0.0.1:")
        assert "dashboard" not in info["services"]
        # a fit that fails is a row and, asked for, its result (fit_many never throws)
        failed, results = brdffit.fit_many([samples_csv], "ggx", workers=1, max_steps=1,
                                           return_results=True)
        assert not failed["success"].iloc[0] and failed["worker"].iloc[0] == first["worker"].iloc[0]
        assert results[0].status == "nonlinear_max_steps_reached" and not results[0].success
        assert type(results[0]) is brdffit.FitResult  # with plot() and export()
        other = brdffit.fit_many([samples_csv], "ggx", workers=1, keep_cluster=False)
        assert other["worker"].iloc[0] != first["worker"].iloc[0]  # a cluster of its own
        assert session_client() is client
        from brdffit.batch import open_client

        with pytest.raises(KeyboardInterrupt), open_client(workers=1, keep=True) as (c, _):
            assert c is client  # an interrupted batch leaves jobs running: the cluster closes
            raise KeyboardInterrupt
        assert session_client() is None and client.status == "closed"
    finally:
        close_session()


KEPT_AT_EXIT = """
import sys
import brdffit

if __name__ == "__main__":
    a = brdffit.fit_many([sys.argv[1]], "ggx", workers=1)
    b = brdffit.fit_many([sys.argv[1]], "ggx", workers=1)
    print(a["worker"].iloc[0], b["worker"].iloc[0], bool(a["success"].all() and b["success"].all()))
"""


def test_the_kept_cluster_closes_quietly_at_exit(samples_csv, tmp_path):
    """A script that calls fit_many twice and just ends: one cluster served both calls, and
    the exit stops it without a warning, a traceback or a scratch folder left behind."""
    import psutil

    script = tmp_path / "twice.py"
    script.write_text(KEPT_AT_EXIT)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(scratch)}
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    out = subprocess.run([sys.executable, str(script), str(samples_csv)], cwd=tmp_path,
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    a, b, ok = out.stdout.split()
    assert ok == "True" and a == b, out.stdout
    assert out.stderr == "", out.stderr
    assert list(scratch.glob("brdffit-dask-*")) == []
    assert {p.pid for p in psutil.Process().children(recursive=True)} <= before
