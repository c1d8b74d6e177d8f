r"""The leaderboard: models fitted to one table and the published fits of its material, scored
on identical cells in the literature's metrics and ranked. ``brdffit.compare(table, models)``.

* **Candidates**: every model of ``models`` fitted to the table (:func:`brdffit.fit`), each
  under the common ``options`` or under a preset of its own (``"beckmann@low2012-e2"``: the
  preset's options over the common ones; the same model may appear under several presets),
  and, with ``published``, every published fit of the table's material
  (:func:`brdffit.published.load_published`, matched by the table's name: the file stem of
  ``alumina-oxide.binary``).
* **Cells**: every valid cell of the table above the horizon whose value is a measurement
  (finite, non-negative): the same cells for every candidate, whatever cells a fit used.
* **Scores**: :func:`brdffit.metrics.literature_values` (:data:`brdffit.metrics.LITERATURE_METRICS`:
  Löw's log RMS on all cells and on θ ≤ 80°, Ngan's cosθi-weighted RMS on θ ≤ 80°, the relative
  error in the peak; each per cell and solid-angle weighted), computed here from the
  candidates' values, independently of how each was fitted.
* **Ranking**: by ``rank_by`` (default :data:`DEFAULT_RANK_BY`), lowest first; the frame has
  a ``rank_<metric>`` column for every metric, so a reader sees where each candidate stands in
  each.

A :class:`Leaderboard` prints as a table (:meth:`Leaderboard.text`), is a pandas DataFrame
(:attr:`Leaderboard.frame`, :meth:`Leaderboard.to_parquet`, :meth:`Leaderboard.to_csv`) and a
self-contained HTML report (:meth:`Leaderboard.html`: the table, the lit spheres of the data
and of every candidate side by side under one tone mapping, and for each candidate the image
slice and the peak curves beside the data; figures embedded as base64 PNG, no external file or
script).
"""

from __future__ import annotations

import base64
import dataclasses
import html
import io
import math

import numpy as np

from .errors import BrdffitError, ConfigError, UnknownNameError
from .metrics import LITERATURE_METRICS

#: The metric the leaderboard ranks by unless told otherwise: Löw 2012's log metric over
#: θi, θo ≤ 80°, solid-angle weighted (module docstring of :mod:`brdffit.metrics`).
DEFAULT_RANK_BY = "log_rms_80_sa"
#: The largest value taken as a measurement (1/sr): the fitter's screening bound
#: (``brdffit.fitting.data.MAX_BRDF``).
MAX_BRDF = 1e7
#: Resolution of the figures of the HTML report (dots per inch).
REPORT_DPI = 72


@dataclasses.dataclass
class Candidate:
    """One row of a leaderboard: ``label`` (``"ggx"``, ``"beckmann@low2012-e2"``,
    ``"published: Löw 2012 E2 (low-cooktorrance)"``), ``kind`` (``"fit"`` or
    ``"published"``), the ``result``
    (a :class:`brdffit.FitResult`, or a :class:`brdffit.published.PublishedResult`) and its
    ``scores`` (metric → value)."""

    label: str
    kind: str
    result: object
    scores: dict = dataclasses.field(default_factory=dict)

    @property
    def model(self) -> str:
        return self.result.model_name

    @property
    def converged(self) -> bool | None:
        """Whether the fit converged; ``None`` for a published fit (nothing was fitted here)."""
        return None if self.kind == "published" else bool(self.result.success)

    @property
    def status(self) -> str:
        """``"yes"``, ``"NO"`` (a fit that did not converge) or ``"published"``."""
        return "published" if self.converged is None else ("yes" if self.converged else "NO")

    @property
    def source(self) -> str:
        if self.kind == "published":
            return self.result.source
        options = (self.result.provenance or {}).get("options") or {}
        cutoff = options.get("cutoff")
        return (f"fit ({options.get('loss', self.result.loss)}, "
                f"{options.get('weighting', 'angles')}, "
                f"{'all cells' if cutoff is None else f'θ ≤ {cutoff:g}°'})")


@dataclasses.dataclass
class Leaderboard:
    """The candidates of one table, ranked (module docstring). ``table``: the material's name;
    ``n_cells``: the cells every candidate was scored on; ``rank_by``: the ranking metric."""

    table: str
    candidates: list
    rank_by: str = DEFAULT_RANK_BY
    n_cells: int = 0

    @property
    def frame(self):
        """A pandas DataFrame, one row per candidate in rank order: ``rank``, ``candidate``,
        ``kind``, ``model``, ``source``, ``converged`` (nullable: missing for a published fit),
        every metric of
        :data:`~brdffit.metrics.LITERATURE_METRICS`, ``rank_<metric>`` for each, ``time``
        (seconds of the fit; 0 for a published fit), ``material`` and ``n_cells``."""
        import pandas as pd

        rows = []
        for k, c in enumerate(self.candidates, 1):
            rows.append({"material": self.table, "rank": k, "candidate": c.label,
                         "kind": c.kind, "model": c.model, "source": c.source,
                         "converged": c.converged, **{m: c.scores.get(m, math.nan)
                                                      for m in LITERATURE_METRICS},
                         "time": float(c.result.wall_time), "n_cells": self.n_cells})
        df = pd.DataFrame(rows, columns=["material", "rank", "candidate", "kind", "model",
                                         "source", "converged", *LITERATURE_METRICS, "time",
                                         "n_cells"])
        df["converged"] = df["converged"].astype("boolean")
        for m in LITERATURE_METRICS:
            df[f"rank_{m}"] = df[m].rank(method="min", na_option="bottom").astype(int)
        return df

    def best(self, kind: str | None = None):
        """The best candidate (of ``kind``, ``"fit"`` or ``"published"``, if given), or None."""
        for c in self.candidates:
            if kind is None or c.kind == kind:
                return c
        return None

    def text(self) -> str:
        """The leaderboard as aligned text: rank, candidate, source, converged, the per-cell and
        solid-angle-weighted metrics, time; a line saying what the rank is."""
        from ._columns import columns

        names = list(LITERATURE_METRICS)
        head = ("rank", "candidate", "source", "conv.", *names, "time")
        rows = [head]
        for k, c in enumerate(self.candidates, 1):
            rows.append((str(k), c.label, c.source, c.status,
                         *(_number(c.scores.get(m, math.nan)) for m in names),
                         f"{c.result.wall_time:.2f}s" if c.kind == "fit" else "-"))
        align = "><<<" + ">" * (len(names) + 1)
        note = (f"({self.table or 'table'}: {self.n_cells:,} cells, the same for every candidate; "
                f"ranked by {self.rank_by}, lowest first; _sa: solid-angle weighted, _80: "
                f"θi, θo ≤ 80°)")
        return "\n".join(columns(rows, align, rule=True) + [note])

    def __str__(self) -> str:
        return self.text()

    def to_parquet(self, path) -> None:
        """:attr:`frame` as a Parquet file at ``path``."""
        self.frame.to_parquet(path, index=False)

    def to_csv(self, path) -> None:
        """:attr:`frame` as CSV at ``path``."""
        self.frame.to_csv(path, index=False)

    def to_json(self) -> str:
        """The rows of :attr:`frame` as JSON (strict: NaN as ``null``)."""
        import json

        from .fitting import json_safe

        rows = json.loads(self.frame.to_json(orient="records"))
        return json.dumps({"material": self.table, "rank_by": self.rank_by,
                           "n_cells": self.n_cells, "rows": json_safe(rows)}, indent=2)

    def html(self, data) -> str:
        """The self-contained HTML report of this leaderboard on ``data`` (the table it was
        scored on; module docstring)."""
        return report_html(self, data)

    def _repr_html_(self) -> str:
        return _table_html(self)


def _number(v) -> str:
    return "nan" if not math.isfinite(v) else f"{v:.4g}"


# -- the candidates ---------------------------------------------------------------------------

def parse_models(models) -> list[tuple[str, str, str | None]]:
    """``"ggx,beckmann@low2012-e2"`` (or a list) → ``[(label, model, preset)]``: the model
    names checked against the registry and spelled as registered, each preset found
    (:func:`brdffit.config.find_config`); a label given twice is an error."""
    from .config import find_config
    from .models.registry import get_model

    items = [m.strip() for m in models.split(",")] if isinstance(models, str) else \
        [str(m).strip() for m in models]
    items = [m for m in items if m]
    if not items:
        raise ConfigError("no models to compare: give model names, e.g. ggx,gtr,beckmann")
    out, seen = [], set()
    for item in items:
        name, _, preset = item.partition("@")
        model = get_model(name.strip()).name
        preset = preset.strip() or None
        if preset is not None:
            find_config(preset)
        label = model if preset is None else f"{model}@{preset}"
        if label in seen:
            raise ConfigError(f"{label!r} is given twice; give each model (or model@preset) once")
        seen.add(label)
        out.append((label, model, preset))
    return out


def _options_for(options, preset):
    from .config import FitOptions, load_config
    from .fitting import fit_options

    base = options if isinstance(options, FitOptions) else FitOptions(**fit_options(options))
    return base if preset is None else base.merged(load_config(preset))


def _fit_candidates(data, parsed, options, progress) -> list[Candidate]:
    from .api import fit

    out = []
    for label, model, preset in parsed:
        if progress is not None:
            progress(f"fitting {label}")
        opts = _options_for(options, preset)
        result = fit(data, model, opts, throw=False)
        out.append(Candidate(label, "fit", result))
    return out


def published_candidates(published, material: str) -> list[Candidate]:
    """The published fits of ``material`` in ``published`` (a ``.fit`` file or a folder of
    them, :func:`brdffit.published.load_published`), as candidates labelled by their source;
    a folder without a fit of that material gives none."""
    from .published import load_published

    return [published_candidate(r) for r in load_published(published, material)]


def published_candidate(result) -> Candidate:
    """A :class:`~brdffit.published.PublishedResult` as a candidate, labelled by its source and
    model (``"published: Ngan 2005 (ngan-cooktorrance)"``: a study publishes several models)."""
    return Candidate(f"{result.source} ({result.model_name})", "published", result)


# -- scoring ----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Cells:
    """The cells every candidate is scored on: directions, measured values and their share of
    the angle domain (``SampleSet.weight``, or ``None``)."""

    wi: np.ndarray
    wo: np.ndarray
    rgb: np.ndarray
    weight: np.ndarray | None

    def __len__(self) -> int:
        return len(self.rgb)


def scoring_cells(data) -> Cells:
    """The valid cells of ``data`` (anything with ``.to_samples()``) with both directions above
    the horizon and a value that is a measurement (finite, non-negative, at most
    :data:`brdffit.fitting.data.MAX_BRDF`); :class:`~brdffit.errors.BrdffitError` when none."""
    s = data.to_samples()
    wi, wo = np.asarray(s.wi, float), np.asarray(s.wo, float)
    rgb = np.asarray(s.rgb, float)
    with np.errstate(invalid="ignore"):
        ok = (np.asarray(s.valid, bool) & (wi[:, 2] > 0) & (wo[:, 2] > 0)
              & np.all(np.isfinite(rgb), axis=1) & np.all(rgb >= 0, axis=1)
              & np.all(rgb <= MAX_BRDF, axis=1))
    if not ok.any():
        raise BrdffitError(f"table {getattr(s, 'name', '') or '(unnamed)'}: no valid cell above "
                           f"the horizon to score the candidates on")
    weight = None if s.weight is None else np.asarray(s.weight, float)[ok]
    return Cells(wi[ok], wo[ok], rgb[ok], weight)


def score(cells: Cells, model, params) -> dict:
    """:func:`brdffit.metrics.literature_values` of ``model`` with ``params`` on ``cells``
    (evaluated in float64)."""
    import jax

    from .metrics import literature_values
    from .models.evaluate import evaluate_model

    with jax.enable_x64(True):
        f = np.asarray(evaluate_model(model, params, cells.wi, cells.wo), float)
    return literature_values(f, cells.rgb, cells.wi, cells.wo, cells.weight)


def rank(candidates, rank_by: str) -> list:
    """``candidates`` sorted by ``rank_by`` (lowest first; NaN last), stable."""
    def key(c):
        v = c.scores.get(rank_by, math.nan)
        return (not math.isfinite(v), v if math.isfinite(v) else 0.0)

    return sorted(candidates, key=key)


def check_rank_by(rank_by: str) -> str:
    """``rank_by`` if it names a metric of :data:`~brdffit.metrics.LITERATURE_METRICS`."""
    if rank_by not in LITERATURE_METRICS:
        raise UnknownNameError("metric", rank_by, LITERATURE_METRICS)
    return rank_by


def compare(table, models=(), published=None, *, options=None, rank_by: str = DEFAULT_RANK_BY,
            progress=None) -> Leaderboard:
    """Fit every model of ``models`` to ``table``, add the published fits of its material,
    score all on the same cells in the literature's metrics and rank them (module docstring).

    Args:
        table: a path (any format :func:`brdffit.fit` reads) or a table in memory.
        models: model names, a comma-separated string or a list; ``"model@preset"`` fits that
            model under a preset (``"beckmann@low2012-e2"``). May be empty when ``published``
            gives candidates.
        published: ``None``, a ``.fit`` file or a folder of them (``../shared/published/fits``);
            its fits of the table's material (by name) join the board.
        options: the fit options of every model (a :class:`~brdffit.config.FitOptions`, a
            mapping of option names); a model's ``@preset`` goes over them.
        rank_by: the metric to rank by (:data:`~brdffit.metrics.LITERATURE_METRICS`).
        progress: ``None`` or a callable taking one message per fit.

    Everything is checked before any fit: the model names, presets, the metric, the options and
    the published files (a malformed one raises, naming its line). Returns a
    :class:`Leaderboard`; a fit that does not converge is on it, marked.
    """
    from .api import load
    from .fitting import fit_options

    check_rank_by(rank_by)
    parsed = parse_models(models) if (models or published is None) else []
    fit_options(options)  # checked before the table is read
    for _, _, preset in parsed:
        _options_for(options, preset)
    data, _path = load(table)
    name = getattr(data, "name", "") or ""
    pub = published_candidates(published, name) if published is not None else []
    cells = scoring_cells(data)
    fits = _fit_candidates(data, parsed, options, progress)
    return board(data, fits + pub, rank_by, cells)


def board(data, candidates, rank_by: str = DEFAULT_RANK_BY, cells: Cells | None = None
          ) -> Leaderboard:
    """The :class:`Leaderboard` of ``candidates`` (:class:`Candidate` objects, or results:
    a :class:`brdffit.FitResult` becomes a ``"fit"`` labelled by its model, a
    :class:`~brdffit.published.PublishedResult` a ``"published"`` one) on ``data``: each scored
    on ``cells`` (default :func:`scoring_cells` of ``data``) and ranked by ``rank_by``. No fit is
    run: this ranks results made elsewhere (a batch's)."""
    from .published import PublishedResult

    check_rank_by(rank_by)
    cells = scoring_cells(data) if cells is None else cells
    out = []
    for c in candidates:
        if not isinstance(c, Candidate):
            c = (published_candidate(c) if isinstance(c, PublishedResult)
                 else Candidate(c.model_name, "fit", c))
        c.scores = score(cells, c.result.model_name, c.result.params)
        out.append(c)
    return Leaderboard(getattr(data, "name", "") or "", rank(out, rank_by), rank_by, len(cells))


# -- the HTML report --------------------------------------------------------------------------

def _png(fig, dpi: int = REPORT_DPI) -> str:
    """``<img>`` of ``fig`` as an embedded base64 PNG."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f"<img alt='figure' src='data:image/png;base64,{data}'>"


def spheres_figure(board: Leaderboard, data, size: int = 160):
    """One figure: the lit sphere of the data and of every candidate, side by side, under one
    tone mapping (the data's), each titled with its label and rank metric."""
    from .plots import InlineFigure, log_levels, log_tonemap, measured_lookup, render_sphere
    from .plots.sphere import DEFAULT_LIGHT, sphere_directions
    from .models.evaluate import evaluate_model

    meas = render_sphere(measured_lookup(data), size)
    inside, _, wi, wo = sphere_directions(size, DEFAULT_LIGHT)
    lit = inside & (wi[..., 2] > 0) & (wo[..., 2] > 0)
    levels = log_levels(meas[lit])
    images = [("measured", meas)]
    for c in board.candidates:
        img = render_sphere(lambda a, b, c=c: evaluate_model(c.model, c.result.params, a, b), size)
        images.append((f"{c.label}\n{board.rank_by} {_number(c.scores.get(board.rank_by, math.nan))}",
                       img))
    cols = min(len(images), 6)
    rows = -(-len(images) // cols)
    fig = InlineFigure(figsize=(2.2 * cols, 2.5 * rows), dpi=REPORT_DPI, layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, (label, img) in zip(axes, images):
        ax.imshow(log_tonemap(img, *levels), extent=(-1, 1, -1, 1))
        ax.set_title(label, fontsize=7)
        ax.set_axis_off()
    for ax in axes[len(images):]:
        ax.set_visible(False)
    fig.suptitle(f"{board.table or 'table'}: lit spheres, one tone mapping (the data's)",
                 fontsize=9)
    return fig


def _table_html(board: Leaderboard) -> str:
    names = list(LITERATURE_METRICS)
    best = {m: min((c.scores.get(m, math.inf) for c in board.candidates), default=math.inf)
            for m in names}
    head = "".join(f"<th title='{html.escape(LITERATURE_METRICS[m].label)}'>{html.escape(m)}</th>"
                   for m in names)
    rows = []
    for k, c in enumerate(board.candidates, 1):
        cells = "".join(
            f"<td{' class=best' if c.scores.get(m) == best[m] else ''}>"
            f"{_number(c.scores.get(m, math.nan))}</td>" for m in names)
        conv = "<b>NO</b>" if c.status == "NO" else c.status
        rows.append(f"<tr><td>{k}</td><td>{html.escape(c.label)}</td>"
                    f"<td>{html.escape(c.source)}</td><td>{conv}</td>{cells}</tr>")
    return ("<table class='board'><tr><th>rank</th><th>candidate</th><th>source</th>"
            f"<th>converged</th>{head}</tr>{''.join(rows)}</table>")


_STYLE = ("body{font-family:sans-serif;margin:1.5em;max-width:1400px}"
          "table.board{border-collapse:collapse;font-size:13px}"
          "table.board td,table.board th{border:1px solid #ccc;padding:3px 6px;text-align:right}"
          "table.board td:nth-child(2),table.board td:nth-child(3){text-align:left}"
          "td.best{background:#d8f0d8;font-weight:bold}img{max-width:100%}"
          "details{margin:0.6em 0}summary{cursor:pointer;font-weight:bold}")


def report_html(board: Leaderboard, data) -> str:
    """The self-contained HTML report (module docstring); ``data``: the table scored."""
    import jax

    from .plots import plot_peaks, plot_slice

    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>brdffit leaderboard: "
             f"{html.escape(board.table)}</title><style>{_STYLE}</style></head><body>",
             f"<h1>{html.escape(board.table or 'table')}: leaderboard</h1>",
             f"<p>{board.n_cells:,} cells, the same for every candidate; ranked by "
             f"<b>{html.escape(board.rank_by)}</b> "
             f"({html.escape(LITERATURE_METRICS[board.rank_by].label)}), lowest first; the best "
             f"value of each metric is green.</p>", _table_html(board),
             "<h2>What the metrics are</h2><ul>"]
    parts += [f"<li><b>{html.escape(m.name)}</b>: {html.escape(m.label)}, "
              f"<code>{html.escape(m.formula)}</code>: {html.escape(m.description)}</li>"
              for m in LITERATURE_METRICS.values()]
    parts.append("</ul>")
    with jax.enable_x64(True):
        parts += ["<h2>Lit spheres</h2>", _png(spheres_figure(board, data))]
        parts.append("<h2>Each candidate against the data</h2>")
        for k, c in enumerate(board.candidates, 1):
            error = f"{board.rank_by} {_number(c.scores.get(board.rank_by, math.nan))}"
            slice_fig = plot_slice(data, c.model, c.result.params, error=error)
            peaks_fig = plot_peaks(data, c.model, c.result.params, error=error)
            parts.append(f"<details{' open' if k == 1 else ''}><summary>{k}. "
                         f"{html.escape(c.label)} ({html.escape(c.source)})</summary>"
                         f"{_png(slice_fig)}{_png(peaks_fig)}</details>")
    parts.append("</body></html>")
    return "".join(parts)


__all__ = ["DEFAULT_RANK_BY", "Candidate", "Cells", "Leaderboard", "board", "compare", "parse_models",
           "published_candidates", "rank", "report_html", "score", "scoring_cells"]
