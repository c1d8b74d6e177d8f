"""brdffit: differentiable BRDF fitting for measured reflectance data.

Layers (imports only go downward and never in a circle, checked by ``tests/test_layers.py``):
:mod:`data_formats` (file formats, NumPy only) → :mod:`brdffit.terms` (the physics pieces, pure
``jnp``: NDFs, masking, Fresnel, diffuse, the microfacet lobe, energy terms, the APS generator)
→ :mod:`brdffit.models` (registered models and their registry) → :mod:`brdffit.fitting` (least
squares; its result is data) → :mod:`brdffit.export`, :mod:`brdffit.plots` →
:mod:`brdffit.posterior` (emcee), :mod:`brdffit.batch`, :mod:`brdffit.api` (the result type
with its ``plot``/``export`` methods) → :mod:`brdffit.cli`.

The names below load their modules on first use (PEP 562), so ``import brdffit`` and
``brdffit --help`` do not pay for importing JAX. The library never changes ``jax.config``'s
numerics: :func:`brdffit.fit` and :func:`brdffit.sample_posterior` run inside
``jax.enable_x64(True)`` (float64 for the duration of the call, the global setting untouched),
and the low-level :func:`brdffit.fitting.fit` uses whatever the caller set. The one setting
they make, at their first call and never at import, is JAX's persistent compilation cache
folder (:mod:`brdffit.compilation_cache`: a per-user folder, an opt-out, left alone when the
user chose one).
"""

from __future__ import annotations

from ._lazy import lazy_exports
from .errors import BrdffitError, ConfigError, FitError, UnknownNameError

__version__ = "0.1.0"

#: Public name → the module that defines it (imported lazily by ``__getattr__``).
_LAZY = {
    "Model": ".models",
    "Param": ".models",
    "available_models": ".models",
    "get_model": ".models",
    "register": ".models",
    "FitResult": ".api",
    "fit": ".api",
    "fit_report": ".fitting",
    "get_loss": ".fitting",
    "fit_many": ".batch",
    "compare": ".leaderboard",
    "Leaderboard": ".leaderboard",
    "load_published": ".published",
    "PosteriorResult": ".posterior",
    "sample_posterior": ".posterior",
}

__all__ = ["BrdffitError", "ConfigError", "FitError", "UnknownNameError", *_LAZY]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
