r"""A fit's report, as lmfit's ``fit_report``: :func:`fit_report` (text) and :func:`report_html`
(what a notebook shows for a :class:`~brdffit.fitting.FitResult`).

Both give the verdict, every scalar with its value ± standard error, start value, bounds and
status, the fit statistics (cost, χ², reduced χ², the steps of the last stage and the solver
steps in all, lmfit's ``nfev``; starts, optimality, time), the error metrics with their
meanings (:mod:`brdffit.metrics`), the strongest correlations (:attr:`FitResult.correlation`) and the information criteria of :func:`information_criteria`:

.. math::

    \chi^2 = \textstyle\sum r^2 = 2\,\mathrm{cost}, \qquad
    \mathrm{AIC} = N \ln(\chi^2/N) + 2k, \qquad
    \mathrm{BIC} = N \ln(\chi^2/N) + k \ln N,

``N`` the residuals (three a cell; one for monochrome data) and ``k`` the free scalars, as lmfit
computes them (Gaussian residuals of one unknown variance). They assume independent residuals.
Those of a model fitted to a measured BRDF are mostly model error, correlated from cell to
cell, so ``N`` overstates the evidence: AIC and BIC rank models fitted to the same data with the
same loss, and their absolute values and differences carry no probability. The report says so.
"""

from __future__ import annotations

import html
import math

import numpy as np

from ..metrics import METRICS, metric_text
from .plausibility import summary_lines
from .statistics import ESTIMATOR_CAVEAT, estimator_text

#: Correlations listed by the reports: those at least this strong (absolute value).
MIN_CORRELATION = 0.1


def value_with_error(value: float, err: float) -> str:
    """``value ± err`` with the error to two significant digits and the value to the same
    decimal place (``0.08012 ± 0.00011``); ``value`` alone (6 significant digits) when the
    error is not a positive finite number."""
    if not (math.isfinite(err) and err > 0):
        return f"{value:.6g}"
    place = math.floor(math.log10(err)) - 1  # the error's second significant digit
    if place >= 0:
        return f"{round(value, -place):.0f} ± {round(err, -place):.0f}"
    return f"{value:.{-place}f} ± {err:.{-place}f}"


#: At most this many correlations are listed (all are in ``result.correlation``).
MAX_LISTED = 10
#: The summary (:meth:`FitResult.summary`) lists this many.
SUMMARY_CORRELATIONS = 3
#: The one-line caveat printed under AIC and BIC.
CRITERIA_CAVEAT = ("residuals of a model fitted to a measured BRDF are correlated model error, "
                   "not independent noise: AIC/BIC compare models on the same data only")


def information_criteria(result) -> dict:
    """``n_data`` (N), ``n_free`` (k), ``chi2``, ``reduced_chi2``, ``aic``, ``bic`` of the
    module docstring (NaN where the cost is not finite or ``N ≤ k``)."""
    n = int(result.n_cells) * (1 if (result.provenance or {}).get("tied") else 3)
    k = len(result.free)
    chi2 = 2.0 * float(result.cost)
    ok = math.isfinite(chi2) and chi2 > 0 and 0 < n < 2**53  # a count a float holds exactly
    fit = n * math.log(chi2 / n) if ok else float("nan")
    return {"n_data": n, "n_free": k, "chi2": chi2,
            "reduced_chi2": chi2 / (n - k) if ok and n > k else float("nan"),
            "aic": fit + 2 * k, "bic": fit + k * math.log(n) if ok else float("nan")}


def strongest_correlations(result, min_abs: float = MIN_CORRELATION) -> list[tuple]:
    """``(name, name, r)`` for every pair of scalars with ``|r| ≥ min_abs``, strongest first
    (scalars without a standard error have no correlation)."""
    corr, names = result.correlation, list(result.names)
    i, j = np.triu_indices(len(names), 1)
    r = corr[i, j]
    keep = np.isfinite(r) & (np.abs(r) >= min_abs)
    order = np.argsort(-np.abs(r[keep]), kind="stable")
    return [(names[a], names[b], float(c))
            for a, b, c in zip(i[keep][order], j[keep][order], r[keep][order])]


def _init_flat(result) -> dict:
    out = {}
    for name, value in (result.init or {}).items():
        a = np.asarray(value, float)
        if a.ndim == 0:
            out[name] = float(a)
        else:
            out.update({f"{name}[{c}]": float(v) for c, v in enumerate(a.ravel())})
    return out


def _relative(value: float, err: float) -> str:
    if not (math.isfinite(err) and err > 0 and value != 0):
        return ""
    pct = 100 * err / abs(value)
    return f"{pct:.0f} %" if pct >= 100 else f"{pct:.2g} %"


def _verdict(result) -> str:
    word = "converged" if result.success else "FAILED"
    starts = len(result.starts)
    steps = f"{result.steps} step" + ("" if result.steps == 1 else "s")
    total = result.total_steps
    return (f"{word} ({result.status}) in {steps}"
            + (f", best of {starts} starts" if starts > 1 else "")
            + (f"; {total} solver step{'' if total == 1 else 's'} in all (nfev: every "
               f"evaluation of the residuals and their Jacobian, all stages)" if total else ""))


def _statistics(result) -> list[tuple[str, str]]:
    ic = information_criteria(result)
    t = result.timings or {}
    parts = ", ".join(f"{k} {v:.2f}" for k, v in t.items())
    return [
        ("fit", _verdict(result)),
        ("loss, solver", f"{result.loss}, {result.solver}"),
        ("covariance", estimator_text(result.covariance)),
        ("data", f"{result.n_cells} cells used of {result.n_total}, N = {ic['n_data']} "
                 f"residuals, k = {ic['n_free']} free scalars"),
        ("cost", f"{result.cost:.6g} (χ² = Σr² = {ic['chi2']:.6g}, reduced χ² "
                 f"{ic['reduced_chi2']:.4g})"),
        ("AIC, BIC", f"{ic['aic']:.6g}, {ic['bic']:.6g}"),
        ("optimality", f"{result.optimality:.2g} (the fraction of the cost a step could remove)"),
        ("time", f"{result.wall_time:.2f} s" + (f" ({parts})" if parts else "")),
    ]


def fit_report(result, *, min_correl: float = MIN_CORRELATION) -> str:
    """The text report of ``result`` (module docstring), in lmfit's sections: ``[[Fit]]``,
    ``[[Metrics]]``, ``[[Variables]]``, ``[[Correlations]]``. ``min_correl``: the weakest
    correlation listed."""
    lines = [f"[[Fit]] {result.model_name} fit of {result.table or 'table'}"]
    for key, value in _statistics(result):
        lines.append(f"    {key:<13} {value}")
        if key == "AIC, BIC":
            lines.append(f"    {'':<13} ({CRITERIA_CAVEAT})")
        if key == "covariance":
            lines.append(f"    {'':<13} ({ESTIMATOR_CAVEAT})")
    if result.message:
        lines.append(f"    {'message':<13} {result.message}")
    lines.append("[[Metrics]]")
    for name, value in _metrics(result):
        m = METRICS.get(name)
        lines.append(f"    {metric_text(name, value):<22}"
                     + (f" {m.label}: {m.formula}" if m else ""))
    lines.append("[[Variables]]")
    lines += _variables(result)
    lines += [f"    {r['name']}  {r['value']:.6g}  derived from the parameters"
              for r in result.derived_rows()]
    lines.append("[[Plausibility]]")
    lines += [line[2:] for line in summary_lines(result.plausibility)]
    pairs = strongest_correlations(result, min_correl)
    lines.append(f"[[Correlations]] (|r| ≥ {min_correl:g}, strongest first)")
    lines += [f"    C({a}, {b}) = {c:+.3f}" for a, b, c in pairs[:MAX_LISTED]] or ["    none"]
    if len(pairs) > MAX_LISTED:
        lines.append(f"    ... and {len(pairs) - MAX_LISTED} more (result.correlation)")
    return "\n".join(lines)


def _variables(result) -> list[str]:
    """The ``[[Variables]]`` lines: name, value ± error, relative error, start, bounds, status."""
    init, rows = _init_flat(result), result.rows()
    cols = [(r["name"], value_with_error(r["value"], r["stderr"]),
             f"({rel})" if (rel := _relative(r["value"], r["stderr"])) else "",
             "" if init.get(r["name"]) is None else f"init {init[r['name']]:.4g}",
             f"[{r['lower']:g}, {r['upper']:g}]", r["status"]) for r in rows]
    widths = [max((len(c[i]) for c in cols), default=0) for i in range(5)]
    return ["    " + "  ".join(f"{v:<{w}}" for v, w in zip(c, widths)) + "  " + c[5]
            for c in cols]


def _metrics(result) -> list[tuple[str, float]]:
    names = [n for n in METRICS if n in result.metrics]
    return [(n, result.metrics[n]) for n in names + [n for n in result.metrics
                                                       if n not in METRICS]]


def _esc(text) -> str:
    return html.escape(str(text))


def _corr_colour(r: float) -> str:
    """A cell's background: red for positive, blue for negative, stronger with ``|r|``; none
    below :data:`MIN_CORRELATION`."""
    if not (math.isfinite(r) and abs(r) >= MIN_CORRELATION):
        return ""
    return f" style='background:{'#d62728' if r > 0 else '#1f77b4'}{int(min(abs(r), 1) * 153):02x}'"


def _matrix_html(result) -> str:
    """The correlation matrix over the scalars that have a standard error, in ``<details>``."""
    corr = result.correlation
    keep = [i for i in range(len(result.names)) if math.isfinite(corr[i, i])]
    if len(keep) < 2:
        return ""
    names = [result.names[i] for i in keep]
    head = "".join(f"<th>{_esc(n)}</th>" for n in names)
    rows = "".join(
        f"<tr><th>{_esc(names[a])}</th>" + "".join(
            f"<td{_corr_colour(corr[i, j])}>{corr[i, j]:+.2f}</td>" if i != j else "<td></td>"
            for j in keep) + "</tr>"
        for a, i in enumerate(keep))
    return (f"<details><summary>correlation matrix</summary><table><tr><th></th>{head}</tr>"
            f"{rows}</table></details>")


def report_html(result, *, min_correl: float = MIN_CORRELATION) -> str:
    """The HTML report (module docstring): what ``result._repr_html_`` shows in a notebook."""
    verdict = "converged" if result.success else f"<b>FAILED</b> ({_esc(result.status)})"
    head = (f"<b>{_esc(result.model_name)}</b> fit of <code>{_esc(result.table or 'table')}"
            f"</code>: {verdict}")
    msg = f"<p>message: {_esc(result.message)}</p>" if result.message else ""
    init = _init_flat(result)
    params = "".join(
        f"<tr><td>{_esc(r['name'])}</td><td>{_esc(value_with_error(r['value'], r['stderr']))}"
        f"</td><td>{_esc(_relative(r['value'], r['stderr']))}</td>"
        f"<td>{'' if init.get(r['name']) is None else format(init[r['name']], '.4g')}</td>"
        f"<td>[{r['lower']:g}, {r['upper']:g}]</td><td>{_esc(r['status'])}</td></tr>"
        for r in result.rows())
    params = ("<table class='brdffit-params'><tr><th>parameter</th><th>value ± stderr</th>"
              "<th>rel.</th><th>initial</th><th>bounds</th><th>status</th></tr>"
              f"{params}</table>")
    stats = "".join(f"<tr><th style='text-align:left'>{_esc(k)}</th><td style='text-align:"
                    f"left'>{_esc(v)}</td></tr>" for k, v in _statistics(result))
    metrics = "".join(
        f"<tr><td>{_esc(n)}</td><td>{v:.4g}</td><td style='text-align:left'>"
        f"{_esc(METRICS[n].label + ': ' + METRICS[n].formula) if n in METRICS else ''}</td></tr>"
        for n, v in _metrics(result))
    pairs = strongest_correlations(result, min_correl)
    corr = ", ".join(f"{_esc(a)}–{_esc(b)} {c:+.3f}" for a, b, c in pairs[:MAX_LISTED])
    more = f" (and {len(pairs) - MAX_LISTED} more)" if len(pairs) > MAX_LISTED else ""
    plaus = "<br>".join(_esc(line.strip()) for line in summary_lines(result.plausibility))
    return (f"<div class='brdffit-fit'><p>{head}</p>{msg}<p>{plaus}</p>{params}"
            f"<table>{stats}</table><p><small>{_esc(CRITERIA_CAVEAT)}</small></p>"
            f"<table><tr><th>metric</th><th>value</th><th>meaning</th></tr>{metrics}</table>"
            f"<p>strongest correlations (|r| ≥ {min_correl:g}): {corr or 'none'}{more}</p>"
            f"{_matrix_html(result)}</div>")
