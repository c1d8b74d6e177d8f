"""Posteriors of fitted BRDF parameters with emcee: ``sample_posterior(table, fit_or_model)``.

Public surface: :func:`sample_posterior`, :class:`PosteriorResult`, the prior objects
(:class:`Uniform`, :class:`LogUniform`, :class:`Normal`), :class:`Diagnostics` and
:class:`ChainTooShortWarning`. The likelihood and its noise model are documented in
:mod:`brdffit.posterior.likelihood`.
"""

from .diagnostics import ChainTooShortWarning, Diagnostics
from .priors import LogUniform, Normal, Uniform
from .result import PosteriorResult
from .sampler import (
    DEFAULT_BURN,
    DEFAULT_STEPS,
    DEFAULT_SUBSAMPLE,
    DEFAULT_WALKERS,
    sample_posterior,
)

__all__ = [
    "DEFAULT_BURN",
    "DEFAULT_STEPS",
    "DEFAULT_SUBSAMPLE",
    "DEFAULT_WALKERS",
    "ChainTooShortWarning",
    "Diagnostics",
    "LogUniform",
    "Normal",
    "PosteriorResult",
    "Uniform",
    "sample_posterior",
]
