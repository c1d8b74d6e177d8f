"""``brdffit demo``: the main job end to end on a material whose parameters are known.

Synthesizes a MERL table of a gold-like metallic paint from known ``ggx`` parameters (1%
multiplicative noise), writes it into a temporary folder and reads it back, fits it with the
default options, prints the recovered values beside the true ones, and writes the result JSON and
the diagnostic figures into ``--outdir`` (default ``brdffit-demo``). Nothing is downloaded.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from ._common import Progress, check_outputs, write_text

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
    from .. import get_model
    from ..api import fit
    from .plotting import figure_paths, write_figures
    from .synth import synthesize_table

    outdir = Path(args.outdir)
    if outdir.exists() and not outdir.is_dir():
        from ._common import UsageError

        raise UsageError(f"--outdir {outdir}: exists and is not a folder")
    figures, result_path = outdir / "demo.png", outdir / "result.json"
    if outdir.is_dir():  # a new folder is created only once there is something to write
        check_outputs([result_path, *figure_paths(figures)], args.force)
    progress = Progress(args.quiet)
    model = get_model(MODEL)
    with tempfile.TemporaryDirectory(prefix="brdffit-demo-") as tmp:
        from data_formats.merl import read_merl, write_merl

        progress(f"synthesizing a {MODEL} table with {NOISE:.0%} noise")
        path = Path(tmp) / "gold-paint.binary"
        write_merl(path, synthesize_table(model, TRUTH, noise=NOISE, seed=SEED, name=path.stem))
        table = read_merl(path)
        progress(f"fitting {MODEL} to {path.name} ({path.stat().st_size:,} bytes)")
        result = fit(table, model, subsample=args.subsample, throw=False,
                     progress=progress if progress.enabled else None)
        print(result.summary())
        print(f"\nrecovered against true ({MODEL}, {NOISE:.0%} noise):")
        print(comparison(result, TRUTH))
        outdir.mkdir(parents=True, exist_ok=True)
        write_text(result_path, result.to_json() + "\n")
        written = write_figures(table, figures, model=model, params=result.params,
                                converged=result.success, progress=progress)
    print(f"\nwrote {result_path} and " + ", ".join(str(p) for p in written))
    return 0 if result.success else 1
