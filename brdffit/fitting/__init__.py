"""Fitting BRDF models to measured tables: ``fit(table, model) -> FitResult``.

The public surface is ``__all__`` below, and only that: code elsewhere in ``brdffit`` (the
posterior, the API, the command line, batch runs, exports) imports these names from
``brdffit.fitting`` itself, never a module of the package and never an underscore name. The
tests and the benchmarks, which examine the engine's parts, may import its modules, but no
underscore name either. ``tests/test_fitting_surface.py`` checks both rules. What is not
listed may change without notice.

* the fit: :func:`fit`, its options (:data:`FIT_DEFAULTS`, :func:`fit_options`,
  :class:`Settings`, :func:`tolerances`, :func:`default_precision`, :data:`WEIGHTINGS`) and its result
  (:class:`FitResult`, :class:`FittedModel`, :func:`json_safe`, :func:`value_with_error`,
  its report :func:`fit_report`, the one line that says a fitted material is implausible
  (:func:`plausibility_warning`, :mod:`brdffit.fitting.plausibility`),
  the statuses that say the data cannot give a fit (:data:`DATA_VERDICTS`), and the errors
  of reading one back, :class:`ResultFormatError`, :class:`ResultChoiceError`);
* the registries: losses (:data:`LOSSES`, :data:`DEFAULT_LOSS`, :func:`get_loss`,
  :class:`Loss`) and solvers (:data:`SOLVERS`, :data:`DEFAULT_SOLVER`);
* the pieces another estimator of the same problem needs (the posterior sampler): the cells
  (:func:`select`, :class:`Selection`, :class:`FitData`, :class:`Subsample`,
  :func:`check_enough`), the free scalars (:class:`Scalars`, :func:`assign`), the problem
  (:class:`Problem`, built by :meth:`Problem.build`), and the data-driven features of a start
  (:func:`measure`, :class:`Features`).
"""

from .data import WEIGHTINGS, FitData, Selection, Subsample, check_enough, select
from .fitter import fit
from .losses import DEFAULT_LOSS, LOSSES, Loss, get_loss
from .outcome import DATA_VERDICTS
from .options import FIT_DEFAULTS, Settings, default_precision, fit_options, tolerances
from .parameters import Scalars, assign
from .plausibility import warning_text as plausibility_warning
from .problem import Problem
from .report import fit_report, value_with_error
from .result import FitResult, FittedModel, json_safe
from .result_json import ResultChoiceError, ResultFormatError
from .solvers import DEFAULT_SOLVER, SOLVERS
from .start import Features, measure

__all__ = [
    "DATA_VERDICTS",
    "DEFAULT_LOSS",
    "DEFAULT_SOLVER",
    "FIT_DEFAULTS",
    "LOSSES",
    "SOLVERS",
    "WEIGHTINGS",
    "Features",
    "FitData",
    "FitResult",
    "FittedModel",
    "Loss",
    "Problem",
    "ResultChoiceError",
    "ResultFormatError",
    "Scalars",
    "Selection",
    "Settings",
    "Subsample",
    "assign",
    "check_enough",
    "default_precision",
    "fit",
    "fit_options",
    "fit_report",
    "get_loss",
    "json_safe",
    "plausibility_warning",
    "measure",
    "select",
    "tolerances",
    "value_with_error",
]
