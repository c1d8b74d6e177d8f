"""``brdffit demo``: the main job end to end on a material whose parameters are known.

Synthesizes a MERL table of a gold-like metallic paint from known ``ggx`` parameters (1%
multiplicative noise), writes it into a temporary folder and reads it back, fits it with the
default options, prints the recovered values beside the true ones, and writes the result JSON and
the diagnostic figures into ``--outdir`` (default ``brdffit-demo``). Nothing is downloaded.
"""

from __future__ import annotations

import functools
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from ._common import Progress, UsageError, check_outputs, write_text
from ._signals import add_cleanup, remove_cleanup

#: The known material: a gold-like metallic paint.
TRUTH = {"diffuse": (0.10, 0.06, 0.02), "f0": (0.90, 0.60, 0.30), "alpha": 0.15}
MODEL, NOISE, SEED = "ggx", 0.01, 0


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "demo",
        parents=parents,
        allow_abbrev=False,
        help="synthesize a known material, fit it, compare, write figures (no download)",
        description="Synthesize a MERL table from known ggx parameters (1% noise) in a "
        "temporary folder, fit it, print recovered against true values, and write the result "
        "(result.json) and the figures (demo-*.png) into OUTDIR.",
    )
    p.add_argument("--outdir", default="brdffit-demo", metavar="OUTDIR",
                   help="folder for the result and figures (created; default brdffit-demo)")
    p.add_argument("--force", action="store_true", help="overwrite files already in OUTDIR")
    p.add_argument("--subsample", type=int, metavar="N",
                   help="fit on N random valid cells instead of all ~1.1 million (quicker)")
    p.set_defaults(run=run)


def comparison(result, truth: dict) -> str:
    """Rows ``name  true  recovered ± stderr  deviation/σ`` for every scalar entry."""
    errors = getattr(result, "stderr", None) or {}
    rows = [("parameter", "true", "recovered", "± std. err.", "|dev|/σ")]
    for name, true in truth.items():
        true = np.atleast_1d(np.asarray(true, float))
        got = np.atleast_1d(np.asarray(result.params[name], float))
        err = np.atleast_1d(np.asarray(errors.get(name, np.full_like(got, np.nan)), float))
        for k in range(len(true)):
            label = name if len(true) == 1 else f"{name}[{k}]"  # the names of summary() and --fix
            sigma = abs(got[k] - true[k]) / err[k] if err[k] > 0 else float("nan")
            rows.append((label, f"{true[k]:.5f}", f"{got[k]:.5f}", f"{err[k]:.1e}", f"{sigma:.1f}"))
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    return "\n".join("  ".join(f"{c:>{w}}" for c, w in zip(r, widths)) for r in rows)


def run(args) -> int:
    from .plotting import figure_paths

    outdir = Path(args.outdir)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"--outdir {outdir}: exists and is not a folder")
    figures, result_path = outdir / "demo.png", outdir / "result.json"
    written = figure_paths(figures)
    created = not outdir.exists()
    if created:
        try:
            outdir.mkdir(parents=True)
        except OSError as exc:
            raise UsageError(f"--outdir {outdir}: cannot create it ({exc.strerror})") from None
    remove_if_empty = functools.partial(_rmdir_quietly, outdir)
    if created:  # a folder made for this run goes again when nothing was published
        add_cleanup(remove_if_empty)
    try:
        return _run(args, outdir, figures, result_path, written)
    except BaseException:
        if created:
            remove_if_empty()
        raise
    finally:
        remove_cleanup(remove_if_empty)


def _rmdir_quietly(folder) -> None:
    try:
        os.rmdir(folder)  # only when empty: never what was published
    except OSError:
        pass


def _run(args, outdir, figures, result_path, written) -> int:
    from .. import get_model
    from ..api import fit
    from .plotting import write_figures
    from .synth import synthesize_table

    progress = Progress.of(args)
    model = get_model(MODEL)
    with check_outputs([result_path, *written], args.force) as outputs, \
            tempfile.TemporaryDirectory(prefix="brdffit-demo-") as tmp:
        from data_formats.merl import read_merl, write_merl

        cleanup = functools.partial(shutil.rmtree, tmp, ignore_errors=True)
        add_cleanup(cleanup)  # os._exit on a signal skips the context manager
        progress(f"synthesizing a {MODEL} table with {NOISE:.0%} noise")
        path = Path(tmp) / "gold-paint.binary"
        write_merl(path, synthesize_table(model, TRUTH, noise=NOISE, seed=SEED, name=path.stem))
        table = read_merl(path)
        progress(f"fitting {MODEL} to {path.name} ({path.stat().st_size:,} bytes)")
        result = fit(table, model, subsample=args.subsample, throw=False,
                     progress=progress.fit_events)
        outputs.write(result_path, lambda tmp_path: write_text(tmp_path, result.to_json() + "\n"))
        outputs.write(figures, lambda base: write_figures(
            table, base, model=model, params=result.params, converged=result.success,
            progress=progress), base=True)
        print(result.summary())
        print(f"\nrecovered against true ({MODEL}, {NOISE:.0%} noise):")
        print(comparison(result, TRUTH))
        sys.stdout.flush()
        outputs.publish()
        remove_cleanup(cleanup)
    print(f"\nwrote {result_path} and " + ", ".join(str(p) for p in written))
    return 0 if result.success else 1
