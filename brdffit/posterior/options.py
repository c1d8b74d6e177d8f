"""The sampler's options (:class:`McmcOptions`, one field each), in a module free of heavy imports.

Each field's :class:`~brdffit.config.Option` (``metadata["option"]``) holds its default, range
and ``brdffit fit --mcmc`` flag, as the fit's :class:`~brdffit.config.FitOptions` fields do: the
command line's flags, the range checks of both the flags (:data:`FLAG_RANGES`) and
:func:`~brdffit.posterior.sample_posterior`'s options (:data:`RANGES`), and the flags its advice
names come from there. A field without a flag is set from Python only (``seed`` is the fit's).
The chain holds ``walkers * steps * parameters`` doubles: 10^4 x 10^5 x 10 would be 80 GB, so
the command line also bounds the product (:data:`MAX_CHAIN_VALUES`).
"""

from __future__ import annotations

import dataclasses

from ..config import Option
from .defaults import DEFAULT_BURN, DEFAULT_STEPS, DEFAULT_SUBSAMPLE_CELLS, DEFAULT_WALKERS

#: The most values (``walkers * steps * parameters``) a command-line chain may hold.
MAX_CHAIN_VALUES = 10**8


def _option(default=None, **spec):
    return dataclasses.field(default=default, metadata={"option": Option(default=default, **spec)})


def _default_subsample():
    from ..fitting import Subsample  # imports JAX: only when an McmcOptions is made

    return Subsample(DEFAULT_SUBSAMPLE_CELLS, "stratified")


@dataclasses.dataclass(frozen=True)
class McmcOptions:
    """The sampler's options of :func:`~brdffit.posterior.sample_posterior` (each described
    there), with their defaults. ``seed`` and ``subsample`` also choose the cells of a fit made
    from a model name, so that the walkers start at the mode of the likelihood they sample."""

    nwalkers: int = _option(
        DEFAULT_WALKERS, kind=int, low=2, high=10_000, want="an even integer in [2, 10000]",
        flag="--walkers", metavar="N",
        help=f"emcee walkers (default {DEFAULT_WALKERS}; even, >= 2 x free parameters)")
    nsteps: int = _option(
        DEFAULT_STEPS, kind=int, low=1, high=1_000_000, want="an integer in [1, 1000000]",
        flag="--steps", metavar="N", help=f"steps per walker (default {DEFAULT_STEPS})")
    burn: int = _option(
        DEFAULT_BURN, kind=int, low=0, high=1_000_000, want="an integer in [0, 1000000]",
        flag="--burn", metavar="N",
        help=f"burn-in steps dropped (default {DEFAULT_BURN}, or steps/5 if smaller)")
    thin: int = _option(1)
    seed: int = _option(0)
    noise: object = _option(
        kind=str, choices=("sandwich", "fixed", "sampled", "measured"), flag="--noise",
        help="noise model: sandwich (scale learned from the residuals, curvature calibrated "
        "to the fit's sandwich covariance), fixed at the least-squares estimate, sampled, or "
        "measured (the sample list's sigma columns); default measured when the input has "
        "sigma columns, else sandwich (fixed for --covariance gn)")
    subsample: object = dataclasses.field(
        default_factory=_default_subsample, metadata={"option": Option(
            default=DEFAULT_SUBSAMPLE_CELLS, kind=int, low=1, high=2**24,
            want="an integer in [1, 16777216]", flag="--mcmc-subsample", metavar="N",
            help=f"cells the likelihood uses (default {DEFAULT_SUBSAMPLE_CELLS}, stratified "
            f"in θh)")})
    prior: object = _option()
    chain_path: object = _option()
    moves: object = _option()


#: Every sampler option, name -> :class:`~brdffit.config.Option`, in field order.
MCMC_OPTIONS = {f.name: f.metadata["option"] for f in dataclasses.fields(McmcOptions)}
#: The options with a ``brdffit fit`` flag: the flag's argparse name -> the option's name.
FLAG_KEYS = {o.flag[2:].replace("-", "_"): key for key, o in MCMC_OPTIONS.items() if o.flag}
#: The ranges of the sampler's numeric options, keyed by option name, for
#: :func:`brdffit.config.check_fit_options` (``sample_posterior`` checks its options with them).
RANGES = {key: (o.kind is int, o.low, o.high, o.low_in, o.want)
          for key, o in MCMC_OPTIONS.items() if o.high is not None}
#: The same ranges keyed by the flags' argparse names (``brdffit fit --walkers`` ...).
FLAG_RANGES = {dest: RANGES[key] for dest, key in FLAG_KEYS.items() if key in RANGES}
