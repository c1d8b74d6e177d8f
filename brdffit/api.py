"""``brdffit.fit``: the notebook-facing fit, around :func:`brdffit.fitting.fit`.

What it adds to the low-level fit (to which it hands the options checked once, as a
:class:`~brdffit.fitting.Settings`):

* **a path**: ``table`` may be a ``str`` or ``os.PathLike``, read by suffix through
  :func:`brdffit.io.read_path` (the dispatch the command line uses);
* **float64 for the call**: the fit runs inside ``jax.enable_x64(True)``, so a session that
  never set ``jax_enable_x64`` gets the same converged float64 fit as one that did, and the
  global ``jax.config`` is left as it was (the library never changes it);
* **progress**: ``progress=True`` is a ``tqdm.auto`` bar (:mod:`brdffit.progress`), a callable
  still gets the fitter's events;
* **monochrome data**: a sample list with one value column fits a grey model
  (:mod:`brdffit.grey`);
* **provenance**: the result's ``provenance`` records the input (path, SHA-256), every option
  with its defaults resolved, the versions of brdffit, JAX and optimistix, and the date;
* **the persistent compilation cache**, turned on before the first fit of a process
  (:func:`brdffit.compilation_cache.ensure`: a per-user folder, opt-out), so a new process
  loads the programs an earlier one compiled;
* **a failed fit's result**: with ``throw=True`` the :class:`~brdffit.errors.FitError` of a
  fit that ran carries the result (``err.result``), finished as ``throw=False`` returns it;
* **a result with its uses**: :class:`FitResult`, the fitting layer's record
  (:class:`brdffit.fitting.FitResult`, the same fields and JSON) with the methods of the layers
  above it: ``plot()`` (:func:`brdffit.plots.plot_result`), ``export(to)``
  (:func:`brdffit.export.export_payload`) and ``render_merl()``
  (:func:`brdffit.export.render_merl`). They live here, at the top, so that the fitting layer
  imports nothing above it.
"""

from __future__ import annotations

import dataclasses
import datetime
import os
import platform
from pathlib import Path

from . import fitting
from .errors import FitError
from .io import formats_text, is_path, read_path, sha256


class FitResult(fitting.FitResult):
    """A fit's result, as :func:`brdffit.fit` returns it: the fields, JSON and reports of
    :class:`brdffit.fitting.FitResult`, plus the plot, the export and the MERL rendering.

    ``FitResult.from_json`` reads a file back as this class; :meth:`of` turns the fitting
    layer's record (from :func:`brdffit.fitting.fit`) into one.
    """

    @classmethod
    def of(cls, record: fitting.FitResult) -> FitResult:
        """``record`` (a :class:`brdffit.fitting.FitResult`) as this class, fields shared."""
        if isinstance(record, cls):
            return record
        return cls(**{f.name: getattr(record, f.name) for f in dataclasses.fields(record)})

    def render_merl(self, name: str | None = None, shape=None):
        """The fitted model on a whole MERL grid: :func:`brdffit.export.render_merl`."""
        from .export import render_merl

        return render_merl(self, name=name, shape=shape)

    def export(self, to: str, *, approximate: bool = False, **options):
        """The fitted material for a renderer: ``"mitsuba-dict"`` (what ``mitsuba.load_dict``
        takes), ``"mitsuba-xml"`` (a ``<bsdf>`` element) or ``"gltf"`` (a glTF 2.0 document).

        Delegates to :func:`brdffit.export.export_payload` (the parameter mapping and the
        ``approximate`` option are documented in :mod:`brdffit.export`).
        """
        from .export import export_payload

        return export_payload(self, to, approximate=approximate, **options)

    def plot(self, data=None, *, only=None):
        """The diagnostic figures of this fit as one matplotlib ``Figure`` (shown inline in a
        notebook): the image slice, the specular-peak curves, the directional albedo and the lit
        spheres, measured beside fitted, the titles stating this fit's ``rmse_log``.

        ``data`` is what was fitted; by default the file ``provenance`` names is read again
        (a result fitted to data in memory needs them). ``only`` picks views by name
        (``"slice"``, ``"peaks"``, ``"albedo"``, ``"spheres"``). Delegates to
        :func:`brdffit.plots.plot_result`; ``brdffit.plots.diagnostics`` writes PNG files.
        """
        from .plots import plot_result

        return plot_result(self, data, only=only)


def _jsonable(value):
    """Options as plain JSON values: names for objects, dicts of lists for parameter maps."""
    import numpy as np

    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in np.asarray(value, dtype=object).tolist()]
    if hasattr(value, "params") and hasattr(value, "model_name"):  # init=FitResult
        return {"from_fit": value.model_name, **_jsonable(value.params)}
    if hasattr(value, "label"):  # a Loss
        return value.label
    if hasattr(value, "size") and hasattr(value, "method"):  # a Subsample
        return {"size": value.size, "method": value.method}
    return getattr(value, "name", None) or type(value).__name__


def versions() -> dict:
    """Versions of brdffit and of what computed the fit."""
    from importlib.metadata import PackageNotFoundError, version

    from . import __version__

    out = {"brdffit": __version__, "python": platform.python_version()}
    for dist in ("jax", "jaxlib", "optimistix", "equinox", "numpy"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = None
    return out


def _input_record(table, path) -> dict:
    source = path if path is not None else getattr(table, "path", None)
    record = {"name": getattr(table, "name", "") or "", "path": None, "sha256": None}
    if source is not None and Path(source).is_file():
        record["path"] = str(Path(source).resolve())
        record["sha256"] = sha256(source)
    return record


def resolved_options(model, options: dict) -> dict:
    """Every option of the fit: the given ones over the code's defaults, with the solver
    tolerances' dtype-dependent defaults and the default precision filled in (float64: the
    call runs with x64 enabled)."""
    from .fitting import FIT_DEFAULTS, tolerances
    from .models.registry import get_model

    merged = {**FIT_DEFAULTS, **options}
    precision = merged.get("precision") or "float64"
    merged["precision"] = precision
    merged["rtol"], merged["atol"], merged["ftol"] = tolerances(
        precision, merged.get("rtol"), merged.get("atol"), merged.get("ftol"))
    merged["model"] = get_model(model).name
    return _jsonable(merged)


def provenance(table, path, model, options: dict) -> dict:
    """The ``provenance`` record of a result (see :class:`brdffit.fitting.FitResult`)."""
    return {
        "input": _input_record(table, path),
        "options": resolved_options(model, options),
        "versions": versions(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def load(table):
    """``(data, path)``: a path is read by :func:`brdffit.io.read_path`; anything else is
    returned as is (it must have ``.to_samples()``), with ``path=None``."""
    if is_path(table):
        return read_path(table), Path(os.fspath(table))
    if not hasattr(table, "to_samples"):
        raise TypeError(
            f"table must be a path (str or PathLike: {formats_text()}) or an object with "
            f".to_samples() (MERLTable, SampleSet, RGLMaterial); got {type(table).__name__}"
        )
    return table, None


def fit(table, model, options=None, *, progress=None, throw: bool = True, **kwargs):
    """Fit ``model`` to ``table``: :func:`brdffit.fitting.fit` with a path accepted, float64
    enabled for the call, ``progress=True`` as a progress bar, and the provenance recorded in
    the result.

    Args:
        table: a path (``str`` or ``PathLike``; any format of :data:`brdffit.io.READERS`:
            ``.binary`` MERL table, ``.csv``/``.npz`` sample list, ``.bsdf`` RGL material) or
            anything with ``.to_samples()``.
        model: a registry name or a :class:`~brdffit.models.Model`. Monochrome data (a
            sample list with one ``value`` column) fit its grey variant (:mod:`brdffit.grey`).
        options: a :class:`~brdffit.config.FitOptions` (e.g. a preset from
            :func:`brdffit.config.load_config`) or a mapping of option names; ``kwargs``
            override it, option by option.
        progress: ``True`` (a ``tqdm.auto`` bar), ``None``/``False``, or a callable
            ``progress(event, info)`` (events in :func:`brdffit.fitting.fit`).
        throw: raise :class:`~brdffit.errors.FitError` when the fit does not converge or
            the data do not determine the model; the error's ``result`` is the failed fit's
            :class:`~brdffit.fitting.FitResult` (``success=False``, ``status``, ``message``;
            provenance recorded). ``throw=False`` returns that result instead (scipy's and
            lmfit's convention); a fit that cannot start (no usable cells) raises either way.
        **kwargs: the options, by name: the fields of :class:`~brdffit.config.FitOptions`
            but ``model`` (:class:`brdffit.fitting.Settings` describes each).
    """
    import jax

    from . import compilation_cache
    from .grey import is_monochrome, tie_options
    from .models.registry import get_model
    from .progress import resolve

    options = fitting.fit_options(options, **kwargs)  # checked before the input is touched
    data, path = load(table)
    solve_options, tied = options, {}
    if is_monochrome(data):
        solve_options, tied = tie_options(get_model(model), options)
    compilation_cache.ensure()
    callback, bar = resolve(progress)
    try:
        with jax.enable_x64(True):
            settings = fitting.Settings.of(solve_options)  # the defaults of float64
            result = fitting.fit(data, model, settings, progress=callback, throw=throw)
    except FitError as err:
        if err.result is not None:  # a fit that ran: its result as throw=False returns it
            err.result = _finished(err.result, data, path, model, options, tied)
        raise
    finally:
        if bar is not None:
            bar.close()
    return _finished(result, data, path, model, options, tied)


def _finished(result, data, path, model, options, tied):
    """``result`` with its provenance, and in the data's channels (:func:`brdffit.grey.untie`),
    as a :class:`FitResult`."""
    from .grey import untie
    from .models.registry import get_model

    record = provenance(data, path, model, options)
    if tied:
        result = untie(result, get_model(model), tied)
        record.update(channels=1, tied=tied)
    return FitResult.of(dataclasses.replace(result, provenance=record))
