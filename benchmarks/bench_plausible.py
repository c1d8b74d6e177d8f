"""Benchmark: how many default fits of the realistic corpus are implausible materials (by hand).

    .venv/bin/python benchmarks/bench_plausible.py [--models ggx,gtr,...] [--materials N |
        --names a,b] [--cache DIR] [--csv out.csv] [--cutoff DEG]

Fits every material of ``../shared/realistic`` (rendered as in ``bench_realistic.py``) with each
model under :func:`brdffit.fit`'s defaults and applies checks of its own to every result, so
that two checkouts (``PYTHONPATH=/path/to/other/checkout``) are counted by the same rules:

* ``f90<f0``: a generalized Schlick term whose grazing reflectance is below its normal one in
  some channel (``f90 < f0_c − 1e-6``); where a model has no free ``f90`` parameter, the
  ``f90`` a model derives from its parameters (``Model.derived``, where it exists) counts too;
  ``F(θd → 90°)`` and ``F(0)`` are not separable from the BRDF otherwise, so this check
  counts only models that declare ``f0`` and ``f90`` one way or the other;
* ``albedo>1``: the fitted model's directional albedo above 1 + 1e-3 at some incidence from 0°
  to 89° (:func:`brdffit.plots.albedo.model_albedo`, half-vector quadrature);
* ``diffuse@1``: a diffuse albedo or base colour component on its upper bound 1;
* ``dark-metal``: ``metallic`` ≥ 0.9 with every base-colour component below 0.05 (a black
  metal: the fit traded the colour away);
* ``metal-dielectric``: a dielectric that looks like a metal or the reverse: ``metallic`` ≥ 0.5
  where the material's measured diffuse floor (the median of the table's cells with θh > 40°
  and θd < 60°) is above 0.02 /sr in some channel — a metal has no diffuse floor; or, in a
  model with a dielectric ``ior`` (``gltf-pbr``), ``metallic`` < 0.5 with ``ior`` > 3 (the
  dielectric's ``F0`` above 0.25: a metal's flat Fresnel curve read as a dielectric);
* ``not converged``: ``success`` false.

Per model: the count of fits failing each check, the median and worst ``rmse_log`` and
``rmse_cosine`` (on the fit's own cells), the median and worst ``log_rms_80`` (Löw's log RMS
over the cells with θi, θo ≤ 80°, computed here: the same cells for every fit and every
checkout, whatever cells the fit used), the median warm time. ``--cutoff DEG`` fits on the
cells within ``DEG`` only (the code's default otherwise). ``--csv`` writes the rows (parameters as JSON) for a
comparison of two runs.
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np

import brdffit
from brdffit.plots.albedo import model_albedo

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_realistic import load_render, table_of  # noqa: E402

MODELS = ("ggx", "beckmann", "gtr", "disney", "gltf-pbr", "mitsuba-principled")
CHECKS = ("f90<f0", "albedo>1", "diffuse@1", "dark-metal", "metal-dielectric", "not converged")
ALBEDO_ANGLES = np.linspace(0.0, 89.0, 30)


def diffuse_floor(table) -> np.ndarray:
    """Median ``f_r`` (RGB) of the cells with θh > 40° and θd < 60°: far from the specular peak,
    away from grazing; a metal's is near 0."""
    from data_formats.merl import cell_angles

    rgb = np.asarray(table.rgb)
    i, j, k = np.indices(rgb.shape[:3], sparse=True)
    th, td, _ = cell_angles(i, j, k, rgb.shape[:3])
    sel = (th > np.radians(40)) & (td < np.radians(60)) & np.asarray(table.valid)
    return np.median(rgb[sel], axis=0)


def checks(model, params: dict, success: bool, floor: np.ndarray) -> dict:
    p = {k: np.asarray(v, float) for k, v in params.items()}
    out = dict.fromkeys(CHECKS, False)
    derived = getattr(model, "derived", None)  # F90 = F0 + (1 - F0) grazing, where declared
    if derived is not None and "f90" not in p:
        p.update({k: np.asarray(v, float) for k, v in derived(p).items()})
    if "f90" in p and "f0" in p:
        out["f90<f0"] = bool(np.any(p["f90"] < p["f0"] - 1e-6))
    out["albedo>1"] = bool(np.nanmax(model_albedo(model, params, ALBEDO_ANGLES)) > 1 + 1e-3)
    for name in ("diffuse", "base_color"):
        if name in p:
            upper = model.param(name).upper
            out["diffuse@1"] |= bool(np.any(p[name] >= min(upper, 1.0) - 1e-6))
    if "metallic" in p:
        metallic = float(np.max(p["metallic"]))
        base = p.get("base_color", np.ones(3))
        out["dark-metal"] = bool(metallic >= 0.9 and np.all(base < 0.05))
        out["metal-dielectric"] = bool(metallic >= 0.5 and np.max(floor) > 0.02)
        if "ior" in p:  # a dielectric with a metal's F0 ((ior-1)/(ior+1))^2 > 0.25
            out["metal-dielectric"] |= bool(metallic < 0.5 and float(p["ior"]) > 3.0)
    out["not converged"] = not success
    return out


def log_rms_80(table, model, params) -> float:
    """Löw's log RMS of ``model`` with ``params`` over the valid cells of ``table`` with
    θi, θo ≤ 80° (NumPy on the model's own function, in float64)."""
    import jax.numpy as jnp

    s = table.to_samples()
    wi, wo, m = np.asarray(s.wi, float), np.asarray(s.wo, float), np.asarray(s.rgb, float)
    c80 = np.cos(np.radians(80.0))
    keep = (np.asarray(s.valid, bool) & (wi[:, 2] >= c80) & (wo[:, 2] >= c80)
            & np.all(np.isfinite(m), axis=1) & np.all(m >= 0, axis=1))
    wi, wo, m = wi[keep], wo[keep], m[keep]
    p = {k: jnp.asarray(np.asarray(v, float)) for k, v in params.items()}
    f = np.concatenate([np.asarray(model.fn(p, jnp.asarray(wi[i:i + 262144]),
                                            jnp.asarray(wo[i:i + 262144])), float)
                        for i in range(0, len(wi), 262144)])
    ci = wi[:, 2:3]
    return float(np.sqrt(np.mean((np.log1p(f * ci) - np.log1p(m * ci)) ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--materials", type=int, default=80)
    ap.add_argument("--names", default=None)
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--csv", default=None)
    ap.add_argument("--cutoff", type=float, default=None)
    args = ap.parse_args()
    render = load_render()
    names = (args.names.split(",") if args.names else sorted(render.names())[: args.materials])
    models = args.models.split(",")
    print(f"brdffit from {Path(brdffit.__file__).parent}; {len(names)} materials x {models}",
          flush=True)
    rows = []
    options = {} if args.cutoff is None else {"cutoff": args.cutoff}
    out = open(args.csv, "w", newline="") if args.csv else None
    writer = None
    for name in names:
        table = table_of(render, name, args.cache)
        floor = diffuse_floor(table)
        for m in models:
            model = brdffit.get_model(m)
            t = time.perf_counter()
            res = brdffit.fit(table, m, throw=False, **options)
            dt = time.perf_counter() - t
            params = {k: np.asarray(v).tolist() for k, v in res.params.items()}
            row = {"material": name, "model": m, "time": dt, "success": bool(res.success),
                   "rmse_log": res.metrics["rmse_log"], "rmse_cosine": res.metrics["rmse_cosine"],
                   "log_rms_80": log_rms_80(table, model, params),
                   "params": json.dumps(params), "floor": json.dumps(floor.tolist())}
            row.update(checks(model, params, bool(res.success), floor))
            rows.append(row)
            if out is not None:
                if writer is None:
                    writer = csv.DictWriter(out, fieldnames=list(row))
                    writer.writeheader()
                writer.writerow(row)
                out.flush()
            flags = [c for c in CHECKS if row[c]]
            print(f"{name:28s} {m:20s} {dt:6.2f} s  rmse_log {row['rmse_log']:.4f}  "
                  f"{' '.join(flags) or 'plausible'}", flush=True)
    print()
    for m in models:
        mine = [r for r in rows if r["model"] == m]
        warm = [r["time"] for r in mine[1:]] or [mine[0]["time"]]
        logs = [r["rmse_log"] for r in mine]
        l80 = [r["log_rms_80"] for r in mine]
        coss = [r["rmse_cosine"] for r in mine]
        counts = "  ".join(f"{c} {sum(r[c] for r in mine)}" for c in CHECKS)
        bad = sum(any(r[c] for c in CHECKS) for r in mine)
        print(f"{m:20s} implausible {bad}/{len(mine)}: {counts}\n{'':20s} rmse_log median "
              f"{statistics.median(logs):.4f} worst {max(logs):.4f}; rmse_cosine median "
              f"{statistics.median(coss):.4g} worst {max(coss):.4g}; log_rms_80 median "
              f"{statistics.median(l80):.4f} worst {max(l80):.4f}; warm median "
              f"{statistics.median(warm):.2f} s, cold {mine[0]['time']:.2f} s")
    if out is not None:
        out.close()


if __name__ == "__main__":
    main()
