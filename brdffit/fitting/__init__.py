"""Fitting BRDF models to measured tables: ``fit(table, model) -> FitResult``.

Public surface: :func:`fit`, :class:`FitResult`, the loss registry (:data:`LOSSES`,
:func:`get_loss`, :class:`Loss`), the solver registry (:data:`SOLVERS`), :class:`Subsample`.
"""

from .data import Subsample
from .losses import DEFAULT_LOSS, LOSSES, Loss, get_loss
from .result import FitResult, FittedModel
from .fitter import fit
from .solvers import DEFAULT_SOLVER, SOLVERS

__all__ = [
    "DEFAULT_LOSS",
    "DEFAULT_SOLVER",
    "LOSSES",
    "SOLVERS",
    "FitResult",
    "FittedModel",
    "Loss",
    "Subsample",
    "fit",
    "get_loss",
]
