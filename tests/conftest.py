"""Test configuration: float64 everywhere (the library never flips jax.config itself)."""

import os

import jax

# Tests call the CLI in-process (`main(argv)`), which would point this process's jax.config at
# the per-user compilation cache; keep the suite hermetic (tests/test_compilation_cache.py
# removes the variable in its own subprocesses).
os.environ.setdefault("BRDFFIT_NO_COMPILATION_CACHE", "1")

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
