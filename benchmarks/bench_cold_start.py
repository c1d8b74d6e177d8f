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
   for) and the fit's own ``wall_time`` from its JSON, the ratio first/second, the cache's
   size, and the load average (the machine may be shared).
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

BRDFFIT = [sys.executable, "-c", "import sys; from brdffit.cli import main; sys.exit(main())"]


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
    opts = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="brdffit-bench-cold-"))
    try:
        cache = work / "cache"
        env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
        env.pop("BRDFFIT_NO_COMPILATION_CACHE", None)
        name = "in.csv" if opts.samples else "in.binary"
        synth = ["synth", "--model", opts.model, "-o", name, "--quiet"]
        run(synth + (["--samples", str(opts.samples)] if opts.samples else []),
            {**env, "BRDFFIT_NO_COMPILATION_CACHE": "1"}, work)
        fit = ["fit", name, "--model", opts.model, "--json", "--quiet"]
        first = run(fit, env, work)
        cached = [run(fit, env, work) for _ in range(opts.repeat)]
        off_env = {**env, "BRDFFIT_NO_COMPILATION_CACHE": "1"}
        off = [run(fit, off_env, work) for _ in range(opts.repeat)]
        what = f"{opts.samples} samples" if opts.samples else "a full MERL table"
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
        print(f"  load average {os.getloadavg()[0]:.2f} (cores {os.cpu_count()})")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
