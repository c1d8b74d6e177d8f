"""Benchmark: brdffit's models against the published fits of the 80 realistic materials (by hand).

    .venv/bin/python benchmarks/bench_leaderboard.py [--materials N | --names a,b]
        [--cache DIR] [--shard K/N] [--models a,b] --csv out.csv
    .venv/bin/python benchmarks/bench_leaderboard.py --summarize out1.csv [out2.csv ...]

For each realistic material (the neural proxies of ``../shared/realistic``, rendered as
:mod:`bench_realistic` does, or read from ``--cache``) this fits

* every model of :data:`MODELS` with :func:`brdffit.fit`'s defaults (``"default"`` rows): the
  literature's models of ``brdffit.models.classic`` and ``brdffit.models.fitted_distributions``
  and the house's own;
* for every published file of ``../shared/published/fits`` (:data:`PROTOCOLS`), the model of its
  fit of that material re-fitted under the paper's protocol preset (``"refit"`` rows);

reads every published fit of the material (``"published"`` rows), and scores all of them on the
same cells in every metric of :data:`brdffit.metrics.LITERATURE_METRICS` with the leaderboard
(:func:`brdffit.leaderboard.board`). One CSV row per candidate: material, kind, label, model,
preset, protocol metric, fit time (the first fit of each model and preset in the process is its
**cold** time), steps, converged, every metric.

``--summarize`` reads one or several such CSVs (shards of one run) and prints

1. per published file: on how many materials brdffit's re-fit (the same model, the paper's
   protocol) is at least as good as the published fit **in the protocol's own metric**, the
   median and worst ratio re-fit / published;
2. per metric: the count of materials where the best of brdffit's default fits (and the best of
   all its fits) beats the best published fit, and the median ratio;
3. per model: cold time and the median and worst warm time of its default fit, with the load
   average and the machine reference (:func:`bench_realistic.machine_reference`) of each shard.

``--shard K/N`` takes every N-th material from the K-th (1-based): N processes on N cores.
Times of shards run side by side share the machine: compare them only with the machine
reference printed beside them.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402

import brdffit  # noqa: E402
from bench_realistic import load_render, machine_reference, table_of  # noqa: E402
from brdffit.leaderboard import Candidate, board  # noqa: E402
from brdffit.metrics import LITERATURE_METRICS  # noqa: E402
from brdffit.published import load_published  # noqa: E402

FITS = HERE.parent.parent / "shared" / "published" / "fits"

#: The literature's models (new) and the house's models, fitted with the defaults.
LITERATURE = ("ngan-cooktorrance", "low-cooktorrance", "ngan-ashikhmin-shirley",
              "low-ashikhmin-shirley", "ward", "ward-duer", "ngan-blinn-phong", "lafortune",
              "lafortune-2", "lafortune-3", "low-smooth", "low-microfacet", "sgd", "student-t")
HOUSE = ("ggx", "beckmann", "gtr", "two-lobe-ggx", "disney", "blinn-phong")
MODELS = LITERATURE + HOUSE

#: Published file stem → (the paper's protocol preset, the metric it minimises). The model is
#: the one the file's line for the material names (Lafortune's lobe count varies per line).
PROTOCOLS = {
    **dict.fromkeys(("ngan_cooktorrance", "ngan_ashikhminshirley", "ngan_blinnphong",
                     "ngan_ward", "ngan_wardduer", "ngan_lafortune"),
                    ("ngan2005", "ngan_rms_80_sa")),
    **dict.fromkeys(("low_cooktorrance_E1", "low_ashikhminshirley_E1"),
                    ("low2012-e1", "cos_rms_sa")),
    **dict.fromkeys(("low_cooktorrance_E2", "low_ashikhminshirley_E2", "low_lowsmooth_E2",
                     "low_lowmicrofacet_E2"), ("low2012-e2", "log_rms_sa")),
    "bagher_sgd": ("bagher2012", "ngan_rms_80_sa"),
}
FIELDS = ["material", "kind", "label", "model", "preset", "stem", "protocol_metric", "time",
          "cold", "steps", "converged", *LITERATURE_METRICS]


def run(args) -> None:
    from brdffit.config import load_config

    render = load_render()
    names = args.names.split(",") if args.names else render.names()[: args.materials]
    k, n = (int(v) for v in args.shard.split("/"))
    names = names[k - 1::n]
    models = args.models.split(",")
    if unknown := sorted(set(models) - set(MODELS)):
        raise SystemExit(f"--models: not among the benchmark's models: {', '.join(unknown)}")
    reference = machine_reference()
    print(f"load average {os.getloadavg()[0]:.2f}; machine reference {reference:.3f} s; "
          f"{len(names)} materials (shard {args.shard})", flush=True)
    seen: set = set()
    out = open(args.csv, "w", newline="")
    writer = csv.DictWriter(out, fieldnames=FIELDS)
    writer.writeheader()
    configs = {}
    for name in names:
        table = table_of(render, name, args.cache)
        cands, meta = [], []

        def fit(model, preset, kind, stem="", metric=""):
            opts = None
            if preset:
                opts = configs.setdefault(preset, load_config(preset))
            t0 = time.perf_counter()
            r = brdffit.fit(table, model, opts, throw=False)
            dt = time.perf_counter() - t0
            key = (model, preset)
            cold = key not in seen
            seen.add(key)
            label = model if not preset else f"{model}@{preset}"
            cands.append(Candidate(label if kind == "default" else f"{label} ({stem})", "fit", r))
            meta.append({"kind": kind, "model": model, "preset": preset, "stem": stem,
                         "protocol_metric": metric, "time": dt, "cold": cold,
                         "steps": r.steps, "converged": bool(r.success)})
            print(f"  {name:<28} {label:<36} {dt:6.2f} s{' cold' if cold else ''}"
                  f"{'' if r.success else ' NOT CONVERGED'}", flush=True)

        for model in models:
            fit(model, "", "default")
        for stem, (preset, metric) in PROTOCOLS.items():
            for pub in load_published(FITS / f"{stem}.fit", name):
                if pub.model_name not in models:
                    continue
                fit(pub.model_name, preset, "refit", stem, metric)
                cands.append(Candidate(f"published {stem}", "published", pub))
                meta.append({"kind": "published", "model": pub.model_name, "preset": "",
                             "stem": stem, "protocol_metric": metric, "time": 0.0,
                             "cold": False, "steps": 0, "converged": True})
        b = board(table, cands)
        by_id = {id(c): m for c, m in zip(cands, meta)}
        for c in b.candidates:
            writer.writerow({"material": name, "label": c.label, **by_id[id(c)],
                             **{m: c.scores[m] for m in LITERATURE_METRICS}})
        out.flush()
    out.close()
    print(f"load average {os.getloadavg()[0]:.2f}; machine reference after "
          f"{machine_reference():.3f} s", flush=True)


def _ratio_line(ratios) -> str:
    ratios = [r for r in ratios if math.isfinite(r)]
    if not ratios:
        return "no finite ratio"
    return f"median ratio {statistics.median(ratios):.3f}, worst {max(ratios):.3f}"


def summarize(paths) -> None:
    rows = []
    for p in paths:
        with open(p, newline="") as f:
            rows += list(csv.DictReader(f))
    for r in rows:
        for m in [*LITERATURE_METRICS, "time"]:
            r[m] = float(r[m])
        r["cold"] = r["cold"] == "True"
        r["converged"] = r["converged"] == "True"
    materials = sorted({r["material"] for r in rows})
    print(f"{len(materials)} materials, {len(rows)} rows from {', '.join(map(str, paths))}\n")

    print("1. re-fit (same model, the paper's protocol) against the published fit, in the "
          "protocol's own metric")
    print(f"   {'published file':<26} {'metric':<15} {'re-fit ≤ published':>20}  ratios "
          f"re-fit / published; re-fits not converged")
    total_wins = total = 0
    for stem, (_preset, metric) in PROTOCOLS.items():
        ratios, wins, count, failed = [], 0, 0, 0
        for name in materials:
            refit = [r for r in rows if r["material"] == name and r["stem"] == stem
                     and r["kind"] == "refit"]
            pub = [r for r in rows if r["material"] == name and r["stem"] == stem
                   and r["kind"] == "published"]
            if not refit or not pub:
                continue
            a, b = refit[0][metric], pub[0][metric]
            count += 1
            wins += a <= b * (1 + 1e-9)
            failed += not refit[0]["converged"]
            ratios.append(a / b if b > 0 else math.nan)
        total_wins += wins
        total += count
        print(f"   {stem:<26} {metric:<15} {wins:>4} / {count:<3} ({100 * wins / max(count, 1):5.1f} %)"
              f"  {_ratio_line(ratios)}; {failed}")
    print(f"   all files: {total_wins} / {total} ({100 * total_wins / max(total, 1):.1f} %)\n")

    print("2. best of brdffit's fits against the best published fit, per metric (wins: brdffit "
          "lower)")
    for which, kinds in (("default fits", {"default"}), ("all fits", {"default", "refit"})):
        print(f"   brdffit's {which}:")
        for metric in LITERATURE_METRICS:
            wins, ratios = 0, []
            for name in materials:
                ours = [r[metric] for r in rows if r["material"] == name and r["kind"] in kinds
                        and math.isfinite(r[metric])]
                pub = [r[metric] for r in rows if r["material"] == name
                       and r["kind"] == "published" and math.isfinite(r[metric])]
                if not ours or not pub:
                    continue
                a, b = min(ours), min(pub)
                wins += a < b
                ratios.append(a / b if b > 0 else math.nan)
            print(f"     {metric:<15} wins {wins:>3} / {len(ratios):<3} {_ratio_line(ratios)}")
    print()

    print("3. time of the default fit per model (cold: the first fit of the process, "
          "tracing and compilation included; warm: the others)")
    print(f"   {'model':<24} {'cold':>8} {'warm median':>12} {'warm worst':>11} "
          f"{'converged':>10}")
    for model in MODELS:
        mine = [r for r in rows if r["kind"] == "default" and r["model"] == model]
        if not mine:
            continue
        cold = [r["time"] for r in mine if r["cold"]]
        warm = [r["time"] for r in mine if not r["cold"]]
        conv = sum(r["converged"] for r in mine)
        print(f"   {model:<24} {statistics.median(cold) if cold else math.nan:7.2f}s "
              f"{statistics.median(warm) if warm else math.nan:11.2f}s "
              f"{max(warm) if warm else math.nan:10.2f}s {conv:>5} / {len(mine)}")
    print("   re-fits under the papers' protocols:")
    for stem, (preset, _m) in PROTOCOLS.items():
        mine = [r for r in rows if r["kind"] == "refit" and r["stem"] == stem]
        warm = [r["time"] for r in mine if not r["cold"]]
        if warm:
            print(f"   {stem:<24} {'':>8} {statistics.median(warm):11.2f}s {max(warm):10.2f}s "
                  f"{sum(r['converged'] for r in mine):>5} / {len(mine)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--materials", type=int, default=80)
    ap.add_argument("--names", default="")
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--shard", default="1/1")
    ap.add_argument("--models", default=",".join(MODELS),
                    help="the models fitted with the defaults, and the only ones re-fitted "
                         "(default: every model of MODELS)")
    ap.add_argument("--csv", type=Path, default=None)
    ap.add_argument("--summarize", type=Path, nargs="+", default=None)
    args = ap.parse_args()
    if args.summarize:
        summarize(args.summarize)
    elif args.csv is None:
        ap.error("give --csv OUT.csv (or --summarize CSV...)")
    else:
        run(args)


if __name__ == "__main__":
    main()
