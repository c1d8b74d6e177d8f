"""SIGINT at random times during ``brdffit batch``: count what is left behind and how it exits.

Run from the repository root (50 trials: about 8 minutes on two cores)::

    python benchmarks/signal_trials_batch.py [--trials 50] [--seed 0] [--inputs 3]
                                             [--samples 2000] [--subsample 300] [--window 0.8]
                                             [--hang 60]

Setup: ``--inputs`` small synthetic sample lists (``brdffit synth --samples``); two batches
without a signal give the run time T (the second, warm one). Then each trial starts ``brdffit
batch IN... -m ggx --subsample N --workers 1 -o OUTDIR`` as a real process (``cli.py``) in its
own session, with ``TMPDIR`` a fresh folder, waits a uniform random time in [0.2 s, ``--window``
* T], and sends SIGINT: to the process alone on even trials, to its whole process group (what
Ctrl-C in a terminal does) on odd ones. The window is below T so that most trials land before
the batch ends; those that do not are counted as *finished*.

Counted per trial (the problem counts must all be zero):

* **exit codes**: 130 is right when the signal came before the batch ended; a batch that had
  already ended is *finished* (not counted); 0/1 after the signal with every result written is
  *finished despite the signal* (listed); anything else is a **wrong exit** (past ``--hang``
  seconds after the signal: a **hang**, then the group is killed).
* **leftovers**: ``.brdffit-*`` anywhere, hidden temporaries in OUTDIR (``.name.XXXX.ext``),
  a ``<model>.json`` that does not parse or lacks its ``<model>.meta.json`` (or the reverse),
  a ``results.csv``/``results.parquet`` after exit 130 that does not parse, any other file in
  OUTDIR or beside the inputs, anything left in the trial's ``TMPDIR`` (Dask's scratch space,
  ``dask-scratch-space/worker-*``; not its two shared ``*.lock`` files, which every run
  leaves), and any process of the batch's session still alive 5 s
  after it exited (orphaned workers).
* **warnings**: stderr lines beyond the one message, e.g. "leaked semaphore", "Traceback",
  "Exception ignored", "CancelledError", "Task was destroyed".

Per-fit results completed before the signal are kept on purpose (a batch is resumable) and are
not leftovers. Exits 1 when any problem was counted.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
EXPECTED_MODEL_FILES = re.compile(r"^[\w.+-]+/(ggx|beckmann)(\.json|\.meta\.json|-[\w-]+\.png)$")
TEMPORARY = re.compile(r"(^|/)\.brdffit-|(^|/)\.[^/]+\.\w{8}(\.\w+)?$|\.tmp$|\.part$")
#: Dask's shared scratch-space locks: every run leaves them (unsignalled too), by design.
DASK_LOCKS = {"dask-scratch-space/global.lock", "dask-scratch-space/purge.lock"}
KINDS = [("leaked semaphore", "leaked semaphore"), ("Traceback", "Traceback"),
         ("Exception ignored", "Exception ignored"), ("already in use", "port 8787 in use"),
         ("CancelledError", "CancelledError"), ("Task was destroyed", "Task was destroyed")]
WARNINGS = re.compile(r"leaked|Traceback|Exception ignored|CancelledError|Task was destroyed|"
                      r"Warning|ERROR|Error", re.IGNORECASE)


def session_processes(sid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            with contextlib.suppress(OSError):
                if os.getsid(int(entry)) == sid:
                    out.append(int(entry))
    return out


def start(argv, cwd, tmpdir) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmpdir)}
    return subprocess.Popen([sys.executable, str(ROOT / "cli.py"), *map(str, argv)], cwd=cwd,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            stdin=subprocess.DEVNULL, start_new_session=True)


def leftovers(folder: Path, inputs: set, outdir: Path, tmpdir: Path, code) -> list[str]:
    found = []
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_dir() or rel in inputs:
            continue
        if TEMPORARY.search(rel):
            found.append(f"temporary {rel}")
            continue
        if not p.is_relative_to(outdir):
            found.append(f"stray {rel}")
            continue
        inner = str(p.relative_to(outdir))
        if inner in ("results.csv", "results.parquet"):
            try:
                if inner.endswith(".csv"):
                    p.read_text().splitlines()[0].index("material")
                else:
                    import pyarrow.parquet as pq

                    pq.read_table(p)
            except Exception as exc:  # noqa: BLE001 - a partial table
                found.append(f"partial {rel} ({type(exc).__name__})")
            continue
        if not EXPECTED_MODEL_FILES.match(inner):
            found.append(f"stray {rel}")
            continue
        if inner.endswith(".json"):
            try:
                json.loads(p.read_text())
            except ValueError:
                found.append(f"partial {rel} (not JSON)")
            twin = (p.with_name(p.name.replace(".meta.json", ".json")) if ".meta." in p.name
                    else p.with_name(p.name.replace(".json", ".meta.json")))
            if not twin.exists():
                found.append(f"partial {rel} (without {twin.name})")
    for p in sorted(tmpdir.rglob("*")):
        if str(p.relative_to(tmpdir)) in DASK_LOCKS:
            continue
        if not p.is_dir() or not any(p.iterdir()):
            found.append(f"in TMPDIR: {p.relative_to(tmpdir)}")
    return found


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--inputs", type=int, default=3, help="sample lists in the batch")
    ap.add_argument("--samples", type=int, default=2000, help="samples per list")
    ap.add_argument("--subsample", default="300", help="the batch's --subsample")
    ap.add_argument("--window", type=float, default=0.8,
                    help="signal times are uniform in [0.2 s, WINDOW * T]")
    ap.add_argument("--hang", type=float, default=60.0,
                    help="seconds after the signal that count as a hang")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    base = Path(tempfile.mkdtemp(prefix="signal-trials-batch-"))
    try:
        return run(args, rng, base)
    finally:
        shutil.rmtree(base, ignore_errors=True)


def run(args, rng, base: Path) -> int:
    folder = base / "work"
    folder.mkdir()
    names = []
    for i in range(args.inputs):
        name = f"m{i}.csv"
        model = ["ggx", "beckmann", "gltf-pbr"][i % 3]
        r = subprocess.run([sys.executable, str(ROOT / "cli.py"), "synth", "-m", model,
                            "--samples", str(args.samples), "--seed", str(i), "-o", name, "-q"],
                           cwd=folder, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert r.returncode == 0
        names.append(name)
    argv = ["batch", *names, "-m", "ggx", "--subsample", args.subsample, "--workers", "1",
            "-o", "out", "-q"]
    tmpdir = base / "tmp0"
    tmpdir.mkdir()
    for _ in range(2):  # the second, warm run (compilation cache filled) gives T
        shutil.rmtree(folder / "out", ignore_errors=True)
        t0 = time.perf_counter()
        p = start(argv, folder, tmpdir)
        out, err = p.communicate()
        full = time.perf_counter() - t0
    print(f"command: brdffit {' '.join(argv)}\nunsignalled run: exit {p.returncode} in "
          f"{full:.1f} s; stderr {err.strip()[-200:]!r}", flush=True)
    codes: collections.Counter = collections.Counter()
    problems: collections.Counter = collections.Counter()
    examples: list[str] = []
    warning_kinds: collections.Counter = collections.Counter()
    left = leftovers(folder, set(names), folder / "out", tmpdir, p.returncode)
    print(f"unsignalled run leaves: {left or 'nothing'}", flush=True)

    def note(kind, text):
        problems[kind] += 1
        if len(examples) < 30:
            examples.append(f"{kind}: {text}")

    for trial in range(args.trials):
        shutil.rmtree(folder / "out", ignore_errors=True)
        tmpdir = base / f"tmp{trial + 1}"
        tmpdir.mkdir()
        delay = float(rng.uniform(0.2, args.window * full))
        group = trial % 2 == 1
        p = start(argv, folder, tmpdir)
        time.sleep(delay)
        finished_before = p.poll() is not None
        if not finished_before:
            with contextlib.suppress(ProcessLookupError):
                (os.killpg if group else os.kill)(p.pid, signal.SIGINT)
        t_sig = time.perf_counter()
        try:
            out, err = p.communicate(timeout=args.hang)
            code = p.returncode
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            out, err = p.communicate()
            code = None
            note("hangs", f"trial {trial}: still running {args.hang:.0f} s after the signal")
        waited = time.perf_counter() - t_sig
        time.sleep(0.5)
        alive = session_processes(p.pid)
        deadline = time.perf_counter() + 5
        while alive and time.perf_counter() < deadline:
            time.sleep(0.25)
            alive = session_processes(p.pid)
        label = "finished" if finished_before else str(code)
        codes[label] += 1
        where = f"trial {trial} (SIGINT to {'group' if group else 'process'} at {delay:.2f} s)"
        if not finished_before and code not in (130, None):
            outdir = folder / "out"
            complete = (outdir / "results.csv").is_file() and len(
                (outdir / "results.csv").read_text().splitlines()) == args.inputs + 1
            if code in (0, 1) and complete:
                codes[f"{code} (finished despite the signal)"] += 1
            else:
                note("wrong exits", f"{where}: exit {code}; stderr {err.strip()[-200:]!r}")
        if alive:
            note("orphans", f"{where}: {len(alive)} processes of the batch alive after it exited")
            for pid in alive:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        found = leftovers(folder, set(names), folder / "out", tmpdir, code)
        for f in found:
            note("leftovers", f"{where}: {f}")
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        extra = lines[1:] if lines and not WARNINGS.search(lines[0]) else lines
        bad = [ln for ln in extra if WARNINGS.search(ln)] or (extra if len(lines) > 1 else [])
        if bad:
            note("warnings", f"{where}: {bad[:3]}")
            for needle, kind in KINDS + [("", "other")]:
                if any(needle in ln for ln in bad):
                    warning_kinds[kind] += 1
                    break
        print(f"trial {trial:3d}: SIGINT to {'group  ' if group else 'process'} at {delay:5.2f} s"
              f" -> {label:>8s} after {waited:5.2f} s; leftovers {len(found)}, orphans "
              f"{len(alive)}, stderr {err.strip()[-90:]!r}", flush=True)
        shutil.rmtree(tmpdir, ignore_errors=True)
    print(f"\n{args.trials} trials: exit codes {dict(codes)}")
    print("problems: " + ", ".join(f"{k} {problems.get(k, 0)}" for k in
                                   ("wrong exits", "hangs", "leftovers", "orphans", "warnings")))
    print(f"trials with warnings, by kind: {dict(warning_kinds)}")
    for e in examples:
        print("  " + e)
    return 1 if sum(problems.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
