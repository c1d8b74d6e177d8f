"""``brdffit render RESULT.json -o sphere.png``: a sphere with the exported material, in Mitsuba 3.

The scene of :mod:`brdffit.export.render` (orthographic view, one directional light 45° above
the view axis, a constant environment): a few seconds or less on a CPU with the ``scalar_rgb``
variant. Needs ``pip install 'brdffit[mitsuba]'``. A result whose model is not a Mitsuba model
needs ``--approximate`` (see ``brdffit export``); ``--model NAME`` picks one result of a file of
several, as there. ``--size``, ``--spp`` and ``--environment`` are checked against
:data:`brdffit.export.render.RENDER_OPTION_RANGES` before anything is read (one line, exit code
2); the PNG is staged and published by :mod:`brdffit.cli._outputs`.
"""

from __future__ import annotations

from ._common import check_outputs, number
from .plotting import read_result, add_model_option


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "render",
        parents=parents,
        allow_abbrev=False,
        help="render a lit sphere with the fitted material in Mitsuba 3",
        description="Export the material of a `brdffit fit --out` result to Mitsuba 3 and render "
        "a sphere with it (directional light + constant environment) into a PNG.",
    )
    p.add_argument("result", metavar="RESULT.json", help="a result written by `brdffit fit --out`")
    add_model_option(p, "render")
    p.add_argument("--output", "-o", required=True, metavar="SPHERE.png", help="the PNG to write")
    p.add_argument("--size", type=number, default=256, metavar="N",
                   help="image width and height in pixels, 8 to 4096 (256)")
    p.add_argument("--spp", type=number, default=16, metavar="N",
                   help="samples per pixel, 1 to 4096 (16)")
    p.add_argument("--environment", type=number, default=0.1, metavar="L",
                   help="radiance of the constant environment, 0 to 100 (0.1; 0 for the light "
                   "alone)")
    p.add_argument("--approximate", action="store_true",
                   help="render the native Mitsuba model fitted to a non-native result")
    p.add_argument("--force", action="store_true", help="overwrite the PNG if it exists")
    p.set_defaults(run=run)


def run(args) -> int:
    import time

    from ..export import export
    from ..export.render import check_render_options, render_mitsuba, write_png

    check_render_options(lambda name: f"--{name}", size=args.size, spp=args.spp,
                         environment=args.environment)
    with check_outputs([args.output], args.force) as outputs:
        result = read_result(args.result, model=args.model, flag="")
        out = export(result, "mitsuba-dict", approximate=args.approximate, error=False)
        start = time.perf_counter()
        image = render_mitsuba(out.payload, size=args.size, spp=args.spp,
                               environment=float(args.environment))
        seconds = time.perf_counter() - start
        outputs.write(args.output, lambda tmp: write_png(image, tmp))
        outputs.publish()
    if not args.quiet:
        print(f"wrote {args.output} ({out.model_name}, {args.size}x{args.size}, {args.spp} spp, "
              f"rendered in {seconds:.2f} s)")
    return 0

