"""``sample_posterior``: emcee ensemble sampling (differential-evolution moves) around a fit.

The pipeline: the posterior's cells → the least-squares fit on those cells (a given fit is
refitted there from its optimum; a model is fitted) → the fit's data selection, loss and
parameter bookkeeping (:mod:`brdffit.fitting`) → :class:`~.likelihood.LogPosterior` → walkers in a
small ball around the optimum → ``emcee.EnsembleSampler(vectorize=True)`` → diagnostics →
:class:`~.result.PosteriorResult`.

Defaults (chosen so a default ``ggx`` run, fit included, stays well under a minute on a
2-core CPU; ``benchmarks/bench_posterior.py`` measures it): a stratified subsample of
:data:`DEFAULT_SUBSAMPLE` cells (one per ``θh`` stratum, so the specular peak is always
represented), and the walkers, steps and burn-in of :class:`~.options.McmcOptions` (from
:mod:`.defaults`). A subsample carries less information than the whole table,
so its posterior is *wider* than a full-table one (by about ``sqrt(N/n)`` for independent
residuals): pass ``subsample=None`` for all cells, at a cost proportional to the cell count.
The least-squares values and errors beside it are those of the same cells, and its summary
says how many cells of the fit's it used.
"""

from __future__ import annotations

import dataclasses
import time

import emcee
import jax
import jax.numpy as jnp
import numpy as np

from ..config import FitOptions, check_fit_options
from ..errors import ConfigError
from ..fitting import WEIGHTINGS, FitResult, Subsample, check_enough, default_precision, select
from ..fitting import fit as run_fit
from ..models.registry import get_model
from .defaults import DEFAULT_SUBSAMPLE_CELLS
from .diagnostics import check, diagnose
from .likelihood import (
    LogPosterior,
    least_squares_sigma,
    log_posterior_batch,
    n_observations,
    noise_setup,
    sandwich_adjustment,
)
from .priors import build_prior
from .from_fit import loss_of, problem_from
from .options import RANGES as MCMC_RANGES
from .options import McmcOptions
from .result import PERCENTILES, PosteriorResult

DEFAULT_SUBSAMPLE = Subsample(DEFAULT_SUBSAMPLE_CELLS, "stratified")
#: Start-ball radius in units of each scalar's least-squares standard error.
BALL = 0.1


def default_moves():
    """Differential-evolution moves (80% DE, ter Braak 2006; 20% DE snooker, ter Braak & Vrugt
    2008), the mixture emcee's "Moves" tutorial shows for near-Gaussian posteriors (emcee:
    Foreman-Mackey et al. 2013; its default stretch move is Goodman & Weare 2010).

    Measured on a 7-parameter ``ggx`` posterior (2000 cells, 32 walkers): integrated
    autocorrelation time about 26 steps against 66 for the stretch move, at the same cost per
    step, so a chain of ``50 τ`` is 2.5 times shorter. Pass ``moves=`` to choose others."""
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


def _check_run(nwalkers, nsteps, burn, thin, ndim):
    if int(nwalkers) < 2 * ndim or int(nwalkers) % 2:
        raise ConfigError(
            f"nwalkers must be even and at least 2 x {ndim} (the sampled dimensions): emcee "
            f"moves each half of the walkers using the other half; got {nwalkers}. Try "
            f"nwalkers={max(2 * ndim, 32)}"
        )
    if not (int(nsteps) > int(burn) >= 0 and int(thin) >= 1):
        raise ConfigError(
            f"need nsteps > burn >= 0 and thin >= 1; got nsteps={nsteps}, burn={burn}, "
            f"thin={thin}"
        )


def _start_ball(center, scale, lo, hi, nwalkers, rng):
    """``center + BALL·scale·N(0,1)`` reflected at the prior box (a clipped start would put
    walkers on one value and the ensemble moves could never spread them). A centre outside a
    user's narrower prior is first moved to the nearest point of the box."""
    p0 = center + BALL * scale * rng.standard_normal((nwalkers, len(center)))
    p0 = np.where(p0 < lo, 2 * lo - p0, p0)
    p0 = np.where(p0 > hi, 2 * hi - p0, p0)
    eps = 1e-12 * (hi - lo)
    return np.clip(p0, lo + eps, hi - eps)


def _scales(result, problem, lo, hi):
    se = np.sqrt(np.clip(np.diag(np.asarray(result.cov, float)), 0, None))[list(problem.free)]
    fallback = 1e-3 * (hi - lo)
    return np.where(np.isfinite(se) & (se > 0), np.minimum(se, 0.1 * (hi - lo)), fallback)


def _batched(post, half):
    """NumPy ``(B, d) → (B,)`` for emcee, evaluated in chunks of ``half`` rows (padded), so
    the jitted program is compiled for one shape only."""

    def log_prob(thetas):
        thetas = np.asarray(thetas, float)
        out = []
        for k in range(0, len(thetas), half):
            chunk = thetas[k : k + half]
            pad = np.concatenate([chunk, np.repeat(chunk[-1:], half - len(chunk), 0)])
            out.append(np.asarray(log_posterior_batch(post, jnp.asarray(pad)))[: len(chunk)])
        return np.concatenate(out)

    return log_prob


def _least_squares(table, result_or_model, loss, fit_kwargs):
    """The least-squares fit on the posterior's cells, so that the walkers start at the mode of
    the likelihood they sample and the least-squares errors beside the posterior are of the
    same cells: a fresh fit of the given model, or the given :class:`FitResult` refitted there
    from its own optimum (its fixed scalars held, its loss and covariance kept; a few steps
    when the cells are those of the fit). A refit that fails keeps the given result."""
    t = time.perf_counter()
    if not isinstance(result_or_model, FitResult):
        result = run_fit(table, get_model(result_or_model), loss=loss or "log", **fit_kwargs)
        return result, time.perf_counter() - t
    given = result_or_model
    x = dict(zip(given.names, np.asarray(given.x, float)))
    kwargs = {**fit_kwargs, "fixed": {n: x[n] for n in given.fixed} or None,
              "init": {n: x[n] for n in given.free}, "covariance": given.covariance}
    refit = run_fit(table, get_model(given.model_name), loss=loss or given.loss, throw=False,
                    **kwargs)
    if not np.isfinite(refit.cost):
        return given, time.perf_counter() - t
    return refit, time.perf_counter() - t


def _cutoff_of(result_or_model):
    """The cutoff a result was fitted with: its recorded option (``None``: every cell); the
    default (:data:`brdffit.config.DEFAULT_CUTOFF`) for a model name or a result that records
    no options."""
    from ..config import DEFAULT_CUTOFF

    options = (getattr(result_or_model, "provenance", None) or {}).get("options")
    if options is None or "cutoff" not in options:
        return DEFAULT_CUTOFF
    return options["cutoff"]


def _weighting_of(result_or_model) -> str:
    """The weighting a result was fitted with: its recorded option; ``"samples"`` for a result
    whose recorded options predate the option (every sample counted once then); else the
    default."""
    options = (getattr(result_or_model, "provenance", None) or {}).get("options")
    if options is None:
        return WEIGHTINGS[0]
    return options.get("weighting", "samples")


def _posterior(result, samples, *, loss, cutoff, subsample, seed, bounds, noise, prior,
               weighting="angles"):
    """The :class:`LogPosterior`, its selection, the start centre and scales, noise info."""
    model = get_model(result.model_name)
    loss_obj = loss_of(result, loss)
    dtype = default_precision()
    sel = select(samples, loss_obj, cutoff=cutoff, subsample=subsample, seed=seed, dtype=dtype,
                 weighting=weighting)
    problem, lo, hi = problem_from(result, model, loss_obj, bounds, sel.chunks)
    check_enough(sel, len(problem.free), samples.name)
    free = list(problem.free)
    x_ls = np.asarray(result.x, float)[free]
    s_hat = least_squares_sigma(problem, x_ls, sel.data)
    sigma, sample_sigma, extra = noise_setup(noise, s_hat)
    adjust = None
    if noise == "sandwich":
        keep = [n not in result.at_bound and n not in result.not_identified
                for n in np.asarray(result.names)[free]]
        adjust = jnp.asarray(sandwich_adjustment(problem, x_ls, sel.data, keep), dtype)
    box = build_prior(model, free, lo, hi, prior, extra)
    blo, bhi = np.asarray(box.lo, float), np.asarray(box.hi, float)
    center = np.concatenate([x_ls, [sigma]]) if sample_sigma else x_ls
    scale = _scales(result, problem, lo[free], hi[free])
    m = n_observations(sel.data)  # the standard error of s is about s / sqrt(2m)
    scale = np.concatenate([scale, [sigma / np.sqrt(2.0 * m)]]) if sample_sigma else scale
    inside = np.clip(x_ls, blo[: len(free)], bhi[: len(free)])
    adjusted = {} if adjust is None else {
        "adjust": adjust, "anchor": jnp.asarray(x_ls, dtype),
        "lo": jnp.asarray(lo[free], dtype), "hi": jnp.asarray(hi[free], dtype)}
    post = LogPosterior(problem, sel.data, box, jnp.asarray(sigma, dtype),
                        float(m), jnp.asarray(inside, dtype), sample_sigma, **adjusted)
    mode = "sampled" if sample_sigma else (noise if isinstance(noise, str) else "given")
    return post, sel, center, scale, {"mode": mode, "sigma": float(sigma), "sigma_ls": s_hat}


def _run_emcee(post, center, scale, nwalkers, nsteps, seed, moves, progress=None):
    """Run the sampler; returns it and the seconds spent compiling and sampling.

    ``progress(event, info)`` (if given) gets ``sample-step`` with ``step`` and ``of`` after
    each ensemble step."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(post.prior.lo, float), np.asarray(post.prior.hi, float)
    p0 = _start_ball(np.clip(center, lo, hi), scale, lo, hi, nwalkers, rng)
    log_prob = _batched(post, nwalkers // 2)
    t0 = time.perf_counter()
    lp0 = log_prob(p0)  # compiles the one program
    t1 = time.perf_counter()
    if not np.all(np.isfinite(lp0)):
        raise ConfigError(
            f"{int(np.sum(~np.isfinite(lp0)))} of {nwalkers} starting walkers have zero "
            f"posterior density: the least-squares optimum lies outside the `prior` given, or "
            f"the model is not finite there. Widen the prior or refit."
        )
    sampler = emcee.EnsembleSampler(nwalkers, len(center), log_prob, vectorize=True,
                                    moves=moves)
    rstate = np.random.RandomState(int(rng.integers(2**32 - 1))).get_state()
    state = emcee.State(p0, log_prob=lp0, random_state=rstate)
    for k, _ in enumerate(sampler.sample(state, iterations=nsteps, progress=False), start=1):
        if progress is not None:
            progress("sample-step", {"step": k, "of": nsteps})
    return sampler, t1 - t0, time.perf_counter() - t1


def _by_param(model, flat: dict) -> dict:
    out = {}
    for p in model.params:
        keys = [p.name] if p.shape == () else [f"{p.name}[{i}]" for i in range(p.size)]
        vals = [float(flat[k]) for k in keys]
        out[p.name] = vals[0] if p.shape == () else vals
    return out


def _assemble(result, post, sel, sampler, noise, run, timings):
    """The :class:`PosteriorResult` from the finished sampler."""
    model = get_model(result.model_name)
    names = list(post.prior.names)
    chain = sampler.get_chain()
    flat = sampler.get_chain(discard=run["burn"], thin=run["thin"], flat=True)
    pct = np.percentile(flat, PERCENTILES, axis=0)
    diag = diagnose(chain, sampler.acceptance_fraction, names, run["burn"])
    check(diag)
    medians = dict(zip(result.names, np.asarray(result.x, float)))
    medians.update({n: float(v) for n, v in zip(names, pct[1])})
    if noise["mode"] == "sampled":
        noise = {**noise, "sigma": float(pct[1][names.index("sigma")])}
    se = np.sqrt(np.clip(np.diag(np.asarray(result.cov, float)), 0, None))
    return PosteriorResult(
        model_name=result.model_name, table=result.table, names=list(result.names),
        free=list(result.free), fixed=list(result.fixed), sampled=names,
        params=_by_param(model, medians),
        percentiles={n: [float(v) for v in pct[:, i]] for i, n in enumerate(names)},
        std={n: float(v) for n, v in zip(names, flat.std(axis=0, ddof=1))},
        x_ls=np.asarray(result.x, float),
        stderr_ls={n: (float("nan") if n in result.at_bound or n in result.not_identified
                       else float(v))
                   for n, v in zip(result.names, se) if n in result.free},
        samples=flat, chain=chain, log_prob=sampler.get_log_prob(), noise=noise,
        prior=post.prior.describe(), diagnostics=diag,
        settings={**run, "loss": loss_of(result, run["loss"]).label, "n_cells": sel.n_used,
                  "n_total": sel.n_total},
        wall_time=sum(timings.values()), timings=timings,
    )


#: The fit options the posterior uses (the others do not change its likelihood).
POSTERIOR_FIT_OPTIONS = ("loss", "cutoff", "bounds", "fixed", "init", "weighting")


def _split_options(options, mcmc, kwargs) -> tuple[FitOptions, McmcOptions]:
    """``(fit options, McmcOptions)`` from the arguments of :func:`sample_posterior`."""
    mine = {f.name for f in dataclasses.fields(McmcOptions)}
    unknown = sorted(set(kwargs) - mine - set(POSTERIOR_FIT_OPTIONS))
    if unknown:
        raise TypeError(f"sample_posterior() got unknown option(s) {', '.join(unknown)}; valid "
                        f"options: {', '.join(sorted(mine | set(POSTERIOR_FIT_OPTIONS)))}")
    if options is None:
        fit = FitOptions()
    elif isinstance(options, FitOptions):
        fit = options
    else:
        fit = FitOptions(**dict(options))
    fit = dataclasses.replace(fit, **{k: v for k, v in kwargs.items() if k not in mine})
    mcmc = dataclasses.replace(mcmc or McmcOptions(), **{k: v for k, v in kwargs.items()
                                                        if k in mine})
    return fit, mcmc


def sample_posterior(table, result_or_model, options=None, mcmc: McmcOptions | None = None, *,
                     progress=None, **kwargs) -> PosteriorResult:
    """Sample the posterior of a model's free parameters on ``table`` with emcee.

    Runs inside ``jax.enable_x64(True)`` (float64 for the call; ``jax.config`` is left as it
    was), with the persistent compilation cache on (:func:`brdffit.compilation_cache.ensure`),
    as :func:`brdffit.fit` does.

    The options come in two objects: ``options``, the fit's (a
    :class:`~brdffit.config.FitOptions` or a mapping: ``loss``, ``cutoff``, ``bounds``,
    ``fixed``, ``init``, ``weighting``), and ``mcmc``, the sampler's (:class:`McmcOptions`);
    keyword arguments override either, by name.

    Args:
        table: a path (``str`` or ``PathLike``: any format of ``brdffit.io.READERS``, read by
            :func:`brdffit.io.read_path`), or a ``MERLTable`` / ``SampleSet`` (anything with
            ``.to_samples()``).
        result_or_model: a :class:`~brdffit.fitting.FitResult` (its optimum, free/fixed split and
            loss are used), or a model name / :class:`Model` (fitted here first, on the same
            cells as the posterior, with ``loss``, ``cutoff``, ``bounds``, ``fixed``, ``init``).
        nwalkers, nsteps, burn, thin: the ensemble and the chain (``burn`` steps dropped,
            every ``thin``-th kept for the percentiles; diagnostics use the unthinned chain).
        seed: seeds the start ball, emcee's generator and the subsample; same seed, same chain.
        noise: ``"sandwich"`` (``σ`` learned from the residuals, the curvature calibrated to
            the sandwich covariance), ``"fixed"`` (least-squares ``s``), ``"sampled"``,
            ``"measured"`` (the data's own ``sigma`` columns) or a number (see
            :mod:`.likelihood`). Default: ``"measured"`` when the data carry ``sigma``, else
            ``"sandwich"`` (``"fixed"`` for a fit whose covariance is ``"gn"``), so that near
            the mode the posterior's covariance is the fit's estimator on the same cells.
        subsample: cells the likelihood uses: a count, a fraction, a ``Subsample`` or ``None``
            (all). Default: 2000 cells stratified in ``θh``. A given fit is refitted on these
            cells from its own optimum (its fixed scalars held), so that the least-squares
            values and errors reported beside the posterior are of the same cells.
        prior: name → ``(lo, hi)`` / ``Uniform`` / ``LogUniform`` / ``Normal`` (see
            :mod:`.priors`); default uniform within the physical bounds.
        loss, cutoff, bounds: as for :func:`brdffit.fit` (``loss`` defaults to the result's,
            ``cutoff`` to the result's recorded one, else the fit's default of 80°).
        weighting: as for :func:`brdffit.fit`; default the result's (recorded in its
            provenance), else ``"angles"``, so that the likelihood weights the cells as the
            fit did.
        fixed, init: passed to the fit when a model is given (fixed scalars stay fixed).
        chain_path: also save the chain there as NPZ (:meth:`PosteriorResult.save_chain`).
        moves: emcee moves; default :func:`default_moves` (differential evolution).
        progress: ``True`` for a ``tqdm.auto`` bar over the steps, or a callable
            ``progress(event, info)`` (``sample-step`` with ``step``, ``of``); see
            :mod:`brdffit.progress`.
    """
    from .. import compilation_cache
    from ..api import load
    from ..progress import resolve

    fit, mcmc = _split_options(options, mcmc, kwargs)
    check_fit_options({key: getattr(mcmc, key) for key in MCMC_RANGES}, ranges=MCMC_RANGES)
    if isinstance(result_or_model, FitResult):  # no fit here to check the fit options
        check_fit_options(fit.fit_kwargs())
    table, _path = load(table)
    compilation_cache.ensure()
    callback, bar = resolve(progress, desc="posterior")
    try:
        with jax.enable_x64(True):
            return _sample(table, result_or_model, fit, mcmc, callback)
    finally:
        if bar is not None:
            bar.close()


def _sample(table, result_or_model, fit: FitOptions, mcmc: McmcOptions, progress):
    samples = table.to_samples()
    weighting = fit.weighting
    if weighting is None:
        weighting = _weighting_of(result_or_model)
    noise = mcmc.noise
    if noise is None and getattr(samples, "sigma", None) is not None:
        noise = "measured"
    if noise == "measured" and getattr(samples, "sigma", None) is None:
        raise ConfigError(
            "noise='measured' needs measurement uncertainties: a sample list with a sigma "
            "column (or sigma_r, sigma_g, sigma_b); use noise='fixed' or 'sampled' otherwise"
        )
    loss, cutoff, bounds = fit.loss, fit.cutoff, fit.bounds or None
    if cutoff is None:  # the fit's own cells: its recorded cutoff, else the default
        cutoff = _cutoff_of(result_or_model)
    subsample, seed = mcmc.subsample, mcmc.seed
    fit_kwargs = {"cutoff": cutoff, "subsample": subsample, "seed": seed, "bounds": bounds,
                  "fixed": fit.fixed or None, "init": fit.init or None, "weighting": weighting}
    result, t_fit = _least_squares(table, result_or_model, loss, fit_kwargs)
    if noise is None:  # the posterior's covariance near the mode is the fit's estimator
        noise = "fixed" if result.covariance == "gn" else "sandwich"
    post, sel, center, scale, noise_info = _posterior(
        result, samples, loss=loss, cutoff=cutoff, subsample=subsample, seed=seed,
        bounds=bounds, noise=noise, prior=mcmc.prior, weighting=weighting,
    )
    nwalkers, nsteps, burn, thin = mcmc.nwalkers, mcmc.nsteps, mcmc.burn, mcmc.thin
    _check_run(nwalkers, nsteps, burn, thin, len(center))
    sampler, t_compile, t_sample = _run_emcee(
        post, center, scale, int(nwalkers), int(nsteps), seed,
        default_moves() if mcmc.moves is None else mcmc.moves, progress)
    run = {"nwalkers": int(nwalkers), "nsteps": int(nsteps), "burn": int(burn), "thin": int(thin),
           "seed": int(seed), "loss": loss, "cutoff": cutoff, "subsample": repr(subsample),
           "weighting": weighting, "fit_n_cells": (result_or_model.n_cells if isinstance(
               result_or_model, FitResult) else result.n_cells)}
    out = _assemble(result, post, sel, sampler, noise_info,
                    run, {"fit": t_fit, "compile": t_compile, "sample": t_sample})
    if mcmc.chain_path is not None:
        out.save_chain(mcmc.chain_path)
    return out
