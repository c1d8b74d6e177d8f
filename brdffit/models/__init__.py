"""Composite BRDF models and the registry of named models.

Importing this package registers the built-in models. A new model: write ``fn(params, wi, wo)``
from the pieces in :mod:`brdffit.ndf`, :mod:`brdffit.masking`, :mod:`brdffit.fresnel` and
:mod:`brdffit.diffuse`, declare its :class:`Param` list, and :func:`register` it in a module
imported here.
"""

from . import standard  # noqa: F401  (registers ggx, ggx-aniso, two-lobe-ggx, ...)
from . import disney  # noqa: F401
from ..aps import models as _aps_models  # noqa: F401  (registers aps-gaussian, aps-velvet, aps-satin, aps-vgroove)
from . import cloth, energy  # noqa: F401  (registers cloth-velvet, cloth-sheen, ggx-ms, ggx-coupled)
from . import gltf_pbr, mitsuba_principled, mitsuba_roughconductor  # noqa: F401  (renderer-native models)
from .microfacet import microfacet_specular
from .registry import Model, Param, available_models, get_model, register

__all__ = ["Model", "Param", "available_models", "get_model", "microfacet_specular", "register"]
