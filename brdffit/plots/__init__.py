"""Diagnostic figures of a measured BRDF and, optionally, a fitted model (Burley 2012 §3).

Four views, one module each, each a function returning a :class:`matplotlib.figure.Figure`
(built without ``pyplot``: no GUI backend, nothing to close; a notebook shows it inline,
:class:`._style.InlineFigure`), drawn into a given figure or sub-figure with ``fig=``:

* :func:`plot_slice`: the image slice at φd = 90°, measured | fitted | ratio.
* :func:`plot_peaks`: log f_r against θh at θd = 1°, 30°, 60°, 80° (φd = 90°).
* :func:`plot_albedo`: directional albedo against incidence angle.
* :func:`plot_spheres`: a sphere under a directional light, measured | fitted.
* :func:`plot_polar`: the lobe over the outgoing hemisphere at a few incidences, in polar
  coordinates, measured | fitted: the view of anisotropy (written for the inputs that can be
  anisotropic, :func:`figure_names`; available for any input through ``only``).

``data`` is a MERL table (``data_formats.merl.MERLTable``) or a :class:`data_formats.SampleSet`;
the slice and the peak curves then bin the samples near φd = 90°, the albedo and the spheres use
the nearest sample (see each module). :func:`plot_diagnostics` draws the views as one figure,
:func:`plot_result` that figure of a :class:`~brdffit.FitResult` (what ``result.plot()``
returns), :func:`diagnostics` writes each view to its own PNG. The titles state the fit's
``rmse_log`` (:mod:`.error`, :mod:`brdffit.metrics`). JAX precision is the caller's choice
(enable ``jax_enable_x64`` for float64, as the CLI does; :func:`plot_result` runs in float64).
"""

from __future__ import annotations

from pathlib import Path

from ._eval import evaluate_model, measured_lookup
from ._style import InlineFigure, log_levels, log_tonemap, new_figure, save_png
from .albedo import directional_albedo, measured_albedo, model_albedo, plot_albedo
from .albedo import figure_size as _albedo_size
from .error import format_error, model_error, result_error, rms_log_error
from .peaks import figure_size as _peaks_size
from .peaks import plot_peaks
from .polar import figure_size as _polar_size
from .polar import lobe_maps, plot_polar
from .slice import figure_size as _slice_size
from .slice import plot_slice, slice_data
from .sphere import figure_size as _spheres_size
from .sphere import plot_spheres, render_sphere

#: The figures :func:`diagnostics` writes for every input, in order, with their file-name
#: suffixes.
FIGURES = (("slice", plot_slice), ("peaks", plot_peaks), ("albedo", plot_albedo),
           ("spheres", plot_spheres))
#: Figures written for some inputs only (:func:`figure_names`), after :data:`FIGURES`.
EXTRA_FIGURES = (("polar", plot_polar),)
_ALL = dict(FIGURES + EXTRA_FIGURES)
#: Each view's size in inches, with (True) or without (False) a fit drawn.
SIZES = {"slice": _slice_size, "peaks": lambda fitted: _peaks_size(),
         "albedo": lambda fitted: _albedo_size(), "spheres": _spheres_size,
         "polar": _polar_size}
#: The widest row of :func:`plot_diagnostics`, inches.
ROW_WIDTH = 15.4


def figure_names(source=None) -> tuple[str, ...]:
    """The figures :func:`diagnostics` writes by default for ``source`` (data, a path, or
    ``None``): :data:`FIGURES`, plus ``polar`` for a measurement that can be anisotropic and
    evaluates itself at any direction pair (an RGL material, or a path of a format whose
    reader gives one, :data:`brdffit.io.SELF_EVALUATING`)."""
    from ..io import SELF_EVALUATING, is_path, is_table, kind_of

    names = tuple(name for name, _ in FIGURES)
    if source is None:
        return names
    if is_path(source):
        polar = kind_of(source) in SELF_EVALUATING
    else:
        polar = not is_table(source) and callable(getattr(source, "eval", None))
    return names + (("polar",) if polar else ())


def figure_paths(path, names=None) -> list[Path]:
    """Where :func:`diagnostics` writes the figures ``names`` (default :data:`FIGURES`) for
    ``path``: ``fig.png`` → ``fig-slice.png``, ….

    A ``path`` that is an existing directory (or ends in a separator) receives ``slice.png``, ….
    """
    names = names or [name for name, _ in FIGURES]
    p = Path(path)
    if p.is_dir() or str(path).endswith(("/", "\\")):
        return [p / f"{name}.png" for name in names]
    stem = p.name[: -len(p.suffix)] if p.suffix.lower() == ".png" else p.name
    return [p.with_name(f"{stem}-{name}.png") for name in names]


def diagnostics(data, model=None, params=None, *, path, error: str | None = None,
                only=None) -> list[Path]:
    """Write the diagnostic PNGs for ``data`` (and the fit, if given); return their paths.

    Args:
        data: a MERL table or a :class:`data_formats.SampleSet`.
        model: a :class:`brdffit.Model` or a registry name; ``params`` its parameter dict
            (missing entries take the defaults). Both None: measured data only.
        path: ``"out/fig.png"`` writes ``out/fig-slice.png``, ``-peaks``, ``-albedo``,
            ``-spheres`` (and ``-polar``, :func:`figure_names`); an existing directory receives
            ``slice.png`` etc. (:func:`figure_paths`).
        error: title text for the fit's error; by default the ``rmse_log`` of the model over
            the data (:func:`.error.model_error`, computed once, on at most 100 000 valid
            measurements); pass :func:`result_error` of a fit result to state its own.
        only: an optional name or subset of ``("slice", "peaks", "albedo", "spheres",
            "polar")``; default :func:`figure_names` of ``data``.

    Files are written atomically (temporary file, then rename) and overwrite existing ones: the
    caller decides whether that is allowed.
    """
    names = _check_only(only, data)
    if model is not None and error is None:
        error = model_error(data, model, params)
    written = []
    for name, target in zip(names, figure_paths(path, names)):
        written.append(save_png(_ALL[name](data, model, params, error=error), target))
    return written


def _check_only(only, data=None) -> list[str]:
    """The names of the views ``only`` picks, in :data:`FIGURES` then :data:`EXTRA_FIGURES`
    order; without it the ones :func:`figure_names` gives ``data``."""
    if only is None:
        return list(figure_names(data))
    only = [only] if isinstance(only, str) else list(only)
    unknown = sorted(set(only) - set(_ALL))
    if unknown:
        from ..errors import UnknownNameError

        raise UnknownNameError("figure", unknown[0], list(_ALL))
    return [n for n in _ALL if n in only]


def _rows(names, fitted: bool) -> list[list[str]]:
    """The views packed into rows left to right, a row at most :data:`ROW_WIDTH` wide."""
    rows, width = [], 0.0
    for name in names:
        w = SIZES[name](fitted)[0]
        if rows and width + w <= ROW_WIDTH:
            rows[-1].append(name)
            width += w
        else:
            rows.append([name])
            width = w
    return rows


def plot_diagnostics(data, model=None, params=None, *, error: str | None = None, only=None):
    """The diagnostic views of :func:`diagnostics` as one figure (a sub-figure each, every view
    at its own size); returns it (a notebook shows it inline).

    ``only`` picks views (a name or names of :data:`FIGURES` and :data:`EXTRA_FIGURES`; by
    default :func:`figure_names` of ``data``); ``error`` is the title text of the fit's error
    (by default the model's ``rmse_log`` over ``data``, :func:`model_error`).
    """
    names = _check_only(only, data)
    fitted = model is not None
    if fitted and error is None:
        error = model_error(data, model, params)
    plots = _ALL
    rows = _rows(names, fitted)
    sizes = [[SIZES[n](fitted) for n in row] for row in rows]
    width = max(sum(w for w, _ in row) for row in sizes)
    heights = [max(h for _, h in row) for row in sizes]
    fig = new_figure(width, sum(heights))
    subs = fig.subfigures(len(rows), 1, height_ratios=heights, squeeze=False)[:, 0]
    for sub, row, size in zip(subs, rows, sizes):
        widths = [w for w, _ in size]
        spare = width - sum(widths)
        cells = sub.subfigures(1, len(row) + (spare > 0.05), squeeze=False,
                               width_ratios=widths + ([spare] if spare > 0.05 else []))[0]
        for cell, name in zip(cells, row):
            plots[name](data, model, params, error=error, fig=cell)
    return fig


def plot_result(result, data=None, *, only=None):
    """:func:`plot_diagnostics` of a fit result: its model and parameters, its own ``rmse_log``
    in the titles (:func:`result_error`). ``data``: what was fitted; by default the file the
    result names (``result.provenance["input"]["path"]``, :func:`result_data`). Evaluated in
    float64 (``jax.enable_x64`` for the call), as :func:`brdffit.fit` fits."""
    import jax

    if data is None:
        data = result_data(result)
    with jax.enable_x64(True):
        return plot_diagnostics(data, result.model_name, result.params,
                                error=result_error(result), only=only)


def result_data(result):
    """The data a fit result was fitted to, read again from the path its provenance records.

    Raises :class:`~brdffit.errors.BrdffitError` when the result names no file (it was
    fitted to data in memory: pass them) or the file changed since (its SHA-256 differs).
    """
    from ..errors import BrdffitError
    from ..io import read_path, sha256

    record = (result.provenance or {}).get("input") or {}
    path = record.get("path")
    if not path:
        raise BrdffitError(f"this {result.model_name} result records no input file (it was "
                           "fitted to data in memory); pass the data: result.plot(table)")
    from pathlib import Path

    if not Path(path).is_file():
        raise BrdffitError(f"{path}: the file this result was fitted to is gone; pass the "
                           "data: result.plot(table)")
    if record.get("sha256") and sha256(path) != record["sha256"]:
        raise BrdffitError(f"{path} changed since this result was fitted to it (SHA-256 "
                           "differs); pass the data: result.plot(table)")
    return read_path(path)


__all__ = [
    "EXTRA_FIGURES",
    "FIGURES",
    "InlineFigure",
    "diagnostics",
    "figure_names",
    "directional_albedo",
    "evaluate_model",
    "figure_paths",
    "format_error",
    "log_levels",
    "log_tonemap",
    "measured_albedo",
    "measured_lookup",
    "model_albedo",
    "model_error",
    "plot_albedo",
    "lobe_maps",
    "plot_diagnostics",
    "plot_peaks",
    "plot_polar",
    "plot_result",
    "plot_slice",
    "plot_spheres",
    "render_sphere",
    "result_data",
    "result_error",
    "rms_log_error",
    "save_png",
    "slice_data",
]
