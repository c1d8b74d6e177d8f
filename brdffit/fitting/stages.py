"""The stages of one start, and the best of several starts.

Each start runs through up to three stages, each beginning where the previous one ended:

1. **scan** (``scan=True``, models with a free lobe width): the start and copies with the lobe
   widths divided and multiplied by ``SCAN_FACTOR`` (8), each solved to the
   loose ``SCAN_FTOL`` on the first blocks holding ``SCAN_CELLS`` cells; the lowest cost goes
   on (a real table can have several minima: a narrow lobe on the peak, a wide one on the
   glossy tail). A model that refines a simpler one (``Model.refines``) scans the starts its
   map gives instead, where it gives more than one (:attr:`Run.choices`): where the new lobe
   goes is the choice there, and the simpler fit has already placed the others;
2. **warm** (selections of at least ``WARM_MIN_CHUNKS`` blocks): the optimum on
   ``WARM_FRACTION`` of the blocks, a fraction of a full pass per step;
3. **full**: the whole selection, to the optimality test (:class:`~.bounded.Optimality`).

After the first stage the solver's quadratic model is Newton's, ``JᵀJ`` plus the second-order
term (:func:`.solve.second_order`), alternating with Gauss–Newton's model every
``ROUND_STEPS`` steps while the solve has not converged (:meth:`Run.solve`): on real materials
the residual at the optimum is mostly model error and Gauss–Newton alone converges only
linearly. Each stage, and each round, starts with the trust region the previous one ended with
(except after a round on the other model that accepted no step: :meth:`Run.solve`). The blocks
are interleaved (:func:`.data.select`), so every leading subset is an even sample of the
table. How the stages fit into a fit: ``docs/design/fitting.md`` ("The fit path, module by
module").
"""

from __future__ import annotations

import dataclasses
import threading

import equinox as eqx
import numpy as np

from .data import FitData
from .events import Events
from .parameters import flat_scanned
from .problem import Problem
from .solve import Solved, compile_second_ahead, cost_floor, second_order, solve
from .bounded import with_ftol, with_initial_step

#: The warm start runs when the selection has at least this many blocks of cells ...
WARM_MIN_CHUNKS = 8
#: ... on this fraction of them (at least one block; evenly spread cells, see
#: :func:`brdffit.fitting.data.select`).
WARM_FRACTION = 1 / 16
#: The start scan solves each candidate on the first blocks holding at least this many cells
#: (an evenly spread subset; all of a smaller selection), to the loose tolerance ``SCAN_FTOL``.
SCAN_CELLS = 8192
SCAN_FTOL = 1e-4
#: The scan's candidate starts divide and multiply every log-scaled parameter (the lobe
#: widths) by this factor: 0.3 of the box for ``α ∈ [10⁻³, 1]``, 0.53 for Disney's
#: ``roughness ∈ [0.02, 1]`` (a fixed shift in box units would be a factor 3.2 there, too
#: little to leave the basin of a start read off a sharp peak).
SCAN_FACTOR = 8.0
#: Solves run in rounds of at most this many steps (:meth:`Run.solve`).
ROUND_STEPS = 10
#: A solve ends, converged, after this many rounds in a row that ran out of steps and left the
#: fit where it was (:func:`still`); with Newton's model, one round on each quadratic model.
STILL_ROUNDS = 2
#: The stillness test allows the cost to fall by this many ``ftol`` of itself per step: 1e-8
#: at the default ``ftol``, the default ``ftol`` of ``scipy.optimize.least_squares``, which
#: stops on a single step that lowers the cost by less (here: every step of ``STILL_ROUNDS``
#: rounds in a row, on average).
STILL_RATE = 10.0


def still(z0, cost0: float, out: Solved, floor: float, ftol: float) -> bool:
    r"""Whether a round of ``n`` steps from ``z0`` (cost ``cost0``) to ``out`` left the fit
    where it was, in the units of the data: with ``F`` the end point's cost plus the cost
    floor, the cost moved by at most ``STILL_RATE · ftol`` of itself per step, and the
    predictions by at most ``ftol · F``,

    .. math:: |F_0 - F| \le n\,\mathrm{STILL\_RATE}\;\mathrm{ftol}\,F, \qquad
              \tfrac12\,\Delta z^\top J^\top J\,\Delta z \le \mathrm{ftol}\,F,

    with ``½ ΔzᵀJᵀJΔz ≈ ½ ‖ρ̂(z) − ρ̂(z₀)‖²`` in the residual's units (``JᵀJ`` at the end
    point): the test of a relative cost change and of a step in the units of the data. Over a
    round, not one step: a single short step of a shrinking trust region moves nothing and
    proves nothing."""
    dz = np.asarray(out.z, float) - np.asarray(z0, float)
    cost = float(out.cost) + floor
    moved = 0.5 * dz @ np.asarray(out.jtj, float) @ dz
    fell = abs(cost0 + floor - cost)
    return bool(fell <= int(out.steps) * STILL_RATE * ftol * cost and moved <= ftol * cost)


def starts(z0: np.ndarray, multistart: int, seed: int) -> list[np.ndarray]:
    """The default start, then ``multistart`` perturbed copies (normal steps of 0.15 of each
    parameter's range in the box coordinates, clamped to the box)."""
    rng = np.random.default_rng(seed + 1)
    return [z0] + [
        np.clip(z0 + rng.normal(0.0, 0.15, size=z0.shape), 0.0, 1.0) for _ in range(int(multistart))
    ]


def scanned(problem: Problem) -> np.ndarray:
    """Per free scalar of ``problem``, whether the scan shifts it (a lobe width,
    :attr:`~brdffit.models.registry.Param.scanned`; always log-scaled)."""
    return flat_scanned(problem.model)[list(problem.free)]


def candidates(problem: Problem, z0: np.ndarray) -> list[np.ndarray]:
    """``z0`` and two copies with every free lobe width (:func:`scanned`) divided and
    multiplied by ``SCAN_FACTOR`` (a shift of ``log(SCAN_FACTOR)`` over the parameter's log
    range in box units, clamped to the box); only ``z0`` if the model has none free."""
    width = scanned(problem)
    if not np.any(width):
        return [z0]
    span = np.asarray(problem.shi, float) - np.asarray(problem.slo, float)
    shift = np.where(width, np.log(SCAN_FACTOR) / np.where(width, span, 1.0), 0.0)
    return [z0] + [np.clip(z0 + sign * shift, 0.0, 1.0) for sign in (-1.0, 1.0)]


def plan(chunks: int, block_cells: int, scan: bool) -> list[tuple[str, int]]:
    """The stages of a start as ``(name, blocks)``, for a selection of ``chunks`` blocks of
    ``block_cells`` cells each."""
    stages = []
    if scan:
        stages.append(("scan", min(chunks, -(-SCAN_CELLS // block_cells))))
    if chunks >= WARM_MIN_CHUNKS:
        stages.append(("warm", max(1, round(chunks * WARM_FRACTION))))
    stages.append(("full", chunks))
    return stages


def start_plan(problem: Problem, data: FitData, scan: bool,
               choices: bool = False) -> list[tuple[str, int]]:
    """The stages of a start of a fit (:func:`plan`): the scan where the start has
    :attr:`Run.choices` to pick among, or where ``scan`` is asked for and the model has a lobe
    width to scan (:func:`scanned`)."""
    chunks = problem.chunks
    return plan(chunks, data.wi.shape[0] // chunks,
                choices or (scan and bool(np.any(scanned(problem)))))


@dataclasses.dataclass(frozen=True)
class Run:
    """The parts of one fit that every solve shares: the problem, the cells, their cost floor
    (:func:`.solve.cost_floor`), the step limit, and where progress events go."""

    problem: Problem
    data: FitData
    floor: object
    max_steps: int
    events: Events
    #: the second-order program being compiled ahead (:func:`.solve.compile_second_ahead`),
    #: joined before the first second-order term and when :func:`best_of` ends, also by an
    #: exception: a compile still running when the interpreter shuts down could crash it
    ahead: threading.Thread | None = None
    #: the first start's scan candidates, where the fit gives more than one (the starts a
    #: refined model's ``refines`` maps the simpler fit to), instead of :func:`candidates`;
    #: the first start is the first of them
    choices: tuple = ()

    def wait(self):
        """Wait for the second-order program compiled ahead, if any."""
        if self.ahead is not None:
            self.ahead.join()

    def solve(self, solver, z0, active: int, newton: bool = False) -> Solved:
        """Up to ``max_steps`` solver steps from ``z0`` over the first ``active`` blocks, with
        their share of the cost floor, in rounds of ``ROUND_STEPS`` (the last one shorter).

        A round that runs out of steps hands its end point and trust region to the next. With
        ``newton``, the first round's quadratic model adds the second-order term measured where
        it starts (:func:`.solve.second_order`); after a round that ran out of steps the next
        one uses the other model, Gauss–Newton's or Newton's with the term measured afresh: a
        term measured far from the optimum, or on too few cells, can make a positive definite
        but wrong model whose steps crawl, and Gauss–Newton alone converges only linearly.

        A round that accepted no step (every trial point raised the cost) shrank the trust
        region on its own model's account; the next round, on the other model, starts from the
        region the failed round started with. Otherwise a wrong Newton model leaves
        Gauss–Newton a region shrunk ×0.25 per rejection each time, and the two crawl by turns
        until the step limit. When two rounds in a row accepted no step (both models, from the
        same point), the region the last one shrank is handed on: the fault is then no one
        model's, and starting each round again from the same region repeats the same
        rejections until the step limit, while a region shrinking further reaches steps the
        models predict well. Every round of the default step
        limit has the same length, so one compiled program serves them all.

        The solve also ends, converged, when ``STILL_ROUNDS`` rounds in a row that ran out of
        steps each accepted steps and left the fit where it was (:func:`still`): the quadratic
        models still promise a decrease (``ω > ftol``) that no step they propose finds, and the
        answer no longer changes in the units of the data (a shallow curved valley of a model
        that does not fit the table).
        """
        chunks = self.problem.chunks
        floor = self.floor if active == chunks else self.floor * active / chunks
        self.events.floor = float(floor)
        ftol = float(solver.ftol)
        total, out, model, quiet, cost0, stuck = 0, None, newton, 0, None, 0
        while total < self.max_steps:
            steps = min(ROUND_STEPS, self.max_steps - total)
            if model:
                self.wait()
            second = second_order(self.problem, z0, self.data, active) if model else None
            out = solve(self.problem, solver, z0, self.data, floor, steps, active, second)
            self.events.steps(total, out)
            total += int(out.steps)
            if not (out.ran_out and out.finite):
                break
            moved = not np.array_equal(np.asarray(out.z), np.asarray(z0))
            calm = moved and cost0 is not None and still(z0, cost0, out, float(floor), ftol)
            quiet = quiet + 1 if calm else 0
            if quiet >= STILL_ROUNDS:
                out = eqx.tree_at(lambda s: s.still, out, True)
                break
            if moved:
                cost0 = float(out.cost)
            stuck = 0 if moved else stuck + 1
            if moved or not newton or stuck >= 2:
                z0, solver = out.z, with_initial_step(solver, float(out.step_size))
            model = newton and not model  # a round that ran out: the other model next
        return eqx.tree_at(lambda s: s.steps, out, np.asarray(total))

    def scan(self, solver, cands, active: int) -> np.ndarray:
        """The end point of the best of ``cands`` (the :func:`candidates` of a start, or the
        :attr:`choices`), each solved on the first ``active`` blocks to ``SCAN_FTOL`` (costs
        compared on the same cells); the first candidate if none ends finite."""
        loose = with_ftol(solver, SCAN_FTOL)
        best = (np.inf, cands[0])
        for k, z in enumerate(cands):
            with self.events.in_stage("scan"):
                out = self.solve(loose, z, active)
            cost = float(out.cost)
            self.events.emit("scan", candidate=k, of=len(cands), cost=cost, steps=int(out.steps))
            if out.finite and cost < best[0]:
                best = (cost, out.z)
        return best[1]

    def warm(self, solver, z0, active: int, newton: bool):
        """``(z, solver)``: the end point on the first ``active`` blocks and the solver with
        the trust region it ended with (the start and ``solver`` unchanged if not finite)."""
        with self.events.in_stage("warm"):
            out = self.solve(solver, z0, active, newton)
        self.events.emit("warm-done", blocks=active, of=self.problem.chunks, steps=int(out.steps))
        if out.finite:
            return out.z, with_initial_step(solver, float(out.step_size))
        return z0, solver

    def start(self, solver, z0, k: int, scan: bool = True) -> Solved:
        """Start ``k`` from ``z0`` through its stages (module docstring). With :attr:`choices`,
        the first start's scan picks among them instead of its :func:`candidates`."""
        self.events.start = k
        choose = k == 0 and len(self.choices) > 1
        for i, (name, active) in enumerate(start_plan(self.problem, self.data, scan, choose)):
            newton = i > 0  # Newton's model from the second stage on
            if name == "scan":
                cands = list(self.choices) if choose else candidates(self.problem, z0)
                z0 = self.scan(solver, cands, active)
            elif name == "warm":
                z0, solver = self.warm(solver, z0, active, newton)
            else:
                return self.solve(solver, z0, active, newton)


def best_of(problem: Problem, solver, data: FitData, zs, max_steps: int, scan: bool,
            events: Events, choices=()) -> tuple[Solved, list[float]]:
    """Solve from every start in ``zs``; the best solve (:meth:`Solved.better_than`) and the
    cost of each start. ``choices`` (more than one): the first start scans these instead of
    its :func:`candidates`, whatever ``scan`` says (:attr:`Run.choices`; ``scan`` is off for
    a refined model, whose other lobes its simpler fit has placed)."""
    # every stage after the first uses the second-order program: compile it meanwhile, unless
    # the model builds a table per pass (gtr's numerical Λ): its solve program's compilation
    # keeps both cores busy, and compiling the second-order program beside it made a cold fit
    # no faster, for more memory
    staged = len(start_plan(problem, data, scan)) > 1
    ahead = (compile_second_ahead(problem, zs[0], data)
             if staged and problem.model.per_pass is None else None)
    run = Run(problem, data, cost_floor(problem, data), max_steps, events, ahead, tuple(choices))
    ftol = float(solver.ftol)
    best, costs = None, []
    try:
        for k, z0 in enumerate(zs):
            events.emit("start", start=k, of=len(zs))
            out = run.start(solver, z0, k, scan)
            costs.append(out.ranked_cost)
            events.emit("start-done", start=k, cost=costs[-1], steps=int(out.steps),
                        success=out.converged(ftol))
            if best is None or out.better_than(best, ftol):
                best = out
    finally:
        run.wait()  # no thread outlives the fit
    return best, costs
