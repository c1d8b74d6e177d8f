"""Posteriors of fitted BRDF parameters with emcee: ``sample_posterior(table, fit_or_model)``.

Public surface: :func:`sample_posterior` and its :class:`McmcOptions`, :class:`PosteriorResult`,
the prior objects (:class:`Uniform`, :class:`LogUniform`, :class:`Normal`), :class:`Diagnostics`
and :class:`ChainTooShortWarning`. The likelihood and its noise model are documented in
:mod:`brdffit.posterior.likelihood`. Names load their modules on first use (PEP 562), so the
command line's ``--help`` does not import emcee and JAX.
"""

from __future__ import annotations

from .._lazy import lazy_exports
from .defaults import DEFAULT_BURN, DEFAULT_STEPS, DEFAULT_WALKERS

_LAZY = {
    "DEFAULT_SUBSAMPLE": ".sampler",
    "sample_posterior": ".sampler",
    "McmcOptions": ".options",
    "ChainTooShortWarning": ".diagnostics",
    "Diagnostics": ".diagnostics",
    "LogUniform": ".priors",
    "Normal": ".priors",
    "Uniform": ".priors",
    "PosteriorResult": ".result",
}

__all__ = ["DEFAULT_BURN", "DEFAULT_STEPS", "DEFAULT_WALKERS", *_LAZY]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
