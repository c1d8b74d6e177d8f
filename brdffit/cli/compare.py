"""``brdffit compare TABLE --models ggx,gtr [--published DIR]``: the leaderboard of one table.

Every model is fitted to TABLE (under the fit options and ``--config`` preset given, or a preset
of its own: ``--models ggx,beckmann@low2012-e2``), every published fit of the table's material
in ``--published`` (a ``.fit`` file or a folder of them, matched by the table's file stem) joins
them, and all are scored on the same cells in the literature's metrics and ranked
(:mod:`brdffit.leaderboard`). The table is printed; ``--out`` writes it as Parquet, ``--csv`` as
CSV, ``--html`` as a self-contained report with the figures, ``--json`` prints it as JSON.

Every output is checked before any work and the set is published together at the end
(:mod:`brdffit.cli._outputs`): a bad model, preset, metric, option or published file is one line
and exit code 2 with nothing written. Exit code 1 when a fit did not converge (it is on the
board, marked; the outputs are written).
"""

from __future__ import annotations

import argparse
import sys

from ..io import formats_text
from ._common import Progress, UsageError, check_outputs, read_input, write_text
from .fitting import add_fit_options


def add_parser(sub, parents) -> None:
    from ..leaderboard import DEFAULT_RANK_BY
    from ..metrics import LITERATURE_METRICS

    p = sub.add_parser(
        "compare",
        parents=parents,
        allow_abbrev=False,
        help="rank models fitted to a table and the published fits of its material",
        description="Fit every model of --models to FILE, add the published fits of its "
        "material (--published: a .fit file or a folder of them, matched by the file stem), "
        "score all on the same cells in the literature's metrics (Löw 2012's log RMS, Ngan "
        "2005's cosθi-weighted RMS over θ ≤ 80°, the relative error in the peak; each per cell "
        "and solid-angle weighted) and print them ranked. Exit 1 if a fit did not converge "
        "(it is listed, marked); 2 for bad input, with nothing written.",
    )
    p.add_argument("file", metavar="FILE", help=f"a {formats_text()}")
    p.add_argument("--models", "--model", "-m", dest="models", default="",
                   help="models to fit, comma-separated (ggx,gtr,beckmann); MODEL@PRESET fits "
                   "a model under a preset of its own (beckmann@low2012-e2)")
    p.add_argument("--published", metavar="PATH",
                   help="a published .fit file, or a folder of them (../shared/published/fits)")
    p.add_argument("--rank-by", default=DEFAULT_RANK_BY, choices=list(LITERATURE_METRICS),
                   metavar="METRIC", help=f"the metric to rank by (default {DEFAULT_RANK_BY}; "
                   f"one of {', '.join(LITERATURE_METRICS)})")
    add_fit_options(p.add_argument_group("fit options (as for `brdffit fit`, every model)"))
    p.add_argument("--out", "-o", metavar="BOARD.parquet", help="write the table as Parquet")
    p.add_argument("--csv", metavar="BOARD.csv", help="write the table as CSV")
    p.add_argument("--html", metavar="REPORT.html",
                   help="write a self-contained HTML report (table and figures)")
    p.add_argument("--json", action="store_true", help="print the table as JSON on stdout")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(run=run)


def _options(args, parsed):
    """The fit options common to every model: the preset and the flags, checked against every
    model (:func:`brdffit.cli.fitting.options_from`)."""
    from ..config import FitOptions
    from .fitting import options_from

    models = ",".join(dict.fromkeys(model for _, model, _ in parsed))
    if not models:
        return FitOptions()
    _, options = options_from(argparse.Namespace(**{**vars(args), "model": models}))
    return options


def run(args) -> int:
    from ..leaderboard import compare, parse_models
    from ..published import published_files

    if not args.models.strip() and not args.published:
        raise UsageError("nothing to compare: give --models (e.g. --models ggx,gtr) and/or "
                         "--published DIR")
    parsed = parse_models(args.models) if args.models.strip() else []
    options = _options(args, parsed)
    if args.published:
        published_files(args.published)
    outs = [args.out, args.csv, args.html]
    with check_outputs(outs, args.force) as outputs:
        data = read_input(args.file)
        progress = Progress.of(args)
        board = compare(data, [label for label, _, _ in parsed], args.published,
                        options=options, rank_by=args.rank_by, progress=progress)
        if args.out:
            outputs.write(args.out, lambda tmp: board.to_parquet(tmp))
        if args.csv:
            outputs.write(args.csv, lambda tmp: board.to_csv(tmp))
        if args.html:
            progress("drawing the report's figures")
            text = board.html(data)
            outputs.write(args.html, lambda tmp: write_text(tmp, text))
        print(board.to_json() if args.json else board.text())
        sys.stdout.flush()  # a failed stdout publishes nothing
        outputs.publish()
    if args.published and board.best("published") is None:
        print(f"brdffit compare: warning: {args.published} holds no published fit of "
              f"{board.table!r} (matched by the table's name)", file=sys.stderr)
    failed = [c.label for c in board.candidates if c.kind == "fit" and not c.converged]
    if failed:
        print(f"brdffit compare: warning: {', '.join(failed)} did not converge; they are on the "
              f"board, marked", file=sys.stderr)
        return 1
    return 0
