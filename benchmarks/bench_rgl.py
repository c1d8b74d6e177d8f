"""Benchmark the RGL ``.bsdf`` format: write, read, evaluate 1,000,000 pairs, agreement.

Run by hand from the repository root::

    .venv/bin/python benchmarks/bench_rgl.py [--repeat 3] [--pairs 1000000] [--mitsuba 20000]

Makes virtual measurements (``synthesize_rgl``) of an isotropic and an anisotropic GGX at the
resolutions of the RGL database's files (isotropic: 1 x 10 slices, anisotropic: 13 x 10 slices;
32 x 32 tables), writes and reads them, and reports for each: the synthesis, write and read
times, ``RGLMaterial.eval`` on ``--pairs`` random direction pairs (best of ``--repeat``, wall and
CPU), ``to_samples``; the agreement with the source model (median, 99th percentile and maximum of
``|f_file - f_model| / (f_model + 1e-3)`` for ``θi, θo < 70°``, where the largest error lies,
and the same in ``f cos θo`` over the whole hemisphere); and, when Mitsuba 3 is importable,
the largest relative difference from Mitsuba's ``measured`` plugin (``scalar_rgb``, ``--mitsuba`` pairs, its
``eval`` divided by ``cos θo``). The models are plain NumPy here (benchmarks do not import the
tests). Goals: none; the figures are for the record.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from data_formats import read_rgl, synthesize_rgl, write_rgl  # noqa: E402


def ggx(wi, wo, ax=0.3, ay=0.3, kd=(0.1, 0.2, 0.3), f0=0.04):
    """GGX (Heitz 2014 eqs. 85-86, isotropic when ``ax == ay``), Schlick Fresnel, Smith G2."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    d = 1 / (np.pi * ax * ay * ((h[:, 0] / ax) ** 2 + (h[:, 1] / ay) ** 2 + h[:, 2] ** 2) ** 2)

    def lam(w):
        return 0.5 * (np.sqrt(1 + ((ax * w[:, 0]) ** 2 + (ay * w[:, 1]) ** 2) / w[:, 2] ** 2) - 1)

    fres = f0 + (1 - f0) * (1 - np.clip(np.sum(wi * h, 1), 0, 1)) ** 5
    spec = fres * d / (1 + lam(wi) + lam(wo)) / (4 * wi[:, 2] * wo[:, 2])
    return np.asarray(kd) / np.pi + spec[:, None]


def ggx_aniso(wi, wo):
    return ggx(wi, wo, ax=0.15, ay=0.4)


def pairs(rng, n):
    d = rng.normal(size=(2, n, 3))
    d[..., 2] = np.abs(d[..., 2])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return d[0], d[1]


def timed(fn, repeat=1):
    best_wall = best_cpu = float("inf")
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        best_wall = min(best_wall, time.perf_counter() - w)
        best_cpu = min(best_cpu, time.process_time() - c)
    return out, best_wall, best_cpu


def agreement(mat, brdf, wi, wo):
    f, ref = mat.eval(wi, wo), brdf(wi, wo)
    rel = (np.abs(f - ref) / (ref + 1e-3)).max(axis=1)
    deg_i, deg_o = (np.degrees(np.arccos(np.clip(w[:, 2], -1, 1))) for w in (wi, wo))
    inner = (deg_i < 70) & (deg_o < 70)
    k = np.argmax(np.where(inner, rel, -1))
    h = wi[k] + wo[k]
    th = np.degrees(np.arccos(h[2] / np.linalg.norm(h)))
    # Over the whole hemisphere, in f_r cos θo (what the file tabulates): near the horizon the
    # tables interpolate towards the zeros stored below it, which f_r = value / cos θo magnifies.
    cos_o = wo[:, 2:3]
    rel_cos = (np.abs(f - ref) * cos_o / (ref * cos_o + 1e-3)).max(axis=1)
    return (np.median(rel[inner]), np.quantile(rel[inner], 0.99), rel[inner].max(),
            (deg_i[k], deg_o[k], th), np.quantile(rel_cos, 0.99), rel_cos.max())


def mitsuba_difference(path, mat, wi, wo):
    try:
        import mitsuba as mi
    except ImportError:
        return None
    mi.set_variant("scalar_rgb")
    bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    wi, wo = (np.asarray(w, np.float32).astype(np.float64) for w in (wi, wo))
    theirs = np.empty((len(wi), 3))
    for k in range(len(wi)):
        si.wi = mi.Vector3f(*wi[k])
        v = bsdf.eval(ctx, si, mi.Vector3f(*wo[k]))
        theirs[k] = (v[0], v[1], v[2])
    theirs /= wo[:, 2:3]
    mine = mat.eval(wi, wo)
    return float(np.max(np.abs(mine - theirs) / (np.abs(theirs) + 1e-6)))


CASES = {
    "ggx isotropic (a=0.3)": (ggx, dict(isotropic=True)),
    "ggx anisotropic (0.15, 0.4)": (ggx_aniso, dict(isotropic=False, n_phi_i=13)),
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--pairs", type=int, default=1_000_000)
    parser.add_argument("--mitsuba", type=int, default=20_000)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    wi, wo = pairs(rng, args.pairs)
    with tempfile.TemporaryDirectory() as tmp:
        for label, (brdf, kw) in CASES.items():
            path = os.path.join(tmp, "m.bsdf")
            mat, t_syn, _ = timed(lambda: synthesize_rgl(brdf, **kw))
            _, t_write, _ = timed(lambda: write_rgl(path, mat), args.repeat)
            back, t_read, c_read = timed(lambda: read_rgl(path), args.repeat)
            back.eval(wi[:10], wo[:10])  # build the interpolants once (as Mitsuba's loader)
            _, t_eval, c_eval = timed(lambda: back.eval(wi, wo), args.repeat)
            samples, t_samp, _ = timed(lambda: back.to_samples())
            med, p99, mx, (ti, to, th), p99_all, mx_all = agreement(back, brdf, wi, wo)
            print(f"{label}: {back!r}, {os.path.getsize(path):,} bytes")
            print(f"  synthesize {t_syn:.2f} s, write {t_write * 1e3:.1f} ms, "
                  f"read {t_read * 1e3:.1f} ms (cpu {c_read * 1e3:.1f} ms)")
            print(f"  eval {args.pairs:,} pairs: {t_eval:.2f} s (cpu {c_eval:.2f} s), "
                  f"{args.pairs / t_eval / 1e6:.2f} M pairs/s")
            print(f"  to_samples: {len(samples):,} pairs ({samples.n_valid:,} valid) "
                  f"in {t_samp:.2f} s")
            print(f"  vs model, θi, θo < 70°: median {med:.4f}, p99 {p99:.4f}, max {mx:.3f} "
                  f"at θi {ti:.1f}°, θo {to:.1f}°, θh {th:.1f}°; whole hemisphere, in f cos θo: "
                  f"p99 {p99_all:.3f}, max {mx_all:.2f}")
            diff = mitsuba_difference(path, back, wi[:args.mitsuba], wo[:args.mitsuba])
            print("  vs Mitsuba measured: " + ("not installed" if diff is None else
                  f"max relative difference {diff:.2e} over {args.mitsuba:,} pairs"))


if __name__ == "__main__":
    main()
