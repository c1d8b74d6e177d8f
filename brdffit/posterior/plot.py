"""Corner plot of a posterior (the ``corner`` package), with the truth or the LS optimum marked."""

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


def corner_plot(result, path, truths=None):
    """Write a corner plot of ``result.samples`` to ``path`` (format from the suffix).

    Dashed lines in each 1-D panel mark the 16/50/84 percentiles; the blue lines mark
    ``truths`` (see :func:`truth_vector`). Returns the ``matplotlib`` figure
    (a plain ``Figure``, not registered with ``pyplot``).
    """
    import corner
    from matplotlib.figure import Figure

    marks, label = truth_vector(result, truths)
    marks = [None if not np.isfinite(v) else float(v) for v in marks]
    d = len(result.sampled)
    fig = Figure(figsize=(1.6 * d + 1, 1.6 * d + 1))  # no pyplot: no backend, no global state
    corner.corner(
        np.asarray(result.samples), fig=fig, labels=list(result.sampled), truths=marks,
        quantiles=[0.16, 0.5, 0.84], show_titles=True, title_fmt=".3g",
        title_kwargs={"fontsize": 9}, label_kwargs={"fontsize": 9},
    )
    fig.suptitle(f"{result.model_name} posterior of {result.table or 'table'} "
                 f"(blue: {label})", fontsize=11, y=1.0)
    fig.savefig(Path(path), dpi=80, bbox_inches="tight")
    return fig
