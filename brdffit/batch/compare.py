"""A batch's leaderboards: per material, its fits and its published fits ranked on the same cells.

``brdffit batch ... --compare [--published DIR]`` runs the batch as usual, then, for every
material, scores the results of its jobs that have parameters (converged or not; a job that
failed without a result is left out) and the published fits of that material (matched by the
material's name, the input's file stem) on the material's cells in the literature's metrics,
and ranks them (:func:`brdffit.leaderboard.board`). The rows of all materials make one table,
``OUTDIR/leaderboard.parquet`` and its copy ``leaderboard.csv`` (the columns of
:attr:`brdffit.leaderboard.Leaderboard.frame`, ``material`` first), written atomically; a
material whose input cannot be read is left out and named in the returned notes.

The scoring runs in the calling process, after the fits (each material's table is read once
more); it runs no fit.
"""

from __future__ import annotations

import os
from pathlib import Path

#: The leaderboard's files in OUTDIR (also in :data:`brdffit.batch.outdir.TABLE_FILES`).
LEADERBOARD_FILES = ("leaderboard.parquet", "leaderboard.csv")


def leaderboards(job_list, results, published=None, rank_by=None, progress=None):
    """``(frame, notes)``: the leaderboard rows of every material of ``job_list`` (jobs of
    :func:`brdffit.batch.runner.make_jobs`, ``results`` the :class:`~brdffit.FitResult` of each
    job or ``None``, in job order), with the published fits in ``published`` (a ``.fit`` file or
    folder, or ``None``); ``notes`` says which materials were left out and why."""
    import pandas as pd

    from ..errors import BrdffitError
    from ..io import read_path
    from ..leaderboard import DEFAULT_RANK_BY, board
    from ..published import load_published

    rank_by = rank_by or DEFAULT_RANK_BY
    pub = load_published(published) if published is not None else []
    by_material: dict = {}
    for job, result in zip(job_list, results):
        entry = by_material.setdefault(job.material, [job.source, []])
        if result is not None:
            entry[1].append(result)
    frames, notes = [], []
    for material, (source, fits) in by_material.items():
        candidates = fits + [r for r in pub if r.table == material]
        if not candidates:
            notes.append(f"{material}: no result to rank")
            continue
        if progress is not None:
            progress(f"scoring {material}")
        try:
            data = read_path(source) if isinstance(source, (str, os.PathLike)) else source
            frames.append(board(data, candidates, rank_by).frame)
        except (BrdffitError, OSError, ValueError) as exc:
            notes.append(f"{material}: {' '.join(str(exc).split())}")
    frame = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    return frame, notes


def write(frame, outdir) -> list:
    """``leaderboard.parquet`` and ``leaderboard.csv`` in ``outdir``, each written atomically."""
    from data_formats.files import atomic_path

    paths = []
    for name, writer in zip(LEADERBOARD_FILES, (lambda p: frame.to_parquet(p, index=False),
                                                lambda p: frame.to_csv(p, index=False))):
        with atomic_path(Path(outdir) / name) as tmp:
            writer(tmp)
        paths.append(Path(outdir) / name)
    return paths


def summary(frame) -> str:
    """One line per material: its best candidate by the ranking metric, and the best published
    fit with its rank (when there is one)."""
    if frame.empty:
        return "leaderboard: no material to rank"
    lines = []
    for material, rows in frame.groupby("material", sort=False):
        top = rows.iloc[0]
        line = f"  {material}: best {top['candidate']}"
        pub = rows[rows["kind"] == "published"]
        if len(pub) and top["kind"] != "published":
            first = pub.iloc[0]
            line += f"; best published {first['candidate']} (rank {int(first['rank'])})"
        lines.append(line)
    return "leaderboard (best first per material):\n" + "\n".join(lines)
