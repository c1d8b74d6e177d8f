"""The solver registry: optimistix's Gauss–Newton family by name.

All three see the Gauss–Newton normal form of the residual (:mod:`brdffit.fit.normal_form`),
with exact first derivatives from JAX.

* ``lm`` (default): :class:`optimistix.LevenbergMarquardt`, damped steps with a classical
  trust-region update; robust from poor starting points.
* ``gauss-newton``: :class:`optimistix.GaussNewton`, full undamped steps; fast near the optimum,
  may diverge far from it.
* ``dogleg``: :class:`optimistix.Dogleg`, a trust region along the dogleg path.

One part is swapped in the two trust-region solvers (optimistix solvers are built from parts):
:class:`NoiseTolerantTrustRegion` accepts a step whose actual change of the cost is within
rounding noise of zero. Optimistix's ``ClassicalTrustRegion`` rejects such steps (their
predicted reduction is ~1e-20 while the cost, a sum over millions of cells, carries rounding
noise of ~1e-15 relative), and a rejected step never triggers the convergence test: at an
optimum that is already reached, the solver would keep evaluating the full table, shrinking
the step, for several more iterations.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import optimistix as optx

from ..errors import UnknownNameError

SOLVERS = {
    "lm": optx.LevenbergMarquardt,
    "gauss-newton": optx.GaussNewton,
    "dogleg": optx.Dogleg,
}

DEFAULT_SOLVER = "lm"

#: Relative change of the cost treated as rounding noise, by compute dtype.
COST_NOISE = {"float64": 1e-12, "float32": 1e-6}


class NoiseTolerantTrustRegion(optx.ClassicalTrustRegion):
    """``ClassicalTrustRegion`` that also accepts steps changing the cost by less than
    ``noise × cost`` (see the module docstring); otherwise identical."""

    noise: float = 1e-12

    def step(self, first_step, y, y_eval, f_info, f_eval_info, state):
        step_size, accept, result, new_state = super().step(
            first_step, y, y_eval, f_info, f_eval_info, state
        )
        f_min = f_info.as_min()
        flat = jnp.abs(f_eval_info.as_min() - f_min) <= self.noise * jnp.abs(f_min)
        rescued = flat & ~accept
        step_size = jnp.where(rescued, state.step_size, step_size)
        return step_size, accept | flat, result, eqx.tree_at(lambda s: s.step_size, new_state, step_size)


def _quiet(**kwargs):
    del kwargs


def make_solver(name, rtol: float, atol: float, verbose=None, noise: float = 1e-12):
    """An optimistix solver from a registry name (or pass an optimistix solver through)."""
    if isinstance(name, optx.AbstractLeastSquaresSolver):
        return name
    try:
        cls = SOLVERS[name]
    except (KeyError, TypeError):
        raise UnknownNameError("solver", str(name), SOLVERS) from None
    solver = cls(rtol=rtol, atol=atol, verbose=verbose or _quiet)
    if isinstance(getattr(solver, "search", None), optx.ClassicalTrustRegion):
        solver = eqx.tree_at(lambda s: s.search, solver, NoiseTolerantTrustRegion(noise=noise))
    return solver


def solver_label(solver) -> str:
    if isinstance(solver, str):
        return solver
    return type(solver).__name__
