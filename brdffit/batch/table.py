"""The table of a batch's results: one row per (material, model); its columns, files and summary.

The table of an output folder holds every result in it: a batch merges its rows into the table
already there (:func:`read`, :func:`merge`): a row of the same (material, model) is replaced,
every other row is kept, new ones follow. A table the batch cannot read as one of its own (not
parquet, a column missing, a (material, model) twice) stops the batch before any work
(:class:`~brdffit.batch.outdir.BatchOutputError`) instead of being dropped. Both files are
written atomically (:func:`write`): a failure or a signal leaves the old table as it was.

Columns, in this order (:data:`BASE_COLUMNS`, then per-result columns in order of appearance):

* ``material``, ``model``; ``success`` (the fit converged); ``outcome``: ``converged``,
  ``not converged``, ``degenerate`` (the data cannot determine the model: zeros, a constant,
  too few directions), ``implausible`` (the data are beyond any physical reflectance),
  ``error`` (the job raised: a malformed file, a fit that could not start) or ``worker died``
  (the process running it was lost: out of memory, killed); ``message`` (the solver's message,
  or the error); ``skipped`` (the row was read from an existing result).
* ``steps``, ``time`` (seconds of the fit itself), ``job_time`` (seconds of the whole job on its
  worker: reading, fitting, writing), ``cost``, ``n_cells``, ``at_bound`` (``name=lower;...``),
  ``not_identified`` (``name;...``: free parameters the data do not determine; no ``se_``).
* ``plausible`` (the fitted material passed every plausibility check:
  :mod:`brdffit.fitting.plausibility`; empty for a job without a result or a result older
  than the verdict), ``implausible`` (``name;...``: the checks it failed), ``albedo_max``
  (the ``energy`` check's largest directional albedo).
* ``input`` (the path, or ``<memory>``), ``checksum`` (``sha256:`` of the input),
  ``options`` (the key of the model and fit options, see :func:`brdffit.batch.jobs.options_key`),
  ``brdffit_version``, ``worker``, ``result`` (the JSON result's path, relative to the outdir).
* Then every error metric of the results (``rmse``, ``rmse_cosine``, ``rmse_log``, ``rel_error``)
  and, for every fitted parameter's flat name (``alpha``, ``f0[0]`` …), ``p_<name>`` and its
  standard error ``se_<name>``, then ``p_<name>`` of every quantity the model derives from
  them (``p_f90[0]`` …, no ``se_``); NaN where a model has no such parameter or a job failed.
"""

from __future__ import annotations

import math
import os

import numpy as np

BASE_COLUMNS = (
    "material", "model", "success", "outcome", "message", "skipped", "steps", "time", "job_time",
    "cost", "n_cells", "at_bound", "not_identified", "plausible", "implausible", "albedo_max",
    "input", "checksum", "options", "brdffit_version", "worker",
    "result",
)
#: ``degenerate`` and ``implausible`` (:data:`brdffit.fitting.outcome.DATA_VERDICTS`, spelled
#: here so that importing the batch package imports no JAX) are their own outcome; every other
#: failed fit is ``not converged``.
OUTCOMES = ("converged", "not converged", "degenerate", "implausible", "error", "worker died")
#: The metric that ranks models of one material in the summary (the fitted loss's RMS residual).
RANK_BY = "rmse"


def _flat(prefix: str, values: dict) -> dict:
    out = {}
    for name, v in values.items():
        a = np.asarray(v, float)
        if a.ndim == 0:
            out[f"{prefix}{name}"] = float(a)
        else:
            out.update({f"{prefix}{name}[{i}]": float(x) for i, x in enumerate(a.ravel())})
    return out


def result_row(result) -> dict:
    """The columns a :class:`~brdffit.FitResult` fills (everything but the job's own)."""
    row = {
        "success": bool(result.success),
        "outcome": ("converged" if result.success else result.status
                    if result.status in OUTCOMES else "not converged"),
        "message": str(result.message or ""),
        "steps": int(result.steps),
        "time": float(result.wall_time),
        "cost": float(result.cost),
        "n_cells": int(result.n_cells),
        "at_bound": ";".join(f"{k}={v}" for k, v in sorted(result.at_bound.items())),
        "not_identified": ";".join(result.not_identified),
    }
    row.update(_plausibility(result.plausibility))
    row.update({k: float(v) for k, v in result.metrics.items()})
    row.update(_flat("p_", result.params))
    row.update(_flat("se_", result.stderr))
    row.update(_flat("p_", result.derived))
    return row


def _plausibility(record: dict) -> dict:
    """The verdict's columns; none for a result without one (older than the verdict)."""
    if not record:
        return {}
    checks = record.get("checks", [])
    energy = [c["value"] for c in checks if c["name"] == "energy"]
    return {"plausible": bool(record["plausible"]),
            "implausible": ";".join(c["name"] for c in checks if c["passed"] is False),
            "albedo_max": float(energy[0]) if energy else float("nan")}


def failure_row(outcome: str, message: str) -> dict:
    """The columns of a job that produced no result."""
    assert outcome in ("error", "worker died"), outcome
    return {"success": False, "outcome": outcome, "message": " ".join(str(message).split())}


def frame(rows: list[dict]):
    """A pandas DataFrame of ``rows`` with the columns in the documented order."""
    import pandas as pd

    extra = list(dict.fromkeys(k for r in rows for k in r if k not in BASE_COLUMNS))
    metrics = [k for k in extra if not k.startswith(("p_", "se_"))]
    params = [c for k in extra if k.startswith("p_") for c in (k, "se_" + k[2:]) if c in extra]
    orphans = [k for k in extra if k.startswith("se_") and k not in params]
    columns = [*BASE_COLUMNS, *metrics, *params, *orphans]
    df = pd.DataFrame.from_records(rows, columns=columns)
    for col in ("success", "skipped"):
        df[col] = df[col].fillna(False).astype(bool)
    for col in ("steps", "n_cells"):
        df[col] = df[col].astype("Int64")
    df["plausible"] = df["plausible"].astype("boolean")  # <NA> where no verdict: Parquet keeps it
    return df


#: The columns a table must have for a batch to merge into it.
KEY = ("material", "model")
REQUIRED = (*KEY, "success", "outcome")


def read(outdir):
    """The table in ``outdir`` (``results.parquet``) as a DataFrame, ``None`` if there is none.

    :class:`~brdffit.batch.outdir.BatchOutputError` for a file that is not a batch table (not
    parquet, a required column missing, a (material, model) twice, a name that is not text),
    and for a ``results.csv`` without its ``results.parquet`` (the CSV is a copy: a batch
    would replace it by a table without its rows)."""
    import pandas as pd

    from .outdir import CLOEXEC, NOFOLLOW, BatchOutputError

    where = os.path.join(os.fspath(outdir), "results.parquet")
    hint = ("a batch merges its results into the table of its output folder: move the file "
            "away or choose another --outdir")
    try:
        fd = os.open(where, os.O_RDONLY | NOFOLLOW | CLOEXEC)
    except FileNotFoundError:
        csv = os.path.join(os.fspath(outdir), "results.csv")
        if os.path.lexists(csv):
            raise BatchOutputError(f"{csv}: exists without results.parquet, the table it copies; "
                                   f"{hint}") from None
        return None
    except OSError as exc:
        raise BatchOutputError(f"{where}: cannot read the existing table "
                               f"({exc.strerror or exc}); {hint}") from None
    try:
        with os.fdopen(fd, "rb") as f:
            df = pd.read_parquet(f)
    except Exception as exc:  # noqa: BLE001 (pyarrow's errors: not parquet, truncated)
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise BatchOutputError(f"{where}: not a table of brdffit batch results ({reason}); "
                               f"{hint}") from None
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        raise BatchOutputError(f"{where}: not a table of brdffit batch results (no column "
                               f"{', '.join(missing)}); {hint}")
    names = df[list(KEY)]
    if not all(isinstance(v, str) and v for v in names.to_numpy().ravel()):
        raise BatchOutputError(f"{where}: a row without a material or model name; {hint}")
    twice = names[names.duplicated()]
    if len(twice):
        m, model = twice.iloc[0]
        raise BatchOutputError(f"{where}: holds {m} × {model} more than once; {hint}")
    return df


def merge(previous, df):
    """``df`` (this batch's rows) merged into ``previous`` (:func:`read`, or ``None``).

    A row of ``previous`` whose (material, model) ``df`` has is replaced in place; the other
    rows of ``previous`` are kept; the rest of ``df`` follows, in its order. Returns the merged
    table and ``{"kept": ..., "replaced": ...}`` (rows of ``previous`` kept, and replaced)."""
    if previous is None or not len(previous):
        return df, {"kept": 0, "replaced": 0}
    new = {(r["material"], r["model"]): r for r in df.to_dict("records")}
    rows, replaced = [], 0
    for old in previous.to_dict("records"):
        row = new.pop((old["material"], old["model"]), None)
        replaced += row is not None
        rows.append(row if row is not None else
                    {k: v for k, v in old.items() if k in BASE_COLUMNS or not _missing(v)})
    rows += new.values()
    return frame(rows), {"kept": len(previous) - replaced, "replaced": replaced}


def _missing(value) -> bool:
    """NaN / NA: a column a row does not have (another model's parameter)."""
    import pandas as pd

    try:
        return bool(pd.isna(value))
    except (TypeError, ValueError):  # an array
        return False


def merge_note(df, merged: dict | None) -> str:
    """What the table holds beyond this batch's ``df`` ("" when nothing was kept or replaced)."""
    if not merged or not (merged["kept"] or merged["replaced"]):
        return ""
    total = len(df) + merged["kept"]
    replaced = (f" ({merged['replaced']} replacing an earlier result of the same material "
                f"and model)" if merged["replaced"] else "")
    return (f"the table holds {total} results: {len(df)} from this run{replaced}, "
            f"{merged['kept']} kept from earlier runs")


def write(df, outdir) -> list:
    """``results.parquet`` and ``results.csv`` in ``outdir``, each written atomically."""
    from pathlib import Path

    from data_formats.files import atomic_path

    paths = []
    for name, writer in (("results.parquet", lambda p: df.to_parquet(p, index=False)),
                         ("results.csv", lambda p: df.to_csv(p, index=False))):
        with atomic_path(Path(outdir) / name) as tmp:
            writer(tmp)
        paths.append(Path(outdir) / name)
    return paths


def best_models(df) -> dict:
    """Material → ``(model, rmse)`` of its converged fit with the lowest :data:`RANK_BY`."""
    ok = df[df["success"]]
    if RANK_BY not in ok or ok.empty:
        return {}
    ok = ok[np.isfinite(ok[RANK_BY].astype(float))]
    best = ok.loc[ok.groupby("material", sort=False)[RANK_BY].idxmin()]
    return {r.material: (r.model, float(getattr(r, RANK_BY))) for r in best.itertuples()}


def counts(df) -> dict:
    """``succeeded`` / ``failed`` (fitted in this run) and ``skipped`` (existing results)."""
    fitted = ~df["skipped"]
    return {"succeeded": int((fitted & df["success"]).sum()),
            "failed": int((fitted & ~df["success"]).sum()),
            "skipped": int(df["skipped"].sum())}


def summary(df, wall_time: float, where: str = "") -> str:
    """What a batch did, for people: counts, each failure with its reason, the best model per
    material (lowest RMS residual of the fitted loss among converged fits), total time."""
    c = counts(df)
    where = f" on {where}" if where else ""
    lines = [(f"{len(df)} fits: {c['succeeded']} succeeded, {c['failed']} failed, {c['skipped']} "
             f"skipped (existing results) in {_duration(wall_time)}{where}")]
    bad = df[~df["success"]]
    if len(bad):
        lines.append("not successful:")
        lines += [f"  {r.material} × {r.model}: {r.outcome}{' (skipped)' * bool(r.skipped)}: "
                  f"{r.message}" for r in bad.itertuples()]
    odd = df[df["plausible"].eq(False)] if "plausible" in df else df.iloc[:0]
    if len(odd):
        lines.append("implausible materials (the failed plausibility checks; see each result's "
                     "summary):")
        lines += [f"  {r.material} × {r.model}: {r.implausible}" for r in odd.itertuples()]
    best = best_models(df)
    if best:
        lines.append(f"best model per material (lowest {RANK_BY} among converged fits):")
        width = max(map(len, best))
        lines += [f"  {m:<{width}}  {model} ({RANK_BY} {v:.4g})" for m, (model, v) in best.items()]
    return "\n".join(lines)


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds) or seconds < 120:
        return f"{seconds:.1f} s"
    return f"{int(seconds // 60)} min {seconds % 60:02.0f} s"
