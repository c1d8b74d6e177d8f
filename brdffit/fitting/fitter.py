"""``fit``: least-squares fitting of a registered model to a measured table, with optimistix.

The pipeline: the options, checked (:mod:`~brdffit.fitting.options`) → the cells (:mod:`.data`)
→ the free scalars and their bounds (:mod:`.parameters`) → the starting point (:mod:`.start`, or
the user's) → the problem in box coordinates (:mod:`.problem`, :mod:`.transforms`) → bounded
optimistix solves of the Gauss–Newton normal form (:mod:`.normal_form`, :mod:`.bounded`,
:mod:`.solve`), start by start and stage by stage (:mod:`.stages`) → the verdict, covariance and
metrics (:mod:`.outcome`, :mod:`.statistics`) → :class:`~.result.FitResult`.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..models.frame import FRAME_ANGLE
from ..models.registry import get_model
from .data import check_enough, select
from .events import Events
from .options import Settings, fit_options
from .outcome import Prepared, assemble, end_point
from .parameters import assign, free_scalars
from .problem import Problem
from .result import FitResult
from .bounded import COST_NOISE, make_solver
from .constraints import LIMIT, PENALTIES, TOLERANCE, energy_excess, limited
from .stages import best_of, starts
from .start import measure, start_point


def fit(table, model, options=None, *, progress=None, throw: bool = True, **kwargs) -> FitResult:
    """Fit ``model`` to ``table`` by nonlinear least squares; returns a :class:`FitResult`.

    Args:
        table: anything with ``.to_samples()`` giving a ``data_formats.SampleSet`` (a
            ``MERLTable``, a ``SampleSet``).
        model: a registry name (``"ggx"``) or a :class:`~brdffit.models.Model`.
        options: a :class:`~brdffit.config.FitOptions` (a preset, say) or a mapping of option
            names; the keyword options override it, option by option. A
            :class:`~brdffit.fitting.options.Settings` (options checked and resolved by
            :meth:`Settings.of`) is taken as it is.
        progress: ``callback(event, info)`` with events ``setup``, ``start``, ``scan-step`` and
            ``scan`` (one per candidate of the start scan), ``warm-step`` and ``warm-done``
            (large tables: the warm start on a subset of the blocks), ``step`` (the whole
            selection), ``start-done``, ``done``; a model that refines a simpler one
            (``Model.refines``) first sends the simpler fit's events prefixed ``base-`` and a
            ``base`` event with its ``model``, ``cost``, ``steps`` and ``success``. Step events
            carry the step's number in its stage and the cost it left the fit at (of the cells
            of its stage); they are sent as each round of at most ``ROUND_STEPS`` solver steps
            returns (:mod:`.events`: the fit runs the same compiled program with or without a
            callback). Each fit's events go to its own callback, also with fits running in
            several threads at once.
        throw: raise :class:`~brdffit.errors.FitError` when the solver does not converge or
            the data do not determine the model (status ``degenerate`` or ``implausible``:
            :mod:`.outcome`); the error carries the result (``err.result``). With ``False``
            that result is returned: ``success=False``, the status and a message saying what
            to do.
        **kwargs: the options, by name: the fields of :class:`~brdffit.config.FitOptions`
            but ``model``, each described with its default in
            :class:`~brdffit.fitting.options.Settings`. All are checked before the table is
            read.
    """
    if isinstance(options, Settings) and not kwargs:
        settings = options  # checked and resolved already (brdffit.fit)
    else:
        settings = Settings.of(fit_options(options, **kwargs))
    t0 = time.perf_counter()
    model = get_model(model)
    events = Events(progress)
    solver = make_solver(settings.solver, settings.rtol, settings.atol, None,
                         COST_NOISE[settings.precision], settings.ftol)
    prep = prepare(table, model, settings)
    events.emit("setup", n_cells=prep.selection.n_used, n_free=len(prep.scalars.free),
                model=model.name)
    t1 = time.perf_counter()
    first, scan = [], settings.scan
    if model.refines is not None and settings.init is None:
        (prep, first), scan = refined(prep, solver, events), False
    zs = starts(prep.z0, settings.multistart, settings.seed)
    if first and not settings.scan:  # no scan: every start of the simpler fit to the end
        zs, first = first + zs[1:], []
    best, costs = best_of(prep.problem, solver, prep.selection.data, zs, settings.max_steps,
                          scan, events, first)
    prep, best, costs = reread(prep, best, costs, solver, events)
    prep, best = energy_limited(prep, best, solver, events)
    t2 = time.perf_counter()
    return assemble(prep, best, costs, (t0, t1, t2), events, throw)


def refined(prep: Prepared, solver, events: Events) -> tuple[Prepared, list[np.ndarray]]:
    """``(prep, zs)`` for a model that refines a simpler one (``Model.refines``): the simpler
    model is fitted first on the same cells, with the same options except the user's
    ``fixed`` and ``bounds`` (they name this model's parameters), from its own data-driven start
    and scan; ``zs`` are the box coordinates of the starts ``refines`` maps its optimum to
    (each clamped to this fit's bounds; fixed scalars keep their values; the first start's
    scan picks among them, :func:`.stages.best_of`, or with the scan off each is fitted to the
    end), and ``prep`` takes the first as its starting point. The simpler fit's events carry
    the prefix ``base-``; a ``base`` event then reports its ``model``, ``cost``, ``steps`` and
    ``success``."""
    name, to_starts = prep.model.refines
    simple = get_model(name)
    settings = dataclasses.replace(prep.settings, fixed=None, bounds=None)
    sub = prepare_on(prep.selection, simple, settings, prep.name)
    with events.nested("base-"):
        out, _ = best_of(sub.problem, solver, sub.selection.data, [sub.z0], settings.max_steps,
                         settings.scan, events)
    events.emit("base", model=simple.name, cost=float(out.cost), steps=int(out.steps),
                success=out.converged(float(solver.ftol)))
    x_simple, _ = end_point(sub, out)
    free, lo, hi = list(prep.scalars.free), prep.scalars.lo, prep.scalars.hi
    xs = []
    for values in to_starts(simple.unflatten(x_simple)):
        x, given = prep.x_start.copy(), prep.x_start.copy()
        assign(prep.model, values, given, f"start from {simple.name} of")
        x[free] = np.clip(given[free], lo[free], hi[free])
        xs.append(x)
    prep = dataclasses.replace(prep, x_start=xs[0], z0=prep.scalars.to_box(xs[0]))
    return prep, [prep.scalars.to_box(x) for x in xs]


def reread(prep: Prepared, best, costs, solver, events: Events):
    """``(prep, best, costs)`` of the material's reading (``Model.reading``, held at its first
    value by :func:`prepare_on`): where the first fit's parameters say the material is the other
    reading, the fit is made again on the same cells with the parameter held at the other
    value, and that fit is the result; the message says which reading and why. Unchanged
    where the model has no reading or the user fixed or started its parameter."""
    reading = prep.model.reading
    if reading is None or reading.param not in prep.held:
        return prep, best, costs
    x, _ = end_point(prep, best)
    why = reading.decide(prep.model.unflatten(x), prep.features)
    name = reading.param
    if not why:
        note = (f"{name} held at {reading.first:g}, {reading.names[0]} (start {name} to fit a "
                f"blend)")
        return dataclasses.replace(prep, notes=prep.notes + (note,)), best, costs
    holds = {k: v for k, v in reading.other_holds.items() if k not in _given(prep.settings)}
    settings = dataclasses.replace(prep.settings, fixed={**(prep.settings.fixed or {}),
                                                         name: reading.other, **holds})
    other = prepare_on(prep.selection, prep.model, settings, prep.name)
    zs = starts(other.z0, settings.multistart, settings.seed)
    best, costs = best_of(other.problem, solver, other.selection.data, zs, settings.max_steps,
                          settings.scan, events)
    note = f"{name} held at {reading.other:g}, {reading.names[1]}: {why}"
    return dataclasses.replace(other, notes=other.notes + (note,)), best, costs


def energy_limited(prep: Prepared, best, solver, events: Events):
    """``(prep, best)`` under the energy constraint (:mod:`.constraints`): unchanged where the
    fit's largest directional albedo is at most 1 (or the option ``energy`` is ``"free"``);
    otherwise solved again from its optimum with
    the constraint's penalty attached to the problem, the message saying so."""
    if prep.settings.energy == "free":
        return prep, best
    x, _ = end_point(prep, best)
    rho, theta = energy_excess(prep.model, x)
    if not rho > LIMIT:  # the verdict's energy check reads this albedo instead of its own
        return dataclasses.replace(prep, albedo=(rho, theta)), best
    out = best
    for penalty in PENALTIES:
        problem = limited(prep.problem, float(best.cost), penalty)
        out, _ = best_of(problem, solver, prep.selection.data, [np.asarray(out.z)],
                         prep.settings.max_steps, False, events)
        after = energy_excess(prep.model, end_point(prep, out)[0])
        if after[0] <= LIMIT + TOLERANCE:
            break
    note = (f"energy held: the unconstrained optimum's directional albedo was {rho:.3g} at "
            f"θi = {theta:.0f}°; constrained to at most 1 it is {after[0]:.4f}")
    return dataclasses.replace(prep, problem=problem, notes=prep.notes + (note,),
                               albedo=after), out


def prepare(table, model, settings: Settings) -> Prepared:
    """The cells, the free scalars, the starting point and the problem of a fit."""
    samples = table.to_samples()
    scalars = free_scalars(model, settings.fixed, settings.bounds)  # bad names fail before select
    sel = select(samples, settings.loss, cutoff=settings.cutoff, subsample=settings.subsample,
                 seed=settings.seed, dtype=settings.precision, weighting=settings.weighting)
    return prepare_on(sel, model, settings, samples.name, scalars)


#: The parameter that turns an anisotropic model's tangent (:mod:`brdffit.models.frame`).
FRAME = FRAME_ANGLE.name


def prepare_on(sel, model, settings: Settings, name: str, scalars=None) -> Prepared:
    """:func:`prepare` on cells already selected (``scalars``: :func:`.parameters.free_scalars`
    of ``model`` and ``settings``, if already made).

    Where the cells do not determine the lobe's axes (:attr:`.start.Features.axes`: a MERL
    table, whose half vectors all lie in one plane) and the user neither fixed nor started
    ``frame_angle``, it is held at 0, the tangent on the data's ``x`` (:func:`held_frame`):
    fitted there it would only move the one azimuth such a table samples."""
    wi, wo, rgb, good = sel.host
    features = measure(rgb, wi, wo, good)
    held = {**held_frame(model, settings, features), **held_reading(model, settings)}
    if held:
        settings = dataclasses.replace(settings, fixed={**(settings.fixed or {}), **held})
        scalars = None
    scalars, x0 = scalars or free_scalars(model, settings.fixed, settings.bounds)
    check_enough(sel, len(scalars.free), name)
    x_start = start_point(model, features, scalars, x0, settings.init)
    problem = Problem.build(scalars, settings.loss, x_start, settings.precision, sel.chunks)
    notes = (f"{FRAME} held at 0: the data do not determine the lobe's axes (half vectors in "
             f"one plane, as in an isotropic table)",) if FRAME in held else ()
    return Prepared(model, settings, scalars, sel, problem, x_start, scalars.to_box(x_start),
                    name, notes, held, features)


def _given(settings: Settings) -> set[str]:
    """The parameters the user fixed or started."""
    init = getattr(settings.init, "params", settings.init) or {}
    return set(settings.fixed or {}) | set(init)


def held_reading(model, settings: Settings) -> dict:
    """``{param: first}`` of ``model``'s :class:`~brdffit.models.registry.Reading` unless the
    user fixed or started that parameter (then it is fitted as any other); otherwise empty."""
    reading = model.reading
    if reading is None or reading.param in _given(settings):
        return {}
    return {reading.param: reading.first}


def held_frame(model, settings: Settings, features) -> dict:
    """``{"frame_angle": 0.0}`` where ``model`` turns its tangent, the data do not determine
    the lobe's axes and the user gave the angle neither as a fixed value nor as a start;
    otherwise empty."""
    if FRAME not in model.names or features.axes:
        return {}
    return {} if FRAME in _given(settings) else {FRAME: 0.0}
