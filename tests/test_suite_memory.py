"""The suite's own memory guard (``tests/conftest.py``): each pytest process's peak resident
memory is reported at the end of a session, and with ``BRDFFIT_TEST_MAX_GB`` set (``.ci/run``
sets 3) a process that peaked above it fails the session, in one process and under xdist.

A tiny suite with this conftest runs in a subprocess; its limit is set below what any Python
process with JAX imported holds (0.01 GB), or far above it, so nothing here depends on timing or
on how much the machine has.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(),
                                reason="the peak is read from /proc (Linux)")


def _session(tmp_path, workers, limit):
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_tiny.py").write_text("def test_one():\n    assert 1 + 1 == 2\n")
    env = {k: v for k, v in os.environ.items() if k not in ("BRDFFIT_TEST_MAX_GB",
                                                            "BRDFFIT_TEST_MEMLOG")}
    if limit is not None:
        env["BRDFFIT_TEST_MAX_GB"] = str(limit)
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-c", os.devnull,
           "--rootdir", str(tmp_path), "-n", str(workers), "test_tiny.py"]
    return subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.parametrize("workers", [0, 1])
def test_a_process_above_the_limit_fails_the_session(tmp_path, workers):
    run = _session(tmp_path, workers, limit=0.01)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "1 passed" in run.stdout
    who = "pytest" if workers == 0 else "gw0"
    assert f"peak resident memory per pytest process: {who} " in run.stdout
    assert f"FAILED: {who} peaked above 0.01 GB" in run.stdout


@pytest.mark.parametrize("limit", [None, 1000])
def test_below_the_limit_or_without_one_the_peak_is_only_reported(tmp_path, limit):
    run = _session(tmp_path, 1, limit=limit)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "peak resident memory per pytest process: gw0 " in run.stdout
    assert "FAILED" not in run.stdout
