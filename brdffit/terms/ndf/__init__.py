"""Normal distribution functions: one module per family, each giving ``D`` and ``Lambda``."""

from .abc import ABC
from .base import ALPHA_MIN, NDF, clamp_alpha
from .beckmann import Beckmann, beckmann_lambda_exact, beckmann_lambda_rational
from .blinn_phong import BlinnPhong, beckmann_alpha_to_phong, phong_to_beckmann_alpha
from .ggx import GGX
from .gtr import GTR, gtr_log_normalization
from .sgd import SGD, bagher_g1
from .student_t import StudentT
from .numerical import (
    ProjectedAreaTable,
    isotropic,
    numerical_lambda,
    projected_area,
    projected_area_normal,
)

__all__ = [
    "ABC",
    "ALPHA_MIN",
    "GGX",
    "GTR",
    "NDF",
    "SGD",
    "StudentT",
    "Beckmann",
    "BlinnPhong",
    "ProjectedAreaTable",
    "bagher_g1",
    "beckmann_alpha_to_phong",
    "beckmann_lambda_exact",
    "beckmann_lambda_rational",
    "clamp_alpha",
    "gtr_log_normalization",
    "isotropic",
    "numerical_lambda",
    "phong_to_beckmann_alpha",
    "projected_area",
    "projected_area_normal",
]
