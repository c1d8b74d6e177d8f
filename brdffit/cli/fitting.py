"""``brdffit fit FILE --model NAME``: fit a model, print a summary, write the requested outputs.

``--model ggx,gtr,disney`` fits several models to the same cells and prints them side by side,
best (lowest cost: the same loss on the same cells) first, with the error metrics of the
literature (Ngan 2005's cosine-weighted RMSE, Löw 2012's log RMSE); ``--out`` then holds all
results, best first.

Options come from three layers, later ones winning: the code's defaults, a preset
(``--config``, see :mod:`brdffit.config`), then the flags. Every output is checked before the fit
runs (an existing file needs ``--force``), so no work is wasted; the outputs are written into a
staging folder and published together after the summary is printed, so either the whole set
appears or none does (:mod:`brdffit.cli._outputs`).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

from ..errors import BrdffitError
from ..io import SELF_EVALUATING, formats_text, suffixes_of
from ._words import cli_words
from ._common import (
    Progress,
    UsageError,
    check_no_conflict,
    check_outputs,
    check_params,
    parse_assignments,
    read_input,
    write_text,
)


def _count_or_fraction(text: str):
    """``200000`` or ``1e5`` → a count (int), ``0.1`` → a fraction; ranges: check_fit_options."""
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"--subsample {text!r}: give a count (200000) or a fraction (0.1)") from None
    whole = math.isfinite(value) and value == int(value) and value >= 1
    return int(value) if whole and ("." not in text or value > 1) else value


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "fit",
        parents=parents,
        allow_abbrev=False,
        help="fit a model to a measured table, sample list or material",
        description=f"Fit a registered model to FILE ({formats_text()}) "
        "and print a summary: parameters with standard errors, error metrics, convergence, "
        "parameters at a bound, time. Exit code 1 if the fit did not converge (outputs are "
        "still written, marked success=false).",
    )
    p.add_argument("file", metavar="FILE", help=f"a {formats_text()}")
    p.add_argument("--model", "-m", help="a registered model (see `brdffit models`), or "
                   "several separated by commas (compared side by side); may come from the "
                   "preset instead")
    add_fit_options(p, p.add_argument_group(
        "solver (defaults in brdffit.fit; a preset's [solver] table)"))
    p.add_argument("--out", "-o", metavar="RESULT.json", help="write the result as JSON")
    p.add_argument("--plot", metavar="FIG.png",
                   help="write the diagnostic figures FIG-slice.png, FIG-peaks.png, "
                   "FIG-albedo.png, FIG-spheres.png (FIG-polar.png for a "
                   f"{suffixes_of(*SELF_EVALUATING)}, "
                   "FIG-corner.png with --mcmc)")
    p.add_argument("--table", metavar="FITTED.binary",
                   help="write the fitted model rendered over the MERL grid")
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    from ..posterior.cli_support import add_arguments as add_mcmc_arguments

    add_mcmc_arguments(p)
    p.set_defaults(run=run)


def add_fit_options(target, solver=None) -> None:
    """The options that shape a fit, each overriding the preset, added to ``target`` (a parser
    or an argument group); the solver's (a preset's ``[solver]`` table) go to ``solver``
    (default ``target``). ``brdffit fit`` and ``brdffit batch`` both take them, from here; the
    flags, their help and types come from :data:`brdffit.config.OPTIONS`; :func:`options_from`
    reads them."""
    from ..config import OPTIONS

    target.add_argument("--config", "-c", metavar="PRESET",
                        help="a TOML preset: a path, or a bare name looked up as "
                        "configs/NAME.toml")
    for key, option in OPTIONS.items():
        if option.flag is None:
            continue
        group = solver if option.table == "solver" and solver is not None else target
        if key in _TABLE_PARSERS:
            group.add_argument(option.flag, dest=key, action="append", metavar=option.metavar,
                               help=option.help)
            continue
        kind = _count_or_fraction if key == "subsample" else option.kind
        if option.choices:
            group.add_argument(option.flag, dest=key, choices=option.choices, type=str.lower,
                               help=option.help)
        else:
            group.add_argument(option.flag, dest=key, type=kind, metavar=option.metavar,
                               help=option.help)


def _parse_bounds(items, flag="--bound") -> dict:
    """``["alpha=0.01,0.5"]`` → ``{"alpha": (0.01, 0.5)}``."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        parts = value.split(",")
        try:
            lo, hi = (float(v) for v in parts)
        except ValueError:
            lo = hi = None
        if not sep or not name.strip() or lo is None or not lo < hi:
            raise UsageError(f"--bound {item!r}: expected NAME=LOWER,UPPER with LOWER < UPPER, "
                             f"e.g. --bound alpha=0.01,0.5")
        out[name.strip()] = (lo, hi)
    return out


def options_from(args):
    """Preset (if any) merged with the flags, checked against the model's parameters."""
    from .. import get_model
    from ..config import OPTIONS, FitOptions, check_fit_options, load_config

    given = {key: getattr(args, key) for key in OPTIONS if OPTIONS[key].flag}
    check_fit_options(given, lambda key: OPTIONS[key].flag)
    _check_mcmc_ranges(args)
    for key, parse in _TABLE_PARSERS.items():
        given[key] = parse(given[key], OPTIONS[key].flag)
    flags = FitOptions(model=args.model, **given, sources=("command line",))
    preset = load_config(args.config) if args.config else FitOptions()
    options = preset.merged(flags)
    if options.model is None:
        raise UsageError("no model given: pass --model NAME (see `brdffit models`) or a preset "
                         "that names one")
    models = [get_model(name.strip()) for name in str(options.model).split(",") if name.strip()]
    if not models or len({m.name for m in models}) != len(models):
        raise UsageError(f"--model {options.model!r}: give distinct model names separated by "
                         f"commas, e.g. --model ggx,gtr,disney")
    check_no_conflict(flags.init, flags.fixed)
    for model in models:
        check_params(model, flags.init, "--init")
        check_params(model, flags.fixed, "--fix")
        options.check_params(model)
    options = _check_names(options)
    return models, options


#: The table options' flags (repeatable ``NAME=VALUE``) and their parsers.
_TABLE_PARSERS = {"init": parse_assignments, "fixed": parse_assignments, "bounds": _parse_bounds}


def _check_mcmc_ranges(args) -> None:
    from ..config import check_fit_options
    from ..posterior.options import FLAG_RANGES, MAX_CHAIN_VALUES, MCMC_OPTIONS

    values = {k: getattr(args, k, None) for k in FLAG_RANGES}
    check_fit_options(values, lambda key: f"--{key.replace('_', '-')}", FLAG_RANGES)
    walkers = values["walkers"] or MCMC_OPTIONS["nwalkers"].default
    steps = values["steps"] or 1
    if walkers * steps * 64 > MAX_CHAIN_VALUES:  # 64: a generous number of parameters
        raise UsageError(f"--walkers {walkers} x --steps {steps} is a chain of more than "
                         f"{MAX_CHAIN_VALUES:,} values; use fewer walkers or steps")


def _check_names(options):
    """``options`` with its loss and solver names checked now, so that a typo fails before the
    input is read, and spelled as registered (names ignore case: ``--loss LOG`` is ``log``)."""
    from ..fitting import get_loss, get_solver

    loss, solver = options.loss, options.solver
    if loss is not None:
        get_loss(loss)
        loss = loss.lower() if isinstance(loss, str) else loss  # all registered: lower case
    if solver is not None:
        solver = get_solver(solver).name
    return dataclasses.replace(options, loss=loss, solver=solver)


def run(args) -> int:
    from ..api import fit

    models, options = options_from(args)
    if len(models) > 1:
        return _run_several(args, models, options)
    model = models[0]
    out, plot, table = (args.out, args.plot, args.table)
    from ..posterior import cli_support as mcmc

    mcmc_paths = [p for p in mcmc.output_paths(args).values() if p]
    with check_outputs([out, table] + _plot_paths(plot, args.file) + mcmc_paths, args.force,
                       sizes={table: _MERL_BYTES} if table else None) as outputs:
        data = read_input(args.file)
        progress = Progress.of(args)
        progress(f"fitting {model.name} to {args.file}")
        try:
            result = fit(data, model, options, throw=False,
                         progress=progress.fit_events)
            result = dataclasses.replace(result, message=cli_words(result.message), provenance={
                **result.provenance, "command": "brdffit fit", "config": list(options.sources)})
            post = _posterior(data, result, args, options, progress, mcmc, outputs)
        except BrdffitError as exc:  # the library's advice, in flags
            raise UsageError(cli_words(str(exc))) from exc
        text = mcmc.combined_json(result, post) if post else result.to_json()
        if out:
            outputs.write(out, lambda tmp: write_text(tmp, text + "\n"))
        if table:
            _write_table(result, outputs, table, progress)
        if plot:
            from .plotting import write_figures

            outputs.write(plot, lambda base: write_figures(data, base, result, progress=progress),
                          base=True)
        lines = [result.summary()] + ([cli_words(post.summary())] if post else [])
        print(text if args.json else "\n".join(lines))
        sys.stdout.flush()  # a failed stdout publishes nothing
        outputs.publish()
    warn_implausible(result)
    if not result.success:
        from ..fitting import DATA_VERDICTS

        what = (f"the fit is {result.status}" if result.status in DATA_VERDICTS
                else "the fit did not converge")
        print(f"brdffit fit: warning: {what} ({result.message}); outputs were written and "
              f"marked success=false", file=sys.stderr)
        return 1
    return 0


def warn_implausible(result) -> None:
    """One warning line on stderr when the fitted material fails a plausibility check
    (:mod:`brdffit.fitting.plausibility`), whether or not the fit converged; the exit code
    stays what convergence makes it."""
    from ..fitting import plausibility_warning

    line = plausibility_warning(result.plausibility, f"the {result.model_name} fit of "
                                f"{result.table or 'the table'}")
    if line:
        print(f"brdffit fit: warning: {cli_words(line)}", file=sys.stderr)


def _run_several(args, models, options) -> int:
    """Fit each of ``models`` to the same cells; print the comparison (best first) and the
    summaries; ``--out`` gets ``{"results": [...]}`` in the same order."""
    if args.plot or args.table or args.mcmc:
        raise UsageError("--plot, --table and --mcmc take one model; fit the chosen model "
                         "again with --model NAME")
    with check_outputs([args.out], args.force) as outputs:
        return _fit_several(args, models, options, outputs)


def _fit_several(args, models, options, outputs) -> int:
    import json

    from ..api import fit

    data = read_input(args.file)
    progress = Progress.of(args)
    results = []
    for model in models:
        progress(f"fitting {model.name} to {args.file}")
        try:
            result = fit(data, model, options, throw=False,
                         progress=progress.fit_events)
        except BrdffitError as exc:  # the library's advice, in flags
            raise UsageError(cli_words(str(exc))) from exc
        results.append(dataclasses.replace(result, message=cli_words(result.message)))
    results.sort(key=lambda r: (not r.success, r.cost))
    text = json.dumps({"results": [json.loads(r.to_json()) for r in results]}, indent=2)
    if args.json:
        print(text)
    else:
        print(comparison(results))
        print("\n\n".join(r.summary() for r in results))
    if args.out:
        outputs.write(args.out, lambda tmp: write_text(tmp, text + "\n"))
    sys.stdout.flush()  # a failed stdout publishes nothing
    outputs.publish()
    for r in results:
        warn_implausible(r)
    failed = [r.model_name for r in results if not r.success]
    if failed:
        print(f"brdffit fit: warning: {', '.join(failed)} did not converge; see the summaries",
              file=sys.stderr)
        return 1
    return 0


def comparison(results) -> str:
    """A table of fits of one table, in the given order: convergence, cost, the literature's
    error metrics, free parameters, time; columns sized to their content."""
    from .._columns import columns

    rows = [("rank", "model", "converged", "cost", "rmse_log", "rmse_cosine", "free", "time")]
    for k, r in enumerate(results, 1):
        rows.append((str(k), r.model_name, "yes" if r.success else "NO", f"{r.cost:.6g}",
                     f"{r.metrics['rmse_log']:.4g}", f"{r.metrics['rmse_cosine']:.4g}",
                     str(len(r.free)), f"{r.wall_time:.2f}s"))
    loss = {r.loss for r in results}
    return "\n".join(columns(rows, "><<>>>>>", rule=True) + [
        f"(same cells, {'/'.join(sorted(loss))} loss; best first by cost, failed fits last)"])


def _posterior(data, result, args, options, progress, mcmc, outputs):
    """``--mcmc``: emcee around the converged fit (see :mod:`brdffit.posterior.cli_support`)."""
    if not args.mcmc:
        return None
    if not result.success:
        print("brdffit fit: warning: --mcmc skipped: the least-squares fit did not converge, "
              "so there is no optimum to start the walkers from", file=sys.stderr)
        return None
    progress("sampling the posterior with emcee")
    post, _files, notes = mcmc.run_mcmc(data, result, args, options, outputs.write)
    for note in notes:
        print(f"brdffit fit: warning: {cli_words(note)}", file=sys.stderr)
    return post


def _plot_paths(plot, source):
    if not plot:
        return []
    from .plotting import figure_paths

    return figure_paths(plot, source)


def _write_table(result, outputs, path, progress) -> None:
    from data_formats.merl import write_merl

    progress(f"rendering the fitted model into {path}")
    rendered = result.render_merl(name=Path(path).stem)
    outputs.write(path, lambda tmp: write_merl(tmp, rendered))


_MERL_BYTES = 34_992_012  # a table rendered over the MERL grid
