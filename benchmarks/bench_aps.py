"""Speed: APS 2000 models over a full MERL grid (90 × 90 × 180 = 1,458,000 direction pairs)
against the closed-form ``ggx`` model (goal: within 3× once the tables are built).

Two ways of evaluating are timed, each for ``ggx``, the isotropic ``aps-velvet`` (the MERL
case: 1-D tables) and the anisotropic ``aps-gaussian`` (2-D tables):

* **library**: :func:`brdffit.models.evaluate.evaluate_model` over the whole grid, the path that
  renders fitted tables (``FitResult.to_table``, ``brdffit fit --table``), ``brdffit synth`` and
  the figures. It builds an APS model's tables once per call (``Model.stages``) and runs the
  per-pair quantities and the RGB combination as two compiled programs; chunks of 32,768 pairs.
  The table builds are included in the time.
* **one program**: ``jax.jit(model)`` over all pairs at once, as a fit traces the model, tables
  built inside; and the per-pair evaluation alone with the tables built beforehand.

Run: ``.venv/bin/python benchmarks/bench_aps.py [--repeat 5] [--float32]``. The machine may be
shared: the load average is printed.
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

MODELS = {
    "ggx": dict(alpha=0.2),
    "aps-velvet": dict(sigma=0.5),
    "aps-gaussian": dict(sigma_x=0.2, sigma_y=0.4),
}


def _best(fn, repeat):
    jax.block_until_ready(fn())  # compile + warm
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - t)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--float32", action="store_true", help="float32 (default float64)")
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", not args.float32)

    import brdffit
    from brdffit.models.evaluate import evaluate_model
    from data_formats.merl import cell_directions

    dt = jnp.float32 if args.float32 else jnp.float64
    wi_np, wo_np = (np.asarray(a).reshape(-1, 3) for a in cell_directions())
    wi, wo = jnp.asarray(wi_np, dt), jnp.asarray(wo_np, dt)
    colour = dict(diffuse=[0.5, 0.3, 0.2], f0=[0.05, 0.05, 0.05])

    rows = {}
    for name, shape in MODELS.items():
        model = brdffit.get_model(name)
        params = {**colour, **shape}
        lib = _best(lambda m=model, p=params: evaluate_model(m, p, wi_np, wo_np), args.repeat)
        p = {k: jnp.asarray(v, dt) for k, v in model.complete(params).items()}
        whole = jax.jit(lambda p, a, b, m=model: m.fn(p, a, b))
        one = _best(lambda: whole(p, wi, wo), args.repeat)
        pre = np.nan
        if model.stages is not None:
            prepare, per_pair, combine = model.stages
            state = jax.jit(prepare)(p)
            body = jax.jit(lambda s, a, b: combine(s, per_pair(s, a, b)))
            pre = _best(lambda: body(state, wi, wo), args.repeat)
        rows[name] = (lib, one, pre)

    ref_lib, ref_one, _ = rows["ggx"]
    print(f"{len(wi_np):,} direction pairs, {jnp.dtype(dt).name}, {jax.devices()[0].platform}, "
          f"best of {args.repeat}, load average {os.getloadavg()}")
    print(f"  {'model':14s} {'library':>18s} {'one program':>20s} {'one program, tables prebuilt':>32s}")
    for name, (lib, one, pre) in rows.items():
        pre_text = "" if np.isnan(pre) else f"{pre * 1e3:8.1f} ms {pre / ref_one:5.2f}x"
        print(f"  {name:14s} {lib * 1e3:8.1f} ms {lib / ref_lib:5.2f}x "
              f"{one * 1e3:10.1f} ms {one / ref_one:5.2f}x {pre_text:>24s}")
    print("  (ratios against ggx timed the same way)")


if __name__ == "__main__":
    main()
