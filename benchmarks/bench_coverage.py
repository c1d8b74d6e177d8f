"""Coverage of the truth by the least-squares ± and the posterior's intervals, over many seeds.

Run by hand from the repository root::

    nice -n 5 .venv/bin/python benchmarks/bench_coverage.py [--seeds 50] [--cells 600]
        [--noise multiplicative|log] [--steps 600] [--classical]

Each seed draws a noisy synthetic sample list of ``ggx`` (``--cells`` random direction pairs,
uniform on the hemisphere, with the angle weights of a MERL table's ``θh`` warp so that the
default ``weighting="angles"`` weights them unevenly, as on a measured table), fits it, and
samples the posterior with the defaults (``noise="sandwich"``) on the same cells. The noise:

* ``multiplicative`` (the default): ``ρ · exp(0.05 ε)``, the relative noise of a measurement;
  under the ``log`` loss the peak cells' residuals then spread a hundred times more than a dark
  diffuse floor's, which the one-scale Gaussian likelihood does not know;
* ``log``: Gaussian ``0.01 ε`` on ``log(1 + ρ cos θi)``, the plain likelihood's own model (the
  residuals still have unequal spreads through the weights).

It prints, per scalar and pooled, the fraction of seeds whose interval holds the truth, for
the least-squares ``± stderr`` (sandwich), the posterior's 16–84 % interval, and with
``--classical`` the plain one-scale Gaussian posterior (``noise="fixed"``, what the posterior
used before the sandwich calibration), beside the nominal 68.3 % and the range a correct
interval stays in for that many seeds (binomial, 2.5 standard deviations).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import brdffit  # noqa: E402
from brdffit.posterior import ChainTooShortWarning, sample_posterior  # noqa: E402
from data_formats import SampleSet  # noqa: E402

NOMINAL = math.erf(1 / math.sqrt(2))  # 0.6827: ±1 σ of a Gaussian, and p16–p84
TRUTH = {"diffuse": [0.3, 0.35, 0.4], "f0": [0.5, 0.4, 0.3], "alpha": 0.2, "grazing": 1.0}
FIXED = {"grazing": 1.0}


def hemisphere(rng, n):
    """``n`` directions uniform on the upper hemisphere."""
    v = rng.standard_normal((n, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def noisy_samples(model, truth, n, noise, seed) -> SampleSet:
    """``n`` random direction pairs of ``model`` at ``truth`` with ``noise``, MERL-like angle
    weights (``∝ sqrt(θh)``: the share of the angle domain of a cell of the warped ``θh`` axis)."""
    rng = np.random.default_rng(seed)
    wi, wo = hemisphere(rng, n), hemisphere(rng, n)
    params = {k: jax.numpy.asarray(v) for k, v in truth.items()}
    rho = np.asarray(model(params, jax.numpy.asarray(wi), jax.numpy.asarray(wo)))
    eps = rng.standard_normal(rho.shape)
    if noise == "multiplicative":
        rho = rho * np.exp(0.05 * eps)
    else:
        ci = wi[:, 2:3]
        rho = np.maximum(np.expm1(np.log1p(rho * ci) + 0.01 * eps) / ci, 0.0)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    weight = np.sqrt(np.arccos(np.clip(h[:, 2], -1, 1))) + 0.05
    return SampleSet(wi, wo, rho, np.ones(n, bool), name=f"seed{seed}", weight=weight)


def covered(post, truth, name, lo_hi) -> bool:
    lo, hi = lo_hi
    return bool(lo <= truth[name] <= hi)


def run(seeds, cells, noise, steps, classical):
    model = brdffit.get_model("ggx")
    truth = dict(zip(model.flat_names(), model.flatten(TRUTH)))
    kinds = ["least squares ±", "posterior p16–p84"] + (["classical posterior"] if classical
                                                          else [])
    hits = {k: {} for k in kinds}
    t0 = time.perf_counter()
    for seed in range(seeds):
        samples = noisy_samples(model, TRUTH, cells, noise, seed)
        runs = {"posterior p16–p84": "sandwich", "classical posterior": "fixed"}
        for kind in kinds[1:]:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ChainTooShortWarning)
                post = sample_posterior(samples, "ggx", fixed=FIXED, subsample=None, seed=seed,
                                        nwalkers=16, nsteps=steps, burn=steps // 4,
                                        noise=runs[kind])
            for n in post.free:
                p16, _, p84 = post.percentiles[n]
                hits[kind].setdefault(n, []).append(covered(post, truth, n, (p16, p84)))
                if kind == kinds[1]:
                    x, se = dict(zip(post.names, post.x_ls))[n], post.stderr_ls[n]
                    hits[kinds[0]].setdefault(n, []).append(
                        covered(post, truth, n, (x - se, x + se)))
    return hits, time.perf_counter() - t0


def band(n: int, k: float = 2.5) -> tuple[float, float]:
    sd = math.sqrt(NOMINAL * (1 - NOMINAL) / n)
    return NOMINAL - k * sd, NOMINAL + k * sd


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--cells", type=int, default=600)
    ap.add_argument("--noise", choices=("multiplicative", "log"), default="multiplicative")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--classical", action="store_true")
    a = ap.parse_args()
    hits, wall = run(a.seeds, a.cells, a.noise, a.steps, a.classical)
    lo, hi = band(a.seeds)
    print(f"ggx, {a.cells} cells, {a.noise} noise, {a.seeds} seeds, grazing fixed (plain Schlick); "
          f"nominal {NOMINAL:.3f} (a correct interval stays in {lo:.2f}–{hi:.2f} per scalar); "
          f"{wall:.0f} s")
    names = list(next(iter(hits.values())))
    print(f"{'scalar':>12} " + " ".join(f"{k:>22}" for k in hits))
    for n in names:
        print(f"{n:>12} " + " ".join(f"{np.mean(h[n]):>22.3f}" for h in hits.values()))
    pooled = {k: np.mean([v for h in hs.values() for v in h]) for k, hs in hits.items()}
    print(f"{'pooled':>12} " + " ".join(f"{v:>22.3f}" for v in pooled.values())
          + f"   (nominal {NOMINAL:.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
