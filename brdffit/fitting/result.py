"""The result of a fit: a small typed object with scipy's vocabulary, JSON round-trip.

``FitResult`` holds the parameters by name in physical units, their standard errors and
covariance (Gauss–Newton approximation at the optimum, in physical units), cost and error
metrics, the solver's verdict (``success``, ``status``, ``message``, ``steps``), the scalars that
ended at a bound, and timings. ``result.model(wi, wo)`` evaluates the fitted BRDF anywhere;
:meth:`FitResult.from_json` reads a path or JSON text back, every field checked
(:mod:`brdffit.fitting.result_json`).

Every result carries a plausibility verdict beside convergence (``plausibility``: is the
fitted material one a renderer can trust; :mod:`brdffit.fitting.plausibility`), and the
quantities its model derives from the parameters (``derived``: the standard models' grazing
reflectance ``f90``), which the summary, :meth:`FitResult.rows` and the JSON report.

For people: ``summary()`` (a few lines), ``report()`` and the notebook's HTML view (lmfit's
``fit_report``: :mod:`brdffit.fitting.report`, with :attr:`FitResult.correlation`,
:attr:`FitResult.aic`, :attr:`FitResult.bic`). The metrics' names and meanings are those of
:mod:`brdffit.metrics`.

This is the fitting layer's record of what a fit produced: it imports nothing above the
fitting layer. Rendering the fitted model on a MERL grid, exporting it to a renderer and
plotting it are functions of the layers above that take a result
(:func:`brdffit.export.render_merl`, :func:`brdffit.export.export`,
:func:`brdffit.plots.plot_result`); the result :func:`brdffit.fit` returns,
:class:`brdffit.FitResult` (:mod:`brdffit.api`), offers them as methods.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from ..metrics import metrics_text
from ..models.registry import get_model


@dataclasses.dataclass(frozen=True)
class FittedModel:
    """A model with its fitted parameters: ``fitted(wi, wo) -> f_r`` (RGB, no cosine)."""

    model: object
    params: dict

    def __call__(self, wi, wo):
        import jax.numpy as jnp

        p = {k: jnp.asarray(v) for k, v in self.params.items()}
        return self.model.fn(self.model.complete(p), jnp.asarray(wi), jnp.asarray(wo))

    @property
    def name(self) -> str:
        return self.model.name


def json_safe(v):
    """NaN/inf become ``None`` (strict JSON); everything else passes through."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [json_safe(x) for x in v]
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    return v


def _short(v) -> str:
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(f"{float(a):.4g}" for a in v) + ")"
    return f"{float(v):.4g}"


@dataclasses.dataclass
class FitResult:
    """Outcome of :func:`brdffit.fit`.

    Attributes:
        model_name: registry name of the fitted model.
        params: parameter name → value (float, or list for RGB), physical units.
        stderr: same keys; standard errors (0 for fixed scalars; NaN, ``null`` in JSON, for
            scalars at a bound and for those the data do not identify: no error bar).
        names: flat scalar names (``f0[0]`` ...), the order of ``x`` and ``cov``.
        x: flat parameter vector. cov: covariance over ``names`` (zero rows for fixed scalars).
        free, fixed: flat names of the fitted and of the frozen scalars.
        at_bound: flat name → ``"lower"``/``"upper"`` for scalars that ended at a bound.
        cost: ``½ Σ r²`` of the chosen loss at the optimum (scipy's ``cost``).
        metrics: ``rmse`` (of the chosen residual), ``rmse_cosine``, ``rmse_log``,
            ``rel_error`` (mean ``|ρ̂-ρ|/max(ρ,1e-3)``), over the cells used; their formulas
            and meanings: :data:`brdffit.metrics.METRICS`.
        success, status, message: the verdict (``status`` is optimistix's result name,
            ``"successful"`` on success by the optimality test, ``"still"`` on success by the
            stillness test, :func:`brdffit.fitting.stages.still`; ``"degenerate"`` when the data
            determine nothing, ``"implausible"`` for data beyond any physical reflectance:
            :mod:`brdffit.fitting.outcome`).
        steps: solver steps of the best start's last stage (on all the cells). starts: cost of
            each start (multi-start).
        loss, solver: what was used. n_cells: cells used; n_total: cells in the input.
        init: the starting parameters of the best start. wall_time: seconds for the whole call;
        timings: a breakdown (``prepare``, ``solve``, ``finish``), seconds.
        table: the input's name. covariance: ``"sandwich"`` or ``"gn"``, how ``cov`` was estimated.
        optimality: ``ω`` at the end point, the fraction of the cost that the bounded
            Gauss–Newton step could still remove (:func:`brdffit.fitting.bounded.optimality`);
            ``success`` means ``ω ≤ ftol``, or status ``"still"``.
        provenance: what produced the result (empty for the low-level
            :func:`brdffit.fitting.fit`; :func:`brdffit.fit` fills it): ``input`` (``path``,
            ``sha256``, ``name``), ``options`` (every fit option, defaults resolved),
            ``versions`` (brdffit, jax, jaxlib, optimistix, numpy, python) and ``date`` (UTC,
            ISO 8601). Written to JSON and read back by :meth:`from_json`.
        not_identified: flat names of the free scalars off their bounds that the data do not
            identify (:mod:`brdffit.fitting.statistics`): held at their values, no standard
            error, zero rows in ``cov``.
        plausibility: the verdict on the fitted material
            (:func:`brdffit.fitting.plausibility.verdict_record`): ``plausible`` and the
            ``checks`` (name, passed, value, limit, meaning); empty for a result read from a
            file older than the verdict. Independent of ``success``.
        total_steps: every solver step the fit took, each one evaluation of the residuals and
            their Jacobian (lmfit's ``nfev``; a progress bar counts the same steps): the start
            scan's candidates, the warm stages on a subset of the cells, every start, and for a
            refined model (``Model.refines``) the simpler model's fit. 0 for a result from a
            file older than the count.
    """

    model_name: str
    params: dict
    stderr: dict
    names: list
    x: np.ndarray
    cov: np.ndarray
    free: list
    fixed: list
    at_bound: dict
    cost: float
    metrics: dict
    success: bool
    status: str
    message: str
    steps: int
    starts: list
    loss: str
    solver: str
    n_cells: int
    n_total: int
    init: dict
    wall_time: float
    timings: dict
    table: str = ""
    covariance: str = "sandwich"
    optimality: float = float("nan")
    provenance: dict = dataclasses.field(default_factory=dict)
    not_identified: list = dataclasses.field(default_factory=list)
    plausibility: dict = dataclasses.field(default_factory=dict)
    total_steps: int = 0

    # -- evaluation -----------------------------------------------------------------------------
    @property
    def model(self) -> FittedModel:
        """The fitted BRDF: ``result.model(wi, wo)`` gives RGB ``f_r`` ``(..., 3)``."""
        return FittedModel(get_model(self.model_name), {k: np.asarray(v) for k, v in self.params.items()})

    @property
    def derived(self) -> dict:
        """The quantities the model derives from the fitted parameters (``Model.derived``), name
        → value (float, or list for RGB): ``f90`` of the standard models. ``{}`` for a model
        without any, or one the registry does not know."""
        from ..errors import UnknownNameError

        try:
            values = get_model(self.model_name).derived_values(self.params)
        except (UnknownNameError, ValueError, TypeError):
            return {}
        return {k: float(v) if v.ndim == 0 else [float(a) for a in v.ravel()]
                for k, v in values.items()}

    @property
    def plausible(self) -> bool | None:
        """Whether every plausibility check passed (``None``: not assessed)."""
        return self.plausibility.get("plausible") if self.plausibility else None

    # -- reporting ------------------------------------------------------------------------------
    def summary(self) -> str:
        """A few readable lines: verdict, parameters ± standard errors (none, and the status
        ``not identified``, for a scalar the data do not determine), metrics, then what ± is
        (the covariance estimator and what it assumes), the strongest correlations, and AIC/BIC
        with their caveat."""
        head = (
            f"{self.model_name} fit of {self.table or 'table'} ({self.loss} loss, {self.solver}): "
            f"{'converged' if self.success else 'FAILED'} in {self.steps} "
            f"step{'' if self.steps == 1 else 's'}"
            + (f" ({self.total_steps} in all stages)" if self.total_steps > self.steps else "")
            + f", {self.wall_time:.2f} s, {self.n_cells} cells"
        )
        lines = [head] + ([f"  message: {self.message}"] if self.message else [])
        flat_x = dict(zip(self.names, np.asarray(self.x, float)))
        se = np.sqrt(np.clip(np.diag(np.asarray(self.cov, float)), 0, None))
        flat_se = dict(zip(self.names, se))
        for n in self.names:
            tag = " (fixed)" if n in self.fixed else ""
            if n in self.at_bound:
                tag = f" (at {self.at_bound[n]} bound)"
            if n in self.not_identified:
                tag = " (not identified)"
            if n in (self.provenance.get("tied") or {}):
                tag = f" (= {self.provenance['tied'][n]}, grey fit of monochrome data)"
            has_error = n in self.free and n not in self.at_bound and n not in self.not_identified
            err = f" ± {flat_se[n]:.3g}" if has_error else ""
            lines.append(f"  {n:>18} = {flat_x[n]:.6g}{err}{tag}")
        for name, value in self.derived.items():
            lines.append(f"  {name:>18} = {_short(value)} (derived from the parameters)")
        lines.append("  " + metrics_text(self.metrics))
        from .plausibility import summary_lines

        lines += summary_lines(self.plausibility)
        lines.append(f"  cost {self.cost:.6g}, optimality {self.optimality:.2g}"
                     + (f"; starts {len(self.starts)}" if len(self.starts) > 1 else ""))
        return "\n".join(lines + self._uncertainty_lines())

    def _uncertainty_lines(self) -> list[str]:
        """What ± is, the strongest correlations, AIC/BIC and their caveat (summary's end)."""
        from .report import CRITERIA_CAVEAT, SUMMARY_CORRELATIONS, strongest_correlations
        from .statistics import ESTIMATOR_CAVEAT

        u = self.uncertainty()
        pairs = strongest_correlations(self)
        corr = ", ".join(f"{a}–{b} {r:+.2f}" for a, b, r in pairs[:SUMMARY_CORRELATIONS])
        more = f" (+{len(pairs) - SUMMARY_CORRELATIONS} more)" if len(
            pairs) > SUMMARY_CORRELATIONS else ""
        return [
            f"  ± one standard error, covariance {u['estimator']}",
            f"    ({ESTIMATOR_CAVEAT})",
            f"  strongest correlations: {corr or 'none with |r| ≥ 0.1'}{more}",
            f"  AIC {u['aic']:.6g}, BIC {u['bic']:.6g} ({CRITERIA_CAVEAT})",
        ]

    def uncertainty(self) -> dict:
        """What the standard errors are and how the scalars co-vary, for people and the JSON:
        ``estimator`` (:data:`brdffit.fitting.statistics.ESTIMATORS`), ``caveat``,
        ``not_identified``, ``correlation`` (:attr:`correlation`, NaN where a scalar has no
        standard error), ``strongest_correlations`` (``[name, name, r]``, ``|r| ≥ 0.1``,
        strongest first), ``aic``, ``bic`` and their ``criteria_caveat``
        (:func:`brdffit.fitting.report.information_criteria`)."""
        from .report import CRITERIA_CAVEAT, information_criteria, strongest_correlations
        from .statistics import ESTIMATOR_CAVEAT, estimator_text

        ic = information_criteria(self)
        return {
            "estimator": estimator_text(self.covariance), "caveat": ESTIMATOR_CAVEAT,
            "not_identified": list(self.not_identified),
            "correlation": self.correlation.tolist(),
            "strongest_correlations": [list(p) for p in strongest_correlations(self)],
            "aic": ic["aic"], "bic": ic["bic"], "criteria_caveat": CRITERIA_CAVEAT,
        }

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        """One line: model, input, verdict, the parameters (RGB as triples), cost."""
        params = ", ".join(f"{k}={_short(v)}" for k, v in self.params.items())
        verdict = "converged" if self.success else f"FAILED ({self.status})"
        return (f"FitResult({self.model_name!r} on {self.table or 'table'!r}: {verdict}, "
                f"{params}, cost={self.cost:.4g})")

    def rows(self) -> list[dict]:
        """One dict per flat scalar (``f0[0]`` ...): ``name``, ``value``, ``stderr`` (NaN for
        fixed scalars, those at a bound and those not identified), ``lower``/``upper`` (the
        bounds the fit used), ``status`` (``free``, ``fixed``, ``at lower bound``, ``at upper
        bound``, ``not identified``, or ``= f0[0] (grey)`` for the copied components of a grey
        fit), ``at_bound``."""
        model = get_model(self.model_name)
        lo, hi = model.flat_bounds()
        user = self.provenance.get("options", {}).get("bounds") or {}
        for name, (a, b) in user.items():
            idx = [i for i, n in enumerate(self.names) if n == name or n.startswith(name + "[")]
            lo[idx], hi[idx] = a, b
        se = np.sqrt(np.clip(np.diag(np.asarray(self.cov, float)), 0, None))
        tied = self.provenance.get("tied") or {}
        out = []
        for i, n in enumerate(self.names):
            fixed, bound, lost = n in self.fixed, self.at_bound.get(n), n in self.not_identified
            status = "fixed" if fixed else (f"at {bound} bound" if bound else "free")
            if lost and not fixed and not bound:
                status = "not identified"
            if n in tied:  # a grey fit of monochrome data: a copy of component 0
                status = f"= {tied[n]} (grey)"
            out.append({
                "name": n, "value": float(np.asarray(self.x, float)[i]),
                "stderr": float("nan") if fixed or bound or lost else float(se[i]),
                "lower": float(lo[i]), "upper": float(hi[i]), "status": status,
                "at_bound": bool(bound),
            })
        return out

    def derived_rows(self) -> list[dict]:
        """:meth:`rows` of the :attr:`derived` quantities (``f90[0]`` ...): status ``derived``,
        no standard error, no bounds."""
        out = []
        for name, value in self.derived.items():
            flat = ([(name, value)] if not isinstance(value, list)
                    else [(f"{name}[{c}]", v) for c, v in enumerate(value)])
            out += [{"name": n, "value": float(v), "stderr": float("nan"),
                     "lower": float("nan"), "upper": float("nan"), "status": "derived",
                     "at_bound": False} for n, v in flat]
        return out

    def to_dataframe(self):
        """A ``pandas.DataFrame`` with one row per flat scalar parameter and derived quantity
        (columns of :meth:`rows`, indexed by ``name``). ``pd.DataFrame(result.params)`` would
        repeat a scalar across the three rows of an RGB parameter; this does not. The
        plausibility verdict rides along in ``df.attrs``: ``plausible`` (bool, None when not
        assessed) and ``implausible`` (the names of the failed checks)."""
        import pandas as pd

        from .plausibility import failed

        df = pd.DataFrame(self.rows() + self.derived_rows()).set_index("name")
        df.attrs["plausible"] = self.plausible
        df.attrs["implausible"] = [c["name"] for c in failed(self.plausibility)]
        return df

    @property
    def correlation(self) -> np.ndarray:
        """The correlation matrix over :attr:`names`, from :attr:`cov`:
        ``cov[i, j] / (σ_i σ_j)``; NaN in the rows and columns of the scalars with no standard
        error (fixed, at a bound, not identified, the copied components of a grey fit), 1 on
        the diagonal elsewhere (:func:`brdffit.fitting.statistics.correlation`)."""
        from .statistics import correlation

        se = np.sqrt(np.clip(np.diag(np.asarray(self.cov, float)), 0, None))
        none = (set(self.fixed) | set(self.at_bound) | set(self.not_identified)
                | set(self.provenance.get("tied") or {}))
        return correlation(self.cov, [float("nan") if n in none else float(v)
                                      for n, v in zip(self.names, se)])

    @property
    def aic(self) -> float:
        """Akaike's information criterion, as lmfit's ``result.aic``; for comparing models fitted
        to the same data only (:func:`brdffit.fitting.report.information_criteria`)."""
        from .report import information_criteria

        return information_criteria(self)["aic"]

    @property
    def bic(self) -> float:
        """The Bayesian information criterion, as lmfit's ``result.bic``; same caveat as
        :attr:`aic`."""
        from .report import information_criteria

        return information_criteria(self)["bic"]

    def report(self, *, min_correl: float = 0.1) -> str:
        """The text report, as lmfit's ``fit_report``: :func:`brdffit.fitting.fit_report`."""
        from .report import fit_report

        return fit_report(self, min_correl=min_correl)

    def _repr_html_(self) -> str:
        """Jupyter's view: the report as HTML (:func:`brdffit.fitting.report.report_html`):
        parameters (value ± standard error, initial value, bounds, status), fit statistics
        (cost, χ², AIC/BIC, steps, time), the metrics and the strongest correlations."""
        from .report import report_html

        return report_html(self)

    def to_dict(self) -> dict:
        """Plain Python types only (lists for arrays): the fields, ``uncertainty``
        (:meth:`uncertainty`) and ``derived`` (:attr:`derived`): both derived from the fields,
        for readers of the JSON, skipped when read back."""
        d = dataclasses.asdict(self)
        d["x"] = [float(v) for v in np.asarray(self.x, float)]
        d["cov"] = np.asarray(self.cov, float).tolist()
        d["uncertainty"] = self.uncertainty()
        d["derived"] = self.derived  # for readers; recomputed from the parameters on reading
        return d

    def to_json(self, path=None, indent: int = 2) -> str:
        """JSON text (strict: NaN written as ``null``); also written to ``path`` if given."""
        text = json.dumps(json_safe(self.to_dict()), indent=indent)
        if path is not None:
            Path(path).write_text(text)
        return text

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "<dict>") -> FitResult:
        """Inverse of :meth:`to_dict` (and of the parsed :meth:`to_json`): every field checked
        (:mod:`brdffit.fitting.result_json`), ``null`` read as NaN; a malformed ``d`` raises
        :class:`~brdffit.fitting.result_json.ResultFormatError` naming ``source``."""
        from . import result_json

        missing = dataclasses.MISSING
        required = [f.name for f in dataclasses.fields(cls)
                    if f.default is missing and f.default_factory is missing]
        return cls(**result_json.fields(source, d, required))

    @classmethod
    def from_json(cls, source, *, model: str | None = None) -> FitResult:
        """Inverse of :meth:`to_json`: ``source`` is a path (``str`` or ``os.PathLike``) to a
        JSON file, or the JSON text (``bytes``, or a ``str`` that starts with ``{`` or ``[``;
        :func:`~brdffit.fitting.result_json.is_json_text`); a UTF-8 byte-order mark is skipped.

        A file of several results (``brdffit fit -m a,b --out``: ``{"results": [...]}``) needs
        ``model``, the one to read; given for a single result, it must be that result's model.
        Raises :class:`~brdffit.fitting.result_json.ResultFormatError` (a ``ValueError``) for
        anything that is not a result, :class:`~brdffit.fitting.result_json.ResultChoiceError`
        when ``model`` is missing or not in the file, ``OSError`` for a path that cannot be read.
        """
        from . import result_json

        return cls._from_document(*result_json.read_document(source), model)

    @classmethod
    def from_json_string(cls, text, *, model: str | None = None) -> FitResult:
        """:meth:`from_json` of JSON text (``str`` or ``bytes``), never taken for a path."""
        from . import result_json

        return cls._from_document("<string>", result_json.parse_text("<string>", text), model)

    @classmethod
    def _from_document(cls, name, document, model) -> FitResult:
        from . import result_json

        items = result_json.entries(name, document)
        results = [cls.from_dict(d, source=name if len(items) == 1 else f"{name} results[{i}]")
                   for i, d in enumerate(items)]
        return result_json.pick(name, results, model)
