"""brdffit: differentiable BRDF fitting for measured reflectance data.

Layers (imports only go downward): :mod:`data_formats` (file formats, NumPy only) →
:mod:`brdffit._math`, :mod:`brdffit.ndf`, :mod:`brdffit.masking`, :mod:`brdffit.fresnel`,
:mod:`brdffit.diffuse` (pure ``jnp`` pieces) → :mod:`brdffit.models` (composed models and their
registry) → fitting and posteriors → :mod:`brdffit.cli`.

The library never changes ``jax.config``; call ``jax.config.update("jax_enable_x64", True)``
yourself for float64 (the CLI and the tests do).
"""

from .errors import BrdffitError, ConfigError, FitError, UnknownNameError
from .models import Model, Param, available_models, get_model, register
from .fit import FitResult, fit, get_loss
from .posterior import PosteriorResult, sample_posterior

__version__ = "0.1.0"

__all__ = [
    "BrdffitError",
    "ConfigError",
    "FitError",
    "FitResult",
    "PosteriorResult",
    "Model",
    "Param",
    "UnknownNameError",
    "available_models",
    "fit",
    "get_loss",
    "get_model",
    "register",
    "sample_posterior",
]
