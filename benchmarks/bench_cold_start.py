"""Benchmark: a second ``brdffit fit`` process against the first, with the compilation cache.

    .venv/bin/python benchmarks/bench_cold_start.py [--model ggx] [--samples N] [--repeat 2]

What it does (the persistent compilation cache, :mod:`brdffit.compilation_cache`):

1. Writes the input into a temporary folder with ``brdffit synth``: a full MERL table
   (default) or, with ``--samples N``, a sample list of ``N`` random direction pairs.
2. Points ``XDG_CACHE_HOME`` at an empty temporary folder and runs ``brdffit fit INPUT
   --model M --json`` in a fresh process: the first, cold process (it compiles everything and
   fills the cache). Then ``--repeat`` more fresh processes: cold processes that find the
   cache. Then the same with ``BRDFFIT_NO_COMPILATION_CACHE=1`` (every process compiles).
3. Prints each process's wall time (start-up, reading, fitting, printing: what a user waits
   for) and the fit's own ``wall_time`` from its JSON, the ratio first/second, the cache-off
   median against the cold-start goal (``GOAL_S``), the cache's size, and the load average
   (the machine may be shared).

``--input FILE`` times a table of your own (a realistic one: ``../shared/realistic/render.py``
writes MERL tables) instead of the synthetic one. Before the first process and after the last
it prints the machine's **fresh-memory reference** (:func:`fresh_memory_reference`): a cold
``brdffit fit`` of a full table touches about 1 GB it never used before, and on a virtual
machine whose host backs guest memory lazily, the first touch of a page can cost ~10 ms per
MB at one moment and 0.1 ms at the next, so two cold figures
compare only beside this one.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BRDFFIT = [sys.executable, "-c", "from brdffit._program import run; run()"]  # the console script

#: The goal for a cold ``brdffit fit --model ggx`` of a full table, compilation included (s).
GOAL_S = 8.0

#: The fresh-memory reference touches this many chunks of this many float64 values (35 MB).
TOUCH_CHUNKS, TOUCH_VALUES = 20, 4_374_000

_TOUCH = f"""
import time, numpy as np
keep, out = [], []
for _ in range({TOUCH_CHUNKS}):
    t = time.perf_counter(); a = np.empty({TOUCH_VALUES}); a[:] = 1.0
    out.append(time.perf_counter() - t); keep.append(a)
print(' '.join(map(repr, out)))
"""


def fresh_memory_reference() -> tuple[float, float]:
    """``(median, max)`` seconds per 35 MB that a fresh process takes to write memory it has
    just allocated (``TOUCH_CHUNKS`` chunks, all kept): the page-fault cost that every cold
    process pays on the memory it uses, which no brdffit code is in."""
    out = subprocess.run([sys.executable, "-c", _TOUCH], capture_output=True, text=True,
                         check=True)
    times = [float(t) for t in out.stdout.split()]
    return statistics.median(times), max(times)


def print_fresh_memory(when: str) -> None:
    med, top = fresh_memory_reference()
    print(f"  fresh-memory reference ({when}): {med * 1e3:.0f} ms median, {top * 1e3:.0f} ms max "
          f"per 35 MB ({TOUCH_CHUNKS} chunks)")


def run(args, env, cwd) -> tuple[float, dict]:
    t = time.perf_counter()
    out = subprocess.run(BRDFFIT + args, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if out.returncode not in (0, 1):
        raise SystemExit(f"brdffit {' '.join(args)} failed:\n{out.stderr}")
    return wall, (json.loads(out.stdout) if "--json" in args else {})


def size_of(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default="ggx")
    ap.add_argument("--samples", type=int, help="a sample list of N pairs instead of a table")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--input", help="a MERL table (.binary) or sample list to time instead")
    opts = ap.parse_args()
    if opts.input and opts.samples:
        raise SystemExit("bench_cold_start: give --input or --samples, not both")
    work = Path(tempfile.mkdtemp(prefix="brdffit-bench-cold-"))
    try:
        cache = work / "cache"
        env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
        env.pop("BRDFFIT_NO_COMPILATION_CACHE", None)
        if opts.input:
            name = str(Path(opts.input).resolve())
        else:
            name = "in.csv" if opts.samples else "in.binary"
            synth = ["synth", "--model", opts.model, "-o", name, "--quiet"]
            run(synth + (["--samples", str(opts.samples)] if opts.samples else []),
                {**env, "BRDFFIT_NO_COMPILATION_CACHE": "1"}, work)
        print_fresh_memory("before")
        fit = ["fit", name, "--model", opts.model, "--json", "--quiet"]
        first = run(fit, env, work)
        cached = [run(fit, env, work) for _ in range(opts.repeat)]
        off_env = {**env, "BRDFFIT_NO_COMPILATION_CACHE": "1"}
        off = [run(fit, off_env, work) for _ in range(opts.repeat)]
        what = (opts.input if opts.input else
                f"{opts.samples} samples" if opts.samples else "a full synthetic MERL table")
        print(f"brdffit fit --model {opts.model} on {what}, one fresh process each:")
        print(f"  first process (empty cache)   {first[0]:6.2f} s  (fit {first[1]['wall_time']:.2f} s)")
        for k, (wall, r) in enumerate(cached, 2):
            print(f"  process {k} (cache filled)     {wall:6.2f} s  (fit {r['wall_time']:.2f} s)")
        for wall, r in off:
            print(f"  cache off (opt-out variable)  {wall:6.2f} s  (fit {r['wall_time']:.2f} s)")
        second = statistics.median(w for w, _ in cached)
        print(f"  first / second process: {first[0] / second:.2f}x; fit time "
              f"{first[1]['wall_time'] / statistics.median(r['wall_time'] for _, r in cached):.2f}x;"
              f" cache {size_of(cache) / 1e6:.1f} MB")
        cold = statistics.median(w for w, _ in off)
        print(f"  cache off, median {cold:.2f} s against the {GOAL_S:.0f} s goal: "
              f"{cold / GOAL_S:.2f}x")
        print_fresh_memory("after")
        print(f"  load average {os.getloadavg()[0]:.2f} (cores {os.cpu_count()})")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
