"""Test configuration: float64 everywhere (the library never flips jax.config itself), the
persistent compilation cache in a temporary folder of this run's own, and each pytest process's
memory kept in bounds (JAX's in-memory caches emptied as a process grows) and reported.

The library turns the cache on at its first fit (:mod:`brdffit.compilation_cache`); the suite
must never write into the user's real cache folder. ``BRDFFIT_COMPILATION_CACHE_DIR`` points
it at a private temporary folder, set before anything runs, so that the subprocesses and Dask
workers the tests start (which inherit the environment) use it too, and pytest-xdist's workers
share the controller's; it is removed when the process that made it ends.
(tests/test_compilation_cache.py removes the variable in its own subprocesses.)

The tests that press Ctrl-C on a command they start (SIGINT to its process group) test a
terminal's Ctrl-C. A pytest started as a background job of a script or under ``nohup`` inherits
SIGINT ignored, its children would inherit that too, and a program keeps an inherited ignored
SIGINT ignored (brdffit does: ``brdffit.cli._signals``), so they would never see the signal: the
suite gives itself, and so its children, a terminal's SIGINT.
"""

import atexit
import ctypes
import gc
import os
import shutil
import signal
import tempfile

import jax
import pytest

if not os.environ.get("BRDFFIT_COMPILATION_CACHE_DIR"):
    _CACHE = tempfile.mkdtemp(prefix="brdffit-test-jax-cache-")
    os.environ["BRDFFIT_COMPILATION_CACHE_DIR"] = _CACHE
    atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)

jax.config.update("jax_enable_x64", True)

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def _status_kib(key: str) -> int:
    """A line of ``/proc/self/status`` in KiB; -1 where there is none (not Linux)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return -1


def pytest_runtest_logfinish(nodeid, location):
    """With ``BRDFFIT_TEST_MEMLOG=FILE``, append each test's process memory after it ran
    (``pid VmRSS VmHWM nodeid``, KiB): which tests raise a worker's peak
    (``benchmarks/suite_memory.py`` summarizes the file)."""
    path = os.environ.get("BRDFFIT_TEST_MEMLOG")
    if path and os.path.exists("/proc/self/status"):
        with open(path, "a") as fh:
            fh.write(f"{os.getpid()} {_status_kib('VmRSS')} {_status_kib('VmHWM')} {nodeid}\n")


# -- each pytest process's peak memory ---------------------------------------------------------
#: ``BRDFFIT_TEST_MAX_GB=G`` (``.ci/run`` sets 3): the session fails when a pytest process (an
#: xdist worker, or the only process under ``-n 0``) peaked above ``G`` GB resident. Without it
#: the peaks are only reported: a subset of the suite in one process, another platform or another
#: jaxlib peaks differently, and the goal is set for the README's command (two workers).
MAX_GB_VAR = "BRDFFIT_TEST_MAX_GB"
_PEAKS: dict[str, float] = {}  # process → VmHWM in GB, on the process that reports


def _peak_gb() -> float:
    return _status_kib("VmHWM") / 2**20


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """On the xdist controller: a worker's peak, handed over by its ``pytest_sessionfinish``."""
    kib = getattr(node, "workeroutput", {}).get("brdffit_vmhwm_kib")
    if kib is not None and kib >= 0:
        _PEAKS[node.gateway.id] = kib / 2**20


def pytest_sessionfinish(session, exitstatus):
    """A worker hands its peak to the controller; the controller (or the only process) fails
    the session when ``BRDFFIT_TEST_MAX_GB`` is set and a process peaked above it."""
    if _status_kib("VmHWM") < 0:
        return
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:  # an xdist worker
        workeroutput["brdffit_vmhwm_kib"] = _status_kib("VmHWM")
        return
    if not _PEAKS and session.testscollected and not session.config.option.collectonly:  # -n 0: this process ran the tests
        _PEAKS["pytest"] = _peak_gb()
    limit = _max_gb()
    if limit is not None and any(gb > limit for gb in _PEAKS.values()) and exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def _max_gb() -> float | None:
    raw = os.environ.get(MAX_GB_VAR)
    if not raw:
        return None
    try:
        return float(raw)
    except ValueError:
        raise pytest.UsageError(f"{MAX_GB_VAR}={raw!r}: expected a number of GB, e.g. 3") from None


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not _PEAKS:
        return
    limit = _max_gb()
    over = {k: gb for k, gb in _PEAKS.items() if limit is not None and gb > limit}
    peaks = ", ".join(f"{k} {gb:.2f} GB" for k, gb in sorted(_PEAKS.items()))
    goal = f" (limit {MAX_GB_VAR}={limit:g})" if limit is not None else ""
    terminalreporter.write_line(f"peak resident memory per pytest process: {peaks}{goal}")
    if over:
        terminalreporter.write_line(
            f"FAILED: {', '.join(over)} peaked above {limit:g} GB: find the tests that raise it "
            f"with BRDFFIT_TEST_MEMLOG=FILE and benchmarks/suite_memory.py FILE", red=True)


# -- JAX's caches of compiled programs ---------------------------------------------------------
#: Growth of a pytest process's resident memory (GB) since JAX's caches were last emptied after
#: which they are emptied again, between two tests.
CACHE_GROWTH_GB = 0.75
_AFTER_CLEAR_KIB = [None]


@pytest.fixture(autouse=True)
def _bounded_jax_caches():
    """JAX keeps every program it compiles (jit, and each primitive run eagerly) for the life of
    the process; with ``--dist loadfile`` a worker runs dozens of files, and their programs,
    never freed, took a worker past 5 GB. After a test that leaves the process more than
    :data:`CACHE_GROWTH_GB` above where the last emptying left it, the caches are emptied
    (``jax.clear_caches``). Tests share programs between them as long as memory allows, and a
    program dropped is compiled again on next use (from this run's persistent cache where JAX
    wrote it there): what runs, and so what is tested, is the same."""
    yield
    rss = _status_kib("VmRSS")
    if rss < 0:
        return
    if _AFTER_CLEAR_KIB[0] is None:
        _AFTER_CLEAR_KIB[0] = rss
    elif rss - _AFTER_CLEAR_KIB[0] > CACHE_GROWTH_GB * 2**20:
        _empty_jax_caches()


def _empty_jax_caches():
    gc.collect()
    jax.clear_caches()
    _trim_malloc()
    _AFTER_CLEAR_KIB[0] = _status_kib("VmRSS")


@pytest.fixture
def few_programs_held():
    """For a test that compiles a large model of its own (the APS anisotropic tables: 1.5 to
    1.9 GB alone): JAX's caches are emptied before it, so that it does not add its programs
    to up to :data:`CACHE_GROWTH_GB` of other tests' (a worker peaked at 2.84 GB of the
    suite's 3 GB)."""
    _empty_jax_caches()
    yield


def _trim_malloc():
    """Hand the pages freed back to the system (glibc keeps them otherwise), so that the
    resident memory measured next is what the process holds."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
