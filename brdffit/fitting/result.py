"""The result of a fit: a small typed object with scipy's vocabulary, JSON round-trip.

``FitResult`` holds the parameters by name in physical units, their standard errors and
covariance (Gauss–Newton approximation at the optimum, in physical units), cost and error
metrics, the solver's verdict (``success``, ``status``, ``message``, ``steps``), the scalars that
ended at a bound, and timings. ``result.model(wi, wo)`` evaluates the fitted BRDF anywhere;
``result.render_merl()`` fills a whole MERL grid with it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

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


def _scalar_or_list(a):
    a = np.asarray(a, float)
    return float(a) if a.ndim == 0 else [float(v) for v in a.ravel()]


def _json_safe(v):
    """NaN/inf become ``None`` (strict JSON); everything else passes through."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_json_safe(x) for x in v]
    if isinstance(v, dict):
        return {k: _json_safe(x) for k, x in v.items()}
    return v


def _from_json_safe(v):
    if v is None:
        return float("nan")
    if isinstance(v, list):
        return [_from_json_safe(x) for x in v]
    return v


@dataclasses.dataclass
class FitResult:
    """Outcome of :func:`brdffit.fit`.

    Attributes:
        model_name: registry name of the fitted model.
        params: parameter name → value (float, or list for RGB), physical units.
        stderr: same keys; standard errors (0 for fixed scalars, NaN for scalars at a bound or
            when the Gauss–Newton matrix is singular).
        names: flat scalar names (``f0[0]`` ...), the order of ``x`` and ``cov``.
        x: flat parameter vector. cov: covariance over ``names`` (zero rows for fixed scalars).
        free, fixed: flat names of the fitted and of the frozen scalars.
        at_bound: flat name → ``"lower"``/``"upper"`` for scalars that ended at a bound.
        cost: ``½ Σ r²`` of the chosen loss at the optimum (scipy's ``cost``).
        metrics: ``rmse`` (of the chosen residual), ``rmse_cosine``, ``rmse_log``,
            ``rel_error`` (mean ``|ρ̂-ρ|/max(ρ,1e-3)``), over the cells used.
        success, status, message: the solver's verdict (``status`` is optimistix's result name,
            ``"successful"`` on success).
        steps: solver steps of the best start. starts: cost of each start (multi-start).
        loss, solver: what was used. n_cells: cells used; n_total: cells in the input.
        init: the starting parameters of the best start. wall_time: seconds for the whole call;
        timings: a breakdown (``prepare``, ``solve``, ``finish``), seconds.
        table: the input's name. covariance: ``"sandwich"`` or ``"gn"``, how ``cov`` was estimated.
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

    # -- evaluation -----------------------------------------------------------------------------
    @property
    def model(self) -> FittedModel:
        """The fitted BRDF: ``result.model(wi, wo)`` gives RGB ``f_r`` ``(..., 3)``."""
        return FittedModel(get_model(self.model_name), {k: np.asarray(v) for k, v in self.params.items()})

    def render_merl(self, name: str | None = None, shape=None):
        """The fitted model on a whole MERL grid (cell corners), as a ``MERLTable``.

        Cells below the horizon are missing, as in the database (``data_formats.merl.synthesize``);
        write it with ``data_formats.merl.write_merl`` for a fitted ``.binary``.
        """
        from data_formats.merl import MERL_SHAPE, synthesize

        from ..models.evaluate import evaluate_model

        fitted = self.model
        return synthesize(lambda wi, wo: evaluate_model(fitted.model, fitted.params, wi, wo),
                          name=name or f"{self.model_name}-fit", shape=shape or MERL_SHAPE)

    def export(self, to: str, *, approximate: bool = False, **options):
        """The fitted material for a renderer: ``"mitsuba-dict"`` (what ``mitsuba.load_dict``
        takes), ``"mitsuba-xml"`` (a ``<bsdf>`` element) or ``"gltf"`` (a glTF 2.0 document).

        Delegates to :func:`brdffit.export.export_payload` (the parameter mapping and the
        ``approximate`` option are documented in :mod:`brdffit.export`).
        """
        from ..export import export_payload

        return export_payload(self, to, approximate=approximate, **options)

    # -- reporting ------------------------------------------------------------------------------
    def summary(self) -> str:
        """A few readable lines: verdict, parameters ± standard errors, metrics."""
        head = (
            f"{self.model_name} fit of {self.table or 'table'} ({self.loss} loss, {self.solver}): "
            f"{'converged' if self.success else 'FAILED'} in {self.steps} steps, "
            f"{self.wall_time:.2f} s, {self.n_cells} cells"
        )
        lines = [head] + ([f"  message: {self.message}"] if self.message else [])
        flat_x = dict(zip(self.names, np.asarray(self.x, float)))
        se = np.sqrt(np.clip(np.diag(np.asarray(self.cov, float)), 0, None))
        flat_se = dict(zip(self.names, se))
        for n in self.names:
            tag = " (fixed)" if n in self.fixed else ""
            if n in self.at_bound:
                tag = f" (at {self.at_bound[n]} bound)"
            err = f" ± {flat_se[n]:.3g}" if n in self.free and n not in self.at_bound else ""
            lines.append(f"  {n:>18} = {flat_x[n]:.6g}{err}{tag}")
        lines.append("  " + ", ".join(f"{k} {v:.4g}" for k, v in self.metrics.items()))
        lines.append(f"  cost {self.cost:.6g}" + (f"; starts {len(self.starts)}" if len(self.starts) > 1 else ""))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_dict(self) -> dict:
        """Plain Python types only (lists for arrays)."""
        d = dataclasses.asdict(self)
        d["x"] = [float(v) for v in np.asarray(self.x, float)]
        d["cov"] = np.asarray(self.cov, float).tolist()
        return d

    def to_json(self, path=None, indent: int = 2) -> str:
        """JSON text (strict: NaN written as ``null``); also written to ``path`` if given."""
        text = json.dumps(_json_safe(self.to_dict()), indent=indent)
        if path is not None:
            Path(path).write_text(text)
        return text

    @classmethod
    def from_dict(cls, d: dict) -> FitResult:
        d = dict(d)
        d["stderr"] = {k: _from_json_safe(v) for k, v in d["stderr"].items()}
        d["x"] = np.asarray(d["x"], float)
        d["cov"] = np.asarray(_from_json_safe(d["cov"]), float).reshape(len(d["x"]), len(d["x"]))
        return cls(**d)

    @classmethod
    def from_json(cls, text_or_path) -> FitResult:
        """Inverse of :meth:`to_json`; accepts JSON text or a path to a JSON file."""
        s = str(text_or_path)
        if not s.lstrip().startswith("{"):
            s = Path(s).read_text()
        return cls.from_dict(json.loads(s))
