"""``brdffit plot FILE [--fit result.json [--model NAME]] -o fig.png``: the diagnostic figures.

``--model`` picks one result of a file of several (``brdffit fit -m a,b --out``); such a file
read without it is refused in one line that lists its models.

``-o fig.png`` writes ``fig-slice.png``, ``fig-peaks.png``, ``fig-albedo.png`` and
``fig-spheres.png``, and for an RGL material also ``fig-polar.png``, the lobe in polar
coordinates (see :func:`brdffit.plots.figure_paths`, :func:`brdffit.plots.figure_names`); an
existing folder receives ``slice.png`` etc. Existing files are not overwritten without
``--force``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import SELF_EVALUATING, formats_text, suffixes_of
from ._common import UsageError, check_outputs, read_input


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "plot",
        parents=parents,
        allow_abbrev=False,
        help="write the diagnostic figures of a table (and of a fit)",
        description="Write the diagnostic PNGs of FILE: the image slice at φd = 90° (measured | "
        "fitted | log ratio), specular-peak curves, directional albedo, lit spheres. With --fit, "
        "the fitted model from a `brdffit fit --out` result is drawn beside the measurement.",
    )
    p.add_argument("file", metavar="FILE", help=f"a {formats_text()}")
    p.add_argument("--fit", metavar="RESULT.json", help="a result written by `brdffit fit --out`")
    add_model_option(p, "draw")
    p.add_argument("--output", "-o", required=True, metavar="FIG.png",
                   help="FIG.png → FIG-slice.png, FIG-peaks.png, FIG-albedo.png, FIG-spheres.png "
                   f"(and FIG-polar.png, the lobe in polar coordinates, for a "
                   f"{suffixes_of(*SELF_EVALUATING)}); an "
                   "existing folder receives slice.png, ...")
    p.add_argument("--force", action="store_true", help="overwrite existing figures")
    p.set_defaults(run=run)


def add_model_option(p, verb: str) -> None:
    """``--model NAME``: which result of a file written by ``brdffit fit -m a,b --out``."""
    p.add_argument("--model", "-m", metavar="NAME",
                   help=f"the model whose result to {verb}, for a file of several results "
                   "(`brdffit fit -m a,b --out`); a file of one result needs none")


def figure_paths(path, source=None) -> list[Path]:
    """The figures written for the input ``source`` (a path or data; ``None``: the ones
    written for every input) at ``path``."""
    from ..plots import figure_names, figure_paths as paths

    return paths(path, figure_names(source))


def write_figures(data, path, result=None, *, progress=None):
    """Write the diagnostic PNGs of ``data`` and of the fit ``result`` if given (atomically, by
    :func:`brdffit.plots.diagnostics`), the titles stating the result's own ``rmse_log``."""
    from ..plots import diagnostics, result_error

    if progress is not None:
        progress(f"writing figures {', '.join(str(p) for p in figure_paths(path, data))}")
    if result is None:
        return diagnostics(data, path=path)
    from .. import get_model

    return diagnostics(data, get_model(result.model_name), result.params, path=path,
                       error=result_error(result))


#: The largest result JSON read by ``--fit`` (results are a few kilobytes).
MAX_RESULT_BYTES = 16 << 20


def read_result(path, *, model=None, flag="--fit"):
    """A :class:`FitResult` from a result file, its model and parameters checked against the
    registry. ``model``: the ``--model`` that picks one result of a several-model file.
    ``flag``: the option that named ``path`` in the command run (``""`` for an argument), so
    that every message names it."""
    where = f"{flag} {path}" if flag else str(path)
    p = Path(path)
    if not p.exists():
        raise UsageError(f"{where}: no such file (write one with `brdffit fit ... --out`)")
    from data_formats.files import NotRegularFileError, open_regular

    try:
        with open_regular(p, "rb") as fh:
            raw = fh.read(MAX_RESULT_BYTES + 1)
    except NotRegularFileError as exc:
        raise UsageError(f"{flag} {exc}" if flag else str(exc)) from None
    if len(raw) > MAX_RESULT_BYTES:
        raise UsageError(f"{where}: larger than {MAX_RESULT_BYTES:,} bytes; not a brdffit "
                         f"result")
    result = _parse_result(where, raw, model)
    _check_result_params(where, result)
    return result


def _parse_result(where, raw: bytes, model):
    from ..fitting import FitResult, ResultChoiceError, ResultFormatError

    try:
        return FitResult.from_json_string(raw, model=model)
    except ResultFormatError as exc:
        raise UsageError(f"{where}: not a brdffit result ({_short(exc.problem)}); write one "
                         f"with `brdffit fit ... --out`") from None
    except ResultChoiceError as exc:
        held = ", ".join(exc.models)
        head = (f"holds {len(exc.models)} results ({held})" if exc.requested is None
                else f"holds no {exc.requested} result (it holds {held})")
        raise UsageError(f"{where} {head}; pick one with --model NAME") from None


def _short(exc) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 200 else text[:197] + "..."


def _check_result_params(where, result) -> None:
    """Model name known; every parameter known, of its declared shape, finite, in bounds."""
    from .. import get_model
    from ..errors import BrdffitError

    try:
        model = get_model(result.model_name)
        for name, value in dict(result.params).items():
            value = model.param(name).check_bounds(value)
            if not np.all(np.isfinite(value)):
                raise BrdffitError(f"parameter {name!r}={value!r} is not finite")
    except (BrdffitError, TypeError, ValueError) as exc:
        raise UsageError(f"{where}: {_short(exc)}") from None


def run(args) -> int:
    from ._common import Progress

    if args.model and not args.fit:
        raise UsageError(f"--model {args.model} picks a result of --fit RESULT.json; pass --fit")
    result = read_result(args.fit, model=args.model) if args.fit else None
    written = figure_paths(args.output, args.file)
    with check_outputs(written, args.force) as outputs:
        data = read_input(args.file)
        outputs.write(args.output, lambda base: write_figures(
            data, base, result, progress=Progress.of(args)), base=True)
        outputs.publish()
    if not args.quiet:
        print("wrote " + ", ".join(str(p) for p in written))
    return 0
