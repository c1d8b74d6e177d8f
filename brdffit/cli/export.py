"""``brdffit export RESULT.json --to TARGET -o OUT``: a renderer material.

The targets are :data:`brdffit.export.TARGETS` (``mitsuba-xml``, ``mitsuba-dict``, ``gltf``):
the ``--to`` choices and the help are read from it.

The result's model must be the target's own BSDF (a renderer-native model: ``mitsuba-principled``,
``mitsuba-roughconductor*``, ``gltf-pbr``); otherwise the command fails naming the native model
to fit, unless ``--approximate``, which fits that native model to the fitted one and prints the
approximation's error in the metrics of a fit. The mapping is documented in
:mod:`brdffit.export`.

Every export prints its own error (:mod:`brdffit.export.faithful`): the written material
evaluated by the target renderer (Mitsuba's ``BSDF.eval``, the glTF reference BRDF) against the
measured table (``--table``, by default the file the result was fitted to), beside the fit's,
as ``rmse_log`` and ``peak_log``. ``--fragment`` writes ``mitsuba-xml`` as the bare ``<bsdf>``
element instead of a scene file; an output named ``*.glb`` gets binary glTF. ``--model NAME`` picks one result of a file of several
(``brdffit fit -m a,b --out``); such a file without it is refused, its models listed.
"""

from __future__ import annotations

from ..export import TARGETS
from ._common import check_outputs, write_text
from .plotting import add_model_option, read_result


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "export",
        parents=parents,
        allow_abbrev=False,
        help="write a fitted material for a renderer ("
        + ", ".join(sorted({t.renderer for t in TARGETS.values()})) + ")",
        description="Write the material of a `brdffit fit --out` result for a renderer: "
        + "; ".join(f"{t.name} ({t.description})" for t in TARGETS.values())
        + ". Only renderer-native models export exactly; --approximate fits the native "
        "model to any other and reports the approximation's error.",
    )
    p.add_argument("result", metavar="RESULT.json", help="a result written by `brdffit fit --out`")
    add_model_option(p, "export")
    p.add_argument("--to", required=True, choices=list(TARGETS), type=str.lower,
                   help="the target format: " + ", ".join(
                       f"{t.name} (fit {t.native} for an exact export)" for t in TARGETS.values()))
    p.add_argument("--output", "-o", required=True, metavar="OUT", help="the file to write")
    p.add_argument("--approximate", action="store_true",
                   help="for a model with no exact counterpart: fit the target's native model to "
                   "it and report that approximation's error")
    p.add_argument("--table", metavar="TABLE",
                   help="the measured data to report the export's error against (default: the "
                   "file the result was fitted to; without it, the fitted model)")
    p.add_argument("--fragment", action="store_true",
                   help="mitsuba-xml: write the bare <bsdf> element to paste into a scene, not "
                   "a scene file")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    p.set_defaults(run=run)


def run(args) -> int:
    import time
    from pathlib import Path

    from ..export import export
    from ._common import UsageError, read_input

    if args.fragment and args.to != "mitsuba-xml":
        raise UsageError(f"--fragment is for --to mitsuba-xml (a <bsdf> element), not {args.to}")
    with check_outputs([args.output], args.force) as outputs:
        result = read_result(args.result, model=args.model, flag="")
        table = read_input(args.table) if args.table else None
        start = time.perf_counter()
        out = export(result, args.to, approximate=args.approximate, data=table,
                     fragment=args.fragment)
        if Path(args.output).suffix.lower() == ".glb" and args.to == "gltf":
            data = out.data(".glb")
            outputs.write(args.output, lambda tmp: Path(tmp).write_bytes(data))
        else:
            text = out.text()
            outputs.write(args.output, lambda tmp: write_text(tmp, text))
        seconds = time.perf_counter() - start
        outputs.publish()
    if out.approximation is not None:
        m = out.approximation.metrics
        print(f"{out.model_name} approximates the {result.model_name} fit "
              f"({'converged' if out.approximation.success else 'NOT converged'}): "
              + ", ".join(f"{k} {v:.4g}" for k, v in m.items()))
    if out.error is not None:
        print(out.error.text())
    elif out.error_note:
        print(f"export error {out.error_note}")
    if not args.quiet:
        print(f"wrote {args.output} ({args.to}, {out.model_name}, {seconds:.2f} s)")
    return 0
