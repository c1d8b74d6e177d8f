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
  :class:`Loss`) and solvers (:data:`SOLVERS`, :data:`DEFAULT_SOLVER`, :func:`get_solver`);
* the pieces another estimator of the same problem needs (the posterior sampler): the cells
  (:func:`select`, :class:`Selection`, :class:`FitData`, :class:`Subsample`,
  :func:`check_enough`), the free scalars (:class:`Scalars`, :func:`assign`), the problem
  (:class:`Problem`, built by :meth:`Problem.build`), and the data-driven features of a start
  (:func:`measure`, :class:`Features`).
"""

from .._lazy import lazy_exports

#: The public names, each imported from its module on first use (PEP 562), so that importing a
#: module of the package (the JAX-free registries :mod:`.losses` and :mod:`.solvers`, which the
#: command line's help reads) does not import the whole engine and JAX with it.
_LAZY = {
    "WEIGHTINGS": ".data", "FitData": ".data", "Selection": ".data", "Subsample": ".data",
    "check_enough": ".data", "select": ".data",
    "fit": ".fitter",
    "DEFAULT_LOSS": ".losses", "LOSSES": ".losses", "Loss": ".losses", "get_loss": ".losses",
    "DATA_VERDICTS": ".outcome",
    "FIT_DEFAULTS": ".options", "Settings": ".options", "default_precision": ".options",
    "fit_options": ".options", "tolerances": ".options",
    "Scalars": ".parameters", "assign": ".parameters",
    "plausibility_warning": ".plausibility:warning_text",
    "Problem": ".problem",
    "fit_report": ".report", "value_with_error": ".report",
    "FitResult": ".result", "FittedModel": ".result", "json_safe": ".result",
    "ResultChoiceError": ".result_json", "ResultFormatError": ".result_json",
    "DEFAULT_SOLVER": ".solvers", "SOLVERS": ".solvers", "get_solver": ".solvers",
    "Features": ".start", "measure": ".start",
}

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
    "get_solver",
    "json_safe",
    "plausibility_warning",
    "measure",
    "select",
    "tolerances",
    "value_with_error",
]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
