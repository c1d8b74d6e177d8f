"""``brdffit render RESULT.json -o sphere.png``: a sphere with the exported material, in Mitsuba 3.

The scene of :mod:`brdffit.export.render` (orthographic view, one directional light 45° above
the view axis, a constant environment): a few seconds or less on a CPU with the ``scalar_rgb``
variant. Needs ``pip install 'brdffit[mitsuba]'``. A result whose model is not a Mitsuba model
needs ``--approximate`` (see ``brdffit export``); ``--model NAME`` picks one result of a file of
several, as there.
"""

from __future__ import annotations

from ._common import UsageError, atomic_write, check_outputs
from .plotting import _read_result, add_model_option


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
    p.add_argument("--size", type=int, default=256, help="image width and height in pixels (256)")
    p.add_argument("--spp", type=int, default=16, help="samples per pixel (16)")
    p.add_argument("--environment", type=float, default=0.1, metavar="L",
                   help="radiance of the constant environment (0.1; 0 for the light alone)")
    p.add_argument("--approximate", action="store_true",
                   help="render the native Mitsuba model fitted to a non-native result")
    p.add_argument("--force", action="store_true", help="overwrite the PNG if it exists")
    p.set_defaults(run=run)


def run(args) -> int:
    import time

    from ..export import export
    from ..export.render import render_mitsuba, write_png

    if args.size < 8 or args.spp < 1:
        raise UsageError(f"--size {args.size} / --spp {args.spp}: need size ≥ 8 and spp ≥ 1")
    check_outputs([args.output], args.force)
    result = _read_result(args.result, model=args.model, flag="")
    out = export(result, "mitsuba-dict", approximate=args.approximate)
    start = time.perf_counter()
    image = render_mitsuba(out.payload, size=args.size, spp=args.spp, environment=args.environment)
    seconds = time.perf_counter() - start
    atomic_write(args.output, lambda tmp: write_png(image, tmp))
    if not args.quiet:
        print(f"wrote {args.output} ({out.model_name}, {args.size}x{args.size}, {args.spp} spp, "
              f"rendered in {seconds:.2f} s)")
    return 0
