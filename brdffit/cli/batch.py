"""``brdffit batch INPUT… --model M1,M2 --outdir DIR``: fit many tables with many models, on Dask.

Every option of ``brdffit fit`` that shapes the fit (``--config``, ``--loss``, ``--solver``,
``--cutoff``, ``--fix``, ``--init``, ``--subsample``, ``--seed``, ``--multistart``) applies to
every job; options are merged and checked against each model before anything runs (a bad name
or value is exit 2, as for ``fit``). Results, the table, resuming and failure isolation are
described in :mod:`brdffit.batch`; where jobs run in :mod:`brdffit.batch.runner`.

Exit codes: 0 every (material, model) has a converged result; 1 some did not (not converged,
an error, a worker that died; each is in the table with its reason); 2 the invocation was wrong
(no input matched, a list of paths that is not UTF-8 text or too large, unknown model, bad
option, a scheduler address that is not one, an outdir that is a file, not writable, holds a
symbolic link or special file where a result belongs, or a ``results.parquet`` that is not a
batch table). Every such check is made before any fit.

``OUTDIR/results.parquet`` (and its copy ``results.csv``) is the table of every result in
OUTDIR: a batch merges its rows into it (a row of the same material and model is replaced, the
others are kept; the ``wrote`` line says how many), see :mod:`brdffit.batch.table`.

``--compare`` (with ``--published PATH``, the published fits) then ranks, per material, its
fits and its published fits on the same cells in the literature's metrics, prints the best of
each and writes ``OUTDIR/leaderboard.parquet`` and ``.csv`` (:mod:`brdffit.batch.compare`);
``--published`` is read, and refused when malformed, before any fit.

The local cluster is closed to other users (TLS with credentials of its own, loopback only) and
serves no HTTP; ``--dashboard [ADDR]`` starts the scheduler's dashboard (default
``127.0.0.1:8787``, loopback only) and prints its link on stderr (another port, said so, when
that one is in use).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..io import formats_text
from ._common import UsageError
from ._signals import add_cleanup, remove_cleanup
from .fitting import add_fit_options


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "batch",
        parents=parents,
        allow_abbrev=False,
        help="fit many tables with many models (on Dask), resumably",
        description="Fit every MODEL to every INPUT on a Dask cluster (by default local worker "
        "processes, one per core) and write OUTDIR/<material>/<model>.json per fit, "
        "OUTDIR/results.parquet and OUTDIR/results.csv (the table of every result in OUTDIR: "
        "a rerun merges its rows in, replacing those of the same material and model), and a "
        "summary. A rerun skips fits whose "
        "result exists for the same input checksum and options (--force refits). A failing "
        "input or fit is recorded and the batch goes on. Exit 0: all fits converged; 1: some "
        "did not; 2: bad invocation.",
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help=f"input files ({formats_text()}), globs ('data/*.binary'), or a "
                   "text file listing paths one per line")
    p.add_argument("--model", "-m", help="model names, comma-separated (ggx,beckmann,gtr); "
                   "default: the preset's model")
    add_fit_options(p.add_argument_group("fit options (as for `brdffit fit`, applied to every job)"))
    p.add_argument("--outdir", "-o", required=True, metavar="DIR",
                   help="folder for the results (created if needed)")
    p.add_argument("--plot", action="store_true",
                   help="also write each fit's figures (OUTDIR/<material>/<model>-slice.png, ...)")
    p.add_argument("--force", action="store_true", help="refit even where a result exists")
    from ..leaderboard import DEFAULT_RANK_BY
    from ..metrics import LITERATURE_METRICS

    p.add_argument("--compare", action="store_true",
                   help="also rank, per material, its fits and its published fits (--published) "
                   "on the same cells in the literature's metrics: OUTDIR/leaderboard.parquet "
                   "and .csv (see `brdffit compare`)")
    p.add_argument("--published", metavar="PATH",
                   help="with --compare: a published .fit file or a folder of them; each "
                   "material's fits (matched by its name) join its leaderboard")
    p.add_argument("--rank-by", default=DEFAULT_RANK_BY, choices=list(LITERATURE_METRICS),
                   metavar="METRIC", help=f"with --compare: the metric to rank by (default "
                   f"{DEFAULT_RANK_BY})")
    p.add_argument("--workers", type=int, metavar="N",
                   help="local worker processes (default: one per CPU core)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="submit to a running Dask scheduler (tcp://HOST:8786; default "
                   "$DASK_SCHEDULER_ADDRESS); inputs and OUTDIR must be visible to its workers")
    p.add_argument("--dashboard", nargs="?", const=None, default=False, metavar="ADDR",
                   help="serve the local cluster's Dask dashboard at ADDR (default "
                   "127.0.0.1:8787; without this option no HTTP server runs)")
    p.set_defaults(run=run)


def jobs_from(args):
    """Materials and per-model fit options from the arguments (every check done here)."""
    from ..batch import inputs, runner
    from .fitting import options_from

    runner.check_workers(args.workers, "--workers")
    if args.dashboard is not False:
        _check_dashboard(args)
    if args.scheduler is not None:
        args.scheduler = runner.check_scheduler_address(args.scheduler)
    elif os.environ.get("DASK_SCHEDULER_ADDRESS"):
        runner.check_scheduler_address(os.environ["DASK_SCHEDULER_ADDRESS"],
                                       "DASK_SCHEDULER_ADDRESS")
    names = [m.strip() for m in (args.model or "").split(",") if m.strip()]
    if not names:
        names = [None]  # the preset must name the model; options_from says so if it does not
    models = []
    for name in dict.fromkeys(names):
        (model,), options = options_from(argparse.Namespace(**{**vars(args), "model": name}))
        models.append((model.name, options.fit_kwargs()))
    outdir = Path(args.outdir)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"--outdir {args.outdir}: exists and is not a folder")
    return runner.make_jobs(inputs.materials(args.inputs), models)


def _check_dashboard(args) -> None:
    """``--dashboard`` serves the local cluster's dashboard: ``HOST:PORT`` or ``:PORT``."""
    if args.scheduler is not None:
        raise UsageError("--dashboard: only a local cluster started by brdffit gets one; with "
                         "--scheduler, open that scheduler's own dashboard")
    if args.dashboard is None:
        return
    from distributed.comm.addressing import parse_host_port

    try:
        _, port = parse_host_port(args.dashboard)
    except (ValueError, TypeError):
        port = -1
    if not 0 <= port < 65536:
        raise UsageError(f"--dashboard {args.dashboard!r}: not an address HOST:PORT (write "
                         "--dashboard=HOST:PORT, or put --dashboard after the inputs)")


def _check_compare(args) -> None:
    """``--published`` needs ``--compare``; its files are read (and refused when malformed)
    before any fit."""
    if args.published and not args.compare:
        raise UsageError("--published ranks published fits in the leaderboard: add --compare")
    if args.published:
        from ..published import load_published

        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # said again after the batch
            load_published(args.published)


def run(args) -> int:
    from ..batch import runner, table

    _check_compare(args)
    job_list = jobs_from(args)
    dashboard = (args.dashboard or runner.DEFAULT_DASHBOARD) if args.dashboard is not False \
        else None
    add_cleanup(runner.close_local_clusters)  # a signal stops the workers before the exit
    try:
        out = runner.run_batch(job_list, outdir=args.outdir, force=args.force, plot=args.plot,
                               client=None, workers=args.workers, scheduler=args.scheduler,
                               dashboard=dashboard, progress=False if args.quiet else None,
                               want_results=args.compare)
    finally:
        remove_cleanup(runner.close_local_clusters)
    print(table.summary(out.frame, out.wall_time, where=out.where))
    note = table.merge_note(out.frame, out.merged)
    files = list(out.files)
    if args.compare:
        files += _leaderboards(args, job_list, out)
    print("wrote " + ", ".join(str(p) for p in files) + (f" ({note})" if note else ""))
    ok = bool(out.frame["success"].all())
    if not ok:
        print(f"brdffit batch: {int((~out.frame['success']).sum())} of {len(out.frame)} fits "
              "not successful (see the table's outcome and message columns)", file=sys.stderr)
    return 0 if ok else 1


def _leaderboards(args, job_list, out) -> list:
    """``--compare``: the per-material leaderboards of the batch's results (and the published
    fits), printed and written to OUTDIR (:mod:`brdffit.batch.compare`)."""
    from ..batch import compare
    from ._common import Progress

    frame, notes = compare.leaderboards(job_list, out.results, args.published, args.rank_by,
                                        Progress.of(args))
    for note in notes:
        print(f"brdffit batch: warning: leaderboard: {note}", file=sys.stderr)
    print(compare.summary(frame))
    return compare.write(frame, args.outdir) if not frame.empty else []
