"""The ``brdffit`` command line: ``fit``, ``batch``, ``info``, ``synth``, ``plot``, ``models``, ``demo``.

One module per command (``add_parser`` + ``run``); this module builds the parser and turns user
mistakes into one line on stderr. Exit codes: 0 success; 1 a fit that did not converge (its
results are still written, marked as such); 2 bad input or usage. ``--debug`` shows tracebacks.

The commands set float64 (``jax_enable_x64``) before any JAX work; the library itself never does.
JAX and the fitter are imported only inside the commands that need them.
"""

from __future__ import annotations

import argparse
import sys
import traceback

from . import batch, catalog, demo, fitting, info, plotting, synth

__all__ = ["main", "build_parser"]

COMMANDS = (fitting, batch, info, synth, plotting, catalog, demo)
EXIT_OK, EXIT_NOT_CONVERGED, EXIT_USAGE = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="brdffit",
        allow_abbrev=False,
        description="Fit analytic BRDF models to measured reflectance (MERL tables, sample lists).",
        epilog="Run `brdffit demo` for a complete example; `brdffit COMMAND --help` for details.",
    )
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"brdffit {__version__}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--quiet", "-q", action="store_true", help="no progress messages")
    common.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS:
        module.add_parser(sub, [common])
    return parser


def _user_errors() -> tuple[type[BaseException], ...]:
    """Exception types that mean "the user can fix this": one line, exit code 2."""
    from data_formats.samplelist import SampleListFormatError

    from ..errors import BrdffitError

    errors: list = [BrdffitError, SampleListFormatError, FileNotFoundError, PermissionError,
                    IsADirectoryError]
    try:
        from data_formats.merl import MERLFormatError

        errors.append(MERLFormatError)
    except ImportError:  # pragma: no cover - the MERL module is part of the package
        pass
    return tuple(errors)


def _enable_x64() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version (0) and usage errors (2)
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    try:
        if getattr(args, "needs_jax", True):
            _enable_x64()
        return int(args.run(args) or 0)
    except _user_errors() as exc:
        if args.debug:
            traceback.print_exc()
        print(f"brdffit {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"brdffit {args.command}: interrupted", file=sys.stderr)
        return 130


def _one_line(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    return " ".join(text.split())
