"""One optimistix solve of a fit's :class:`~.problem.Problem`, and what it returns.

:func:`solve` runs ``optimistix.least_squares`` on the Gauss–Newton normal form
(:func:`.normal_form.normal_form`) over the first ``active`` blocks of the cells and returns a
:class:`Solved`: the end point (the last accepted iterate) with ``JᵀJ``, the sandwich meat, the
error figures and the optimality measure ``ω`` there, all accumulated in the solver's own passes.
``active`` is traced, so one compiled program serves the start scan, the warm start on a few
blocks and the full-table solve (:mod:`.stages`).
"""

from __future__ import annotations

import functools
import threading

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .data import FitData
from .normal_form import normal_form, over_blocks
from .problem import Problem
from .bounded import COST_NOISE, end_optimality, gauss_newton_parts, optimality, with_history
from .statistics import N_CELL_SUMS, metrics_from

#: XLA CPU options for the fitting program (per program: ``jax.config`` and ``XLA_FLAGS`` are
#: untouched; on other backends, or a jaxlib without them, none is set):
#:
#: * keep YNNPACK for matrix products only: its default also routes the reductions of the
#:   3-wide dot products of direction batches through slow YNNPACK fusions;
#: * no while-loop invariant code motion. Each tangent field of the pass
#:   (:meth:`.problem.Problem.tangents_x`) is a ``jvp`` that traces the model's primal again;
#:   outside a loop XLA's common-subexpression elimination merges the copies, but inside the
#:   loop over blocks the motion pass first hoists each copy's parameter-only scalars into a
#:   loop value of its own, and the copies, no longer identical, all stay: a ``beckmann`` pass
#:   computed its ``D`` and both Λ four times (16 ``exp`` per cell instead of 4). Without the
#:   motion the copies merge; the hoisted scalars cost nothing per block.
CPU_COMPILER_OPTIONS = {
    "xla_cpu_experimental_ynn_fusion_type": "LIBRARY_FUSION_TYPE_DOT",
    "xla_disable_hlo_passes": "while-loop-invariant-code-motion",
}

#: The second-order term of a stage is measured on its leading blocks holding at least
#: ``SECOND_CELLS`` cells (an evenly spread subset, :func:`.data.select`; all of a smaller
#: stage): it only sets the solver's quadratic model, so its sampling error changes the
#: convergence rate, never the answer. ``beckmann``'s term is noisy: 8,192 cells made some full
#: fits crawl.
SECOND_CELLS = 32768


class Solved(eqx.Module):
    """What one solve returns, at its end point (the last accepted iterate).

    Attributes:
        z: box coordinates of the free scalars (:mod:`.transforms`).
        result: optimistix's verdict, an item of ``optimistix.RESULTS``.
        steps: solver steps taken.
        cost: ``½ Σ r²`` over the solve's cells (without the cost floor).
        omega: the optimality measure ``ω`` (:func:`.bounded.optimality`).
        gn: the solver's Gauss–Newton model at the end point, ``(J̃ᵀJ̃, J̃ᵀr̃, ½‖r̃‖²)`` of the
            normal form (:func:`.bounded.gauss_newton_parts`): what ``omega`` is computed from,
            kept so that :meth:`omega_over` can test a subset of the scalars.
        jtj, meat: ``JᵀJ`` and ``Jᵀdiag(r²)J`` with respect to ``z``.
        dxdz: ``∂x/∂z`` per free scalar (the box map is elementwise).
        metrics: the error figures (:func:`.statistics.metrics_from`).
        m: the number of residuals with non-zero weight.
        step_size: the trust region's last step size (NaN for a solver without one).
        costs: the solver's cost (floor included) after each step, NaN after the last: the
            step events of a fit's progress (:mod:`.events`).
        still: the solve ended on the stillness test (:func:`.stages.still`, applied by
            :meth:`.stages.Run.solve` between rounds); set on the host, ``False`` from the
            solver.
    """

    z: jax.Array
    result: optx.RESULTS
    steps: jax.Array
    cost: jax.Array
    omega: jax.Array
    gn: tuple
    jtj: jax.Array
    meat: jax.Array
    dxdz: jax.Array
    metrics: dict
    m: jax.Array
    step_size: jax.Array
    costs: jax.Array | None = None
    still: bool = False

    @property
    def successful(self) -> bool:
        """optimistix ended the solve without an error (optimal or not)."""
        return bool(self.result == optx.RESULTS.successful)

    @property
    def ran_out(self) -> bool:
        """optimistix stopped at the solve's step limit."""
        return bool(self.result == optx.RESULTS.nonlinear_max_steps_reached)

    @property
    def finite(self) -> bool:
        return bool(np.all(np.isfinite(self.z)) and np.isfinite(float(self.cost)))

    @property
    def ranked_cost(self) -> float:
        """The cost, or ``inf`` where it is not finite."""
        cost = float(self.cost)
        return cost if np.isfinite(cost) else np.inf

    def omega_over(self, keep) -> float:
        """``ω`` (:func:`.bounded.optimality`) of the solver's model restricted to the free
        scalars where ``keep`` (a boolean mask over them), the others held where they are: the
        fraction of the cost a step in those scalars alone could still remove."""
        keep = np.flatnonzero(np.asarray(keep, bool))
        jtj, g, cost = (np.asarray(a, float) for a in self.gn)
        z = np.asarray(self.z, float)
        omega, _ = optimality(jnp.asarray(jtj[np.ix_(keep, keep)]), jnp.asarray(g[keep]),
                              jnp.asarray(cost), jnp.asarray(z[keep]))
        return float(omega)

    def converged(self, ftol: float) -> bool:
        """A finite point where optimistix succeeded and the optimality test ``ω ≤ ftol``
        holds, or where the stillness test ended the solve (:attr:`still`)."""
        if not self.finite:
            return False
        return bool(self.still) or (self.successful and float(self.omega) <= ftol)

    def better_than(self, other: Solved, ftol: float) -> bool:
        """A converged solve is better than one that did not converge; between two of the same
        kind, the lower (finite) cost is."""
        mine, theirs = self.converged(ftol), other.converged(ftol)
        if mine != theirs:
            return mine
        return self.ranked_cost < other.ranked_cost


def _solve(problem: Problem, solver, z0, data, floor, max_steps: int, active, second) -> Solved:
    """The traced solve behind :func:`solve`; ``second`` (``p × p``, zeros for none) is the
    estimate of the second-order term added to the solver's ``JᵀJ``."""
    penalty = None if problem.energy is None else problem.penalty_sums
    fn = normal_form(problem.block_sums, problem.chunks, problem.pass_tables, N_CELL_SUMS,
                     penalty)
    sol = optx.least_squares(
        fn, with_history(solver, max_steps), z0, args=(data, floor, active, second),
        max_steps=max_steps, throw=False, has_aux=True,
    )
    state = sol.state.inner  # optimistix's, inside Optimality's (.bounded.Recorded)
    aux = state.aux  # JᵀJ, Jᵀdiag(r²)J and the error sums at sol.value
    _, dxdz = jax.jvp(problem.physical, (sol.value,), (jnp.ones_like(sol.value),))
    metrics, cost, m = metrics_from(aux["sum_r2"], aux["extra"])
    step = getattr(state.search_state, "step_size", jnp.nan)
    gn = tuple(a.astype(z0.dtype) for a in gauss_newton_parts(state.f_info))
    return Solved(
        z=sol.value, result=sol.result, steps=sol.stats["num_steps"], cost=cost.astype(z0.dtype),
        omega=end_optimality(sol).astype(z0.dtype), gn=gn, jtj=aux["jtj"], meat=aux["meat"], dxdz=dxdz,
        metrics=metrics, m=m, step_size=jnp.asarray(step, z0.dtype),
        costs=sol.state.costs.astype(z0.dtype),
    )


@functools.cache
def _compiler_options() -> dict:
    if jax.default_backend() != "cpu":
        return {}
    try:
        jax.jit(lambda a: a + 1, compiler_options=CPU_COMPILER_OPTIONS).lower(1.0).compile()
    except Exception:  # noqa: BLE001 (an older/newer jaxlib without this option)
        return {}
    return {"compiler_options": CPU_COMPILER_OPTIONS}


@functools.cache
def _jitted_solve():
    return eqx.filter_jit(_solve, **_compiler_options())


def solve(problem: Problem, solver, z0, data: FitData, floor, max_steps: int, active: int,
          second=None) -> Solved:
    """Solve from ``z0`` over the first ``active`` blocks of ``data`` (``floor``: the cost floor
    of those blocks, :func:`cost_floor`), with ``second`` added to ``JᵀJ`` in the solver's
    quadratic model (none by default); returns host (NumPy) values."""
    if second is None:
        second = np.zeros((len(z0), len(z0)))
    args = (problem, solver, jnp.asarray(z0), data, floor, max_steps, np.int32(active),
            jnp.asarray(second, jnp.result_type(float)))
    return jax.tree.map(np.asarray, _jitted_solve()(*args))


@eqx.filter_jit
def _jitted_floor(problem: Problem, data, noise):
    return problem.cost_floor(data, noise)


def cost_floor(problem: Problem, data: FitData):
    """:meth:`Problem.cost_floor` of all of ``data`` at the compute dtype's noise level, a NumPy
    scalar (so that scaling it to a stage's blocks compiles nothing)."""
    return np.asarray(_jitted_floor(problem, data, COST_NOISE[problem.compute_dtype]))


def _slab_blocks(problem: Problem, data: FitData) -> int:
    """The leading blocks that hold ``SECOND_CELLS`` cells (all of a smaller selection)."""
    block = data.wi.shape[0] // problem.chunks
    return min(problem.chunks, -(-SECOND_CELLS // block))


def second_blocks(problem: Problem, data: FitData, target: int) -> int:
    """The leading blocks the second-order term of a stage on ``target`` blocks is measured on."""
    return min(target, _slab_blocks(problem, data))


def second_steps(z, compute_dtype):
    """The forward-difference steps of :func:`_second` in the box coordinates ``z``: ``√ε`` of
    the model's compute dtype (1.5e-8 in float64, 3.5e-4 in float32), towards the inside of the
    box ``[0, 1]`` (a coordinate on a bound is stepped off it, never past it)."""
    step = np.sqrt(np.finfo(np.dtype(compute_dtype)).eps)
    return jnp.where(z > 0.5, -step, step).astype(z.dtype)


def _second(problem: Problem, z, data, blocks):
    r"""``S = Σ rᵢ∇²rᵢ`` at ``z`` over the first ``blocks`` blocks (traced: one program for
    every stage) of the leading blocks that ``SECOND_CELLS`` cells fill (static).

    Forward differences of exact first derivatives: with the residuals ``r̄ = r(z)`` held
    fixed and ``G(v) = J(v)ᵀ r̄`` (:meth:`Problem.block_gradient_held`), ``∂G/∂v =
    Σ r̄ᵢ∇²rᵢ(v)``, so column ``k`` of ``S`` is ``(G(z + hₖeₖ) − G(z)) / hₖ + O(hₖ)``
    (:func:`second_steps`), symmetrised. The ``p + 1`` points are one ``vmap`` in one loop
    over the blocks; a model with ``per_pass`` tables builds them once per point, before the
    loop. Against the exact term (:meth:`Problem.block_second_order`, ``jax.hessian``) on
    realistic tables: within 2e-6 of its largest entry in float64 and 4.4e-2 in float32,
    while measuring it on ``SECOND_CELLS`` cells instead of the whole table already moves it
    by 4–19e-2 (it only shapes the solver's quadratic model). In exchange its program
    compiles in less time than ``jax.hessian``'s (a cold fit compiles it beside the solve's,
    on the same two cores), runs faster and maps no fresh memory per call."""
    acc = jnp.promote_types(z.dtype, jnp.float32)
    block = data.wi.shape[0] // problem.chunks
    n_blocks = _slab_blocks(problem, data)
    slab = jax.tree.map(lambda a: a[: block * n_blocks], data)
    h = second_steps(z, problem.compute_dtype)
    points = jnp.concatenate([z[None, :], z[None, :] + jnp.diag(h)])
    tables_at = None
    if problem.model.per_pass is not None:
        tables_at = jax.vmap(problem.pass_tables)(points)
    tables = jax.tree.map(lambda a: a[0], tables_at)  # at z (None without per-pass tables)

    def add(total, d):
        r_bar = problem.residual(z, d, tables).reshape(-1, 3).astype(acc)
        at = lambda v, tab: problem.block_gradient_held(v, d, r_bar, tab)
        return total + jax.vmap(at)(points, tables_at)

    g = over_blocks(add, jnp.zeros((z.shape[0] + 1, z.shape[0]), acc), slab, n_blocks, blocks)
    s = (g[1:] - g[0]) / h[:, None].astype(acc)
    return 0.5 * (s + s.T)


@functools.cache
def _second_program():
    """The compiled :func:`_second`, with the fitting program's XLA options
    (:data:`CPU_COMPILER_OPTIONS`)."""
    return eqx.filter_jit(_second, **_compiler_options())


def compile_second_ahead(problem: Problem, z, data: FitData) -> threading.Thread:
    """Trace and lower the second-order program of :func:`second_order` for ``problem`` and
    ``data`` here, then start its XLA compilation on a thread, and return the thread; nothing
    is run, and the caller must ``join`` it before its first :func:`second_order` (two
    compiles of one program would each be paid).

    ``lower()`` and ``compile()`` fill the caches that the first call of :func:`_second_program`
    then finds (its trace, its lowering and the executable), so a cold fit compiles this program
    while the solve's own program is being traced and compiled, instead of after the first
    stage. Tracing and lowering are Python, which holds the interpreter lock: on a thread they
    would only take turns with the tracing of the solve; done first, here, they leave the
    thread the part that runs in parallel, XLA's compilation, overlapped with the solve's
    tracing. The thread runs under the caller's
    ``jax_enable_x64`` (a thread-local setting that :func:`brdffit.fit` sets per call). A
    failure is dropped: the first call then compiles as it would have.
    """
    x64 = bool(jax.config.jax_enable_x64)
    # optimistix compares constant results (equinox enumerations) eagerly while the solve is
    # traced: a small conversion program, compiled once per process. Compiled here, before the
    # thread's compilation occupies the cores, it does not wait for them.
    _ = optx.RESULTS.successful == optx.RESULTS.successful
    try:
        lowered = _second_program().lower(problem, jnp.asarray(z), data, np.int32(1))
    except Exception:  # noqa: BLE001 (only time is at stake; the call compiles instead)
        lowered = None

    def work():
        try:
            with jax.enable_x64(x64):
                lowered.compile()
        except Exception:  # noqa: BLE001 (likewise; also when the lowering failed)
            pass

    thread = threading.Thread(target=work, name="brdffit-second-order-compile", daemon=True)
    thread.start()
    return thread


def second_order(problem: Problem, z, data: FitData, target: int) -> np.ndarray:
    """The second-order term at ``z`` for a stage on the first ``target`` blocks, measured on
    :func:`second_blocks` of them and scaled to ``target`` (the sum grows with the number of
    cells); zeros if it is not finite."""
    blocks = second_blocks(problem, data, target)
    s = np.asarray(_second_program()(problem, jnp.asarray(z), data, np.int32(blocks)))
    s = s * (target / blocks)
    return s if np.all(np.isfinite(s)) else np.zeros_like(s)
