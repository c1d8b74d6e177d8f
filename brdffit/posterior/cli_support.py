"""What ``brdffit fit FILE --model NAME --mcmc`` needs from the posterior package.

The command calls :func:`add_arguments` when it builds its parser, :func:`output_paths` before
any work (so existing outputs are refused up front, as for every other output), and
:func:`run_mcmc` after the least-squares fit. Output names:

* the chain: ``--chain PATH``, else next to ``--out``: ``RESULT.json`` → ``RESULT-chain.npz``;
* the corner plot: next to ``--plot``: ``FIG.png`` → ``FIG-corner.png``.

Files are written atomically by the caller's ``atomic_write``. The likelihood uses its own
cells (``--mcmc-subsample``, default 2000 stratified in θh), not the fit's ``--subsample``; it
shares the fit's loss, cutoff, bounds, fixed values, covariance estimator and seed. The fit is
refitted on those cells from its optimum, so the least-squares values and errors printed beside
the posterior are of the same cells, and the summary says how many of the fit's cells it used
and what its intervals cover.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from ..errors import ConfigError
from .defaults import DEFAULT_BURN
from .options import FLAG_KEYS, MCMC_OPTIONS

#: The flags that only apply with ``--mcmc`` (argparse names).
_ONLY_WITH_MCMC = (*FLAG_KEYS, "chain")


def add_arguments(parser) -> None:
    """The ``--mcmc`` flags of ``brdffit fit``: ``--mcmc``, ``--chain`` and one flag per
    :class:`~.options.McmcOptions` field that has one (its metadata's flag, metavar, help)."""
    g = parser.add_argument_group("posterior sampling (emcee)")
    g.add_argument("--mcmc", action="store_true",
                   help="after the fit, sample the posterior of the free parameters with emcee "
                   "(percentiles in the summary and --out, chain next to --out, corner plot "
                   "next to --plot)")
    for dest, key in FLAG_KEYS.items():
        o = MCMC_OPTIONS[key]
        kind = {"type": str.lower, "choices": o.choices} if o.choices else {"type": o.kind}
        g.add_argument(o.flag, dest=dest, metavar=o.metavar, help=o.help, **kind)
    g.add_argument("--chain", metavar="CHAIN.npz", help="where to write the chain (NPZ)")


def output_paths(args) -> dict:
    """``{"chain": path or None, "corner": path or None}`` for the flags in ``args``."""
    if not getattr(args, "mcmc", False):
        given = [f"--{f.replace('_', '-')}" for f in _ONLY_WITH_MCMC if getattr(args, f, None)]
        if given:
            raise ConfigError(f"{', '.join(given)} only apply to posterior sampling: add --mcmc "
                              f"or drop them")
        return {"chain": None, "corner": None}
    chain = args.chain
    if chain is None and args.out:
        out = Path(args.out)
        chain = str(out.with_name(f"{out.stem}-chain.npz"))
    corner = None
    if args.plot:
        p = Path(args.plot)
        corner = str(p.with_name(f"{p.stem}-corner{p.suffix or '.png'}"))
    return {"chain": chain, "corner": corner}


def _mcmc_options(args, options) -> dict:
    """The keywords of :class:`~.options.McmcOptions` the flags set."""
    kw = {"seed": options.seed or 0}
    for dest, key in FLAG_KEYS.items():
        if getattr(args, dest, None) is not None:
            kw[key] = getattr(args, dest)
    if "nsteps" in kw and "burn" not in kw:
        kw["burn"] = min(DEFAULT_BURN, kw["nsteps"] // 5)
    return kw


def run_mcmc(data, fit_result, args, options, write) -> tuple:
    """Sample the posterior around ``fit_result``; returns ``(PosteriorResult, files, warnings)``.

    ``write(path, fn)`` writes one output atomically (``fn(tmp_path)`` fills it); ``files``
    lists the paths written; ``warnings`` the diagnostics' messages (also in the summary).
    """
    from .diagnostics import ChainTooShortWarning
    from ..config import FitOptions
    from .options import McmcOptions
    from .sampler import sample_posterior

    paths = output_paths(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ChainTooShortWarning)
        fit = FitOptions(cutoff=options.cutoff, bounds=options.bounds)
        post = sample_posterior(data, fit_result, fit, McmcOptions(**_mcmc_options(args, options)))
    messages = [str(w.message) for w in caught if issubclass(w.category, ChainTooShortWarning)]
    files = []
    if paths["chain"]:
        write(paths["chain"], post.save_chain)
        files.append(paths["chain"])
    if paths["corner"]:
        write(paths["corner"], lambda tmp: post.corner_plot(tmp))
        files.append(paths["corner"])
    return post, files, messages


def combined_json(fit_result, post) -> str:
    """The fit's JSON with the posterior under ``"posterior"`` (strict JSON)."""
    import json

    from ..fitting import json_safe

    d = json.loads(fit_result.to_json())
    d["posterior"] = post.to_dict()
    return json.dumps(json_safe(d), indent=2)
