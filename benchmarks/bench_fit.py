"""Benchmark: full-table fits against a hand-written NumPy/scipy reference (run by hand).

    .venv/bin/python benchmarks/bench_fit.py [--precision float64|float32] [--no-scipy]
        [--no-disney] [--repeat 3]

What it does:

1. Synthesizes a full 90×90×180 MERL table (about 1.1 M valid cells) from ``ggx`` with known
   parameters and 2% multiplicative noise (seeded), through ``data_formats.merl.synthesize``.
2. Fits ``ggx`` with :func:`brdffit.fit` from the default (data-driven) initialization:
   the first call in the process is the cold time (tracing + compilation + solve), then the
   median of ``--repeat`` further calls is the warm time.
3. Fits the same model, written in plain NumPy, with ``scipy.optimize.least_squares`` (trf,
   2-point finite differences, bounds, ``x_scale='jac'``, default tolerances) on the same cells
   (every valid cell above the horizon: brdffit's default selection, no cutoff, no subsample),
   with the same loss (``log``), from brdffit's own starting point (``result.init``): what a
   user would write instead.
4. Prints times, the speed ratio, both final costs and parameter errors against the truth
   (relative, and in units of brdffit's standard errors), and the peak resident memory
   (``resource.getrusage``) before and after the scipy reference.
5. Fits ``disney`` (identifiable parameters free) on a full Disney table, warm and cold.

The machine may be shared: the script prints the load average next to the timings.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np
from scipy.optimize import least_squares

import brdffit
from data_formats.merl import synthesize

GGX_TRUTH = {"diffuse": [0.12, 0.08, 0.05], "f0": [0.06, 0.05, 0.04], "alpha": 0.08}
DISNEY_TRUTH = {"base_color": [0.6, 0.3, 0.15], "metallic": 0.2, "specular": 0.6, "roughness": 0.35}
DISNEY_FREE = ("base_color", "metallic", "specular", "roughness")


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def noisy_table(model_name, truth, noise=0.02, seed=1):
    model = brdffit.get_model(model_name)
    params = model.unflatten(model.flatten(truth))
    fn = jax.jit(lambda wi, wo: model(params, wi, wo))
    rng = np.random.default_rng(seed)

    def f(wi, wo):
        clean = np.concatenate([np.asarray(fn(a, b))[None] for a, b in zip(wi, wo)])
        return clean * (1.0 + noise * rng.standard_normal(clean.shape))

    return synthesize(f, name=f"{model_name}-synthetic")


def timed(call, repeat):
    t = time.perf_counter()
    first = call()
    cold = time.perf_counter() - t
    warm = []
    for _ in range(repeat):
        t = time.perf_counter()
        res = call()
        warm.append(time.perf_counter() - t)
    return first, res, cold, statistics.median(warm)


def ggx_numpy(x, wi, wo):
    """Plain NumPy transcription of the ``ggx`` model (RTR eqs. 9.34, 9.41, 9.42, 9.31, 9.18):
    ``x`` is diffuse (3), f0 (3), alpha, grazing (``ggx``'s flat order; ``F90 = F0 + (1 − F0)
    grazing``)."""
    diffuse, f0, a = x[0:3], x[3:6], x[6]
    f90 = f0 + (1 - f0) * x[7]
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    ci, co, ch = wi[:, 2], wo[:, 2], h[:, 2]
    a2 = a * a
    d = a2 / (np.pi * (1 + (a2 - 1) * ch**2) ** 2)

    def lam(c):
        t2 = (1 - c**2) / c**2
        return 0.5 * (np.sqrt(1 + a2 * t2) - 1)

    g2 = 1 / (1 + lam(ci) + lam(co))
    fres = f0 + (f90 - f0) * (1 - np.clip(np.sum(wi * h, axis=1), 0, 1))[:, None] ** 5
    return diffuse / np.pi + fres * (d * g2 / (4 * ci * co))[:, None]


def scipy_reference(samples, x0):
    """``least_squares`` on the log residual of the same cells (above the horizon, valid), each
    times the square root of its cell's share of the angles (``SampleSet.weight`` over its mean
    on these cells: brdffit's default ``weighting="angles"``)."""
    ok = samples.valid & (samples.wi[:, 2] > 0) & (samples.wo[:, 2] > 0)
    wi, wo, rho = samples.wi[ok], samples.wo[ok], samples.rgb[ok]
    ci = wi[:, 2:3]
    target = np.log1p(rho * ci)
    w = np.ones(len(wi)) if samples.weight is None else samples.weight[ok]
    sw = np.sqrt(w / w.mean())[:, None]

    def residual(x):
        return (sw * (np.log1p(ggx_numpy(x, wi, wo) * ci) - target)).ravel()

    lo = np.array([0.0] * 6 + [1e-3, 0.0])
    hi = np.ones(8)
    t = time.perf_counter()
    sol = least_squares(residual, np.clip(x0, lo + 1e-9, hi), bounds=(lo, hi), x_scale="jac")
    return sol, time.perf_counter() - t


def param_error(x, truth_flat):
    return float(np.max(np.abs(np.asarray(x) - truth_flat) / np.abs(truth_flat)))


def bench_ggx(args):
    model = brdffit.get_model("ggx")
    table = noisy_table("ggx", GGX_TRUTH)
    truth = model.flatten(GGX_TRUTH)
    call = lambda: brdffit.fit(table, "ggx", precision=args.precision)
    _first, res, cold, warm = timed(call, args.repeat)
    print(f"load average: {os.getloadavg()}")
    print(res.summary())
    print(f"ggx brdffit ({args.precision}): cold {cold:.2f} s, warm {warm:.2f} s (median of "
          f"{args.repeat}); steps {res.steps}; cost {res.cost:.6g}; "
          f"max rel. param error {param_error(res.x, truth):.2e}; timings {res.timings}")
    print(f"selection: {res.n_cells} of {res.n_total} cells (valid, above the horizon; no cutoff, "
          f"no subsample); warm start on {warm_blocks(res.n_cells)}, then the full table")
    print(f"peak RSS after brdffit fits: {peak_rss_mb():.0f} MB")
    if args.no_scipy:
        return
    samples = table.to_samples()
    x0 = model.flatten(res.init)  # brdffit's own (data-driven) starting point
    sol, t_scipy = scipy_reference(samples, x0)
    se = np.array([v for k in model.names for v in np.ravel(res.stderr[k])])
    print(f"scipy least_squares: {t_scipy:.2f} s, nfev {sol.nfev}, njev {sol.njev}, "
          f"cost {sol.cost:.6g}, max rel. param error {param_error(sol.x, truth):.2e}, "
          f"status {sol.status}")
    print(f"max |x - truth| / stderr: brdffit {np.max(np.abs(res.x - truth) / se):.2f}, "
          f"scipy {np.max(np.abs(sol.x - truth) / se):.2f}")
    print(f"speed ratio scipy / brdffit warm: {t_scipy / warm:.1f}x; cost ratio brdffit/scipy: "
          f"{res.cost / sol.cost:.6f}")
    print(f"peak RSS after scipy: {peak_rss_mb():.0f} MB")


def warm_blocks(n_cells: int) -> str:
    """The warm-start share :func:`brdffit.fit` uses for ``n_cells`` (text for the report)."""
    from brdffit.fitting.data import CHUNK_CELLS
    from brdffit.fitting.stages import plan

    chunks = -(-n_cells // CHUNK_CELLS)
    warm = dict(plan(chunks, CHUNK_CELLS, scan=False)).get("warm")
    if warm is None:
        return "no blocks (table too small)"
    return f"{warm} of {chunks} blocks of {CHUNK_CELLS} cells"


def bench_disney(args):
    table = noisy_table("disney", DISNEY_TRUTH)
    model = brdffit.get_model("disney")
    fixed = {p.name: model.complete(DISNEY_TRUTH)[p.name] for p in model.params
             if p.name not in DISNEY_FREE}
    call = lambda: brdffit.fit(table, "disney", fixed=fixed, precision=args.precision)
    _first, res, cold, warm = timed(call, args.repeat)
    truth = model.flatten(DISNEY_TRUTH)
    free = [model.flat_names().index(n) for n in res.free]
    print(f"load average: {os.getloadavg()}")
    print(res.summary())
    print(f"disney brdffit ({args.precision}): cold {cold:.2f} s, warm {warm:.2f} s; steps "
          f"{res.steps}; max rel. error of free params "
          f"{param_error(res.x[free], truth[free]):.2e}")
    print(f"peak RSS: {peak_rss_mb():.0f} MB")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--precision", default="float64", choices=["float64", "float32"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-scipy", action="store_true")
    ap.add_argument("--no-disney", action="store_true")
    ap.add_argument("--no-ggx", action="store_true")
    args = ap.parse_args()
    if not args.no_ggx:
        bench_ggx(args)
    if not args.no_disney:
        bench_disney(args)


if __name__ == "__main__":
    main()
