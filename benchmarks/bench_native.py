"""Benchmark: the renderer-native models in Mitsuba 3 and what they cost on realistic data.

    .venv/bin/python benchmarks/bench_native.py [--pairs 12000] [--materials a,b,...]
        [--subsample 30000] [--no-mitsuba] [--no-realistic]

What it does:

1. For every parameter set of ``tests/test_export_mitsuba.py::CASES``: export, ``load_dict``,
   ``BSDF.eval`` at ``--pairs`` direction pairs (grazing and near-mirror included), and prints
   the maximum relative error of brdffit's model × cos θo where Mitsuba's value exceeds 1e-6,
   per native model (the worst over its parameter sets).
2. The time to export (dict, XML, glTF) and to render the 256² lit sphere (16 spp, scalar_rgb).
3. On realistic materials (``../shared/realistic/``: neural proxies of real MERL measurements,
   evaluated on a quarter-resolution MERL grid in memory, never written): fits brdffit's
   models (``ggx``, ``two-lobe-ggx``, ``disney``) and the native ones (``mitsuba-principled``,
   ``mitsuba-roughconductor``, ``gltf-pbr``) with their presets' fixed parameters, on a seeded
   subsample, and prints each fit's ``rmse_log`` and ``rel_error`` (``!``: the solver did not
   converge) and the ratio of each native model's ``rmse_log`` to the best brdffit model's: what
   rendering in each renderer gives up. ``rmse_log`` (the fits' loss, ``log(1 + f cos θi)``) is
   dominated by the highlight; ``rel_error`` (mean relative error per cell) by the dark diffuse
   cells: a conductor without a diffuse term can win the first and lose the second.

The machine may be shared: the script prints the load average next to the timings.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np

import brdffit
from brdffit.config import find_config, load_config
from brdffit.export import export
from brdffit.export.approximate import _starts
from brdffit.fitting import measure

ROOT = Path(__file__).resolve().parent.parent
REALISTIC = ROOT.parent / "shared" / "realistic"
MATERIALS = ("aluminium", "chrome-steel", "gold-metallic-paint2", "blue-acrylic",
             "specular-red-phenolic", "pink-fabric2")
OURS = ("ggx", "two-lobe-ggx", "disney")
NATIVE = ("mitsuba-principled", "mitsuba-roughconductor", "gltf-pbr")


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent))
    spec.loader.exec_module(mod)
    return mod


def mitsuba_errors(pairs: int):
    tests = _load(ROOT / "tests" / "test_export_mitsuba.py", "test_export_mitsuba")
    worst = {}
    wi, wo = tests.direction_pairs(pairs)
    for name, label, params in tests.CASES:
        bsdf = tests.mi.load_dict(export((name, params), "mitsuba-dict").payload)
        err = tests.max_relative_error(name, params, bsdf, wi, wo)
        print(f"  {name:45s} {label:26s} max rel err {err:.2e}")
        family = "mitsuba-principled" if "principled" in name else "mitsuba-roughconductor*"
        worst[family] = max(worst.get(family, 0.0), err)
    for k, v in worst.items():
        print(f"  worst {k}: {v:.2e} over {pairs} pairs per parameter set")


def timings():
    from brdffit.export.render import render_mitsuba

    p = dict(base_color=[0.6, 0.3, 0.1], roughness=0.3, metallic=0.2, clearcoat=0.5)
    for target, model in (("mitsuba-dict", "mitsuba-principled"), ("mitsuba-xml", "mitsuba-principled"),
                          ("gltf", "gltf-pbr")):
        t = time.perf_counter()
        for _ in range(100):
            out = export((model, p if model != "gltf-pbr" else dict(base_color=0.5)), target)
        print(f"  export {target:13s} {(time.perf_counter() - t) / 100 * 1e3:.3f} ms")
    d = export(("mitsuba-principled", p), "mitsuba-dict").payload
    render_mitsuba(d, size=16, spp=1)  # plugin loading
    t = time.perf_counter()
    render_mitsuba(d, size=256, spp=16)
    print(f"  render 256x256, 16 spp: {time.perf_counter() - t:.2f} s (load {os.getloadavg()[0]:.1f})")
    del out


def realistic(materials, subsample):
    from data_formats.merl import synthesize

    render = _load(REALISTIC / "render.py", "realistic_render")
    print(f"  {'material':24s} " + " ".join(f"{m:>23s}" for m in OURS + NATIVE))
    for mat in materials:
        table = synthesize(lambda wi, wo: render.brdf(mat, wi, wo), name=mat, shape=(45, 45, 90))
        samples = table.to_samples()
        feat = measure(samples.rgb[samples.valid], samples.wi[samples.valid], samples.wo[samples.valid],
                       np.ones(int(samples.valid.sum()), bool))
        row = {}
        for name in OURS + NATIVE:
            opts = load_config(find_config(ROOT / "configs" / f"{name}.toml"))
            starts = [None] if name in OURS else _starts(brdffit.get_model(name), feat)
            best = None
            for init in starts:
                init = {k: v for k, v in (init or {}).items() if k not in opts.fixed} or None
                res = brdffit.fit(table, name, init=init, fixed=opts.fixed or None, cutoff=opts.cutoff,
                                  subsample=subsample, throw=False)
                best = res if best is None or res.cost < best.cost else best
            row[name] = best
        ours = min(OURS, key=lambda n: row[n].metrics["rmse_log"])
        cells = " ".join(f"{row[n].metrics['rmse_log']:9.4f} ({row[n].metrics['rel_error']:.3f})"
                         + ("*" if n == ours else " ") + (" " if row[n].success else "!")
                         for n in OURS + NATIVE)
        ratio = ", ".join(f"{n} x{row[n].metrics['rmse_log'] / row[ours].metrics['rmse_log']:.2f}"
                          for n in NATIVE)
        print(f"  {mat:24s} {cells}\n  {'':24s} rmse_log against {ours}: {ratio}", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=12000)
    ap.add_argument("--materials", default=",".join(MATERIALS))
    ap.add_argument("--subsample", type=int, default=30000)
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--no-realistic", action="store_true")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    if not args.no_mitsuba:
        print("1. brdffit model x cos θo against Mitsuba 3 BSDF.eval (scalar_rgb)")
        mitsuba_errors(args.pairs)
        print("2. export and render times")
        timings()
    if not args.no_realistic:
        print(f"3. realistic materials, {args.subsample} cells, rmse_log (rel_error); * best of ours")
        realistic(args.materials.split(","), args.subsample)


if __name__ == "__main__":
    main()
