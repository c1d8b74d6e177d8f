"""Signal trials: send SIGINT (or SIGTERM) to a ``brdffit`` command at random times over its run,
then count exit statuses, leftovers and mixed outcomes.

    python benchmarks/signal_trials.py --trials 50
    python benchmarks/signal_trials.py --trials 50 --signal TERM -- \\
        fit {data} -m ggx --subsample 300 --out r.json --plot f.png --table t.binary
    python benchmarks/signal_trials.py --trials 20 -- batch {list} -o out -m ggx --subsample 300

The command (after ``--``; default: the one above, ``fit --out --plot --table``) runs with this
checkout's ``cli.py``, each trial in a fresh folder, where ``{data}`` is a small synthetic ggx
sample list (``--samples`` pairs, made once) and ``{list}`` a batch list naming it. One run
without a signal first gives the run time ``T`` and the files a finished run leaves; each trial
then sends the signal after a delay drawn uniformly from ``[0, 1.1 T]`` (a trial whose command
ended before the delay counts as "finished first", and its run time updates ``T``, the median of
the runs that ended without a signal, as the machine's load changes).

For each trial: the exit status; **leftovers** (any name starting with ``.`` in the folder tree:
staging folders ``.brdffit-*``, temporaries ``.name.XXXX``; or a file a finished run does not
leave); what was **published** (all of a finished run's files, none, or part). The contract
(:mod:`brdffit.cli._signals`): published and the command's own status (0, or 1 for a fit that
did not converge), or nothing and 130 / 143; "published + 130/143" and "partial" are
violations for the all-or-nothing commands (``fit``, ``plot``, ``synth``, ``export``,
``render``, ``demo``). Also counted: tracebacks on stderr and deaths by a signal (negative
status): by the signal sent, when it came before the command installed its handler (nothing
written yet: not a violation), or by another (a crash: a violation).

Nothing is timed against a goal: the figures are counts. ``--json FILE`` writes every trial.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = "fit {data} -m ggx --subsample 300 --out r.json --plot f.png --table t.binary"


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
            "OPENBLAS_NUM_THREADS": "1"}


def _brdffit(args, cwd) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(ROOT / "cli.py"), *args], cwd=cwd, env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _tree(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")
                  if p.is_file() or p.is_symlink() or (p.is_dir() and p.name.startswith(".")))


def _prepare(work: Path, samples: int) -> dict:
    data = work / "data.csv"
    p = _brdffit(["synth", "-m", "ggx", "-p", "alpha=0.2", "--samples", str(samples), "-o",
                  str(data), "-q"], work)
    if p.wait() != 0:
        sys.exit(f"signal_trials: synth failed: {p.stderr.read()}")
    listing = work / "list.txt"
    listing.write_text(f"{data}\n")
    return {"data": str(data), "list": str(listing)}


def _run(args, folder: Path, delay: float | None, signum: int) -> dict:
    p = _brdffit(args, folder)
    start = time.monotonic()
    sent = False
    if delay is not None:
        try:
            p.wait(timeout=delay)
        except subprocess.TimeoutExpired:
            p.send_signal(signum)
            sent = True
    err = p.communicate(timeout=600)[1]
    return {"delay": delay, "sent": sent, "status": p.returncode, "stderr": err,
            "seconds": time.monotonic() - start, "files": _tree(folder)}


def _classify(trial: dict, expected: set, signum: int) -> dict:
    files = set(trial["files"])
    hidden = sorted(f for f in files if any(part.startswith(".") for part in Path(f).parts))
    strange = sorted(files - expected - set(hidden))
    present = files & expected
    published = "all" if present == expected else "none" if not present else "partial"
    code = trial["status"]
    interrupted = code == 128 + signum
    return {
        **trial,
        "leftovers": hidden + strange,
        "published": published,
        "traceback": "Traceback" in trial["stderr"],
        "violation": (bool(hidden or strange) or published == "partial"
                      or (interrupted and published == "all")
                      or (code in (0, 1) and published != "all")
                      or (code < 0 and not (code == -signum and published == "none"))),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=50, help="number of trials (50)")
    parser.add_argument("--signal", choices=("INT", "TERM"), default="INT")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random delays")
    parser.add_argument("--samples", type=int, default=2000,
                        help="direction pairs in the synthetic sample list (2000)")
    parser.add_argument("--json", metavar="FILE", help="write every trial to FILE")
    parser.add_argument("--keep", action="store_true", help="keep the trial folders")
    parser.add_argument("command", nargs=argparse.REMAINDER,
                        help=f"the brdffit command after `--` (default: {DEFAULT})")
    opts = parser.parse_args(argv)
    # children inherit an ignored SIGINT (a shell's background job has one): start them with
    # the default dispositions, as from a terminal
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    command = [c for c in opts.command if c != "--"] or shlex.split(DEFAULT)
    signum = getattr(signal, f"SIG{opts.signal}")
    work = Path(tempfile.mkdtemp(prefix="brdffit-signal-trials-"))
    try:
        names = _prepare(work, opts.samples)
        args = [c.format(**names) for c in command]
        base = work / "calibration"
        base.mkdir()
        ref = _run(args, base, None, signum)
        if ref["status"] not in (0, 1):
            sys.exit(f"signal_trials: the command failed without a signal "
                     f"(exit {ref['status']}): {ref['stderr'].strip()[-500:]}")
        expected, durations = set(ref["files"]), [ref["seconds"]]
        print(f"command: brdffit {shlex.join(args)}")
        print(f"without a signal: exit {ref['status']} in {ref['seconds']:.1f} s, "
              f"{len(expected)} files: {', '.join(sorted(expected))}")
        period = ref["seconds"]
        rng = np.random.default_rng(opts.seed)
        trials = []
        for k in range(opts.trials):
            folder = work / f"t{k:03d}"
            folder.mkdir()
            trial = _classify(_run(args, folder, float(rng.uniform(0, 1.1 * period)), signum),
                              expected, signum)
            trials.append(trial)
            if not trial["sent"]:  # the run time follows the machine's load
                durations.append(trial["seconds"])
                period = float(np.median(durations))
            flag = "  <-- " + ", ".join(
                x for x in (("leftovers " + " ".join(trial["leftovers"]))
                            if trial["leftovers"] else "",
                            f"published {trial['published']}"
                            if trial["violation"] else "",
                            "traceback" if trial["traceback"] else "") if x) \
                if trial["violation"] or trial["traceback"] else ""
            print(f"trial {k:3d}: signal at {trial['delay']:5.2f} s"
                  f"{'' if trial['sent'] else ' (finished first)'}: exit {trial['status']}, "
                  f"published {trial['published']}{flag}", flush=True)
            if not opts.keep:
                shutil.rmtree(folder, ignore_errors=True)
        _summary(trials, signum)
        if opts.json:
            Path(opts.json).write_text(json.dumps(trials, indent=1))
        return 1 if any(t["violation"] for t in trials) else 0
    finally:
        if not opts.keep:
            shutil.rmtree(work, ignore_errors=True)


def _summary(trials, signum) -> None:
    codes = collections.Counter(t["status"] for t in trials)
    sent = [t for t in trials if t["sent"]]
    print(f"\n{len(trials)} trials, signal sent in {len(sent)} "
          f"({len(trials) - len(sent)} finished first)")
    print("exit statuses: " + ", ".join(f"{c}: {n}" for c, n in sorted(codes.items())))
    print(f"leftovers: {sum(bool(t['leftovers']) for t in trials)}")
    print(f"published + {128 + signum}: "
          f"{sum(t['status'] == 128 + signum and t['published'] == 'all' for t in trials)}")
    print(f"partial publication: {sum(t['published'] == 'partial' for t in trials)}")
    print(f"0/1 without the outputs: "
          f"{sum(t['status'] in (0, 1) and t['published'] != 'all' for t in trials)}")
    print(f"killed by the signal itself (status -{signum}: it came before the handler was "
          f"installed): {sum(t['status'] == -signum for t in trials)}")
    print(f"killed by another signal (a crash): "
          f"{sum(t['status'] < 0 and t['status'] != -signum for t in trials)}")
    print(f"tracebacks: {sum(t['traceback'] for t in trials)}")
    print(f"violations: {sum(t['violation'] for t in trials)}")


if __name__ == "__main__":
    sys.exit(main())
