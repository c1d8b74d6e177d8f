r"""The registered solvers (:data:`brdffit.fitting.solvers.SOLVERS`), made bounded: the parts
swapped into optimistix's Gauss–Newton family, and the optimality test.

All three see the Gauss–Newton normal form of the residual (:mod:`brdffit.fitting.normal_form`),
with exact first derivatives from JAX, in the box coordinates ``z ∈ [0, 1]^p`` of
:mod:`brdffit.fitting.transforms`:

* ``lm`` (default): :class:`optimistix.LevenbergMarquardt` whose step is the **bounded**
  Levenberg–Marquardt step of :func:`box_step` (:class:`BoxDampedNewtonDescent`), with a
  classical trust-region update of the damping; robust from poor starting points.
* ``gauss-newton``: :class:`optimistix.GaussNewton` with the undamped bounded step; fast near
  the optimum, may diverge far from it.
* ``dogleg``: :class:`optimistix.Dogleg`, its dogleg step projected onto the box.

Parts swapped in (optimistix solvers are built from parts):

* :class:`BoxDampedNewtonDescent`: Marquardt's scaled damping ``(JᵀJ + λ diag(JᵀJ)) δ = -Jᵀr``
  (Marquardt 1963; MINPACK's ``lmder``) solved over the box ``0 ≤ z + δ ≤ 1`` by a small
  active-set method: coordinates on a bound whose gradient points outward are held there,
  coordinates the step would carry past a bound are put on it, and a held coordinate is released
  when the quadratic model's gradient points back inside. A parameter whose optimum lies at or
  beyond its bound therefore ends exactly on it, in the step that reaches it.
* :class:`NoiseTolerantTrustRegion` (both trust-region solvers): accepts a step whose actual
  change of the cost is within rounding noise of zero (``noise × cost``), which optimistix's
  ``ClassicalTrustRegion`` rejects near an exact fit; a rejected step never triggers the
  convergence test.
* :class:`Optimality` (all three): the convergence test. After each accepted step it computes
  the undamped bounded Gauss–Newton step from the accepted point and its predicted decrease of
  the cost; the solve has **converged** when that decrease is below ``ftol`` times the cost
  (:func:`optimality`): no step the local model can see would lower the cost by more than a
  fraction ``ftol``. A first-order optimality test in the units of the data (the cost), with
  the active set at the bounds (a parameter held on its bound by its gradient contributes
  nothing), that assumes nothing about how well the model fits. Optimistix's own Cauchy test (a
  negligible accepted step and residual change, ``rtol``/``atol``) also ends the solve, but then
  the fit is reported as *stalled* unless the optimality test holds too: the step limit and a
  stall are never success. Between rounds of steps, :func:`brdffit.fitting.stages.still`
  adds the test of a relative cost change and a step in the units of the data, for valleys
  where the local model keeps promising a decrease that no step finds.

How these parts make the solver and its convergence tests: ``docs/design/fitting.md`` ("The
solver", "Convergence tests").
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .solvers import get_solver
from .transforms import held_on_bounds

#: First trust-region step size ``1/λ`` of ``lm``: with Marquardt's scaling, ``λ = 1`` would halve
#: the first Gauss–Newton steps; ``λ = 0.01`` starts close to Gauss–Newton and lets rejections
#: (×0.25 each) damp it when needed.
INITIAL_STEP_SIZE = 100.0

#: Default of the optimality test (:func:`optimality`): converged when the bounded Gauss–Newton
#: step would lower the cost by less than this fraction of it, by compute dtype. In float64,
#: 1e-9 puts the cost within 1e-9 of the local optimum's and the parameters within
#: ``√(2·1e-9·F/(δᵀHδ))`` of it: 0.06 standard errors on a full MERL table with a perfect model.
FTOL = {"float64": 1e-9, "float32": 1e-6}

#: Relative change of the cost treated as rounding noise, by compute dtype.
COST_NOISE = {"float64": 1e-12, "float32": 1e-6}

#: Ridge (relative to each diagonal entry of ``JᵀJ``) of the undamped step, so that a
#: rank-deficient ``JᵀJ`` (a parameter the data do not identify) still gives a bounded step.
GN_RIDGE = 1e-10
#: Marquardt's scaling ``diag(JᵀJ)`` is floored at this fraction of its largest entry. A column
#: that nearly vanishes (``aps-vgroove``'s tilt near 0, where the two facet lobes merge and the
#: cost is even in the tilt) would otherwise get no damping at all: its Gauss–Newton step grows
#: like ``1/tilt``, every step is rejected, and the trust region shrinks to 1e-17 while the
#: well-determined parameters stay where they are (full tables of brass and chrome-steel ran
#: into the 200-step limit). The floor damps such a column as if it were 1e-8 of the largest
#: one; with the large step sizes of a solve going well it changes nothing.
SCALING_FLOOR = 1e-8


def _scaled_solve(mat, rhs):
    """``mat⁻¹ rhs`` for a symmetric positive (semi-)definite ``mat``, after scaling it to unit
    diagonal (Marquardt's scaling; the columns of ``J`` differ by many decades)."""
    d = jnp.sqrt(jnp.maximum(jnp.diagonal(mat), jnp.finfo(mat.dtype).tiny))
    scaled = mat / d[:, None] / d[None, :]
    return jnp.linalg.solve(scaled + 1e-14 * jnp.eye(len(d), dtype=mat.dtype), rhs / d) / d


def box_step(jtj, g, z, damping):
    r"""The step ``δ`` minimising the quadratic model over the box ``0 ≤ z + δ ≤ 1``:

    .. math:: \min_\delta\; g^\top\delta + \tfrac12\,\delta^\top (J^\top J + \Lambda)\,\delta
              \quad\text{s.t.}\quad -z \le \delta \le 1 - z

    with ``g = Jᵀr`` and ``Λ = diag(damping)`` (Levenberg–Marquardt damping; a tiny ridge for the
    undamped step). A primal active-set method with a fixed number of rounds (static shapes, no
    Python branching): start with the coordinates on a bound whose gradient points outward held
    there; each round solves the equality-constrained system for the others, then, if that step
    leaves the box, holds the violators on the bounds they cross, and otherwise releases a held
    coordinate whose multiplier has the wrong sign (the model's gradient points back inside).
    The answer is the solve of the round after ``p + 3`` updates of the active set (``p + 4``
    solves; one linear solve in the program, inside the loop). It is clipped to the box, so every
    iterate is feasible even if the rounds run out; a held coordinate ends exactly on its bound
    (``z + (-z) = 0`` exactly).
    """
    p = z.shape[0]
    mat = jtj + jnp.diag(damping)
    lo, hi = -z, 1.0 - z
    eye = jnp.eye(p, dtype=mat.dtype)

    def round_(_, carry):
        held_lo, held_hi, _ = carry
        held = held_lo | held_hi
        # the equality-constrained step: held coordinates on their bounds, the rest solved for
        val = jnp.where(held_lo, lo, jnp.where(held_hi, hi, 0.0))
        free = ~held
        m = jnp.where(free[:, None] & free[None, :], mat, 0.0) + jnp.where(held, 1.0, 0.0) * eye
        rhs = jnp.where(free, -g - mat @ val, val)
        d = jnp.where(held, val, _scaled_solve(m, rhs))
        # the active set for the next round
        out_lo, out_hi = ~held & (d < lo), ~held & (d > hi)
        grad = mat @ d + g  # gradient of the quadratic model at d (the multipliers of the held)
        back_lo, back_hi = held_lo & (grad < 0), held_hi & (grad > 0)
        leave = jnp.any(out_lo | out_hi)
        held_lo = jnp.where(leave, held_lo | out_lo, held_lo & ~back_lo)
        held_hi = jnp.where(leave, held_hi | out_hi, held_hi & ~back_hi)
        return held_lo, held_hi, d

    held_lo, held_hi = held_on_bounds(z, g)
    _, _, d = jax.lax.fori_loop(0, p + 4, round_, (held_lo, held_hi, jnp.zeros_like(mat[0])))
    d = jnp.where(jnp.isfinite(d), d, 0.0)
    return jnp.clip(d, lo, hi)


def gauss_newton_parts(f_info):
    """``(J̃ᵀJ̃, J̃ᵀr̃, ½‖r̃‖²)`` of the normal form's ``(J̃, r̃)`` (an optimistix function
    information): the solver's local quadratic model, which :func:`optimality` tests."""
    jac, res = f_info.jac.as_matrix(), f_info.residual
    return jac.T @ jac, jac.T @ res, 0.5 * jnp.sum(res**2)


def predicted_decrease(jtj, g, d):
    """Decrease of the Gauss–Newton model ``½‖J δ + r‖²`` along ``δ``: ``-(gᵀδ + ½ δᵀJᵀJδ)``."""
    return -(g @ d + 0.5 * d @ (jtj @ d))


#: Step lengths ``t · (gᵀg / gᵀJᵀJg)``, ``t = 2^0 … 2^-39``, of the projected-gradient steps
#: that bound ``ω`` from below (:func:`optimality`).
CAUCHY_HALVINGS = 40


def cauchy_decrease(jtj, g, z):
    """The best predicted decrease among projected steepest-descent steps ``clip(−t g)`` onto the
    box, at the model's exact line minimum ``t₀ = gᵀg / gᵀJᵀJg`` and its halvings: a lower bound
    of the bounded model's minimum decrease, never negative (the shortest steps decrease it
    whenever the projected gradient is non-zero), and without a linear solve."""
    t0 = (g @ g) / jnp.maximum(g @ (jtj @ g), jnp.finfo(g.dtype).tiny)
    ts = t0 * 0.5 ** jnp.arange(CAUCHY_HALVINGS, dtype=g.dtype)
    steps = jnp.clip(-ts[:, None] * g[None, :], -z, 1.0 - z)
    dec = -(steps @ g + 0.5 * jnp.einsum("ki,ij,kj->k", steps, jtj, steps))
    return jnp.maximum(jnp.max(dec), 0.0)


def optimality(jtj, g, cost, z):
    r"""``(relative decrease, step)``: the undamped bounded Gauss–Newton step ``δ`` from ``z``
    (:func:`box_step`) and its predicted decrease of the cost divided by the cost,

    .. math:: \omega = \frac{-(g^\top\delta + \tfrac12\,\delta^\top J^\top J\,\delta)}{F},

    the fraction of the cost ``F`` any step the local model sees could still remove. ``ω = 0``
    exactly at a stationary point of the bound-constrained problem (a projected gradient of
    zero); the fit has converged when ``ω ≤ ftol``. Where ``JᵀJ`` is numerically singular or
    the active set has not settled, the solved ``δ`` can predict less than a projected gradient
    step, even an increase (disney on a full table of fruitwood-241: ``ω = −0.011``, reported
    as converged); ``ω`` is therefore at least :func:`cauchy_decrease` over ``F``.
    """
    d = box_step(jtj, g, z, GN_RIDGE * jnp.diagonal(jtj))
    dec = jnp.maximum(predicted_decrease(jtj, g, d), cauchy_decrease(jtj, g, z))
    return dec / jnp.maximum(cost, jnp.finfo(cost.dtype).tiny), d


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


class _BoxState(eqx.Module):
    """A descent's state: the point it was last queried at (the last accepted iterate), that
    point's function information, and its optimality measure ``ω`` (:func:`optimality`; ``inf``
    before the first query), computed once per accepted point and read by
    :meth:`Optimality.terminate` and :func:`end_optimality`."""

    y: object
    f_info: object
    omega: jax.Array


def _queried(y, f_info, kept) -> _BoxState:
    """The :class:`_BoxState` of a descent queried at ``y`` (``f_info`` its information),
    keeping ``kept`` (the information itself, or a wrapped descent's own state)."""
    jtj, g, cost = gauss_newton_parts(f_info)
    return _BoxState(y, kept, optimality(jtj, g, cost, y)[0].astype(y.dtype))


def _unqueried(y, f_info) -> _BoxState:
    return _BoxState(y, f_info, jnp.asarray(jnp.inf, y.dtype))


def _omega(state, y):
    """``ω`` of an optimistix Gauss–Newton state at its last accepted point: the descent's
    stored value (:class:`_BoxState`), or computed here for a descent of another kind."""
    descent = state.descent_state
    if isinstance(descent, _BoxState):
        return descent.omega
    jtj, g, cost = gauss_newton_parts(state.f_info)
    return optimality(jtj, g, cost, y)[0]


class BoxDampedNewtonDescent(optx.DampedNewtonDescent):
    """The bounded Levenberg–Marquardt step (:func:`box_step`) with Marquardt's scaling.

    With ``s = 1/λ`` the trust region's step size, the damping is ``diag(JᵀJ)/s`` (floored at
    ``SCALING_FLOOR`` of the largest entry, so a column that vanishes stays damped).
    ``undamped=True`` gives the Gauss–Newton step (a tiny ridge only) whatever the step size. ``J`` is the
    solver's small Jacobian (the normal form), materialised. Records the point it was queried
    at (the last accepted iterate), which :class:`Optimality` reads.
    """

    undamped: bool = False

    def init(self, y, f_info_struct):
        return _unqueried(y, super().init(y, f_info_struct).f_info)

    def query(self, y, f_info, state):
        del state
        return _queried(y, f_info, f_info)

    def step(self, step_size, state):
        jtj, g, _ = gauss_newton_parts(state.f_info)
        d2 = jnp.diagonal(jtj)
        d2 = jnp.maximum(d2, SCALING_FLOOR * jnp.max(d2) + jnp.finfo(d2.dtype).tiny)
        lam = GN_RIDGE if self.undamped else 1.0 / jnp.maximum(step_size, 1e-300)
        return box_step(jtj, g, state.y, lam * d2), optx.RESULTS.successful


class ProjectedDescent(eqx.Module):
    """Any optimistix descent with its step projected onto the box ``0 ≤ z + δ ≤ 1``."""

    inner: optx.AbstractDescent

    def init(self, y, f_info_struct):
        return _unqueried(y, self.inner.init(y, f_info_struct))

    def query(self, y, f_info, state):
        return _queried(y, f_info, self.inner.query(y, f_info, state.f_info))

    def step(self, step_size, state):
        d, result = self.inner.step(step_size, state.f_info)
        return jnp.clip(d, -state.y, 1.0 - state.y), result


class Optimality(optx.AbstractLeastSquaresSolver):
    """A bounded Gauss–Newton-family solver that stops when the optimality test holds.

    After each accepted step, at the point ``z`` just evaluated, :func:`optimality` gives the
    fraction ``ω`` of the cost that the undamped bounded Gauss–Newton step could still remove;
    ``ω ≤ ftol`` ends the solve there (that point's ``aux``, ``JᵀJ`` and the sandwich meat,
    belong to the answer). The inner solver's own Cauchy test also ends it;
    :func:`brdffit.fitting.solve.solve` reads ``ω`` at the end point and the fit reports
    success only when ``ω ≤ ftol``. Everything else (steps, damping, acceptance) is the inner solver's.

    The bounded descents compute ``ω`` when they are queried at an accepted point (in
    optimistix's branch for an accepted step) and keep it in their state (:class:`_BoxState`):
    one instance of :func:`box_step` for the test in the compiled program instead of one each
    for optimistix's initial and per-step termination checks and the end point.

    With ``history = n`` (:func:`with_history`) the state (:class:`Recorded`) also keeps the
    cost ``½‖r‖²`` of the last accepted point after each of the first ``n`` steps: what a
    fit's progress reports, read on the host when the solve returns (the program calls
    nothing back, :mod:`brdffit.fitting.events`).
    """

    inner: optx.AbstractLeastSquaresSolver
    ftol: jax.Array = 1e-9  # an array: another tolerance needs no recompile
    history: int = eqx.field(static=True, default=0)

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
        inner = self.inner.init(fn, y, args, options, f_struct, aux_struct, tags)
        return Recorded(inner, jnp.full(self.history, jnp.nan, y.dtype), jnp.array(0))

    def step(self, fn, y, args, options, state, tags):
        y, inner, aux = self.inner.step(fn, y, args, options, state.inner, tags)
        costs = state.costs
        if self.history:
            cost = 0.5 * jnp.sum(jnp.square(inner.f_info.residual))  # the accepted point's
            costs = costs.at[state.count].set(cost.astype(costs.dtype), mode="drop")
        return y, Recorded(inner, costs, state.count + 1), aux

    def terminate(self, fn, y, args, options, state, tags):
        state = state.inner
        done, result = self.inner.terminate(fn, y, args, options, state, tags)
        # optimistix passes the iterate from *before* the step here; the accepted point is the
        # one the descent was last queried at
        omega = _omega(state, getattr(state.descent_state, "y", y))
        fresh = (state.num_steps_since_acceptance == 0) & (state.num_steps > 0)
        # (a solve whose result is an error stops whatever ``done`` says: optimistix's loop runs
        # only while the result is successful)
        return done | ((omega <= self.ftol) & fresh), result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return self.inner.postprocess(fn, y, aux, args, options, state.inner, tags, result)


class Recorded(eqx.Module):
    """:class:`Optimality`'s state: the inner solver's (``inner``), the cost after each step
    (``costs``, NaN after the last; empty without ``history``) and the steps taken
    (``count``)."""

    inner: object
    costs: jax.Array
    count: jax.Array


def with_history(solver: Optimality, steps: int) -> Optimality:
    """``solver`` recording the cost after each of its first ``steps`` steps (a static length:
    the solve's ``max_steps``)."""
    return dataclasses.replace(solver, history=int(steps))


def end_optimality(sol):
    """``ω`` (:func:`optimality`) at the end point of an optimistix solution ``sol`` (of an
    :class:`Optimality` solver)."""
    state = sol.state.inner
    return _omega(state, getattr(state.descent_state, "y", sol.value))


def _array(value):
    """A strongly typed scalar of the default float dtype: solver settings held as arrays must
    keep one type (a weakly typed ``jnp.asarray(0.1)`` would compile a second program). A NumPy
    array, traced like a JAX one: making it costs no conversion program in a fresh process."""
    return np.asarray(value, dtype=jnp.result_type(float))


def with_ftol(solver, ftol):
    """``solver`` (an :class:`Optimality`) with another optimality tolerance; same program."""
    return eqx.tree_at(lambda s: s.ftol, solver, _array(ftol))


def _quiet(**kwargs):
    del kwargs


def make_solver(name, rtol: float, atol: float, verbose=None, noise: float = 1e-12,
                ftol: float = 1e-9):
    """An optimistix solver from a registry name (:func:`brdffit.fitting.solvers.get_solver`),
    made bounded (module docstring) and wrapped in :class:`Optimality` with tolerance ``ftol``.
    An optimistix solver passed in is wrapped as it is (its steps are then not kept inside the
    box: they are clamped when evaluated)."""
    if isinstance(name, Optimality):
        return name
    if isinstance(name, optx.AbstractLeastSquaresSolver):
        solver = name
    else:
        cls = getattr(optx, get_solver(name).optimistix)
        solver = cls(rtol=rtol, atol=atol, verbose=verbose or _quiet)
        if isinstance(solver, optx.LevenbergMarquardt):
            solver = eqx.tree_at(lambda s: s.descent, solver, BoxDampedNewtonDescent())
        elif isinstance(solver, optx.GaussNewton):
            solver = eqx.tree_at(lambda s: s.descent, solver, BoxDampedNewtonDescent(undamped=True))
        else:
            solver = eqx.tree_at(lambda s: s.descent, solver, ProjectedDescent(solver.descent))
        first = INITIAL_STEP_SIZE if isinstance(solver, optx.LevenbergMarquardt) else 1.0
        if isinstance(getattr(solver, "search", None), optx.ClassicalTrustRegion):
            search = NoiseTolerantTrustRegion(noise=noise, initial_step_size=_array(first))
            solver = eqx.tree_at(lambda s: s.search, solver, search)
    return Optimality(solver, _array(ftol))


def with_initial_step(solver, step_size):
    """``solver`` with its trust region starting at ``step_size`` (unchanged if it has none)."""
    search = getattr(getattr(solver, "inner", None), "search", None)
    if not isinstance(search, NoiseTolerantTrustRegion) or not np.isfinite(step_size):
        return solver
    return eqx.tree_at(lambda s: s.inner.search.initial_step_size, solver, _array(step_size))


def solver_label(solver) -> str:
    if isinstance(solver, str):
        return solver
    return type(getattr(solver, "inner", solver)).__name__
