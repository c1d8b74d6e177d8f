"""``fit``: least-squares fitting of a registered model to a measured table, with optimistix.

The pipeline: select cells (:mod:`.data`) → starting point (:mod:`.start`, or the user's) →
box coordinates of the free scalars (:mod:`.transforms`) → the problem (:mod:`.problem`) →
bounded optimistix solver on the Gauss–Newton normal form (:mod:`.normal_form`,
:mod:`.solvers`), in stages (:func:`_solve_one`) → covariance and metrics
(:mod:`.statistics`) → :class:`~brdffit.fitting.result.FitResult`.

The stages of one start, each beginning where the previous one ended:

1. **scan** (``scan=True``, models with a lobe width): the start and copies with the lobe
   widths shifted by factors of 3 and 8 either way, each solved loosely on ``SCAN_FRACTION``
   of the blocks; the lowest cost wins (a real table can have several minima);
2. **warm** (selections of at least ``WARM_MIN_CHUNKS`` blocks): the optimum on
   ``WARM_FRACTION`` of the blocks, a fraction of a full pass per step;
3. **full**: the whole selection, to the optimality test (:class:`~.solvers.Optimality`).

After the first stage the solver's quadratic model is Newton's, ``JᵀJ`` plus the second-order
term measured at the previous stage's end point (:meth:`.problem.Problem.block_second_order`
on about 8,000 cells): on real materials the residual at the optimum is mostly model error and
Gauss–Newton alone converges only linearly. The blocks are interleaved
(:func:`.data.select`), so every leading subset is an even sample of the table. Measurements
and the history of these choices: ``docs/design/fitting.md``.
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
from . import start as start_mod
from .data import check_enough, select
from .losses import DEFAULT_LOSS, get_loss
from .normal_form import normal_form
from .problem import Problem
from .parameters import assign, check_within, flat_bounds, flat_log
from .solvers import (
    COST_NOISE,
    DEFAULT_SOLVER,
    FTOL,
    end_optimality,
    make_solver,
    solver_label,
    with_ftol,
    with_initial_step,
)
from .statistics import metrics_from
from .transforms import bounds_in_s, to_box

_PROGRESS = {"fn": None, "start": 0, "floor": 0.0, "stage": None}


def _emit(event: str, **info):
    fn = _PROGRESS["fn"]
    if fn is not None:
        fn(event, info)


def _step_callback(step, loss):
    cost = float(loss) - _PROGRESS["floor"]  # the solver's cost carries the constant floor
    stage = _PROGRESS["stage"]  # None, or a solve on a subset of the cells (warm start, scan)
    _emit("step" if stage is None else f"{stage}-step", start=_PROGRESS["start"], step=int(step),
          cost=cost)


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


#: The second-order term is measured on every ``SECOND_STRIDE``-th cell of the first block
#: (about 8,000 cells of an evenly spread subset): it only sets the solver's quadratic model, so
#: its sampling error changes the convergence rate, never the answer.
SECOND_STRIDE = 4


@eqx.filter_jit
def _jitted_second(problem: Problem, z, data):
    """:meth:`Problem.block_second_order` on every ``SECOND_STRIDE``-th cell of block 0."""
    n = data.wi.shape[0] // problem.chunks
    sub = jax.tree.map(lambda a: a[:n:SECOND_STRIDE], data)
    return problem.block_second_order(z, sub)


def _solve(problem: Problem, solver, z0, data, floor, max_steps: int, active, second):
    """One optimistix solve over the first ``active`` blocks of cells, with the Gauss–Newton
    matrix, the error figures and the optimality measure ``ω`` at its end point (accumulated in
    the solver's own passes; ``active`` is traced: one compilation serves the start scan, the
    warm start on a few blocks and the full-table solve). ``second`` (``p × p``, zeros for
    none) is the estimate of the second-order term added to the solver's ``JᵀJ``."""
    fn = normal_form(problem.block_sums, problem.chunks)
    sol = optx.least_squares(
        fn, solver, z0, args=(data, floor, active, second), max_steps=max_steps, throw=False, has_aux=True
    )
    aux = sol.state.aux  # JᵀJ, Jᵀdiag(r²)J and the error sums at sol.value (the last accepted point)
    _, dxdz = jax.jvp(problem.physical, (sol.value,), (jnp.ones_like(sol.value),))
    metrics, cost, m = metrics_from(aux["sum_r2"], aux["extra"])
    step = getattr(sol.state.search_state, "step_size", jnp.nan)
    return {
        "u": sol.value, "code": sol.result._value, "steps": sol.stats["num_steps"], "jtj": aux["jtj"],
        "meat": aux["meat"], "step_size": jnp.asarray(step, z0.dtype),
        "dxdu": dxdz, "metrics": metrics, "cost": cost.astype(z0.dtype), "m": m,
        "omega": end_optimality(sol).astype(z0.dtype),
    }


def _default_dtype():
    return "float64" if jax.config.jax_enable_x64 else "float32"


def _tolerances(rtol, atol, ftol, dtype):
    base = 1e-14 if dtype == "float64" else 1e-6  # the Cauchy test only catches a true stall
    return (
        base if rtol is None else float(rtol),
        base if atol is None else float(atol),
        FTOL[dtype] if ftol is None else float(ftol),
    )


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
    feats = start_mod.measure(rgb, wi, wo, good)
    guess = model.flatten(start_mod.guess(model, feats))
    x = x0.copy()
    x[free] = guess[free]
    if init is not None:
        user = x.copy()
        idx = assign(model, getattr(init, "params", init), user, "init value of")
        check_within(model, user, lo, hi, idx, "init")
        x[[i for i in idx if i not in set(fixed_idx)]] = user[[i for i in idx if i not in set(fixed_idx)]]
    return x


def _starts(z0: np.ndarray, multistart: int, seed: int) -> list[np.ndarray]:
    """The default start, then ``multistart`` perturbed copies (normal steps of 0.15 of each
    parameter's range in the box coordinates, clamped to the box)."""
    rng = np.random.default_rng(seed + 1)
    return [z0] + [
        np.clip(z0 + rng.normal(0.0, 0.15, size=z0.shape), 0.0, 1.0) for _ in range(int(multistart))
    ]


#: The warm start runs when the selection has at least this many blocks of cells ...
WARM_MIN_CHUNKS = 8
#: ... on this fraction of them (at least one block; evenly spread cells, see
#: :func:`brdffit.fitting.data.select`).
WARM_FRACTION = 1 / 16
#: The start scan (:func:`_scan`) solves each candidate on this fraction of the blocks (at
#: least one), to the loose tolerance ``SCAN_FTOL``.
SCAN_FRACTION = 1 / 32
SCAN_FTOL = 1e-4
#: Shifts of the log-scaled parameters (the lobe widths), in box units, of the scan's
#: candidate starts: a box unit is the whole log range (``α ∈ [10⁻³, 1]``: 0.15 is a factor
#: 2.8, 0.3 a factor 8).
SCAN_SHIFTS = (-0.3, -0.15, 0.15, 0.3)


def _call(problem, solver, z0, data, floor, max_steps, active, second=None):
    if second is None:
        second = np.zeros((len(z0), len(z0)))
    args = (problem, solver, jnp.asarray(z0), data, floor, max_steps, jnp.int32(active),
            jnp.asarray(second, jnp.result_type(float)))
    _PROGRESS["floor"] = float(floor)
    out = jax.tree.map(np.asarray, _jitted_solve()(*args))
    cost = float(out["cost"])
    ok = (int(out["code"]) == 0 and not np.any(np.isnan(out["u"])) and np.isfinite(cost)
          and float(out["omega"]) <= float(solver.ftol))
    return out, (not ok, cost if np.isfinite(cost) else np.inf)


def _candidates(problem, z0):
    """``z0`` and copies with every free log-scaled parameter (a lobe width) shifted by each of
    ``SCAN_SHIFTS`` (clamped to the box); only ``z0`` if the model has none free."""
    log = np.asarray(problem.log, bool)
    if not np.any(log):
        return [z0]
    return [z0] + [np.where(log, np.clip(z0 + d, 0.0, 1.0), z0) for d in SCAN_SHIFTS]


def _scan(problem, solver, z0, data, floor, max_steps, active):
    """The best of several starts (:func:`_candidates`), each solved on the first ``active``
    blocks (evenly spread cells) to a loose tolerance: a table that no analytic model fits
    exactly can have several minima (a narrow lobe on the peak, a wide one on the glossy tail),
    and the data-driven start may sit in the basin of the worse one. Costs are compared on the
    same cells. Returns the best candidate's end point."""
    loose = with_ftol(solver, SCAN_FTOL)
    part = floor * active / problem.chunks
    best = (np.inf, z0)
    cands = _candidates(problem, z0)
    for k, z in enumerate(cands):
        with _stage("scan"):
            out, _ = _call(problem, loose, z, data, part, max_steps, active)
        cost = float(out["cost"])
        _emit("scan", candidate=k, of=len(cands), cost=cost, steps=int(out["steps"]))
        if np.isfinite(cost) and np.all(np.isfinite(out["u"])) and cost < best[0]:
            best = (cost, out["u"])
    return best[1]


class _stage:
    """Marks the progress events of a partial solve (``"warm"``, ``"scan"``) while it runs."""

    def __init__(self, name):
        self.name = name

    def __enter__(self):
        _PROGRESS["stage"] = self.name

    def __exit__(self, *exc):
        _PROGRESS["stage"] = None


def _second_order(problem, z, data, target):
    """The second-order term at ``z`` (:func:`_jitted_second`) scaled to ``target`` blocks (the
    sum grows with the number of cells); zeros if it is not finite."""
    s = np.asarray(_jitted_second(problem, jnp.asarray(z), data))
    n = data.wi.shape[0] // problem.chunks
    scale = target * n / len(range(0, n, SECOND_STRIDE))
    return s * scale if np.all(np.isfinite(s)) else np.zeros_like(s)


def _solve_one(problem, solver, z0, data, floor, max_steps, k, scan=True):
    """One start through the stages: the start scan on ``SCAN_FRACTION`` of the blocks, the
    warm start on ``WARM_FRACTION`` (large selections only), then the whole selection.

    Each stage begins where the previous one ended, with the trust region it ended with and,
    after the first, Newton's quadratic model: ``JᵀJ`` plus the second-order term measured at
    the previous stage's end point on its cells (:func:`_second_order`). On a real material
    Gauss–Newton alone converges linearly (cost decrements falling by ~0.4 per pass on a
    metallic paint: 20 passes to ``ftol``); with the term the last stage needs two or three.
    The warm stage's far-from-optimum steps cost a fraction of a full pass each.
    """
    _PROGRESS["start"] = k
    chunks = problem.chunks
    stages = []
    if scan and len(_candidates(problem, z0)) > 1:
        stages.append(("scan", max(1, round(chunks * SCAN_FRACTION))))
    if chunks >= WARM_MIN_CHUNKS:
        stages.append(("warm", max(1, round(chunks * WARM_FRACTION))))
    stages.append(("full", chunks))
    second, prev = None, None
    for name, active in stages:
        if prev is not None:
            second = _second_order(problem, z0, data, active)
        if name == "scan":
            z0 = _scan(problem, solver, z0, data, floor, max_steps, active)
        elif name == "warm":
            with _stage("warm"):
                out, _ = _call(problem, solver, z0, data, floor * active / chunks, max_steps,
                               active, second)
            _emit("warm-done", blocks=active, of=chunks, steps=int(out["steps"]))
            if np.all(np.isfinite(out["u"])) and np.isfinite(float(out["cost"])):
                z0, solver = out["u"], with_initial_step(solver, float(out["step_size"]))
        else:
            return _call(problem, solver, z0, data, floor, max_steps, active, second)
        prev = active


def _run_starts(problem, solver, starts, data, max_steps, scan=True):
    """Solve from every start; return the raw output of the best and the cost of each start."""
    floor = _jitted_floor(problem, data, COST_NOISE[problem.compute_dtype])
    best, costs = None, []
    for k, z0 in enumerate(starts):
        _emit("start", start=k, of=len(starts))
        out, key = _solve_one(problem, solver, z0, data, floor, max_steps, k, scan)
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
    ftol: float | None = None,
    scan: bool = True,
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
        max_steps: the step limit; reaching it is a failure (``success=False``), never the
            normal way out.
        rtol, atol: optimistix's Cauchy test on the accepted step (defaults 1e-14 in float64,
            1e-6 in float32: near rounding, so that it ends only a solve that no longer moves,
            reported as stalled unless the optimality test holds too).
        ftol: the optimality test: converged when the bounded Gauss–Newton step from the end
            point would lower the cost by less than ``ftol`` times the cost (default 1e-9 in
            float64, 1e-6 in float32); see :func:`brdffit.fitting.solvers.optimality`.
        scan: before the warm start, solve a few candidate starts with shifted lobe widths on a
            small evenly spread subset of the cells and keep the best (:func:`_scan`);
            ``False`` starts from the data-driven (or given) start alone.
        throw: raise :class:`~brdffit.errors.FitError` when the solver does not converge;
            with ``False`` the result carries ``success=False`` and the solver's message.
        progress: ``callback(event, info)`` with events ``setup``, ``start``, ``scan-step`` and
            ``scan`` (one per candidate of the start scan), ``warm-step`` and ``warm-done``
            (large tables: the warm start on a subset of the blocks), ``step`` (the whole
            selection), ``start-done``, ``done``. Step events carry the cost of the cells of
            their stage.
        precision: ``"float64"`` or ``"float32"`` model evaluation (products are accumulated in
            float64 either way when x64 is enabled). Defaults to float64 when x64 is enabled.
        covariance: ``"sandwich"`` (default, robust to heteroscedastic residuals) or ``"gn"``
            (classical ``s² (JᵀJ)⁻¹``); see :mod:`brdffit.fitting.statistics`.
    """
    from ..config import check_fit_options

    check_fit_options(dict(rtol=rtol, atol=atol, ftol=ftol, max_steps=max_steps,
                           multistart=multistart, seed=seed, subsample=subsample, cutoff=cutoff))
    if covariance not in ("sandwich", "gn"):
        raise UnknownNameError("covariance", str(covariance), ["sandwich", "gn"])
    if precision not in (None, "float32", "float64"):
        raise UnknownNameError("precision", str(precision), ["float32", "float64"])
    t0 = time.perf_counter()
    model, loss_obj = get_model(model), get_loss(loss)
    dtype = precision or _default_dtype()
    rtol, atol, ftol = _tolerances(rtol, atol, ftol, dtype)
    opt = make_solver(solver, rtol, atol, _verbose_hook if progress else None, COST_NOISE[dtype], ftol)
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
    z0 = to_box(x_start[free], slo[free], shi[free], log[free])
    _PROGRESS["fn"] = progress
    try:
        _emit("setup", n_cells=sel.n_used, n_free=len(free), model=model.name)
        t1 = time.perf_counter()
        out, costs = _run_starts(
            problem, opt, _starts(z0, multistart, seed), sel.data, int(max_steps), bool(scan)
        )
        t2 = time.perf_counter()
    finally:
        _PROGRESS["fn"] = None
    from .outcome import make_result

    return make_result(
        model=model, problem=problem, sel=sel, out=out, u0=z0, costs=costs,
        x_start=x_start, fixed_idx=fixed_idx, loss=loss_obj, solver=solver_label(solver),
        throw=throw, name=samples.name, times=(t0, t1, t2), cov_kind=covariance,
        bounds=(lo, hi), ftol=ftol,
        emit=lambda **kw: progress and progress("done", kw),
    )
