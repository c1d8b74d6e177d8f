"""Benchmark: which cells and weights the default fit should use, scored in every metric (by hand).

    .venv/bin/python benchmarks/bench_compare.py [--models ggx,beckmann] [--materials N |
        --names a,b] [--variants default,cutoff80] [--cache DIR] [--csv out.csv]

For each realistic material (the neural proxies of ``../shared/realistic``, rendered in memory
as :mod:`bench_realistic` does) and model, fits the table under each *variant* of the fit
options and scores every fit with the leaderboard (:func:`brdffit.leaderboard.board`: the same
cells for all, every metric of :data:`brdffit.metrics.LITERATURE_METRICS`). Variants:

* ``default``: :func:`brdffit.fit`'s defaults as they are in the checkout;
* ``all``: every cell above the horizon (``cutoff`` unset);
* ``cutoff80``: cells with θi, θo ≤ 80° only;
* ``sa``, ``sa80``: solid-angle weighting, without and with the 80° cutoff.

Prints one row per (material, model, variant) and, per model, for every metric, the count of
materials where each variant is best and the median ratio of each variant's score to the first
variant's.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402

import brdffit  # noqa: E402
from bench_realistic import load_render, table_of  # noqa: E402
from brdffit.leaderboard import Candidate, board  # noqa: E402
from brdffit.metrics import LITERATURE_METRICS  # noqa: E402

#: Variant name → fit options over the code's defaults (``None`` as a value unsets the option).
VARIANTS = {
    "default": {},
    "all": {"cutoff": None},
    "cutoff80": {"cutoff": 80.0},
    "sa": {"cutoff": None, "weighting": "solid-angle"},
    "sa80": {"cutoff": 80.0, "weighting": "solid-angle"},
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="ggx")
    ap.add_argument("--materials", type=int, default=6)
    ap.add_argument("--names", default="")
    ap.add_argument("--variants", default="all,cutoff80")
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--csv", type=Path, default=None)
    args = ap.parse_args()
    render = load_render()
    names = args.names.split(",") if args.names else render.names()[: args.materials]
    models = args.models.split(",")
    variants = args.variants.split(",")
    print(f"load average {os.getloadavg()[0]:.2f}; materials {len(names)}; models {models}; "
          f"variants {variants}", flush=True)
    rows = []
    for name in names:
        table = table_of(render, name, args.cache)
        cands = []
        for model in models:
            for v in variants:
                t0 = time.perf_counter()
                r = brdffit.fit(table, model, throw=False, **VARIANTS[v])
                cands.append(Candidate(f"{model}/{v}", "fit", r))
                print(f"  {name} {model}/{v}: {time.perf_counter() - t0:.1f}s "
                      f"{'ok' if r.success else 'FAILED'} f90={r.params.get('f90')}", flush=True)
        b = board(table, cands)
        for c in b.candidates:
            model, v = c.label.split("/")
            rows.append({"material": name, "model": model, "variant": v,
                         "success": c.converged, **c.scores})
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    for model in models:
        print(f"\n{model}: per metric, materials where each variant is best; median ratio to "
              f"{variants[0]}")
        for metric in LITERATURE_METRICS:
            per = {}
            for name in names:
                per[name] = {r["variant"]: r[metric] for r in rows
                             if r["material"] == name and r["model"] == model}
            wins = {v: sum(1 for name in names if min(per[name], key=per[name].get) == v)
                    for v in variants}
            ratios = {v: statistics.median(per[n][v] / per[n][variants[0]] for n in names
                                           if np.isfinite(per[n][v] / per[n][variants[0]]))
                      for v in variants[1:]}
            print(f"  {metric:<15} wins " + ", ".join(f"{v} {k}" for v, k in wins.items())
                  + "; median ratio " + ", ".join(f"{v} {x:.3f}" for v, x in ratios.items()))


if __name__ == "__main__":
    main()
