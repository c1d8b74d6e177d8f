"""Benchmark: one full-table pass of the fit (value, ``JᵀJ``, ``Jᵀr`` over every block), per model,
with the fitting program's XLA options and with each of them left out.

    .venv/bin/python benchmarks/bench_pass.py [--models ggx,beckmann,blinn-phong,gtr] [--repeat 10]

A fit's time is mostly passes (a converged full stage takes two or three), so this is the unit
of its cost. The table is a full synthetic MERL table (``data_formats.merl.synthesize``
of the model at its defaults, ``evaluate_model``: no download), prepared once per model; each
variant's program is compiled once and the calls are interleaved across the variants, so a change in the machine's speed during the run affects
them alike. Printed per model and variant: min and median seconds of ``--repeat`` calls, the
number of ``exponential`` instructions in the optimised program (a duplicated primal shows
there), and the min against the default options' min.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

from brdffit.fitting import normal_form  # noqa: E402
from brdffit.fitting.fitter import prepare  # noqa: E402
from brdffit.fitting.options import Settings, fit_options  # noqa: E402
from brdffit.fitting.solve import CPU_COMPILER_OPTIONS  # noqa: E402
from brdffit.fitting.statistics import N_CELL_SUMS  # noqa: E402
from brdffit.models.evaluate import evaluate_model  # noqa: E402
from brdffit.models.registry import get_model  # noqa: E402
from data_formats.merl import synthesize  # noqa: E402


def variants() -> dict[str, dict]:
    """The fitting program's options, and the same with each one left out."""
    out = {"default": dict(CPU_COMPILER_OPTIONS)}
    for key in CPU_COMPILER_OPTIONS:
        out[f"without {key}"] = {k: v for k, v in CPU_COMPILER_OPTIONS.items() if k != key}
    return out


def prepared(model_name: str):
    """The fit's problem, cells and start point of ``model_name`` on a full synthetic table of
    the model at its defaults."""
    model = get_model(model_name)
    table = synthesize(lambda wi, wo: evaluate_model(model, None, wi, wo), name=model_name)
    prep = prepare(table, model, Settings.of(fit_options(None)))
    return prep.problem, prep.selection.data, jnp.asarray(prep.z0)


def compiled_pass(pb, data, u, options: dict):
    """``(call, exps)``: the full-table pass of ``pb`` at ``u`` compiled with ``options``, and
    its number of ``exponential`` instructions."""

    def one_pass(u, d):
        return normal_form.gram(pb.block_sums, u, d, pb.chunks, np.int32(pb.chunks),
                                pb.pass_tables, N_CELL_SUMS)

    compiled = jax.jit(one_pass, compiler_options=options).lower(u, data).compile()
    jax.block_until_ready(compiled(u, data))
    return (lambda: jax.block_until_ready(compiled(u, data))), compiled.as_text().count(
        "exponential(")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="ggx,beckmann,blinn-phong,gtr")
    ap.add_argument("--repeat", type=int, default=10)
    opts = ap.parse_args()
    for name in opts.models.split(","):
        pb, data, u = prepared(name)
        calls = {v: compiled_pass(pb, data, u, o) for v, o in variants().items()}
        times = {v: [] for v in calls}
        for _ in range(opts.repeat):
            for v, (call, _) in calls.items():
                t = time.perf_counter()
                call()
                times[v].append(time.perf_counter() - t)
        base = min(times["default"])
        for v, (_, exps) in calls.items():
            print(f"{name:12s} {v:52s} min {min(times[v]):.3f} s  median "
                  f"{statistics.median(times[v]):.3f} s  exp {exps:3d}  "
                  f"{min(times[v]) / base:.2f}x default")
    print(f"load average {os.getloadavg()[0]:.2f} (cores {os.cpu_count()})")


if __name__ == "__main__":
    main()
