"""The solver registry: optimistix's Gauss–Newton family by name.

All three see the Gauss–Newton normal form of the residual (:mod:`brdffit.fitting.normal_form`),
with exact first derivatives from JAX.

* ``lm`` (default): :class:`optimistix.LevenbergMarquardt` with the parts below: damped steps
  with a classical trust-region update; robust from poor starting points.
* ``gauss-newton``: :class:`optimistix.GaussNewton`, full undamped steps; fast near the optimum,
  may diverge far from it.
* ``dogleg``: :class:`optimistix.Dogleg`, a trust region along the dogleg path.

Parts swapped in (optimistix solvers are built from parts):

* ``lm`` uses :class:`ScaledDampedNewtonDescent`: Marquardt's scaled damping
  ``(JᵀJ + λ diag(JᵀJ)) δ = -Jᵀr`` (Marquardt 1963; MINPACK's ``lmder``) instead of optimistix's
  ``(JᵀJ + λI)``. Bounded parameters live in the logistic coordinate ``u``, where a parameter
  pushed near a bound during the first steps has a tiny column ``∂r/∂u ∝ x - lo``; with ``λI``
  the damping then freezes it there (observed: a polished-metal fit started at ``α = 0.3``
  stalled with two diffuse channels at 1e-6), while the scaled damping is invariant to the
  column scale and lets it come back. The step is also shortened (direction kept) so that no
  coordinate moves by more than ``MAX_STEP_U = 4`` (a factor ``e⁴`` in ``x - lo`` near a bound):
  a linearisation that predicts a negative albedo would otherwise send the albedo to 1e-22 in
  one step, where its derivative is too small for any later step to bring it back. A
  coordinate beyond ``|u| = U_ACTIVE`` is not pushed further out (an active set): a parameter
  whose optimum lies beyond its bound stops there instead of drifting a little every step. (A
  parameter can still be trapped at a bound by a transient; :func:`brdffit.fitting.solve.fit`
  restarts once from the optimum with such parameters moved back inside, and keeps the better.
  Known limitation: on a dark material (albedo 0.005) with noise and only 5,000 cells, a
  transient from the default start can still leave one albedo at its bound, at a cost ~10%
  above the true optimum; ``multistart`` or an ``init`` near the data's diffuse level avoids it.)
* both trust-region solvers use :class:`NoiseTolerantTrustRegion`, which accepts a step whose
  actual change of the cost is within rounding noise of zero. Optimistix's
  ``ClassicalTrustRegion`` rejects such steps (their predicted reduction is ~1e-20 while the
  cost, a sum over millions of cells, carries rounding noise of ~1e-15 relative), and a
  rejected step never triggers the convergence test: at an optimum that is already reached, the
  solver would keep evaluating the full table, shrinking the step, for several more iterations.
* all three are wrapped in :class:`Lookahead`, which applies optimistix's own Cauchy
  termination test to the step the solver has just *proposed* (``δ`` and its predicted change
  ``J̃δ`` of the residual) instead of waiting for it to be evaluated, and also stops when the
  Gauss–Newton step from the last evaluated point is below 0.01 standard errors (MINUIT's
  "estimated distance to minimum"): the solve ends at the last evaluated point, whose ``JᵀJ``
  and sandwich meat are then exact, and saves the full-table passes that would only confirm
  a step that is negligible against the tolerance or against the parameters' uncertainty
  (issue 4, "Speed").
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..errors import UnknownNameError
from .transforms import U_CLIP

SOLVERS = {
    "lm": optx.LevenbergMarquardt,
    "gauss-newton": optx.GaussNewton,
    "dogleg": optx.Dogleg,
}

DEFAULT_SOLVER = "lm"

#: Largest change of one unconstrained coordinate in one Levenberg–Marquardt step.
MAX_STEP_U = 4.0
#: Beyond this |u| (``x`` within ``1e-6`` of the range from a bound, the ``at_bound`` test) a
#: parameter counts as at its
#: bound for the step: moves further out are dropped, moves back in are kept.
U_ACTIVE = 14.0

#: First trust-region step size ``1/λ`` of ``lm``: with Marquardt's scaling, ``λ = 1`` would halve
#: the first Gauss–Newton steps; ``λ = 0.01`` starts close to Gauss–Newton and lets rejections
#: (×0.25 each) damp it when needed.
INITIAL_STEP_SIZE = 100.0

#: The statistical convergence test of :class:`Lookahead`: stop when the Gauss–Newton step is
#: below ``√(2·EDM_TOL) = 0.01`` standard errors.
EDM_TOL = 5e-5

#: Relative change of the cost treated as rounding noise, by compute dtype.
COST_NOISE = {"float64": 1e-12, "float32": 1e-6}


class NoiseTolerantTrustRegion(optx.ClassicalTrustRegion):
    """``ClassicalTrustRegion`` that also accepts steps changing the cost by less than
    ``noise × cost`` (see the module docstring); otherwise identical."""

    noise: float = 1e-12
    initial_step_size: jax.Array = 1.0  # an array, so a warm start changes it without a recompile

    def init(self, y, f_info_struct):
        state = super().init(y, f_info_struct)
        first = jnp.asarray(self.initial_step_size, state.step_size.dtype)
        return eqx.tree_at(lambda s: s.step_size, state, first)

    def step(self, first_step, y, y_eval, f_info, f_eval_info, state):
        step_size, accept, result, new_state = super().step(
            first_step, y, y_eval, f_info, f_eval_info, state
        )
        f_min = f_info.as_min()
        flat = jnp.abs(f_eval_info.as_min() - f_min) <= self.noise * jnp.abs(f_min)
        rescued = flat & ~accept
        step_size = jnp.where(rescued, state.step_size, step_size)
        return step_size, accept | flat, result, eqx.tree_at(lambda s: s.step_size, new_state, step_size)


class _ScaledState(eqx.Module):
    y: object
    f_info: object


class ScaledDampedNewtonDescent(optx.DampedNewtonDescent):
    """Levenberg–Marquardt step with Marquardt's diagonal scaling, a step cap and an active set
    at the bounds (module docstring).

    With ``s = 1/λ`` the trust region's step size, solves ``(s JᵀJ + D²) δ = -s Jᵀr`` with
    ``D² = diag(JᵀJ)`` floored at ``1e-30`` of its largest entry (scale-invariant per coordinate
    down to columns ``1e-15`` times the largest; the same system multiplied by
    ``s``, finite as ``s → 0``). Coordinates beyond ``±U_ACTIVE`` that the step would push further
    out are held; then ``δ`` is shortened so that no coordinate moves by more than
    ``MAX_STEP_U``. ``J`` is the solver's small Jacobian (the normal form), materialised.
    """

    def init(self, y, f_info_struct):
        return _ScaledState(y, super().init(y, f_info_struct).f_info)

    def query(self, y, f_info, state):
        del state
        return _ScaledState(y, f_info)

    def step(self, step_size, state):
        jac, res = state.f_info.jac.as_matrix(), state.f_info.residual
        jtj, g = jac.T @ jac, jac.T @ res
        d2 = jnp.diagonal(jtj)
        dinv = 1.0 / jnp.sqrt(jnp.maximum(d2, 1e-30 * jnp.max(d2) + jnp.finfo(d2.dtype).tiny))
        # in the scaled coordinates z = D δ the matrix is s·C + I (C has unit diagonal): SPD
        scaled = step_size * (dinv[:, None] * jtj * dinv[None, :]) + jnp.eye(len(dinv))
        delta = -dinv * jnp.linalg.solve(scaled, step_size * dinv * g)
        y = state.y
        delta = jnp.where(((y < -U_ACTIVE) & (delta < 0)) | ((y > U_ACTIVE) & (delta > 0)), 0.0, delta)
        delta = jnp.where(jnp.isfinite(delta), delta, 0.0)
        delta = delta * jnp.minimum(1.0, MAX_STEP_U / jnp.maximum(jnp.max(jnp.abs(delta)), 1e-300))
        return jnp.clip(delta, -U_CLIP - y, U_CLIP - y), optx.RESULTS.successful


def _cauchy(rtol, atol, norm, y, y_diff, f, f_diff):
    """Optimistix's ``cauchy_termination`` (``optimistix/_misc.py``), restated for arrays."""
    y_ok = norm(jnp.abs(y_diff) / (atol + rtol * jnp.abs(y))) < 1
    return y_ok & (norm(jnp.abs(f_diff) / (atol + rtol * jnp.abs(f))) < 1)


class Lookahead(optx.AbstractLeastSquaresSolver):
    r"""A Gauss–Newton-family solver that also stops when its *next* step is negligible.

    Two tests, applied after each accepted step at the point ``y`` just evaluated; either ends
    the solve at ``y``, whose ``aux`` (``JᵀJ``, meat) then belongs to the answer:

    * **Cauchy** (optimistix's ``cauchy_termination``, which needs ``|Δy| < atol + rtol |y|`` and
      ``|Δf| < atol + rtol |f|`` for an accepted step, so the last full evaluation of a converged
      solve only confirms a step below the tolerance): the same test on the step just proposed,
      ``δ = y_eval - y``, and its linear prediction ``Δf = J̃ δ`` (exact for the Gauss–Newton
      model). The answer differs from the unwrapped solver's by less than the tolerance.
    * **Statistical** (``edm_tol``; needs the normal form's ``aux["m"]``): the undamped
      Gauss–Newton step from ``y`` is shorter than ``√(2 edm_tol)`` standard errors in the
      Mahalanobis norm. With ``r̃ = (R^{-⊤}Jᵀr, c)`` (:mod:`brdffit.fitting.normal_form`) the
      step is ``δ_GN = -(JᵀJ)^+ Jᵀr`` and

      .. math:: \mathrm{EDM} = \frac{\delta_{GN}^\top J^\top J\,\delta_{GN}}{2 s^2}
                = \frac{\|\tilde r_{1..p}\|^2}{2 s^2}, \qquad s^2 = \frac{\|\tilde r\|^2}{m - p},

      the estimated distance to the minimum in units where one standard error costs ``½``
      (MINUIT's EDM: F. James, M. Roos, *Comput. Phys. Commun.* 10 (1975) 343; its ``migrad``
      stops at ``EDM < 2·10⁻⁴``, i.e. 0.02 standard errors). The default ``EDM_TOL = 5·10⁻⁵``
      stops within 0.01 standard errors of the optimum of the local model, independent of the
      damping of the proposed step. For an exact fit (cost at its rounding floor) ``s`` is at
      rounding level and only the Cauchy test can end the solve. On the 1.1 M-cell benchmark
      table (``benchmarks/bench_fit.py``) the second full-table pass has ``EDM ≈ 10⁻⁶``: the
      third pass, which changed the cost by 4·10⁻¹¹ of 79, is saved.

    Everything else (steps, damping, acceptance) is the inner solver's.
    """

    inner: optx.AbstractLeastSquaresSolver
    edm_tol: float = 0.0

    @property
    def rtol(self):
        return self.inner.rtol

    @property
    def atol(self):
        return self.inner.atol

    @property
    def norm(self):
        return self.inner.norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        return self.inner.init(fn, y, args, options, f_struct, aux_struct, tags)

    def step(self, fn, y, args, options, state, tags):
        return self.inner.step(fn, y, args, options, state, tags)

    def terminate(self, fn, y, args, options, state, tags):
        done, result = self.inner.terminate(fn, y, args, options, state, tags)
        # optimistix passes the iterate from *before* the step here; the accepted point is the
        # one the descent was last queried at (only ScaledDampedNewtonDescent records it)
        y = getattr(state.descent_state, "y", None)
        if y is None:
            return done, result
        delta = jax.tree.map(lambda a, b: a - b, state.y_eval, y)
        f = state.f_info.residual
        df = state.f_info.jac.mv(delta)
        small = _cauchy(self.rtol, self.atol, self.norm, y, delta, f, df)
        m = state.aux.get("m") if isinstance(state.aux, dict) else None
        if m is not None and self.edm_tol > 0:
            small = small | (edm(f, m, y.shape[0]) < self.edm_tol)
        fresh = (state.num_steps_since_acceptance == 0) & (state.num_steps > 0)
        ok = result == optx.RESULTS.successful
        return done | (small & fresh & ok), result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return self.inner.postprocess(fn, y, aux, args, options, state, tags, result)


def edm(rt, m, p: int):
    """MINUIT's estimated distance to the minimum from the normal-form residual ``r̃`` (length
    ``p + 1``) and ``m`` weighted residuals: ``‖r̃_{1..p}‖² (m - p) / (2‖r̃‖²)`` (:class:`Lookahead`)."""
    head = jnp.sum(rt[:-1] ** 2)
    total = jnp.maximum(jnp.sum(rt**2), jnp.finfo(rt.dtype).tiny)
    return 0.5 * head * jnp.maximum(m - p, 1.0) / total


def _quiet(**kwargs):
    del kwargs


def make_solver(name, rtol: float, atol: float, verbose=None, noise: float = 1e-12,
                edm_tol: float = EDM_TOL):
    """An optimistix solver from a registry name (or pass an optimistix solver through), wrapped
    in :class:`Lookahead` with the statistical test ``edm_tol`` (0 turns it off)."""
    if isinstance(name, optx.AbstractLeastSquaresSolver):
        return name
    try:
        cls = SOLVERS[name]
    except (KeyError, TypeError):
        raise UnknownNameError("solver", str(name), SOLVERS) from None
    solver = cls(rtol=rtol, atol=atol, verbose=verbose or _quiet)
    first = 1.0
    if isinstance(solver, optx.LevenbergMarquardt):
        solver = eqx.tree_at(lambda s: s.descent, solver, ScaledDampedNewtonDescent())
        first = INITIAL_STEP_SIZE
    if isinstance(getattr(solver, "search", None), optx.ClassicalTrustRegion):
        search = NoiseTolerantTrustRegion(noise=noise, initial_step_size=jnp.asarray(first))
        solver = eqx.tree_at(lambda s: s.search, solver, search)
    return Lookahead(solver, float(edm_tol))


def with_initial_step(solver, step_size):
    """``solver`` with its trust region starting at ``step_size`` (unchanged if it has none)."""
    search = getattr(getattr(solver, "inner", None), "search", None)
    if not isinstance(search, NoiseTolerantTrustRegion) or not np.isfinite(step_size):
        return solver
    return eqx.tree_at(lambda s: s.inner.search.initial_step_size, solver, jnp.asarray(step_size))


def solver_label(solver) -> str:
    if isinstance(solver, str):
        return solver
    return type(getattr(solver, "inner", solver)).__name__
