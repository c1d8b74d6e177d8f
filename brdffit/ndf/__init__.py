"""Normal distribution functions: one module per family, each giving ``D`` and ``Lambda``."""

from .base import ALPHA_MIN, NDF, clamp_alpha
from .ggx import GGX

__all__ = ["ALPHA_MIN", "NDF", "clamp_alpha", "GGX"]
