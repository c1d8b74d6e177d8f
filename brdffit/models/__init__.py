"""Registered BRDF models and the registry of named models.

Importing this package registers the built-in models. A new model: write ``fn(params, wi, wo)``
from the pieces in :mod:`brdffit.terms` (NDFs, masking, Fresnel, diffuse and energy terms, the
microfacet lobe, the APS generator), declare its :class:`Param` list, and :func:`register` it in
a module imported here. Models import terms; terms never import models.
"""

from . import standard  # noqa: F401  (registers ggx, ggx-aniso, two-lobe-ggx, ...)
from . import disney  # noqa: F401
from . import aps  # noqa: F401  (registers aps-gaussian, aps-velvet, aps-satin, aps-vgroove)
from . import cloth, energy  # noqa: F401  (registers cloth-velvet, cloth-sheen, ggx-ms, ggx-coupled)
from . import fitted_distributions  # noqa: F401  (registers low-smooth, low-microfacet, sgd, student-t)
from . import gltf_pbr, mitsuba_principled, mitsuba_roughconductor  # noqa: F401  (renderer-native models)
from . import classic  # noqa: F401  (Ngan 2005, Löw 2012: Cook–Torrance, Ashikhmin–Shirley, Ward, Lafortune, ...)
from .published import PublishedForm, published_forms, published_params, register_published
from .registry import Model, Param, PerPass, Reading, available_models, get_model, register

__all__ = ["Model", "Param", "PerPass", "PublishedForm", "Reading", "available_models", "get_model",
           "published_forms", "published_params", "register", "register_published"]
