"""From a :class:`~brdffit.fitting.FitResult` back to the fit's loss and problem.

A ``FitResult`` records the loss as a label (``"log"``, ``"log+huber(0.1)"``), the free and
fixed scalars by flat name and the optimum ``x``; it does not record ``bounds``, ``cutoff`` or
``subsample``, so those are passed again by the caller (the CLI passes the same options).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..fitting import Problem, Scalars, default_precision, get_loss


def loss_of(result, loss=None):
    """The :class:`~brdffit.fitting.Loss` of ``result`` (or ``loss`` when given)."""
    return get_loss(result.loss if loss is None else loss)


def problem_from(result, model, loss, bounds=None, chunks: int = 1):
    """``(problem, lo, hi)``: the fit's :class:`Problem` at its optimum and the flat bounds.

    ``chunks`` is the selection's block count (only the fit's Jacobian uses it). Raises
    :class:`ConfigError` when ``result`` was fitted with another model.
    """
    if result.model_name != model.name or list(result.names) != model.flat_names():
        raise ConfigError(
            f"the fit result is for model {result.model_name!r} but the posterior was asked for "
            f"{model.name!r}; pass the matching model (or the result alone)"
        )
    names = model.flat_names()
    scalars = Scalars.of(model, [names.index(n) for n in result.free], bounds)
    lo, hi = scalars.lo, scalars.hi
    x = np.asarray(result.x, float)
    outside = [names[i] for i in scalars.free if not lo[i] <= x[i] <= hi[i]]
    if outside:
        raise ConfigError(
            f"the least-squares optimum has {outside} outside the bounds given here; pass the "
            f"same `bounds` as the fit"
        )
    return Problem.build(scalars, loss, x, default_precision(), chunks), lo, hi
