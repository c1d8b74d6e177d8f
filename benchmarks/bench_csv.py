"""Benchmark reading a large CSV sample list: wall time and peak memory (RSS) of ``read_samples``.

Run by hand from the repository root::

    .venv/bin/python benchmarks/bench_csv.py [--rows 2000000] [--checkout PATH ...]

Writes a CSV of ``--rows`` random angle-layout samples (17 significant digits, as
``write_samples`` writes them; 2 M rows are about 266 MB) into a temporary folder, then reads it
in a fresh subprocess per checkout (this one by default; pass other checkouts, e.g. an older
commit in a ``git worktree``, to compare readers) and prints the wall time of ``read_samples``
and the process's peak resident memory (``ru_maxrss``, which includes the ~70 MB interpreter
and NumPy baseline). Each reader runs ``--repeat`` times; the best time and the largest peak are
shown, with the load average (figures from a shared machine vary).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = r"""
import resource, sys, time
sys.path.insert(0, sys.argv[1])
from data_formats.samplelist import read_samples
t0 = time.perf_counter()
s = read_samples(sys.argv[2])
dt = time.perf_counter() - t0
print(len(s), dt, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def write_csv(path, rows: int, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    with open(path, "w") as fh:
        fh.write("theta_i,phi_i,theta_o,phi_o,r,g,b\n")
        for start in range(0, rows, 250_000):
            n = min(250_000, rows - start)
            block = np.column_stack([rng.uniform(0, 89, n), rng.uniform(0, 360, n),
                                     rng.uniform(0, 89, n), rng.uniform(0, 360, n),
                                     rng.uniform(0, 50, (n, 3))])
            np.savetxt(fh, block, delimiter=",", fmt="%.17g")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--checkout", action="append", help="a checkout whose reader to time")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "big.csv")
        write_csv(path, args.rows)
        print(f"{args.rows:,} rows, {os.path.getsize(path) / 1e6:.0f} MB; "
              f"load average {os.getloadavg()[0]:.2f}")
        for checkout in args.checkout or [ROOT]:
            times, peaks = [], []
            for _ in range(args.repeat):
                out = subprocess.run([sys.executable, "-c", CHILD, checkout, path],
                                     capture_output=True, text=True, check=True).stdout.split()
                times.append(float(out[1]))
                peaks.append(float(out[2]))
            print(f"{checkout}: read {min(times):.2f} s, peak RSS {max(peaks):.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
