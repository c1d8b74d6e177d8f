"""The solver registry: optimistix's Gauss–Newton family by name.

All three see the Gauss–Newton normal form of the residual (:mod:`brdffit.fit.normal_form`),
with exact first derivatives from JAX.

* ``lm`` (default): :class:`optimistix.LevenbergMarquardt`, damped steps with a classical
  trust-region update; robust from poor starting points.
* ``gauss-newton``: :class:`optimistix.GaussNewton`, full undamped steps; fast near the optimum,
  may diverge far from it.
* ``dogleg``: :class:`optimistix.Dogleg`, a trust region along the dogleg path.
"""

from __future__ import annotations

import optimistix as optx

from ..errors import UnknownNameError

SOLVERS = {
    "lm": optx.LevenbergMarquardt,
    "gauss-newton": optx.GaussNewton,
    "dogleg": optx.Dogleg,
}

DEFAULT_SOLVER = "lm"


def make_solver(name, rtol: float, atol: float, verbose=False):
    """An optimistix solver from a registry name (or pass an optimistix solver through)."""
    if isinstance(name, optx.AbstractLeastSquaresSolver):
        return name
    try:
        cls = SOLVERS[name]
    except (KeyError, TypeError):
        raise UnknownNameError("solver", str(name), SOLVERS) from None
    return cls(rtol=rtol, atol=atol, verbose=verbose)


def solver_label(solver) -> str:
    if isinstance(solver, str):
        return solver
    return type(solver).__name__
