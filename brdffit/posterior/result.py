"""The result of :func:`~brdffit.posterior.sample_posterior`: percentiles, diagnostics, chain.

Vocabulary follows :class:`~brdffit.fitting.FitResult`: ``names`` are the model's flat scalar names
(``f0[0]`` ...), ``free``/``fixed`` say which were sampled; ``params`` holds the posterior
medians grouped by parameter (a list for RGB), fixed scalars keeping their fixed value.
``percentiles`` maps every sampled flat name (and ``sigma`` when the noise scale is sampled) to
its 16/50/84 percentiles. The chain itself goes to an NPZ file (:meth:`save_chain`), not to JSON.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from .._columns import columns
from .diagnostics import Diagnostics

#: The percentiles reported for every sampled scalar (median and a 68% interval).
PERCENTILES = (16.0, 50.0, 84.0)


def _median_interval(row) -> str:
    """``p50 −a +b`` with digits that follow the smaller half-width (two significant digits)."""
    import math

    lo, mid, hi = row["p50"] - row["p16"], row["p50"], row["p84"] - row["p50"]
    err = min(lo, hi)
    if not (math.isfinite(err) and err > 0):
        return f"{mid:.6g}"
    dec = max(0, 1 - math.floor(math.log10(err)))
    return f"{mid:.{dec}f} −{lo:.{dec}f} +{hi:.{dec}f}"


#: What the likelihood assumes of the residuals, by noise mode (:mod:`.likelihood`).
_NOISE_MODELS = {
    "sandwich": "independent residuals of the scale σ learned from them, the curvature "
                "calibrated to their sandwich covariance (no common spread assumed)",
    "fixed": "independent Gaussian residuals of one scale σ learned from them",
    "sampled": "independent Gaussian residuals of one scale σ sampled under a Jeffreys prior",
    "given": "independent Gaussian residuals of the given scale σ",
    "measured": "independent Gaussian measurement errors of the data's own sigma columns",
}


def interval_meaning(noise_mode: str, n_cells: int, fit_n_cells: int | None = None) -> str:
    """One sentence: what the 16–84 % interval of a run covers (its summary's last line)."""
    cells = f"{n_cells} cells"
    if fit_n_cells and fit_n_cells != n_cells:
        cells = f"{n_cells} of the fit's {fit_n_cells} cells"
    model = _NOISE_MODELS.get(noise_mode, _NOISE_MODELS["given"])
    return (f"p16–p84: 68 % credible intervals on {cells}, under {model}; they do not cover "
            f"the model error between this model and the material, which is correlated from "
            f"cell to cell")


@dataclasses.dataclass
class PosteriorResult:
    """Outcome of :func:`~brdffit.posterior.sample_posterior`.

    Attributes:
        model_name, table: what was sampled, on what.
        names: flat names of all scalars; free: those sampled; fixed: those held fixed.
        sampled: column names of ``samples``/``chain`` (``free`` plus ``"sigma"`` if sampled).
        params: posterior medians by parameter (fixed scalars at their value).
        percentiles: sampled name → ``[p16, p50, p84]``. std: sampled name → posterior std.
        x_ls: the least-squares optimum on the posterior's cells (flat, all scalars);
            stderr_ls: free name → its least-squares standard error there (NaN at a bound or
            not identified).
        samples: ``(n, d)`` post-burn, thinned draws. chain: ``(nsteps, nwalkers, d)`` all
            steps, unthinned. log_prob: ``(nsteps, nwalkers)``.
        noise: ``{"mode": "sandwich"|"fixed"|"sampled"|"measured"|"given", "sigma": value
            (median if sampled), "sigma_ls": the least-squares s}``.
        prior: sampled name → a label of its prior. diagnostics: :class:`Diagnostics`.
        settings: nwalkers, nsteps, burn, thin, seed, loss, cutoff, subsample, n_cells (the
            posterior's), fit_n_cells (those of the fit it was given).
        wall_time: seconds for the whole call; timings: ``fit``, ``compile``, ``sample``.
    """

    model_name: str
    table: str
    names: list
    free: list
    fixed: list
    sampled: list
    params: dict
    percentiles: dict
    std: dict
    x_ls: np.ndarray
    stderr_ls: dict
    samples: np.ndarray
    chain: np.ndarray
    log_prob: np.ndarray
    noise: dict
    prior: dict
    diagnostics: Diagnostics
    settings: dict
    wall_time: float
    timings: dict

    def interval(self, name: str, level: float = 0.95) -> tuple[float, float]:
        """The central credible interval of ``name`` holding ``level`` of the posterior mass."""
        if name not in self.sampled:
            raise KeyError(f"{name!r} was not sampled; sampled scalars: {', '.join(self.sampled)}")
        tail = 50.0 * (1.0 - float(level))
        col = self.samples[:, self.sampled.index(name)]
        lo, hi = np.percentile(col, [tail, 100.0 - tail])
        return float(lo), float(hi)

    def summary(self) -> str:
        """Readable lines: the run, each scalar's 16/50/84 percentiles beside the LS fit."""
        s, d = self.settings, self.diagnostics
        lines = [
            f"{self.model_name} posterior of {self.table or 'table'} ({s['loss']} loss, noise "
            f"{self.noise['mode']} σ={self.noise['sigma']:.4g}): {s['nwalkers']} walkers x "
            f"{s['nsteps']} steps (burn {s['burn']}, thin {s['thin']}), {s['n_cells']} cells, "
            f"{self.wall_time:.1f} s",
        ]
        x_ls = dict(zip(self.names, np.asarray(self.x_ls, float)))
        rows = [("", "", "p16", "p50", "p84", "LS (same cells)", "tau", "ess")]
        for n in self.sampled:
            p = self.percentiles[n]
            se = self.stderr_ls.get(n, float("nan"))
            ls = "" if n not in x_ls else (f"{x_ls[n]:.5g} ± {se:.3g}" if np.isfinite(se)
                                           else f"{x_ls[n]:.5g} (no error)")
            rows.append((n, "=", *(f"{v:.5g}" for v in p[:3]), ls, f"{d.tau[n]:.1f}",
                         f"{d.ess[n]:.0f}"))
        width = max([10] + [len(n) for n in [*self.sampled, *self.fixed]])  # the name column
        lines += columns(rows, ">>>>>>>>", indent="  ", gap=" ",
                         minimum=(width, 1, 10, 10, 10, 24, 7, 7))
        lines += [f"  {n:>{width}} = {x_ls[n]:.5g} (fixed)" for n in self.fixed]
        lines.append(f"  acceptance {d.acceptance:.3f} (walkers {d.acceptance_min:.2f}–"
                     f"{d.acceptance_max:.2f}); {'TOO SHORT' if d.too_short else 'chain ≥ 50 τ'}")
        lines += [f"  warning: {m}" for m in d.messages]
        lines.append(f"  {self.interval_meaning}")
        return "\n".join(lines)

    @property
    def interval_meaning(self) -> str:
        """What the intervals cover (:func:`interval_meaning`): the cells, the noise model."""
        return interval_meaning(self.noise.get("mode", "given"), self.settings.get("n_cells", 0),
                                self.settings.get("fit_n_cells"))

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        """One line: model, input, walkers × steps, the medians, acceptance, worst τ."""
        d = self.diagnostics
        med = ", ".join(f"{n}={self.percentiles[n][1]:.4g}" for n in self.sampled)
        tau = max(d.tau.values()) if d.tau else float("nan")
        return (f"PosteriorResult({self.model_name!r} on {self.table or 'table'!r}: "
                f"{self.settings['nwalkers']}x{self.settings['nsteps']}, {med}, "
                f"acceptance={d.acceptance:.2f}, max tau={tau:.1f})")

    def rows(self) -> list[dict]:
        """One dict per sampled scalar: ``name``, ``p16``, ``p50``, ``p84``, ``std``, ``tau``,
        ``ess``, and the least-squares ``ls_value`` and ``ls_stderr`` (NaN for ``sigma``)."""
        d = self.diagnostics
        x_ls = dict(zip(self.names, np.asarray(self.x_ls, float)))
        return [{
            "name": n, "p16": p[0], "p50": p[1], "p84": p[2], "std": self.std[n],
            "tau": float(d.tau[n]), "ess": float(d.ess[n]),
            "ls_value": float(x_ls.get(n, float("nan"))),
            "ls_stderr": float(self.stderr_ls.get(n, float("nan"))),
        } for n, p in ((n, self.percentiles[n]) for n in self.sampled)]

    def to_dataframe(self):
        """A ``pandas.DataFrame``, one row per sampled scalar (columns of :meth:`rows`, indexed
        by ``name``)."""
        import pandas as pd

        return pd.DataFrame(self.rows()).set_index("name")

    def _repr_html_(self) -> str:
        """Jupyter's view: the run, a table of percentiles beside the least-squares values,
        τ and effective sample sizes, the acceptance and any warnings."""
        import html

        from ..fitting import value_with_error

        s, d = self.settings, self.diagnostics
        esc = html.escape
        head = (f"<b>{esc(self.model_name)}</b> posterior of <code>{esc(self.table or 'table')}"
                f"</code> ({esc(str(s['loss']))} loss, noise {esc(self.noise['mode'])} "
                f"σ={self.noise['sigma']:.4g}): {s['nwalkers']} walkers × {s['nsteps']} steps "
                f"(burn {s['burn']}), {s['n_cells']} cells, {self.wall_time:.1f} s")
        body = "".join(
            f"<tr><td>{esc(r['name'])}</td><td>{esc(_median_interval(r))}</td>"
            f"<td>{esc(value_with_error(r['ls_value'], r['ls_stderr']))}</td>"
            f"<td>{r['tau']:.1f}</td><td>{r['ess']:.0f}</td></tr>"
            for r in self.rows()
        )
        table = ("<table><thead><tr><th>parameter</th><th>median (16–84 %)</th>"
                 "<th>least squares (same cells)</th><th>τ</th><th>ess</th></tr></thead>"
                 f"<tbody>{body}</tbody></table>")
        verdict = "chain too short (&lt; 50 τ)" if d.too_short else "chain ≥ 50 τ"
        warn = "".join(f"<p>warning: {esc(m)}</p>" for m in d.messages)
        return (f"<div class='brdffit-posterior'><p>{head}</p>{table}<p>acceptance "
                f"{d.acceptance:.3f} (walkers {d.acceptance_min:.2f}–{d.acceptance_max:.2f}); "
                f"{verdict}</p>{warn}<p><small>{esc(self.interval_meaning)}</small></p></div>")

    def to_dict(self) -> dict:
        """Everything but the chain arrays (see :meth:`save_chain`), as plain Python values."""
        return {
            "model_name": self.model_name, "table": self.table, "names": list(self.names),
            "free": list(self.free), "fixed": list(self.fixed), "sampled": list(self.sampled),
            "params": self.params, "percentiles": self.percentiles, "std": self.std,
            "percentile_levels": list(PERCENTILES),
            "x_ls": [float(v) for v in np.asarray(self.x_ls, float)],
            "stderr_ls": self.stderr_ls, "noise": self.noise, "prior": self.prior,
            "diagnostics": self.diagnostics.to_dict(), "settings": self.settings,
            "wall_time": self.wall_time, "timings": self.timings,
            "intervals": self.interval_meaning,
        }

    def to_json(self, path=None, indent: int = 2) -> str:
        """Strict JSON (NaN as ``null``); also written to ``path`` if given."""
        from ..fitting import json_safe

        text = json.dumps(json_safe(self.to_dict()), indent=indent)
        if path is not None:
            Path(path).write_text(text)
        return text

    def save_chain(self, path) -> Path:
        """The chain as NPZ: ``chain``, ``log_prob``, ``samples``, ``names`` (``sampled``),
        ``burn``, ``thin``. ``np.load(path)`` reads it back."""
        path = Path(path)
        with open(path, "wb") as f:  # a file object: numpy would append ".npz" to a bare name
            np.savez_compressed(
                f, chain=self.chain, log_prob=self.log_prob, samples=self.samples,
                names=np.asarray(self.sampled), burn=self.settings["burn"],
                thin=self.settings["thin"],
            )
        return path

    def corner(self, truths=None):
        """A corner plot of the samples (the ``corner`` package) as a matplotlib figure, shown
        inline in a notebook; ``truths`` marks values (default: the least-squares optimum). See
        :func:`~brdffit.posterior.plot.corner_figure`; :meth:`corner_plot` writes a file."""
        from .plot import corner_figure

        return corner_figure(self, truths)

    def corner_plot(self, path, truths=None):
        """A corner plot of the samples (the ``corner`` package) written to ``path``; see
        :func:`~brdffit.posterior.plot.corner_plot`."""
        from .plot import corner_plot

        return corner_plot(self, path, truths=truths)
