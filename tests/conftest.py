"""Test configuration: float64 everywhere (the library never flips jax.config itself), and the
persistent compilation cache in a temporary folder of this run's own.

The library turns the cache on at its first fit (:mod:`brdffit.compilation_cache`); the suite
must never write into the user's real cache folder. ``BRDFFIT_COMPILATION_CACHE_DIR`` points
it at a private temporary folder, set before anything runs, so that the subprocesses and Dask
workers the tests start (which inherit the environment) use it too, and pytest-xdist's workers
share the controller's; it is removed when the process that made it ends.
(tests/test_compilation_cache.py removes the variable in its own subprocesses.)
"""

import atexit
import os
import shutil
import tempfile

import jax

if not os.environ.get("BRDFFIT_COMPILATION_CACHE_DIR"):
    _CACHE = tempfile.mkdtemp(prefix="brdffit-test-jax-cache-")
    os.environ["BRDFFIT_COMPILATION_CACHE_DIR"] = _CACHE
    atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)

jax.config.update("jax_enable_x64", True)


def _status_kib(key: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return -1


def pytest_runtest_logfinish(nodeid, location):
    """With ``BRDFFIT_TEST_MEMLOG=FILE``, append each test's process memory after it ran
    (``pid VmRSS VmHWM nodeid``, KiB): which tests raise a worker's peak
    (``benchmarks/suite_memory.py`` summarizes the file)."""
    path = os.environ.get("BRDFFIT_TEST_MEMLOG")
    if path and os.path.exists("/proc/self/status"):
        with open(path, "a") as fh:
            fh.write(f"{os.getpid()} {_status_kib('VmRSS')} {_status_kib('VmHWM')} {nodeid}\n")
