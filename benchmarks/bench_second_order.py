"""Benchmark: the second-order program of a fit against the exact term's program.

    .venv/bin/python benchmarks/bench_second_order.py [--models ggx,beckmann,two-lobe-ggx]
        [--input TABLE.binary] [--repeat 12] [--at start|optimum] [--precision float64|float32]

Each Newton round of a fit measures ``Σ rᵢ∇²rᵢ`` on the leading 32,768 cells
(:func:`brdffit.fitting.solve.second_order`). The fit's program takes forward differences of
exact first derivatives (``solve._second``); the reference is the exact term,
``Problem.block_second_order`` (``jax.hessian``) over the whole slab in one piece, compiled
without options. Each is compiled by its first call
(timed: the seconds a cold fit pays for it), then called ``--repeat`` times, interleaved, at
the fit's start point on a full table (a synthetic one of the model at its defaults, or
``--input``, e.g. a realistic table written by ``../shared/realistic/render.py``). Printed
per model and program: the first call's seconds, min and median milliseconds per call, the
memory each call touched for the first time (minor page faults × 4 KiB: a temporary buffer
the C library maps afresh at every call shows here), the largest difference between the two
terms relative to the term's largest entry, and the ratios of the reference's figures to the
fit's. ``--at optimum`` measures at the end point of a default fit instead of the start point;
``--precision float32`` evaluates the model in float32 (the differences then take float32's
step).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import brdffit  # noqa: E402
from brdffit.fitting import solve  # noqa: E402
from brdffit.fitting.fitter import prepare  # noqa: E402
from brdffit.fitting.options import Settings, fit_options  # noqa: E402
from brdffit.io import read_path  # noqa: E402
from brdffit.models.evaluate import evaluate_model  # noqa: E402
from brdffit.models.registry import get_model  # noqa: E402
from data_formats.merl import synthesize  # noqa: E402


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def _one_slab(problem, z, data, blocks):
    """The exact term: the slab's rows past ``blocks`` blocks weighted zero, one piece."""
    block = data.wi.shape[0] // problem.chunks
    rows = block * solve._slab_blocks(problem, data)
    slab = jax.tree.map(lambda a: a[:rows], data)
    keep = (jnp.arange(rows) < blocks * block)[:, None]
    slab = eqx.tree_at(lambda d: d.sqrt_weight, slab, jnp.where(keep, slab.sqrt_weight, 0.0))
    return problem.block_second_order(z, slab)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="ggx,beckmann,two-lobe-ggx")
    ap.add_argument("--input", default=None, help="a MERL table to use instead of synthetic ones")
    ap.add_argument("--repeat", type=int, default=12)
    ap.add_argument("--at", choices=("start", "optimum"), default="start")
    ap.add_argument("--precision", choices=("float64", "float32"), default="float64")
    opts = ap.parse_args()
    given = None if opts.input is None else read_path(opts.input)
    for name in opts.models.split(","):
        model = get_model(name)
        table = given or synthesize(lambda wi, wo: evaluate_model(model, None, wi, wo), name=name)
        init = None
        if opts.at == "optimum":
            init = brdffit.fit(table, model, precision=opts.precision, throw=False).params
            jax.clear_caches()  # the first call below compiles again
        prep = prepare(table, model,
                       Settings.of(fit_options(None, precision=opts.precision, init=init)))
        pb, data, z = prep.problem, prep.selection.data, jnp.asarray(prep.z0)
        blocks = np.int32(solve.second_blocks(pb, data, pb.chunks))
        reference = jax.jit(_one_slab)
        calls = {"fit's (differences)": lambda: solve._second_program()(pb, z, data, blocks),
                 "exact (jax.hessian)": lambda: reference(pb, z, data, blocks)}
        terms, first = {}, {}
        for k, call in calls.items():  # compiles
            t = time.perf_counter()
            terms[k] = np.asarray(call())
            first[k] = time.perf_counter() - t
        times = {k: [] for k in calls}
        fresh = {k: [] for k in calls}
        for _ in range(opts.repeat):
            for k, call in calls.items():
                f, t = _faults(), time.perf_counter()
                jax.block_until_ready(call())
                times[k].append(time.perf_counter() - t)
                fresh[k].append((_faults() - f) * 4 / 1024)
        fit, exact = calls
        diff = np.max(np.abs(terms[fit] - terms[exact])) / np.max(np.abs(terms[exact]))
        for k in calls:
            print(f"{name:14s} {k:20s} first call {first[k]:6.2f} s  min "
                  f"{min(times[k]) * 1e3:7.1f} ms  median {statistics.median(times[k]) * 1e3:7.1f}"
                  f" ms  fresh {statistics.median(fresh[k]):5.0f} MB per call")
        print(f"{name:14s} exact / fit's: first call {first[exact] / first[fit]:.2f}x, min "
              f"{min(times[exact]) / min(times[fit]):.2f}x; terms differ by {diff:.1e} of the "
              f"largest entry")
    print(f"load average {os.getloadavg()[0]:.2f} (cores {os.cpu_count()})")


if __name__ == "__main__":
    main()
