"""Benchmark: fits of every MERL-identifiable model to realistic materials (run by hand).

    .venv/bin/python benchmarks/bench_realistic.py [--models ggx,beckmann,...]
        [--materials N | --names a,b] [--scipy N] [--csv out.csv] [--cache DIR]

The materials are the neural proxies of 80 real MERL measurements in ``../shared/realistic``
(Sztrajman et al. 2021; see its README), rendered into full 90×90×180 tables in memory (never
written). For each material and model, with the default options of :func:`brdffit.fit`:

* the time: the first fit of a model in the process is its **cold** time (tracing and
  compilation included; the compiled program is then reused for every other material of that
  layout), every other fit is **warm**;
* steps, ``success``, the final cost, ``optimality`` (``ω``), the literature's error metrics
  (``rmse_cosine``: Ngan et al. 2005's cosine-weighted RMSE; ``rmse_log``: Löw et al. 2012's
  log RMSE) on the cells used, the parameters at a bound;
* for a model that refines a simpler one (``two-lobe-ggx`` of ``ggx``, when both run): its
  cost against the simpler model's on each material (it must never be above it);
* for ``beckmann``: the fitted roughness ``α`` against the geometric mean of the Cook–Torrance
  ``m`` published by Ngan 2005 and Löw 2012 (``published_roughness.csv``): the fraction within a
  factor 1.5 and the Spearman rank correlation.

A summary line per model: successes, median and worst warm time, NaNs. Then the scipy
reference on the first ``--scipy`` materials: ``scipy.optimize.least_squares`` (trf, 2-point
differences, bounds, ``x_scale='jac'``) on the same ``ggx`` log residuals (an independent NumPy
transcription of the model, ``bench_fit.ggx_numpy``), with the same cell weights (each
cell's share of the angles, brdffit's default ``weighting="angles"``), the same cells and the
same start (``result.init``): its time and cost against brdffit's warm time and cost.

The machine may be shared: the load average is printed with the figures, and so is the
**machine reference**, a fixed workload timed before the first fit and after the last
(:func:`machine_reference`): the times of two runs compare only after dividing by it.
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import statistics
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np

import brdffit
from data_formats.merl import MERLTable

HERE = Path(__file__).resolve().parent
REALISTIC = HERE.parent.parent / "shared" / "realistic"
sys.path.insert(0, str(HERE))

#: Every registered model a MERL table identifies (isotropic; ggx-aniso and aps-gaussian's two
#: widths are not separable at phi_h = 0 and are left out).
MODELS = ("ggx", "beckmann", "blinn-phong", "gtr", "two-lobe-ggx", "disney", "ggx-ms",
          "ggx-coupled", "aps-velvet", "aps-satin", "aps-vgroove", "cloth-sheen", "cloth-velvet",
          "gltf-pbr", "mitsuba-principled", "mitsuba-roughconductor",
          "mitsuba-roughconductor-beckmann", "mitsuba-roughconductor-tint")


def load_render():
    if not (REALISTIC / "render.py").exists():
        sys.exit(f"bench_realistic: {REALISTIC} is missing (the development corpus)")
    sys.path.insert(0, str(REALISTIC))
    import render

    return render


def table_of(render, name: str, cache: Path | None = None) -> MERLTable:
    """The full table of material ``name``, rendered (4 s) or read from ``cache`` (``.npy``
    files of the rendered values, written there on the first render)."""
    path = None if cache is None else cache / f"{name}.npy"
    if path is not None and path.exists():
        rgb = np.load(path)
    else:
        rgb = render.merl_table(name)  # (3, 90, 90, 180), -1 below the horizon
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.save(path, rgb)
    valid = np.all(rgb >= 0, axis=0)
    return MERLTable.from_rgb(np.moveaxis(np.maximum(rgb, 0.0), 0, -1), valid, name=name)


#: :func:`machine_reference` reports the median of this many runs.
REFERENCE_REPEAT = 5


def machine_reference(repeat: int = REFERENCE_REPEAT) -> float:
    """Seconds for a fixed workload that uses no brdffit code, the median of ``repeat`` runs:
    ``bench_fit.ggx_numpy`` (plain NumPy) at one parameter vector over the 1,458,000 cell
    directions of a full MERL table. It measures the machine (core speed, memory bandwidth,
    other load), so that fit times measured on different days can be put side by side."""
    from bench_fit import ggx_numpy
    from data_formats.merl import cell_directions

    wi, wo = (a.reshape(-1, 3) for a in cell_directions())
    x = np.array([0.1, 0.2, 0.3, 0.04, 0.05, 0.06, 0.2, 0.9])
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        ggx_numpy(x, wi, wo)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def published() -> dict[str, float]:
    """Geometric mean of the two published Cook–Torrance roughness values, where both exist."""
    out = {}
    with open(REALISTIC / "published_roughness.csv") as f:
        for row in csv.DictReader(f):
            a, b = row["ngan2005_cooktorrance_m"], row["low2012_cooktorrance_E2_m"]
            if a and b:
                out[row["material"]] = float(np.sqrt(float(a) * float(b)))
    return out


def spearman(a, b) -> float:
    ra = np.argsort(np.argsort(a)).astype(float)
    rb = np.argsort(np.argsort(b)).astype(float)
    return float(np.corrcoef(ra, rb)[0, 1])


def fit_row(table, model: str) -> dict:
    t = time.perf_counter()
    res = brdffit.fit(table, model, throw=False)
    dt = time.perf_counter() - t
    finite = bool(np.all(np.isfinite(res.x)) and np.isfinite(res.cost))
    return {
        "material": table.name, "model": model, "time": dt, "steps": res.steps,
        "success": res.success, "cost": res.cost, "optimality": res.optimality,
        "rmse_cosine": res.metrics["rmse_cosine"], "rmse_log": res.metrics["rmse_log"],
        "at_bound": " ".join(sorted(res.at_bound)), "finite": finite,
        "alpha": float(np.mean(res.params.get("alpha", float("nan")))),  # RGB (sgd): the mean
        "status": res.status, "result": res,
    }


def summarize(rows, model: str, lit: dict) -> str:
    mine = [r for r in rows if r["model"] == model]
    warm = [r["time"] for r in mine[1:]] or [mine[0]["time"]]
    ok = sum(r["success"] for r in mine)
    nan = sum(not r["finite"] for r in mine)
    line = (f"{model:13s} success {ok}/{len(mine)}  warm median {statistics.median(warm):5.2f} s "
            f"max {max(warm):5.2f} s  cold {mine[0]['time']:5.2f} s  NaN {nan}  "
            f"median rmse_cosine {statistics.median(r['rmse_cosine'] for r in mine):.4g} "
            f"rmse_log {statistics.median(r['rmse_log'] for r in mine):.4g}")
    if model == "beckmann":
        pairs = [(r["alpha"], lit[r["material"]]) for r in mine if r["material"] in lit]
        if pairs:
            a, b = np.array(pairs).T
            within = np.mean(np.maximum(a / b, b / a) <= 1.5)
            line += (f"\n{'':13s} roughness vs published (geometric mean, {len(a)} materials): "
                     f"within x1.5 {within:.0%}, Spearman {spearman(a, b):.3f}")
    base = brdffit.get_model(model).refines
    if base is not None:  # a model that contains a simpler one must never end above it
        simple = {r["material"]: r["cost"] for r in rows if r["model"] == base[0]}
        ratio = [r["cost"] / simple[r["material"]] for r in mine if r["material"] in simple]
        if ratio:
            line += (f"\n{'':13s} cost against {base[0]} ({len(ratio)} materials): at or below "
                     f"(rel. 1e-6) on {sum(x <= 1 + 1e-6 for x in ratio)}, median ratio "
                     f"{statistics.median(ratio):.4f}, max {max(ratio):.6f}")
    return line


def scipy_row(table, res) -> dict:
    from bench_fit import scipy_reference

    model = brdffit.get_model("ggx")
    sol, t = scipy_reference(table.to_samples(), model.flatten(res.init))
    return {"material": table.name, "scipy_time": t, "scipy_cost": sol.cost,
            "scipy_status": sol.status, "scipy_alpha": sol.x[6]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--materials", type=int, default=80, help="the first N materials (sorted)")
    ap.add_argument("--names", default=None, help="comma-separated material names instead")
    ap.add_argument("--scipy", type=int, default=10, help="materials for the scipy reference")
    ap.add_argument("--csv", default=None, help="write the per-fit rows here")
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep the rendered tables here (.npy, 35 MB each) for later runs")
    args = ap.parse_args()
    render = load_render()
    names = args.names.split(",") if args.names else render.names()[: args.materials]
    models = args.models.split(",")
    lit = published()
    rows, ref = [], []
    reference = machine_reference()
    print(f"machine reference (NumPy ggx over a full table, median of {REFERENCE_REPEAT}): "
          f"{reference:.3f} s",
          flush=True)
    t_all = time.perf_counter()
    for i, name in enumerate(names):
        table = table_of(render, name, args.cache)
        for model in models:
            row = fit_row(table, model)
            rows.append(row)
            pub = f" published {lit[name]:.3g}" if name in lit and model == "beckmann" else ""
            print(f"{name:26s} {model:13s} {row['time']:6.2f} s steps {row['steps']:3d} "
                  f"{'ok ' if row['success'] else 'FAIL'} cost {row['cost']:.7g} "
                  f"ω {row['optimality']:.1e} rmse_cos {row['rmse_cosine']:.4g} "
                  f"rmse_log {row['rmse_log']:.4g} alpha {row['alpha']:.4g}{pub} "
                  f"bound [{row['at_bound']}]", flush=True)
        if i < args.scipy and "ggx" in models:
            res = next(r["result"] for r in rows if r["material"] == name and r["model"] == "ggx")
            s = scipy_row(table, res)
            s.update(brdffit_time=next(r["time"] for r in rows if r["material"] == name
                                       and r["model"] == "ggx"), brdffit_cost=res.cost)
            ref.append(s)
            print(f"{'':26s} scipy ggx {s['scipy_time']:6.2f} s cost {s['scipy_cost']:.7g} "
                  f"(brdffit {s['brdffit_cost']:.7g}, ratio {s['brdffit_cost'] / s['scipy_cost']:.8f}) "
                  f"speed {s['scipy_time'] / s['brdffit_time']:.1f}x", flush=True)
    print(f"\n{len(names)} materials, {time.perf_counter() - t_all:.0f} s; load average "
          f"{os.getloadavg()}; peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB; "
          f"machine reference {reference:.3f} s before, {machine_reference():.3f} s after")
    for model in models:
        print(summarize(rows, model, lit))
    if ref:
        ratios = [s["brdffit_cost"] / s["scipy_cost"] for s in ref]
        speed = [s["scipy_time"] / s["brdffit_time"] for s in ref]
        worse = sum(r > 1 + 1e-6 for r in ratios)
        print(f"scipy reference (ggx, {len(ref)} materials): cost brdffit/scipy max "
              f"{max(ratios):.8f}, worse than scipy (rel. 1e-6) on {worse}; speed ratio median "
              f"{statistics.median(speed):.1f}x (min {min(speed):.1f}x)")
    if args.csv:
        keys = [k for k in rows[0] if k != "result"]
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, keys)
            w.writeheader()
            w.writerows({k: r[k] for k in keys} for r in rows)


if __name__ == "__main__":
    main()
