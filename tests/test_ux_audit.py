"""What the notebook and command-line tests take for granted, checked: the tests that press
Ctrl-C on a command they start see a terminal's Ctrl-C however the suite was launched, a
fit's progress bar moves while the fit runs (not all at once when it ends), and the summary's
first line reads as English."""

import dataclasses
import os
import signal
import subprocess
import sys
from pathlib import Path

import brdffit
from brdffit.fitting import stages
from test_api import write_sample_list

ROOT = Path(__file__).resolve().parent.parent
IS_DEFAULT = "import signal; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)"


# -- a terminal's Ctrl-C for the commands the tests interrupt -----------------------------------
def test_the_commands_the_suite_starts_get_a_terminals_ctrl_c():
    """A child inherits an ignored SIGINT; one that can be interrupted starts with Python's
    ``KeyboardInterrupt`` handler."""
    child = subprocess.run([sys.executable, "-c", IS_DEFAULT], capture_output=True, text=True,
                           timeout=60)
    assert child.stdout.strip() == "True", "SIGINT reaches the suite's children ignored"


BACKGROUND = ("import os, signal, sys\n"
              "signal.signal(signal.SIGINT, signal.SIG_IGN)  # `pytest &` in a script, nohup\n"
              "os.execv(sys.executable, [sys.executable, *sys.argv[1:]])\n")


def test_a_suite_started_as_a_background_job_still_interrupts_its_children():
    """``pytest ... &`` from a script (or under ``nohup``): SIGINT ignored from the start.
    Before, the tests of Ctrl-C on ``brdffit batch``/``fit`` failed there (the command never
    saw the signal and ran to exit 0): the suite now hands its children a terminal's SIGINT."""
    probe = "tests/test_ux_audit.py::test_the_commands_the_suite_starts_get_a_terminals_ctrl_c"
    run = subprocess.run([sys.executable, "-c", BACKGROUND, "-m", "pytest", "-q", "-n", "0",
                          "-p", "no:cacheprovider", probe], cwd=ROOT, capture_output=True,
                         text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert run.returncode == 0 and "1 passed" in run.stdout, run.stdout[-2000:] + run.stderr


# -- the bar moves while the fit runs -----------------------------------------------------------
def test_a_fits_step_events_arrive_between_its_compiled_rounds(tmp_path, monkeypatch):
    """Each step event is sent when its round of at most ``ROUND_STEPS`` solver steps returns,
    before the next round is run: one solve of more steps than a round (no scan, a start far
    from the optimum) moves its bar (or a callback) during the solve, not once it has ended."""
    path = write_sample_list(tmp_path / "gold.csv", n=300)
    rounds = []
    original = stages.solve
    monkeypatch.setattr(stages, "solve", lambda *a, **k: rounds.append(1) or original(*a, **k))
    seen = []  # the rounds that had run when each step event arrived
    result = brdffit.fit(path, "ggx", scan=False, init={"alpha": 0.002},
                         progress=lambda e, info: seen.append(len(rounds)) if e.endswith("step")
                         else None)
    assert result.steps > stages.ROUND_STEPS, result.steps
    assert len(rounds) > 1 and seen[0] < len(rounds), (seen, len(rounds))
    assert len(set(seen)) > 1 and seen == sorted(seen)


def test_the_summary_counts_one_step_in_the_singular(tmp_path):
    """``converged in 1 steps`` (the report said ``1 step``)."""
    result = brdffit.fit(write_sample_list(tmp_path / "gold.csv", n=300), "ggx")
    for steps, said in ((1, "in 1 step,"), (2, "in 2 steps,")):
        head = dataclasses.replace(result, steps=steps, total_steps=steps).summary().splitlines()[0]
        assert said in head, head


# -- every solver step counted, as lmfit's nfev ---------------------------------------------------
def test_the_result_counts_every_solver_step_as_the_bar_does(tmp_path):
    """``steps`` is the last stage's; ``total_steps`` every solver step of the fit (the start
    scan's candidates, the starts, a refined model's simpler fit): what a progress bar counts
    and lmfit's ``nfev`` reports. Before, the report said "3 steps" where the bar said 35."""
    path = write_sample_list(tmp_path / "gold.csv", n=300)
    for model in ("ggx", "two-lobe-ggx"):  # two-lobe-ggx fits ggx first (Model.refines)
        events = []
        result = brdffit.fit(path, model, multistart=1,
                             progress=lambda e, info: events.append(e))
        stepped = sum(e.endswith("step") for e in events)
        assert result.total_steps == stepped > result.steps, (model, result.total_steps, stepped)
        assert (model == "two-lobe-ggx") == any(e.startswith("base-") for e in events)
        assert f"{result.total_steps} solver steps in all" in result.report()
        assert f"({result.total_steps} in all stages)" in result.summary().splitlines()[0]
        back = brdffit.FitResult.from_json(result.to_json())
        assert back.total_steps == result.total_steps
    # a silent fit counts the same steps (the count does not need a callback)
    assert brdffit.fit(path, "two-lobe-ggx", multistart=1).total_steps == result.total_steps
    # a result written before the count reads as 0, and its report says nothing about it
    import json
    old = json.loads(result.to_json())
    del old["total_steps"]
    legacy = brdffit.FitResult.from_json(json.dumps(old))
    assert legacy.total_steps == 0 and "in all" not in legacy.report()
