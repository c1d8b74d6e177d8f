"""One job of a batch: fit one model to one material, on a Dask worker, and write its files.

:func:`run` is what a worker executes. It never raises for a problem of its own job: a malformed
input, a fit that cannot start or any other exception becomes a row with ``outcome="error"`` and
the reason, so one bad job cannot stop a batch. (A job that takes its worker down, out of memory
or killed, is recorded by the client instead: see :mod:`brdffit.batch.runner`.)

Files, for material ``m`` and model ``k`` under ``outdir``:

* ``m/k.json``: the :class:`~brdffit.FitResult` as :meth:`~brdffit.FitResult.to_json` writes it
  (``brdffit plot --fit`` reads it); ``m/k-slice.png`` … with ``plot``.
* ``m/k.meta.json``: the table row and the resume key (input checksum, options key). Written
  last: a result counts as done only when its meta file exists and names the same checksum and
  options, so a job killed between two writes is simply fitted again.

Every file is written atomically: it appears complete or not at all; the temporary file of a job
killed in mid-write is removed when the pair is fitted again. Files are written and read through
:class:`brdffit.batch.outdir.Folder`: never through a symbolic link or into a special file (such
a refusal is the job's error); figures are drawn in a private staging folder in ``outdir`` and
then moved into the material's folder.
In a worker process the first job sets float64 (``jax_enable_x64``) and the persistent compilation
cache (:mod:`brdffit.compilation_cache`); later jobs reuse the process's compiled programs (one
compilation per model and table layout per worker). Fits within one process run one at a time.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import threading
import time
from pathlib import Path

from . import inputs, outdir as outdirs, table

_FIT_LOCK = threading.Lock()


@dataclasses.dataclass(frozen=True)
class Job:
    """Fit ``model`` to ``material`` with ``fit_kwargs`` (keywords of :func:`brdffit.fit`).

    ``source`` is the path, or the table itself (which the runner sends to the cluster once
    and passes to :func:`run` as ``table``; a Dask future is only resolved as an argument).
    """

    material: str
    model: str
    source: object
    input: str
    fit_kwargs: dict
    key: str

    def names(self, plot: bool = False) -> dict:
        """The file names this job writes in ``OUTDIR/<material>/`` (``plot``: with figures)."""
        names = {"json": f"{self.model}.json", "meta": f"{self.model}.meta.json"}
        if plot:
            from ..plots import figure_names, figure_paths

            names["plots"] = [p.name for p in figure_paths(f"{self.model}.png",
                                                           figure_names(self.source))]
        return names


def _canonical(value):
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    return repr(value)


def options_key(model: str, fit_kwargs: dict) -> str:
    """A short hash of the model name and the fit options: equal options give equal keys.

    Numbers are compared as floats (``cutoff=80`` and ``80.0`` are the same option); objects
    other than numbers, strings and containers by their ``repr``.
    """
    text = json.dumps({"model": model, "options": _canonical(fit_kwargs)}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@functools.cache
def prepare_process() -> str | None:
    """Once per worker process, before any JAX work: float64, the compilation cache, and a
    non-interactive matplotlib backend. Returns the compilation cache folder (or None)."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    import jax

    jax.config.update("jax_enable_x64", True)
    from .. import compilation_cache

    return compilation_cache.ensure()


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def run(job: Job, table_data=None, outdir=None, force: bool = False, plot: bool = False,
        want_result: bool = False) -> dict:
    """Run ``job`` (on ``table_data`` when given, else on ``job.source``); return
    ``{"row": dict, "result": FitResult dict or None}``. Never raises for the job's own
    failures (see the module docstring)."""
    t0 = time.perf_counter()
    if table_data is not None:
        job = dataclasses.replace(job, source=table_data)
    from .. import __version__

    base = {"material": job.material, "model": job.model, "skipped": False, "input": job.input,
            "options": job.key, "brdffit_version": __version__, "worker": _worker_name()}
    try:
        prepare_process()
        checksum = _checksum(job.source)
        base["checksum"] = checksum
        if outdir is not None and not force:
            done = _existing(job, outdir, checksum, plot, want_result)
            if done is not None:
                done["row"].update(skipped=True, input=job.input, worker=base["worker"])
                return done
        row, result = _fit_and_write(job, outdir, plot, base)
        row["job_time"] = time.perf_counter() - t0
        if outdir is not None:
            with outdirs.Folder.open(outdir, job.material, create=True) as folder:
                folder.write(job.names()["meta"], _json_bytes(
                    {"checksum": checksum, "options": job.key, "row": row}))
        return {"row": row, "result": result.to_dict() if want_result else None}
    except Exception as exc:  # noqa: BLE001 (recorded in the table with its reason)
        row = {**base, **table.failure_row("error", f"{type(exc).__name__}: {exc}"),
               "job_time": time.perf_counter() - t0}
        return {"row": row, "result": None}


def _checksum(source) -> str:
    if isinstance(source, (str, Path)):
        return inputs.file_checksum(source)
    return inputs.table_checksum(source)


def _fit_and_write(job: Job, outdir, plot: bool, base: dict):
    from ..fitting import fit

    data = inputs.read(job.source) if isinstance(job.source, (str, Path)) else job.source
    with _FIT_LOCK:
        result = fit(data, job.model, throw=False, **job.fit_kwargs)
    row = {**base, **table.result_row(result)}
    if outdir is not None:
        names = job.names()
        with outdirs.Folder.open(outdir, job.material, create=True) as folder:
            folder.remove(_stale_patterns(job.model))
            folder.write(names["json"], (result.to_json() + "\n").encode("utf-8"))
            if plot:
                _plot_into(folder, outdir, data, result, job.model)
        row["result"] = f"{job.material}/{names['json']}"
    return row, result


def _stale_patterns(model: str) -> tuple:
    """Temporary files left by an earlier job of this (material, model) that was killed while
    writing (an atomic write's ``.NAME.XXXX`` file; only this job writes these names)."""
    return (f".{model}.json.*", f".{model}.meta.json.*", f".{model}-*.png.*")


def _plot_into(folder, outdir, data, result, model: str) -> None:
    """Draw the figures in a private staging folder in ``outdir``, then move them in."""
    import shutil
    import tempfile

    stage = Path(tempfile.mkdtemp(prefix=".brdffit-", dir=outdir))
    try:
        for path in _plot(data, result, stage / f"{model}.png"):
            folder.move_in(path, Path(path).name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _plot(data, result, path) -> None:
    from ..models.registry import get_model
    from ..plots import diagnostics, result_error

    model = get_model(result.model_name)
    return diagnostics(data, model, result.params, path=path, error=result_error(result))


def _existing(job: Job, outdir, checksum: str, plot: bool, want_result: bool) -> dict | None:
    """The stored row (and result) when ``job`` was done with the same input and options."""
    names = job.names(plot)
    with outdirs.Folder.open(outdir, job.material, create=False) as folder:
        if folder is None:
            return None
        meta, text = folder.read(names["meta"]), folder.read(names["json"])
        if meta is None or text is None or not all(map(folder.is_file, names.get("plots", []))):
            return None
    try:
        meta = json.loads(meta.decode("utf-8"))
        if meta.get("checksum") != checksum or meta.get("options") != job.key:
            return None
        return {"row": dict(meta["row"]),
                "result": json.loads(text.decode("utf-8")) if want_result else None}
    except (ValueError, TypeError, KeyError, AttributeError):
        return None


def _json_bytes(obj) -> bytes:
    from ..fitting import json_safe

    return (json.dumps(json_safe(obj), indent=1) + "\n").encode("utf-8")
