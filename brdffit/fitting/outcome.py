"""From the best solve to a :class:`FitResult`: the verdict, the end point on its bounds, the
covariance in physical units, and the figures of the fit.

The verdict is a success only where the data determine the model (:func:`data_verdict`,
:func:`data_determined`, :func:`_if_identified`): a fit on data that carry no information
about a BRDF's shape (every cell the same value per channel: all zeros, a constant), on fewer
distinct directions than the free scalars need, on data beyond any physical reflectance
(:data:`IMPLAUSIBLE`), or where no free scalar off its bounds is identified
(:func:`.statistics.schur_deficient`), ends with ``success=False`` and the status
``degenerate`` or ``implausible``, whatever the solver said. A free scalar the data do not
identify gets no standard error (``NaN``; ``null`` in JSON) and is listed in
``FitResult.not_identified``; the fit can still succeed (Disney's sheen on a metal).

Every result also carries the plausibility verdict on the fitted material
(:mod:`brdffit.fitting.plausibility`), beside and independent of ``success``.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import optimistix as optx

from ..errors import FitError
from .data import Selection
from .options import Settings
from .parameters import Scalars
from .plausibility import assess, verdict_record
from .problem import Problem
from .result import FitResult
from .solve import Solved
from .bounded import solver_label
from .stages import STILL_RATE
from .statistics import identified_covariance
from .transforms import at_bound

#: The names of ``optimistix.RESULTS`` (its documented entries), looked up by attribute.
RESULT_NAMES = ("successful", "max_steps_reached", "singular", "breakdown", "stagnation",
                "conlim", "nonfinite_input", "nonlinear_max_steps_reached",
                "nonlinear_divergence", "nonfinite")
MAX_STEPS_HINT = " Increase `max_steps` or start elsewhere."
#: The statuses that say the data cannot give a fit (not that the solver failed): the data
#: determine nothing (``degenerate``) or are beyond any physical reflectance (``implausible``).
DATA_VERDICTS = ("degenerate", "implausible")

#: Data whose ``ρ cos θo`` (largest channel) exceeds this in more than half of the cells used are
#: beyond any physical reflectance: ``∫ f_r cos θo dωo ≤ 1`` confines values above ``L`` to a
#: solid angle below ``1/L`` sr per incident direction, so half of the measurements would lie
#: within 1e-6 sr (a cone of 0.03°) of one direction. No registered model comes near (the
#: sharpest lobe its bounds allow peaks below 1e6 at normal incidence); such data are in the
#: wrong units or scaled.
IMPLAUSIBLE = 1e6


@dataclasses.dataclass(frozen=True)
class Prepared:
    """A fit as it was prepared for the solver: what its result reports besides the solve."""

    model: object
    settings: Settings
    scalars: Scalars
    selection: Selection
    problem: Problem
    x_start: np.ndarray  # the starting point, flat, physical units
    z0: np.ndarray  # its box coordinates (free scalars)
    name: str  # the table's
    notes: tuple[str, ...] = ()  # what the preparation decided for the user, for the message
    held: dict = dataclasses.field(default_factory=dict)  # parameters it held for the user
    features: object = None  # what the start read off the data (start.Features)
    albedo: tuple | None = None  # (ρ_max, θi) at the end point, where the fit computed it


@dataclasses.dataclass(frozen=True)
class Verdict:
    """``success`` and optimistix's vocabulary for it: ``status`` (a result name, or
    ``nonfinite``, ``stalled``, ``still``, ``degenerate``, ``implausible``) and a ``message``
    saying what to do."""

    success: bool
    status: str
    message: str


def result_name(result) -> str:
    """The name of an ``optimistix.RESULTS`` item (``"unknown"`` for one not documented)."""
    for name in RESULT_NAMES:
        item = getattr(optx.RESULTS, name, None)
        if item is not None and bool(result == item):
            return name
    return "unknown"


def verdict(best: Solved, ftol: float, lost=None) -> Verdict:
    """Success only at a finite point where the cost depends on some free parameter, and
    either optimistix succeeded and the optimality test ``ω ≤ ftol`` holds, or the stillness
    test ended the solve (status ``still``: :func:`.stages.still`, with ``ω`` in the
    message).

    ``lost`` (a boolean mask over the free scalars: those the data do not identify,
    :func:`.statistics.identified_covariance`) restricts the optimality test to the others
    when it fails over all of them: along a direction the cost barely depends on, the model's
    step ``g²/(2 JᵀJ)`` divides two vanishing numbers, and near a cost of zero (an exact fit)
    it is a sizeable fraction of nothing (``ggx-aniso`` on an isotropic lobe, whose
    ``frame_angle`` does nothing). Such a scalar is reported as not identified and gets no
    standard error; the fit is optimal in the scalars the data determine."""
    if not best.finite:
        return Verdict(False, "nonfinite", (
            "the solver produced non-finite parameters or cost; the result reports the starting "
            "point. Try another `init`, `multistart`, or the `log` loss."
        ))
    if best.still:
        return _if_identified(best, Verdict(True, "still", (
            f"converged by the stillness test: in each of the last two rounds of steps the "
            f"cost fell by less than {STILL_RATE * ftol:g} of itself per step and the "
            f"predictions moved by less than ftol = {ftol:g} of the cost, while the local "
            f"quadratic model still promised a fraction {float(best.omega):.2g}"
        )))
    status = result_name(best.result)
    if not best.successful:
        message = optx.RESULTS[best.result]
        if status in ("nonlinear_max_steps_reached", "max_steps_reached"):
            message += MAX_STEPS_HINT
        return Verdict(False, status, message)
    omega = float(best.omega)
    if not omega <= ftol and lost is not None and np.any(lost) and not np.all(lost):
        held = best.omega_over(~np.asarray(lost, bool))
        if held <= ftol:
            return _if_identified(best, Verdict(True, status, (
                f"the optimality test held over the parameters the data identify (ω = "
                f"{held:.2g} ≤ ftol = {ftol:g}; {omega:.2g} with those they do not)")))
    if not omega <= ftol:
        return Verdict(False, "stalled", (
            f"the solver stopped moving before the optimality test held (the Gauss-Newton step "
            f"would still lower the cost by a fraction {omega:.2g} > ftol = {ftol:g}); try "
            f"another `init`, `multistart`, or a looser `ftol`."
        ))
    return _if_identified(best, Verdict(True, status, ""))


def _if_identified(best: Solved, success: Verdict) -> Verdict:
    """``success``, unless the cost depends on no free parameter at the end point."""
    if not np.any(np.diagonal(np.asarray(best.jtj, float)) > 0):
        return Verdict(False, "degenerate", (
            "the cost does not depend on any free parameter at the end point (JᵀJ is zero): "
            "the data determine nothing here; check the data's scale and the `loss`."
        ))
    return success


def distinct_directions(wi, wo, good, limit: int) -> int:
    """The number of distinct ``(wi, wo)`` rows where ``good``, counted up to ``limit``
    (``limit`` when there are at least that many)."""
    head = _distinct(wi[:4096], wo[:4096], good[:4096], limit)
    if head == limit:  # the usual case: a glance at the first rows suffices
        return limit
    return _distinct(wi, wo, good, limit)


def _distinct(wi, wo, good, limit: int) -> int:
    rows = np.concatenate([np.asarray(wi, float), np.asarray(wo, float)], axis=1)[good]
    for n in range(limit):
        if len(rows) == 0:
            return n
        rows = rows[np.any(rows != rows[0], axis=1)]
    return limit


def data_verdict(selection: Selection, n_free: int) -> Verdict | None:
    """A failed verdict for data that cannot determine the model, else ``None``:

    * ``degenerate``: fewer distinct directions ``(wi, wo)`` than ``n_free / 3`` (three values
      a direction): repeated measurements of a handful of cells hold fewer numbers than the
      free scalars to determine;
    * ``implausible``: ``ρ cos θo`` above :data:`IMPLAUSIBLE` in more than half of the cells
      (the median of an evenly spread subset of at most 65,536 cells);
    * ``degenerate``: every channel has one value in all the cells used (all zeros, a
      constant): no angular information, so no lobe of any model is determined.
    """
    wi, wo, rgb, good = selection.host
    good = np.asarray(good, bool)
    n = int(np.count_nonzero(good))
    if n == 0:
        return None
    need = -(-n_free // 3)
    distinct = distinct_directions(wi, wo, good, need)
    if distinct < need:
        return Verdict(False, "degenerate", (
            f"the {n} cells used hold only {distinct} distinct direction pairs, "
            f"{3 * distinct} values for {n_free} free parameters: the data cannot determine "
            f"the model; measure more directions or fix parameters."
        ))
    some = np.flatnonzero(good)[:: max(1, n // 65536)]
    rgb_some = np.asarray(rgb[some], float)
    projected = np.max(rgb_some, axis=1) * np.asarray(wo[some], float)[:, 2]
    median = float(np.median(projected))
    if median > IMPLAUSIBLE:
        return Verdict(False, "implausible", (
            f"the data are beyond any physical reflectance: ρ·cosθo is {median:.3g} or more in "
            f"half of the {n} cells used (a BRDF times cos θo integrates to at most 1 over "
            f"the hemisphere; above {IMPLAUSIBLE:g} half the cells would lie within 1e-6 sr); "
            f"check the data's units and scale."
        ))
    if _flat(rgb_some, np.ones(len(some), bool)) and _flat(np.asarray(rgb, float), good):
        what = "zero" if not np.any(rgb_some) else "the same value per channel"
        return Verdict(False, "degenerate", (
            f"the data are {what} in all {n} cells used: they carry no angular "
            f"information and determine no lobe of a BRDF model; check the input."
        ))
    return None


def _flat(rgb, good) -> bool:
    """Every channel of ``rgb`` has one value (to 1e-12 of the largest) where ``good``."""
    hi = np.max(rgb, axis=0, where=good[:, None], initial=-np.inf)
    lo = np.min(rgb, axis=0, where=good[:, None], initial=np.inf)
    return bool(np.all(hi - lo <= 1e-12 * np.max(np.abs([hi, lo]))))


def data_determined(v: Verdict, bound: np.ndarray, lost: np.ndarray) -> Verdict:
    """``v``, unless it is a success at which some free scalar is not identified and every
    other is on a bound: the data determine nothing inside the bounds (``degenerate``). All on
    bounds, all identified, is an answer (a metal's diffuse albedo on 0, the rest fixed)."""
    if v.success and lost.any() and np.all((bound != 0) | lost):
        return Verdict(False, "degenerate", (
            "every free parameter ended on a bound or is not identified by the data: the data "
            "determine none of them; check the data's scale and the `loss`."
        ))
    return v


def _by_param(model, flat):
    out, i = {}, 0
    for p in model.params:
        v = flat[i : i + p.size]
        out[p.name] = float(v[0]) if p.shape == () else [float(a) for a in v]
        i += p.size
    return out


def end_point(prep: Prepared, best: Solved):
    """``(x, bound)``: the flat end point in physical units, scalars on a bound put exactly on
    it (the starting point where the solve was not finite), and the free scalars' bound flags."""
    z = np.asarray(best.z, float) if best.finite else np.asarray(prep.z0, float)
    bound = at_bound(z)
    free = list(prep.scalars.free)
    x = prep.problem.flat_host(z)
    x[free] = np.where(bound < 0, prep.scalars.lo[free],
                       np.where(bound > 0, prep.scalars.hi[free], x[free]))
    return x, bound


def assemble(prep: Prepared, best: Solved, costs, times, events, throw: bool) -> FitResult:
    """The :class:`FitResult` of the best solve; sends the ``done`` event. On failure with
    ``throw``, raises :class:`FitError` carrying that result (``err.result``) instead. ``costs``: the cost of each start; ``times``:
    ``perf_counter`` readings at the start, before the solves and after them."""
    model, s, free = prep.model, prep.settings, list(prep.scalars.free)
    x, bound = end_point(prep, best)
    cost = float(best.cost) if best.finite else float("nan")
    cov_free, regular, lost = identified_covariance(
        best.jtj, best.meat, best.dxdz, 2 * cost, float(best.m), bound == 0, s.covariance)
    if not best.finite:
        lost = np.zeros_like(lost)
    v = verdict(best, s.ftol, lost if best.finite else None)
    if v.status != "degenerate":  # a cost that depends on nothing says it first
        v = data_verdict(prep.selection, len(free)) or data_determined(v, bound, lost)
    names = model.flat_names()
    message = v.message
    if best.finite and lost.any() and v.success:
        message = "; ".join(filter(None, [message, (
            "not identified by the data (no standard error): "
            + ", ".join(names[free[i]] for i in np.flatnonzero(lost)))]))
    elif best.finite and not regular and not message:
        message = "JᵀJ is singular at the optimum: some parameters are not identified by the data"
    message = "; ".join(filter(None, [message, *prep.notes]))
    cov = np.zeros((len(x), len(x)))
    cov[np.ix_(free, free)] = cov_free
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    se[[f for f, b, n in zip(free, bound, lost) if b != 0 or n]] = np.nan
    t0, t1, t2 = times
    t3 = time.perf_counter()
    result = FitResult(
        model_name=model.name, params=_by_param(model, x), stderr=_by_param(model, se),
        names=names, x=x, cov=cov, free=[names[i] for i in free],
        fixed=[names[i] for i in prep.scalars.fixed],
        at_bound={names[f]: ("lower" if b < 0 else "upper") for f, b in zip(free, bound) if b},
        cost=cost, metrics={k: float(val) for k, val in best.metrics.items()},
        success=v.success, status=v.status, message=message, steps=int(best.steps),
        starts=[float(c) for c in costs], loss=s.loss.label, solver=solver_label(s.solver),
        n_cells=prep.selection.n_used, n_total=prep.selection.n_total,
        init=_by_param(model, prep.x_start), wall_time=t3 - t0,
        timings={"prepare": t1 - t0, "solve": t2 - t1, "finish": t3 - t2},
        table=prep.name, covariance=s.covariance, optimality=float(best.omega),
        not_identified=[names[free[i]] for i in np.flatnonzero(lost) if best.finite],
        total_steps=int(events.solver_steps),
    )
    result.plausibility = verdict_record(assess(model, result.params, result.metrics,
                                                result.loss, prep.albedo))
    if throw and not v.success:
        failed = "did not converge" if v.status not in DATA_VERDICTS else f"is {v.status}"
        raise FitError(f"{model.name} fit of {prep.name or 'table'} {failed}: {v.message} "
                       f"(the result is the error's `.result`; `throw=False` returns it)",
                       result)
    events.emit("done", success=v.success, cost=result.cost)
    return result
