"""Speed: an APS 2000 model over a full MERL grid (90 × 90 × 180 = 1,458,000 direction pairs)
against the closed-form ``ggx`` model, both jitted and warm. Goal: within 3×.

Three APS timings are printed: the registered model as fitting calls it (tables rebuilt from the
parameters inside the jitted function), and the evaluation alone with the tables built
beforehand ("once its tables are built", as the issue states the goal), for the isotropic
velvet (the MERL case: 1-D tables) and the anisotropic Gaussian (2-D tables).

Run: ``.venv/bin/python benchmarks/bench_aps.py [--repeat 5] [--float32]``.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np


def _time(fn, *args, repeat):
    jax.block_until_ready(fn(*args))  # compile + warm
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--float32", action="store_true", help="float32 (default float64)")
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", not args.float32)

    import brdffit
    from brdffit.aps import (
        CORRELATED,
        AnisotropicGaussian,
        Velvet,
        aps_diffuse,
        aps_specular,
        build_g_table,
        build_r_table,
    )
    from brdffit.aps.models import ANISO_RESOLUTION, ISO_RESOLUTION
    from data_formats.merl import cell_directions

    dt = jnp.float32 if args.float32 else jnp.float64
    wi, wo = (jnp.asarray(np.asarray(a).reshape(-1, 3), dt) for a in cell_directions())
    n = wi.shape[0]
    f0, rho = jnp.asarray([0.05, 0.05, 0.05], dt), jnp.asarray([0.5, 0.3, 0.2], dt)

    ggx = brdffit.get_model("ggx")
    p_ggx = dict(diffuse=rho, f0=f0, alpha=jnp.asarray(0.2, dt))
    t_ggx = _time(jax.jit(lambda p, a, b: ggx(p, a, b)), p_ggx, wi, wo, repeat=args.repeat)

    rows = [("ggx (closed form)", t_ggx)]
    for name, extra in (("aps-velvet", dict(sigma=0.5)), ("aps-gaussian", dict(sigma_x=0.2, sigma_y=0.4))):
        m = brdffit.get_model(name)
        p = dict(diffuse=rho, f0=f0, **{k: jnp.asarray(v, dt) for k, v in extra.items()})
        rows.append((f"{name}, tables built inside", _time(jax.jit(lambda p, a, b, m=m: m(p, a, b)), p, wi, wo, repeat=args.repeat)))

    for label, dist, res, shadowing in (
        ("aps-velvet, tables prebuilt", Velvet(jnp.asarray(0.5, dt)), ISO_RESOLUTION, CORRELATED),
        ("aps-gaussian, tables prebuilt", AnisotropicGaussian(jnp.asarray(0.2, dt), jnp.asarray(0.4, dt)), ANISO_RESOLUTION, None),
    ):
        from brdffit.aps import UNCORRELATED

        sh = shadowing or UNCORRELATED
        g = build_g_table(dist, dt, res)
        r = build_r_table(dist, g, dt, res, sh)
        ev = jax.jit(lambda d, g, r, a, b, sh=sh: aps_specular(d, g, f0, a, b, sh) + aps_diffuse(r, rho, f0, a, b))
        rows.append((label, _time(ev, dist, g, r, wi, wo, repeat=args.repeat)))

    print(f"{n:,} direction pairs, {jnp.dtype(dt).name}, {jax.devices()[0].platform}, best of {args.repeat}")
    for label, t in rows:
        print(f"  {label:34s} {t * 1e3:9.1f} ms   {t / t_ggx:5.2f} x ggx")


if __name__ == "__main__":
    main()
