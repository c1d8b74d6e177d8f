"""Corner plot of a posterior (the ``corner`` package), with the truth or the LS optimum marked:
:func:`corner_figure` returns it (``post.corner()``, shown inline in a notebook),
:func:`corner_plot` writes it to a file (``post.corner_plot(path)``, the command line's)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..models.registry import get_model


def truth_vector(result, truths) -> tuple[np.ndarray, str]:
    """Values to mark, one per sampled column, and a label for the legend.

    ``truths=None`` marks the least-squares optimum; a dict (parameter name → value, as in
    ``FitResult.params``; ``"sigma"`` allowed) marks those values (NaN where not given).
    """
    if truths is None:
        x_ls = dict(zip(result.names, np.asarray(result.x_ls, float)))
        return np.array([x_ls.get(n, np.nan) for n in result.sampled]), "least squares"
    model = get_model(result.model_name)
    flat = dict.fromkeys(model.flat_names(), np.nan)
    given = {k: v for k, v in truths.items() if k != "sigma"}
    for p in model.params:
        if p.name in given:
            vals = np.broadcast_to(np.asarray(given[p.name], float), p.shape).ravel()
            keys = [p.name] if p.shape == () else [f"{p.name}[{i}]" for i in range(p.size)]
            flat.update(zip(keys, vals))
    flat.update({k: float(v) for k, v in truths.items() if k in flat or k == "sigma"})
    return np.array([flat.get(n, np.nan) for n in result.sampled], float), "truth"


def interval_digits(p16: float, p50: float, p84: float) -> tuple[str, str, str]:
    """``(median, +upper, -lower)`` as text, all to the decimal place of the smaller half-width's
    second significant digit (``0.08012``, ``0.00011``, ``0.00010``): the digits the uncertainty
    supports, never ``0.08`` with ``+9.58e-06``. Plain ``%.6g`` when a half-width is not
    positive."""
    import math

    lo, hi = p50 - p16, p84 - p50
    err = min(lo, hi)
    if not (math.isfinite(err) and err > 0):
        return f"{p50:.6g}", f"{hi:.2g}", f"{lo:.2g}"
    dec = max(0, 1 - math.floor(math.log10(err)))
    return f"{p50:.{dec}f}", f"{hi:.{dec}f}", f"{lo:.{dec}f}"


def _titles(fig, result, d: int) -> None:
    """Two-line titles over the diagonal panels: the name, then ``median`` with the 16/84
    percentile offsets (:func:`interval_digits`)."""
    axes = np.asarray(fig.axes).reshape(d, d)
    for k, name in enumerate(result.sampled):
        mid, up, down = interval_digits(*result.percentiles[name])
        axes[k, k].set_title(f"{name}\n${mid}^{{+{up}}}_{{-{down}}}$", fontsize=8)


def corner_figure(result, truths=None):
    """A corner plot of ``result.samples`` (the ``corner`` package), as a matplotlib figure that
    a notebook shows inline (:class:`brdffit.plots.InlineFigure`, not registered with
    ``pyplot``).

    Dashed lines in each 1-D panel mark the 16/50/84 percentiles; the blue lines mark
    ``truths`` (see :func:`truth_vector`). Each diagonal panel is titled with the name and the
    median with its 16/84 offsets, to the digits the uncertainty supports
    (:func:`interval_digits`); at most three ticks per axis, rotated, with the axis labels
    set off so they do not overlap the tick labels.
    """
    import corner

    from ..plots import InlineFigure

    marks, label = truth_vector(result, truths)
    marks = [None if not np.isfinite(v) else float(v) for v in marks]
    d = len(result.sampled)
    fig = InlineFigure(figsize=(1.8 * d + 1, 1.8 * d + 1), dpi=80)
    corner.corner(
        np.asarray(result.samples), fig=fig, labels=list(result.sampled), truths=marks,
        quantiles=[0.16, 0.5, 0.84], show_titles=False, max_n_ticks=3, labelpad=0.2,
        label_kwargs={"fontsize": 9},
    )
    for ax in fig.axes:
        ax.tick_params(labelsize=7)
        ax.tick_params(axis="x", labelrotation=0)  # corner's 45° labels reach into the next panel
        ax.xaxis.get_offset_text().set_fontsize(7)
        ax.yaxis.get_offset_text().set_fontsize(7)
    _titles(fig, result, d)
    fig.suptitle(f"{result.model_name} posterior of {result.table or 'table'} "
                 f"(blue: {label})", fontsize=11, y=1.0)
    return fig


def corner_plot(result, path, truths=None):
    """Write :func:`corner_figure` to ``path`` (format from the suffix, 80 dpi, tight bounding
    box) and return the figure."""
    fig = corner_figure(result, truths)
    fig.savefig(Path(path), dpi=80, bbox_inches="tight")
    return fig
