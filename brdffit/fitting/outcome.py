"""From the solver's raw output to a :class:`FitResult`: verdict, bounds, covariance, metrics."""

from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..errors import FitError
from .result import FitResult
from .statistics import covariance
from .transforms import at_bound


def _message(code: int, finite: bool, max_steps_hint: str) -> tuple[str, str]:
    if not finite:
        return "nonfinite", (
            "the solver produced non-finite parameters or cost; the result reports the starting "
            "point. Try another `init`, `multistart`, or the `log` loss."
        )
    names = {int(v._value): k for k, v in optx.RESULTS._name_to_item.items()}
    status = names.get(code, str(code))
    text = optx.RESULTS._index_to_message[code] if code else ""
    if status in ("nonlinear_max_steps_reached", "max_steps_reached"):
        text += max_steps_hint
    return status, text


def _by_param(model, flat):
    out, i = {}, 0
    for p in model.params:
        v = flat[i : i + p.size]
        out[p.name] = float(v[0]) if p.shape == () else [float(a) for a in v]
        i += p.size
    return out


def make_result(*, model, problem, sel, out, u0, costs, x_start, fixed_idx, loss, solver, throw,
                name, times, emit, bounds, ftol, cov_kind="sandwich"):
    """Assemble the :class:`FitResult` (raises :class:`FitError` on failure if ``throw``)."""
    u, code = np.asarray(out["u"], float), int(out["code"])
    finite = bool(np.all(np.isfinite(u)) and np.isfinite(out["cost"]))
    omega = float(out["omega"])
    optimal = finite and code == 0 and omega <= ftol
    status, message = _message(code, finite, " Increase `max_steps` or start elsewhere.")
    if finite and code == 0 and not optimal:
        status, message = "stalled", (
            f"the solver stopped moving before the optimality test held (the Gauss-Newton step "
            f"would still lower the cost by a fraction {omega:.2g} > ftol = {ftol:g}); try "
            f"another `init`, `multistart`, or a looser `ftol`."
        )
    jtj_diag = np.diagonal(np.asarray(out["jtj"], float))
    if optimal and not np.any(jtj_diag > 0):
        optimal = False
        status, message = "degenerate", (
            "the cost does not depend on any free parameter at the end point (JᵀJ is zero): "
            "the data determine nothing here; check the data's scale and the `loss`."
        )
    success = optimal
    if throw and not success:
        raise FitError(f"{model.name} fit of {name or 'table'} did not converge: {message}")
    if not finite:
        u = np.asarray(u0, float)
    x_free = np.asarray(problem.physical(jnp.asarray(u)), float)
    bound = at_bound(u)
    lo, hi = bounds
    free_idx = list(problem.free)
    x_free = np.where(bound < 0, lo[free_idx], np.where(bound > 0, hi[free_idx], x_free))
    cost = float(out["cost"]) if finite else float("nan")
    cov_free, regular = covariance(
        out["jtj"], out["meat"], out["dxdu"], 2 * cost, float(out["m"]), bound == 0, cov_kind
    )
    if finite and not regular and not message:
        message = "JᵀJ is singular at the optimum: some parameters are not identified by the data"
    x = np.asarray(problem.full_vector(jnp.asarray(x_free)), float)
    names, free = model.flat_names(), list(problem.free)
    cov = np.zeros((len(x), len(x)))
    cov[np.ix_(free, free)] = cov_free
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    se[[f for f, b in zip(free, bound) if b != 0]] = np.nan
    t0, t1, t2 = times
    t3 = time.perf_counter()
    result = FitResult(
        model_name=model.name, params=_by_param(model, x), stderr=_by_param(model, se),
        names=names, x=x, cov=cov, free=[names[i] for i in free],
        fixed=[names[i] for i in fixed_idx],
        at_bound={names[f]: ("lower" if b < 0 else "upper") for f, b in zip(free, bound) if b},
        cost=cost, metrics={k: float(v) for k, v in out["metrics"].items()},
        success=success, status=status, message=message, steps=int(out["steps"]),
        starts=[float(c) for c in costs], loss=loss.label, solver=solver,
        n_cells=sel.n_used, n_total=sel.n_total, init=_by_param(model, x_start),
        wall_time=t3 - t0, timings={"prepare": t1 - t0, "solve": t2 - t1, "finish": t3 - t2},
        table=name, covariance=cov_kind, optimality=omega,
    )
    emit(success=success, cost=result.cost)
    return result
