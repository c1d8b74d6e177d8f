"""Diagnostic figures of a measured BRDF and, optionally, a fitted model (Burley 2012 §3).

Four views, one module each, each a function returning a :class:`matplotlib.figure.Figure`
(built without ``pyplot``: no GUI backend, nothing to close):

* :func:`plot_slice`: the image slice at φd = 90°, measured | fitted | log ratio.
* :func:`plot_peaks`: log f_r against θh at θd = 1°, 30°, 60°, 80° (φd = 90°).
* :func:`plot_albedo`: directional albedo against incidence angle.
* :func:`plot_spheres`: a sphere under a directional light, measured | fitted.

``data`` is a MERL table (``data_formats.merl.MERLTable``) or a :class:`data_formats.SampleSet`;
the slice and the peak curves then bin the samples near φd = 90°, the albedo and the spheres use
the nearest sample (see each module). :func:`diagnostics` writes all four PNGs at once.
JAX precision is the caller's choice (enable ``jax_enable_x64`` for float64, as the CLI does).
"""

from __future__ import annotations

from pathlib import Path

from ._eval import evaluate_model, measured_lookup
from ._style import save_png
from .albedo import directional_albedo, measured_albedo, model_albedo, plot_albedo
from .error import format_error, rms_log_error
from .peaks import plot_peaks
from .slice import plot_slice, slice_data
from .sphere import plot_spheres, render_sphere

#: The figures :func:`diagnostics` writes, in order, with their file-name suffixes.
FIGURES = (("slice", plot_slice), ("peaks", plot_peaks), ("albedo", plot_albedo),
           ("spheres", plot_spheres))


def figure_paths(path) -> list[Path]:
    """Where :func:`diagnostics` writes for ``path``: ``fig.png`` → ``fig-slice.png``, ….

    A ``path`` that is an existing directory (or ends in a separator) receives ``slice.png``, ….
    """
    p = Path(path)
    if p.is_dir() or str(path).endswith(("/", "\\")):
        return [p / f"{name}.png" for name, _ in FIGURES]
    stem = p.name[: -len(p.suffix)] if p.suffix.lower() == ".png" else p.name
    return [p.with_name(f"{stem}-{name}.png") for name, _ in FIGURES]


def diagnostics(data, model=None, params=None, *, path, error: str | None = None,
                only=None) -> list[Path]:
    """Write the diagnostic PNGs for ``data`` (and the fit, if given); return their paths.

    Args:
        data: a MERL table or a :class:`data_formats.SampleSet`.
        model: a :class:`brdffit.Model` or a registry name; ``params`` its parameter dict
            (missing entries take the defaults). Both None: measured data only.
        path: ``"out/fig.png"`` writes ``out/fig-slice.png``, ``-peaks``, ``-albedo``,
            ``-spheres``; an existing directory receives ``slice.png`` etc. (:func:`figure_paths`).
        error: title text for the fit's error; by default the RMS ln-ratio of
            :func:`rms_log_error` (computed once, on at most 100 000 valid measurements).
        only: an optional subset of ``("slice", "peaks", "albedo", "spheres")``.

    Files are written atomically (temporary file, then rename) and overwrite existing ones: the
    caller decides whether that is allowed.
    """
    names = [n for n, _ in FIGURES]
    if only is not None:
        unknown = sorted(set(only) - set(names))
        if unknown:
            from ..errors import UnknownNameError

            raise UnknownNameError("figure", unknown[0], names)
    if model is not None and error is None:
        error = format_error(rms_log_error(data, model, params))
    written = []
    for (name, plot), target in zip(FIGURES, figure_paths(path)):
        if only is not None and name not in only:
            continue
        written.append(save_png(plot(data, model, params, error=error), target))
    return written


__all__ = [
    "FIGURES",
    "diagnostics",
    "directional_albedo",
    "evaluate_model",
    "figure_paths",
    "format_error",
    "measured_albedo",
    "measured_lookup",
    "model_albedo",
    "plot_albedo",
    "plot_peaks",
    "plot_slice",
    "plot_spheres",
    "render_sphere",
    "rms_log_error",
    "save_png",
    "slice_data",
]
