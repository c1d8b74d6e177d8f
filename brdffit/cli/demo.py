"""``brdffit demo``: the main job end to end on a material whose parameters are known.

Synthesizes a MERL table of a gold-like metal from known ``ggx`` parameters (1%
multiplicative noise), writes it into a temporary folder and reads it back, fits it with the
default options, prints the recovered values beside the true ones, and writes the result JSON and
the diagnostic figures into ``--outdir`` (default ``brdffit-demo``). Nothing is downloaded.

The demo reruns: it owns what it wrote. Beside its outputs it writes :data:`MANIFEST`, the
SHA-256 of every file it wrote; a later run replaces a file of the folder only where the file
is still exactly what a demo wrote (its bytes hash to the manifest's value), so a rerun needs
no ``--force``. A file the demo did not write, or one changed since (a user's ``result.json``,
an edited figure), still needs ``--force``, as does any other existing output. Why bytes and
not a mark on the folder: a folder mark would let the demo overwrite a file a user put there or
edited after the demo ran; a hash proves the file holds nothing but the demo's own output. The
demo only ever writes its own names (``result.json``, ``demo-*.png``, the manifest): other files
of the folder are never touched, and a folder it did not create is never removed.
"""

from __future__ import annotations

import functools
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from .._columns import columns
from ._common import Progress, UsageError, check_outputs, write_text
from ._signals import add_cleanup, remove_cleanup

#: The known material: a gold-like metal (gold's ``F0``, a faint diffuse term as of a worn
#: surface), plausible by every check of :mod:`brdffit.fitting.plausibility`: a metal's ``F0``
#: over a diffuse albedo above 0.1 would read as neither metal nor dielectric.
TRUTH = {"diffuse": (0.04, 0.025, 0.01), "f0": (0.90, 0.60, 0.30), "alpha": 0.15}
MODEL, NOISE, SEED = "ggx", 0.01, 0
#: The demo's record, in its folder, of the files it wrote: ``{"files": {name: "sha256:..."}}``.
MANIFEST = "brdffit-demo.json"
#: The largest manifest read (a few hundred bytes are written).
MAX_MANIFEST_BYTES = 1 << 16


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "demo",
        parents=parents,
        allow_abbrev=False,
        help="synthesize a known material, fit it, compare, write figures (no download)",
        description="Synthesize a MERL table from known ggx parameters (1% noise) in a "
        "temporary folder, fit it, print recovered against true values, and write the result "
        "(result.json) and the figures (demo-*.png) into OUTDIR, with brdffit-demo.json, the "
        "checksums of what it wrote: a rerun replaces those files.",
    )
    p.add_argument("--outdir", default="brdffit-demo", metavar="OUTDIR",
                   help="folder for the result and figures (created; default brdffit-demo)")
    p.add_argument("--force", action="store_true",
                   help="overwrite files in OUTDIR that an earlier demo did not write (or that "
                   "were changed since); the demo's own files are replaced without it")
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
    return "\n".join(columns(rows, ">>>>>"))


def run(args) -> int:
    from .plotting import figure_paths

    outdir = Path(args.outdir)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"--outdir {outdir}: exists and is not a folder")
    figures, result_path = outdir / "demo.png", outdir / "result.json"
    written = figure_paths(figures)
    foreign = _not_ours([result_path, *written, outdir / MANIFEST], outdir)
    if foreign is not None and not args.force:
        raise UsageError(f"{foreign}: already exists and is not what an earlier demo wrote; "
                         f"pass --force to overwrite it")
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


def _sha256(path: Path) -> str | None:
    """``sha256:<hex>`` of the regular file at ``path`` (never through a link); ``None`` if it
    is no regular file or cannot be read."""
    import stat

    from ..io import sha256_of

    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | os.O_CLOEXEC)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            return None
        return "sha256:" + sha256_of(f)


def _manifest(outdir: Path) -> dict | None:
    """The manifest's ``{name: checksum}`` of ``outdir``; ``None`` if there is none or it is not
    one (then it is a file like any other: only ``--force`` replaces it)."""
    import json

    path = outdir / MANIFEST
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > MAX_MANIFEST_BYTES:
            return None
        files = json.loads(path.read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
        return None
    return files


def _not_ours(paths, outdir: Path) -> Path | None:
    """The first of ``paths`` that exists and is not the demo's own (module docstring)."""
    owned = _manifest(outdir)
    for path in paths:
        if not os.path.lexists(path):
            continue
        if owned is None or (path.name != MANIFEST and (
                path.name not in owned or _sha256(path) != owned[path.name])):
            return path
    return None


def _write_manifest(outputs, outdir: Path, paths) -> None:
    """The manifest of the staged ``paths`` (their checksums), staged with them."""
    import json

    files = {p.name: _sha256(outputs.staged(p)) for p in paths}
    text = json.dumps({"written by": "brdffit demo", "files": files}, indent=2) + "\n"
    outputs.write(outdir / MANIFEST, lambda tmp: write_text(tmp, text))


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
    paths = [result_path, *written, outdir / MANIFEST]
    # Every existing output is the demo's own (checked in run) or --force was given; without
    # one to replace, a file that appears during the run is not overwritten (OutputSet).
    replace = args.force or any(os.path.lexists(p) for p in paths)
    with check_outputs(paths, replace) as outputs, \
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
        outputs.write(figures, lambda base: write_figures(table, base, result, progress=progress),
                      base=True)
        _write_manifest(outputs, outdir, [result_path, *written])
        print(result.summary())
        print(f"\nrecovered against true ({MODEL}, {NOISE:.0%} noise):")
        print(comparison(result, TRUTH))
        sys.stdout.flush()
        outputs.publish()
        remove_cleanup(cleanup)
    print(f"\nwrote {result_path} and " + ", ".join(str(p) for p in written)
          + f" ({outdir / MANIFEST} records them: a rerun replaces them)")
    return 0 if result.success else 1
