"""Benchmark: a full fit of ``ggx`` and ``ggx-aniso`` to a written RGL ``.bsdf`` file, cold and warm.

    .venv/bin/python benchmarks/bench_rgl_fit.py [--repeat 3]

What it does:

1. Writes two virtual measurements with the tables of ``brdffit synth -o X.bsdf`` (10 θi
   slices, 13 φi slices when anisotropic, 32 x 32 nodes per slice): an isotropic GGX
   (:data:`ISO`) and an anisotropic GGX whose axes are turned 30° from the file's x axis
   (:data:`ANISO`); prints the time to synthesize, write and read each.
2. **Cold**: a fresh ``brdffit fit X.bsdf --model M --json`` process with an empty
   ``XDG_CACHE_HOME`` and the compilation cache off (it compiles everything): the process's
   wall time (start-up, reading, fitting) and the fit's own ``wall_time``.
3. **Warm**: in this process, the same fit ``--repeat`` times after a first one (compiled
   programs reused): the median of the fit's wall time, and the largest relative error of a
   fitted parameter against the truth (``frame_angle`` absolute, in degrees).

Timings are of this machine at this moment (it may be shared: the load average is printed).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
ISO = {"diffuse": [0.1, 0.2, 0.3], "f0": [0.8, 0.6, 0.4], "alpha": 0.15}
ANISO = {"diffuse": [0.1, 0.1, 0.1], "f0": [0.8, 0.6, 0.4], "alpha_x": 0.08, "alpha_y": 0.3,
         "frame_angle": float(np.radians(30.0))}
CASES = (("ggx", ISO), ("ggx-aniso", ANISO))


def _errors(params, truth) -> str:
    rel = max(float(np.max(np.abs(np.asarray(params[k]) - np.asarray(v)) / np.abs(v)))
              for k, v in truth.items() if k != "frame_angle")
    text = f"max rel. error {rel:.2e}"
    if "frame_angle" in truth:
        text += f", frame_angle off by {np.degrees(abs(params['frame_angle'] - truth['frame_angle'])):.2e}°"
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    import jax

    jax.config.update("jax_enable_x64", True)
    import brdffit
    from brdffit.cli.synth import synthesize_material
    from data_formats.rgl import read_rgl, write_rgl

    print(f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory(prefix="bench-rgl-") as tmp:
        tmp = Path(tmp)
        for name, truth in CASES:
            path = tmp / f"{name}.bsdf"
            t0 = time.perf_counter()
            material = synthesize_material(brdffit.get_model(name), truth, name=name)
            t1 = time.perf_counter()
            write_rgl(path, material)
            t2 = time.perf_counter()
            samples = read_rgl(path).to_samples()
            t3 = time.perf_counter()
            print(f"\n{name}: {path.stat().st_size / 1e6:.1f} MB, {len(samples.wi):,} pairs "
                  f"({int(np.sum(samples.valid)):,} valid); synthesize {t1 - t0:.2f} s, "
                  f"write {t2 - t1:.3f} s, read + pattern {t3 - t2:.3f} s")

            env = {**os.environ, "PYTHONPATH": str(ROOT), "XDG_CACHE_HOME": str(tmp / "cache"),
                   "BRDFFIT_NO_COMPILATION_CACHE": "1"}
            t0 = time.perf_counter()
            run = subprocess.run([sys.executable, str(ROOT / "cli.py"), "fit", str(path),
                                  "--model", name, "--json"], capture_output=True, text=True,
                                 env=env)
            wall = time.perf_counter() - t0
            if run.returncode != 0:
                print(f"  cold process failed ({run.returncode}): {run.stderr.strip()[-300:]}")
            else:
                fit = json.loads(run.stdout)
                print(f"  cold: process {wall:.1f} s, fit wall_time {fit['wall_time']:.1f} s, "
                      f"{_errors(fit['params'], truth)}")

            first = brdffit.fit(path, name)
            times = []
            for _ in range(args.repeat):
                res = brdffit.fit(path, name)
                times.append(res.wall_time)
            print(f"  warm: first in-process fit {first.wall_time:.1f} s; then median "
                  f"{statistics.median(times):.2f} s over {args.repeat} (min {min(times):.2f}), "
                  f"converged={res.success}, {_errors(res.params, truth)}")


if __name__ == "__main__":
    main()
