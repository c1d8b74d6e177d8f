"""The Ashikhmin–Premože–Shirley (SIGGRAPH 2000) microfacet BRDF generator.

A BRDF from *any* microfacet distribution ``p(h)``: :mod:`.distributions` (the ``p(h)``),
:mod:`.quadrature` (rules on the sphere), :mod:`.tables` (``g(k)``, ``⟨⟨hn⟩⟩``, eqs. 18, 22, 25),
:mod:`.specular` (eqs. 26 and 14), :mod:`.diffuse` (eqs. 28–30), :mod:`.brdf` (the whole BRDF,
:func:`aps_brdf`, in three stages). The paper's distributions as registered models are in
:mod:`brdffit.models.aps`.
"""

from .brdf import aps_brdf
from .diffuse import RTable, aps_diffuse, aps_diffuse_metal, build_r_table
from .distributions import (
    AnisotropicGaussian,
    Distribution,
    FunctionDistribution,
    Mixture,
    NDFDistribution,
    TabulatedDistribution,
    TiltedGaussian,
    Velvet,
    satin,
    v_groove,
)
from .specular import CORRELATED, UNCORRELATED, Correlated, Uncorrelated, aps_specular
from .tables import COARSE, GTable, Resolution, build_g_table

__all__ = [
    "COARSE",
    "CORRELATED",
    "UNCORRELATED",
    "AnisotropicGaussian",
    "Correlated",
    "Distribution",
    "FunctionDistribution",
    "GTable",
    "Mixture",
    "NDFDistribution",
    "RTable",
    "Resolution",
    "TabulatedDistribution",
    "TiltedGaussian",
    "Uncorrelated",
    "Velvet",
    "aps_brdf",
    "aps_diffuse",
    "aps_diffuse_metal",
    "aps_specular",
    "build_g_table",
    "build_r_table",
    "satin",
    "v_groove",
]
