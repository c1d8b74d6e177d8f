"""Diagnostic figures of a measured BRDF and, optionally, a fitted model (Burley 2012 §3).

Four views, one module each, each a function returning a :class:`matplotlib.figure.Figure`
(built without ``pyplot``: no GUI backend, nothing to close):

* :func:`plot_slice`: the image slice at φd = 90°, measured | fitted | log ratio.
* :func:`plot_peaks`: log f_r against θh at θd = 1°, 30°, 60°, 80° (φd = 90°).
* :func:`plot_albedo`: directional albedo against incidence angle.
* :func:`plot_spheres`: a sphere under a directional light, measured | fitted.
* :func:`plot_polar`: the lobe over the outgoing hemisphere at a few incidences, in polar
  coordinates, measured | fitted: the view of anisotropy (written for the inputs that can be
  anisotropic, :func:`figure_names`; available for any input through ``only``).

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
from .polar import lobe_maps, plot_polar
from .slice import plot_slice, slice_data
from .sphere import plot_spheres, render_sphere

#: The figures :func:`diagnostics` writes for every input, in order, with their file-name
#: suffixes.
FIGURES = (("slice", plot_slice), ("peaks", plot_peaks), ("albedo", plot_albedo),
           ("spheres", plot_spheres))
#: Figures written for some inputs only (:func:`figure_names`), after :data:`FIGURES`.
EXTRA_FIGURES = (("polar", plot_polar),)
_ALL = dict(FIGURES + EXTRA_FIGURES)


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
        error: title text for the fit's error; by default the RMS ln-ratio of
            :func:`rms_log_error` (computed once, on at most 100 000 valid measurements).
        only: the figures to write, a subset of ``("slice", "peaks", "albedo", "spheres",
            "polar")``; default :func:`figure_names` of ``data``.

    Files are written atomically (temporary file, then rename) and overwrite existing ones: the
    caller decides whether that is allowed.
    """
    if only is not None:
        unknown = sorted(set(only) - set(_ALL))
        if unknown:
            from ..errors import UnknownNameError

            raise UnknownNameError("figure", unknown[0], list(_ALL))
    names = [n for n in _ALL if n in (figure_names(data) if only is None else only)]
    if model is not None and error is None:
        error = format_error(rms_log_error(data, model, params))
    written = []
    for name, target in zip(names, figure_paths(path, names)):
        written.append(save_png(_ALL[name](data, model, params, error=error), target))
    return written


__all__ = [
    "EXTRA_FIGURES",
    "FIGURES",
    "diagnostics",
    "figure_names",
    "directional_albedo",
    "evaluate_model",
    "figure_paths",
    "format_error",
    "measured_albedo",
    "measured_lookup",
    "model_albedo",
    "plot_albedo",
    "lobe_maps",
    "plot_peaks",
    "plot_polar",
    "plot_slice",
    "plot_spheres",
    "render_sphere",
    "rms_log_error",
    "save_png",
    "slice_data",
]
