"""Fitting BRDF models to measured tables: ``fit(table, model) -> FitResult``.

Public surface: :func:`fit`, :class:`FitResult`, the loss registry (:data:`LOSSES`,
:func:`get_loss`, :class:`Loss`), the solver registry (:data:`SOLVERS`), :class:`Subsample`.
"""

import functools

from ..config import check_fit_options
from .data import Subsample
from .losses import DEFAULT_LOSS, LOSSES, Loss, get_loss
from .result import FitResult, FittedModel
from .solve import fit as _fit_unchecked
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


@functools.wraps(_fit_unchecked)
def fit(table, model, **options):
    # Numeric options are range-checked before any work (brdffit.config.check_fit_options);
    # the check belongs at the top of solve.fit, and moves there once solve.py is rewritten.
    check_fit_options(options)
    return _fit_unchecked(table, model, **options)
