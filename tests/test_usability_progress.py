"""Progress is presentation: the same compiled program with or without it, a bar that moves
with the solver's steps (in a notebook too), and one bar per fit on a terminal with the event
lines under ``--verbose``.

Every fit here is ``ggx`` on the same 1200-sample list, so they share one compiled program."""

import io
import sys
import tomllib
from pathlib import Path

import jax
import pytest

import brdffit
from brdffit.cli import main
from brdffit.progress import Bar
from test_api import write_sample_list

ROOT = Path(__file__).resolve().parent.parent
TRACE_EVENT = "/jax/core/compile/jaxpr_trace_duration"


@pytest.fixture(scope="module")
def samples_csv(tmp_path_factory):
    return write_sample_list(tmp_path_factory.mktemp("progress") / "gold.csv")


class Tty(io.StringIO):
    """A text stream that says it is a terminal."""

    def isatty(self):
        return True


def _traces(call) -> int:
    """The functions JAX traced (each new program starts with a trace, also one that the
    persistent compilation cache then finds) while ``call()`` ran."""
    seen = []

    def listen(event, duration, **kwargs):
        if event == TRACE_EVENT:
            seen.append(event)

    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        call()
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)
    return len(seen)


# -- a fit with progress runs the program of a fit without ------------------------------------
def test_progress_compiles_nothing_that_a_silent_fit_did_not(samples_csv):
    """The reproducer: ``fit(t, "ggx")`` then ``fit(t, "ggx", progress=...)``. Before, the
    second call traced and compiled the solve again (its ``verbose`` hook was another pytree)."""
    brdffit.fit(samples_csv, "ggx")
    steps = []
    callback = lambda event, info: steps.append(info["step"]) if event.endswith("step") else None
    assert _traces(lambda: brdffit.fit(samples_csv, "ggx", progress=callback)) == 0
    assert len(steps) > 5  # the callback still gets every step
    bar = Bar(file=io.StringIO())
    assert _traces(lambda: brdffit.fit(samples_csv, "ggx", progress=bar)) == 0
    assert _traces(lambda: brdffit.fit(samples_csv, "ggx")) == 0  # and back


# -- the bar moves with the solver's steps ------------------------------------------------------
def test_the_bar_counts_the_solver_steps_while_the_fit_runs(samples_csv):
    """Before, the bar's total was the number of starts: it sat at ``0/1`` until the fit
    ended. Now each step event advances it, and it ends full at the steps taken."""
    out = io.StringIO()
    bar = Bar(file=out)
    seen = []

    def watch(event, info):
        bar(event, info)
        if event.endswith("step"):
            seen.append(bar.bar.n)

    result = brdffit.fit(samples_csv, "ggx", progress=watch)
    assert result.success and len(seen) > 5
    assert seen == list(range(1, len(seen) + 1))  # one position per step, as it happens
    text = out.getvalue()
    assert f"{len(seen)}/{len(seen)}" in text and "100%" in text
    assert "start 1/1" in text and "converged" in text and "fit ggx" in text
    assert bar.bar is None  # closed by ``done``


def test_a_bar_given_to_a_fit_is_closed_when_the_fit_raises(samples_csv):
    """A bar left open would take the terminal's next line (the command line's error)."""
    out = io.StringIO()
    bar = Bar(file=out)
    with pytest.raises(brdffit.BrdffitError):
        brdffit.fit(samples_csv, "ggx", progress=bar, max_steps=1)
    assert bar.bar is None and out.getvalue().endswith("\n")


def test_a_notebook_extra_brings_the_widgets():
    """``progress=True`` in Jupyter is a ``tqdm.auto`` widget only with ipywidgets installed
    (before: no way to ask for it, and tqdm's "IProgress not found" warning)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extra = project["optional-dependencies"]["notebook"]
    assert any(req.startswith("ipywidgets") for req in extra)


# -- the command line: one bar on a terminal, the events under --verbose ------------------------
def _fit_cli(monkeypatch, capsys, stream, samples_csv, *flags):
    monkeypatch.setattr(sys, "stderr", stream)
    code = main(["fit", str(samples_csv), "--model", "ggx", *flags])
    capsys.readouterr()
    return code, stream.getvalue()


def test_a_terminal_shows_one_bar_per_fit(monkeypatch, capsys, samples_csv):
    """Before: 73 event lines per fit on a terminal (58 ``scan-step``)."""
    code, err = _fit_cli(monkeypatch, capsys, Tty(), samples_csv)
    assert code == 0
    assert "scan-step" not in err and "setup" not in err
    lines = err.rstrip("\n").split("\n")
    assert len(lines) == 2, err  # the message, then the bar (redrawn in place with \r)
    assert "fitting ggx to" in lines[0]
    last = lines[1].split("\r")[-1]
    assert "fit ggx:" in last and "100%" in last and "converged" in last


def test_verbose_prints_every_event(monkeypatch, capsys, samples_csv):
    """``--verbose``: the event lines, also when stderr is not a terminal (a log file)."""
    code, err = _fit_cli(monkeypatch, capsys, io.StringIO(), samples_csv, "--verbose")
    assert code == 0
    lines = err.splitlines()
    assert any(" setup " in line for line in lines) and any(" done " in line for line in lines)
    steps = [line for line in lines if "scan-step" in line]
    assert len(steps) > 5 and not any("\r" in line or "\x1b" in line for line in lines)
    code, err = _fit_cli(monkeypatch, capsys, io.StringIO(), samples_csv)
    assert code == 0 and err == ""  # piped without --verbose: nothing


@pytest.mark.parametrize("where", ["after", "before", "split"])
def test_quiet_and_verbose_are_one_usage_error(monkeypatch, capsys, samples_csv, where):
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    fit = ["fit", str(samples_csv), "--model", "ggx"]
    argv = {"after": fit + ["--quiet", "--verbose"], "before": ["--quiet", "--verbose"] + fit,
            "split": ["--quiet"] + fit + ["--verbose"]}[where]
    assert main(argv) == 2
    err = sys.stderr.getvalue()
    assert len(err.strip().splitlines()) == 1 and "not allowed with" in err


def test_a_signal_closes_the_bar_before_its_line():
    """The signal's "interrupted" line must be the last one: the bar is closed first (its
    line ended), and an update still arriving from the solve draws nothing after it."""
    from tqdm import tqdm

    from brdffit.cli._signals import _close_progress_bars

    out = Tty()
    bar = tqdm(total=None, file=out, desc="fit ggx")
    bar.update(3)
    _close_progress_bars()
    assert out.getvalue().endswith("\n")
    before = out.getvalue()
    bar.update(1)
    bar.refresh()
    assert out.getvalue() == before


def _read_pty(master: int, until: str, timeout: float = 10.0) -> str:
    """What a pseudo-terminal's master side has to read, up to the first read holding ``until``
    or ``timeout`` seconds. The kernel hands what the slave side wrote to the master side
    asynchronously (its flip buffer is pushed by a work queue), so on a loaded machine one read
    can return only the first part of what was written."""
    import os
    import select
    import time

    text, deadline = "", time.monotonic() + timeout
    while until not in text and (left := deadline - time.monotonic()) > 0:
        if select.select([master], [], [], left)[0]:
            text += os.read(master, 65536).decode(errors="replace")
    return text


def test_the_bar_shows_on_a_terminal_that_does_not_tell_its_size():
    """A pseudo-terminal nobody sized says 0 × 0: tqdm took it for -1 columns and -1 rows and
    drew nothing at all (before, also the old bar)."""
    import os
    import pty

    master, slave = pty.openpty()
    tty = os.fdopen(slave, "w", buffering=1)
    try:
        bar = Bar(file=tty)
        bar("setup", {"model": "ggx", "n_cells": 1200, "n_free": 8})
        bar("start", {"start": 0, "of": 1})
        for k in range(3):
            bar("scan-step", {"start": 0, "step": k, "cost": 1.0 / (k + 1)})
        bar("done", {"success": True, "cost": 0.25})
        tty.flush()
        text = _read_pty(master, until="converged")
    finally:
        tty.close()
        os.close(master)
    assert "fit ggx" in text and "start 1/1" in text and "3/3" in text and "converged" in text


_KERNEL_WITHOUT_WIDGETS = """
import io, sys, types, warnings
ipython = types.ModuleType("IPython")
ipython.get_ipython = lambda: types.SimpleNamespace()
sys.modules["IPython"] = ipython  # what tqdm.auto looks for: a Jupyter kernel's shell
sys.modules["ipykernel.zmqshell"] = types.ModuleType("ipykernel.zmqshell")
sys.modules["ipywidgets"] = None  # not installed
from brdffit.progress import Bar
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    Bar("posterior", file=io.StringIO())("sample-step", {"step": 1, "of": 2})
for w in caught:
    print(w.category.__name__, str(w.message))
"""


_KERNEL_WITH_WIDGETS = """
import io, sys, types, warnings
import IPython
IPython.get_ipython = lambda: types.SimpleNamespace()
sys.modules.setdefault("ipykernel.zmqshell", types.ModuleType("ipykernel.zmqshell"))  # a kernel
from brdffit.progress import Bar
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    bar = Bar("fit", file=io.StringIO())
    bar("setup", {"model": "ggx", "n_cells": 10, "n_free": 7})
    widget = bar.bar
    moved = []
    for k in range(5):
        bar("step", {"step": k, "cost": 1.0})
        moved.append(widget.n)
    bar("done", {"success": True, "cost": 1.0})
print("WIDGET", type(widget.container).__name__, moved, widget.total)
for w in caught:
    print(w.category.__name__, str(w.message))
"""


def test_a_kernel_with_the_notebook_extra_draws_a_widget_that_moves_with_the_steps():
    """With ``brdffit[notebook]`` installed, ``progress=True`` in Jupyter is tqdm's widget
    (an ipywidgets box), advanced by every solver step and full at the end, without a warning."""
    import os
    import subprocess

    pytest.importorskip("ipywidgets")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, "-c", _KERNEL_WITH_WIDGETS], capture_output=True,
                         text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    line = next(x for x in run.stdout.splitlines() if x.startswith("WIDGET"))
    assert line == "WIDGET TqdmHBox [1, 2, 3, 4, 5] 5", run.stdout
    assert "Warning" not in run.stdout.split(line)[1], run.stdout


def test_a_kernel_without_ipywidgets_is_told_which_extra_to_install():
    """Before: tqdm's own "IProgress not found. Please update jupyter and ipywidgets" warning;
    now one that names ``brdffit[notebook]`` (the bar still works, as text)."""
    import os
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, "-c", _KERNEL_WITHOUT_WIDGETS], capture_output=True,
                         text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "TqdmWarning" not in run.stdout and "IProgress" not in run.stdout
    assert "pip install 'brdffit[notebook]'" in run.stdout
