"""``fit``: least-squares fitting of a registered model to a measured table, with optimistix.

The pipeline: select cells (:mod:`.data`) → starting point (:mod:`.init`, or the user's) →
unconstrained problem (:mod:`.transforms`, :mod:`.problem`) → optimistix solver on the
Gauss–Newton normal form (:mod:`.normal_form`, :mod:`.solvers`) → covariance and metrics
(:mod:`.statistics`) → :class:`~brdffit.fitting.result.FitResult`.

Speed (issue 4; ``benchmarks/bench_fit.py``, ``ggx`` on a full 1.1 M-cell MERL table, 2 CPU
cores: about 0.6 s warm where the first version took 13 s). Where the time went, and what
took it away:

* **The full-table pass** (residual, ``JᵀJ``, ``Jᵀr``, the sandwich meat and the error sums,
  block by block): 0.10–0.13 s. One forward-mode product per model parameter, not per scalar
  (``Param.per_channel``; 3 instead of 7 for ``ggx``), and per-channel pair sums instead of a
  mostly-zero Jacobian (:meth:`~brdffit.fitting.problem.Problem.block_sums`): 0.25 s → 0.10 s.
  float32 evaluation (``precision="float32"``) makes a pass ~30 % cheaper but the fit took a
  third pass (0.86 s against 0.67 s in float64, same benchmark): not the default.
* **The number of passes**: on a selection of at least ``WARM_MIN_CHUNKS`` blocks each start is
  first solved on ``WARM_FRACTION`` of the blocks (an evenly interleaved subset, same compiled
  program; a fraction of a pass per step), then on the whole selection from there, and the
  solve stops when the Gauss–Newton step is below 0.01 standard errors
  (:class:`~brdffit.fitting.solvers.Lookahead`): 2 full passes (7 originally). The error
  figures come from the last pass, not from a pass of their own.
* **Preparation** (selecting and laying out the cells, the starting point): about 0.15 s.
"""

from __future__ import annotations

import functools
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..errors import FitError, UnknownNameError
from ..models.registry import get_model
from . import init as init_mod
from .data import check_enough, select
from .losses import DEFAULT_LOSS, get_loss
from .normal_form import normal_form
from .problem import Problem
from .setup import assign, check_within, flat_bounds, flat_log
from .solvers import (
    COST_NOISE,
    DEFAULT_SOLVER,
    EDM_TOL,
    make_solver,
    solver_label,
    with_initial_step,
)
from .statistics import metrics_from
from .transforms import START_MARGIN, at_bound, bounds_in_s, to_unconstrained

_PROGRESS = {"fn": None, "start": 0, "floor": 0.0, "stage": None}


def _emit(event: str, **info):
    fn = _PROGRESS["fn"]
    if fn is not None:
        fn(event, info)


def _step_callback(step, loss):
    cost = float(loss) - _PROGRESS["floor"]  # the solver's cost carries the constant floor
    if _PROGRESS["stage"] == "warm":  # a step on the warm-start subset of the cells
        _emit("warm-step", start=_PROGRESS["start"], step=int(step), cost=float(loss))
    else:
        _emit("step", start=_PROGRESS["start"], step=int(step), cost=cost)


def _verbose_hook(**kwargs):
    """optimistix ``verbose`` callable: forwards (step, cost) to the progress callback."""
    jax.debug.callback(_step_callback, kwargs["num_steps"][1], kwargs["loss_this_step"][1])


#: XLA CPU option for the fitting program: keep YNNPACK for matrix products only. Its default
#: also routes reductions through YNNPACK fusions, which are slow for the 3-wide dot products
#: of direction batches (``dot(wi, wm)``): measured on the benchmark table (2 cores, load ~3),
#: the ggx residual pass took 0.139 s with the default and 0.068 s with this option, a full
#: (r, JᵀJ) pass 0.392 s and 0.349 s. A per-program compiler option: ``jax.config`` and
#: ``XLA_FLAGS`` are untouched; on other backends, or a jaxlib without the option, none is set.
CPU_COMPILER_OPTIONS = {"xla_cpu_experimental_ynn_fusion_type": "LIBRARY_FUSION_TYPE_DOT"}


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


@eqx.filter_jit
def _jitted_floor(problem: Problem, data, noise):
    return problem.cost_floor(data, noise)


def _solve(problem: Problem, solver, u0, data, floor, max_steps: int, active):
    """One optimistix solve over the first ``active`` blocks of cells, with the Gauss–Newton
    matrix and the error figures at its end point (accumulated in the solver's own passes;
    ``active`` is traced: one compilation serves the warm start on a few blocks and the
    full-table solve)."""
    fn = normal_form(problem.block_sums, problem.chunks)
    sol = optx.least_squares(
        fn, solver, u0, args=(data, floor, active), max_steps=max_steps, throw=False, has_aux=True
    )
    aux = sol.state.aux  # JᵀJ, Jᵀdiag(r²)J and the error sums at sol.value (the last accepted point)
    _, dxdu = jax.jvp(problem.physical, (sol.value,), (jnp.ones_like(sol.value),))
    metrics, cost, m = metrics_from(aux["sum_r2"], aux["extra"])
    step = getattr(sol.state.search_state, "step_size", jnp.nan)
    return {
        "u": sol.value, "code": sol.result._value, "steps": sol.stats["num_steps"], "jtj": aux["jtj"],
        "meat": aux["meat"], "step_size": jnp.asarray(step, u0.dtype),
        "dxdu": dxdu, "metrics": metrics, "cost": cost.astype(u0.dtype), "m": m,
    }


def _default_dtype():
    return "float64" if jax.config.jax_enable_x64 else "float32"


def _tolerances(rtol, atol, dtype):
    base = 1e-8 if dtype == "float64" else 1e-5
    return (base if rtol is None else float(rtol)), (base if atol is None else float(atol))


def _build_problem(model, loss, samples, fixed, init, bounds, dtype):
    """Flat start/bounds/free set and the data-driven guess (before selecting cells)."""
    lo, hi = flat_bounds(model, bounds)
    x0 = model.flatten({})
    fixed_idx = sorted(set(assign(model, fixed, x0, "fixed value of")))
    check_within(model, x0, lo, hi, fixed_idx, "fixed")
    free = [i for i in range(len(x0)) if i not in set(fixed_idx)]
    if not free:
        raise FitError(f"every parameter of {model.name!r} is fixed: nothing to fit")
    return x0, lo, hi, fixed_idx, free


def _start_point(model, sel, x0, lo, hi, free, fixed_idx, init):
    """Data-driven guess, then the user's ``init`` on top (fixed scalars keep their values)."""
    wi, wo, rgb, good = sel.host
    feats = init_mod.measure(rgb, wi, wo, good)
    guess = model.flatten(init_mod.guess(model, feats))
    x = x0.copy()
    x[free] = guess[free]
    if init is not None:
        user = x.copy()
        idx = assign(model, getattr(init, "params", init), user, "init value of")
        check_within(model, user, lo, hi, idx, "init")
        x[[i for i in idx if i not in set(fixed_idx)]] = user[[i for i in idx if i not in set(fixed_idx)]]
    return x


def _starts(u0: np.ndarray, multistart: int, seed: int) -> list[np.ndarray]:
    """The default start, then ``multistart`` perturbed copies (unit normal steps in ``u``)."""
    rng = np.random.default_rng(seed + 1)
    return [u0] + [u0 + rng.normal(0.0, 1.0, size=u0.shape) for _ in range(int(multistart))]


#: The warm start runs when the selection has at least this many blocks of cells ...
WARM_MIN_CHUNKS = 8
#: ... on this fraction of them (at least one block; evenly spread cells, see
#: :func:`brdffit.fitting.data.select`).
WARM_FRACTION = 1 / 16


def _call(problem, solver, u0, data, floor, max_steps, active):
    args = (problem, solver, jnp.asarray(u0), data, floor, max_steps, jnp.int32(active))
    out = jax.tree.map(np.asarray, _jitted_solve()(*args))
    cost = float(out["cost"])
    ok = int(out["code"]) == 0 and not np.any(np.isnan(out["u"])) and np.isfinite(cost)
    return out, (not ok, cost if np.isfinite(cost) else np.inf)


def _warm_start(problem, solver, u0, data, floor, max_steps):
    """``(u, solver)`` for the full-table solve: the optimum on a few evenly spread blocks, and
    the trust region it ended with (issue 4, "Speed").

    The far-from-optimum steps then cost a fraction of a full pass each; the full table starts
    within its statistical error of its own optimum, undamped, and needs about two passes.
    What is fitted, and the convergence test, are unchanged. Skipped for small selections.
    """
    if problem.chunks < WARM_MIN_CHUNKS:
        return u0, solver
    active = max(1, round(problem.chunks * WARM_FRACTION))
    _PROGRESS["stage"] = "warm"
    try:
        out, _ = _call(problem, solver, u0, data, floor * active / problem.chunks, max_steps, active)
    finally:
        _PROGRESS["stage"] = None
    _emit("warm-done", blocks=active, of=problem.chunks, steps=int(out["steps"]))
    if not (np.all(np.isfinite(out["u"])) and np.isfinite(float(out["cost"]))):
        return u0, solver
    return out["u"], with_initial_step(solver, float(out["step_size"]))


def _solve_one(problem, solver, u0, data, floor, max_steps, k, warm=True):
    _PROGRESS["start"] = k
    if warm:
        u0, solver = _warm_start(problem, solver, u0, data, floor, max_steps)
    return _call(problem, solver, u0, data, floor, max_steps, problem.chunks)


def _bound_restart(out, key):
    """A start for a second solve when scalars ended at a bound: those moved back inside.

    A transient can push a small albedo to its bound, where its logistic derivative is too small
    to bring it back; a genuinely at-bound scalar simply returns there. ``None`` if not needed.
    """
    u = np.asarray(out["u"], float)
    hit = at_bound(u) != 0
    if key[0] or not np.any(hit):
        return None
    p = np.where(u < 0, START_MARGIN, 1.0 - START_MARGIN)
    return np.where(hit, np.log(p) - np.log1p(-p), u)


def _run_starts(problem, solver, starts, data, max_steps):
    """Solve from every start (and once more from a bound restart); return the raw output of
    the best and the cost of each start."""
    floor = _jitted_floor(problem, data, COST_NOISE[problem.compute_dtype])
    _PROGRESS["floor"] = float(floor)
    best, costs = None, []
    for k, u0 in enumerate(starts):
        _emit("start", start=k, of=len(starts))
        out, key = _solve_one(problem, solver, u0, data, floor, max_steps, k)
        again = _bound_restart(out, key)
        if again is not None:
            _emit("restart", start=k, reason="parameters at a bound")
            out2, key2 = _solve_one(problem, solver, again, data, floor, max_steps, k, warm=False)
            if key2 < key:
                out, key = out2, key2
        costs.append(float(key[1]))
        _emit("start-done", start=k, cost=costs[-1], steps=int(out["steps"]), success=not key[0])
        if best is None or key < best[0]:
            best = (key, out)
    return best[1], costs


def fit(
    table,
    model,
    *,
    loss=DEFAULT_LOSS,
    solver=DEFAULT_SOLVER,
    init=None,
    fixed=None,
    bounds=None,
    cutoff=None,
    subsample=None,
    seed: int = 0,
    multistart: int = 0,
    max_steps: int = 200,
    rtol: float | None = None,
    atol: float | None = None,
    edm_tol: float = EDM_TOL,
    throw: bool = True,
    progress=None,
    precision: str | None = None,
    covariance: str = "sandwich",
):
    """Fit ``model`` to ``table`` by nonlinear least squares; returns a :class:`FitResult`.

    Args:
        table: anything with ``.to_samples()`` giving a ``data_formats.SampleSet`` (a
            ``MERLTable``, a ``SampleSet``).
        model: a registry name (``"ggx"``) or a :class:`~brdffit.models.Model`.
        loss: a name from :data:`brdffit.fitting.LOSSES` (``"log"`` default, ``"log+huber"``...) or a
            :class:`~brdffit.fitting.losses.Loss`.
        solver: ``"lm"`` (default), ``"gauss-newton"``, ``"dogleg"``, or an optimistix
            least-squares solver.
        init: name → starting value (overrides the data-driven guess), or a previous
            ``FitResult``.
        fixed: name → value of scalars held fixed (``"f0"`` or one component ``"f0[1]"``).
        bounds: name → ``(lo, hi)`` overriding the declared bounds.
        cutoff: drop cells with ``θi`` or ``θo`` above this many degrees (Burley 2012 §4.7).
        subsample: a cell count, a fraction, or a :class:`~brdffit.fitting.data.Subsample`.
        seed: for the subsample and the multi-start perturbations.
        multistart: number of extra perturbed starts; the lowest cost wins.
        max_steps, rtol, atol: solver limits (tolerances default to 1e-8 in float64, 1e-5 in
            float32).
        edm_tol: also stop when the Gauss–Newton step is below ``√(2 edm_tol)`` standard errors
            (MINUIT's estimated distance to the minimum; default 5e-5, i.e. 0.01 standard
            errors; 0 turns the test off and converges to ``rtol``/``atol`` alone); see
            :class:`brdffit.fitting.solvers.Lookahead`.
        throw: raise :class:`~brdffit.errors.FitError` when the solver does not converge;
            with ``False`` the result carries ``success=False`` and the solver's message.
        progress: ``callback(event, info)`` with events ``setup``, ``start``, ``warm-step`` and
            ``warm-done`` (large tables: the warm start on a subset of the blocks), ``step``,
            ``start-done``, ``done``.
        precision: ``"float64"`` or ``"float32"`` model evaluation (products are accumulated in
            float64 either way when x64 is enabled). Defaults to float64 when x64 is enabled.
        covariance: ``"sandwich"`` (default, robust to heteroscedastic residuals) or ``"gn"``
            (classical ``s² (JᵀJ)⁻¹``); see :mod:`brdffit.fitting.statistics`.
    """
    if covariance not in ("sandwich", "gn"):
        raise UnknownNameError("covariance", str(covariance), ["sandwich", "gn"])
    if precision not in (None, "float32", "float64"):
        raise UnknownNameError("precision", str(precision), ["float32", "float64"])
    t0 = time.perf_counter()
    model, loss_obj = get_model(model), get_loss(loss)
    dtype = precision or _default_dtype()
    rtol, atol = _tolerances(rtol, atol, dtype)
    opt = make_solver(
        solver, rtol, atol, _verbose_hook if progress else None, COST_NOISE[dtype], edm_tol
    )
    samples = table.to_samples()
    x0, lo, hi, fixed_idx, free = _build_problem(model, loss_obj, samples, fixed, init, bounds, dtype)
    sel = select(samples, loss_obj, cutoff=cutoff, subsample=subsample, seed=seed, dtype=dtype)
    check_enough(sel, len(free), samples.name)
    x_start = _start_point(model, sel, x0, lo, hi, free, fixed_idx, init)
    log = flat_log(model)
    slo, shi = bounds_in_s(lo, hi, log)
    problem = Problem(
        model, loss_obj, tuple(free), tuple(bool(b) for b in log[free]), dtype, sel.chunks,
        jnp.asarray(x_start), jnp.asarray(slo[free]), jnp.asarray(shi[free]),
    )
    u0 = to_unconstrained(x_start[free], slo[free], shi[free], log[free], START_MARGIN)
    _PROGRESS["fn"] = progress
    try:
        _emit("setup", n_cells=sel.n_used, n_free=len(free), model=model.name)
        t1 = time.perf_counter()
        out, costs = _run_starts(
            problem, opt, _starts(u0, multistart, seed), sel.data, int(max_steps)
        )
        t2 = time.perf_counter()
    finally:
        _PROGRESS["fn"] = None
    from .finish import make_result

    return make_result(
        model=model, problem=problem, sel=sel, out=out, u0=u0, costs=costs,
        x_start=x_start, fixed_idx=fixed_idx, loss=loss_obj, solver=solver_label(solver),
        throw=throw, name=samples.name, times=(t0, t1, t2), cov_kind=covariance,
        emit=lambda **kw: progress and progress("done", kw),
    )
