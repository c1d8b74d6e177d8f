"""The ``brdffit`` command line: ``fit``, ``compare``, ``batch``, ``info``, ``synth``, ``plot``,
``models``, ``demo``, ``export``, ``render``.

One module per command (``add_parser`` + ``run``); this module builds the parser and turns user
mistakes into one line on stderr. Exit codes: 0 success; 1 a fit that did not converge (its
results are still written, marked as such); 2 bad input or usage, including a usage error
found by argparse, an output that cannot be written and running out of memory (a
``MemoryError``, or XLA's ``RESOURCE_EXHAUSTED`` on the host or an accelerator); 130 / 143
interrupted by SIGINT / SIGTERM (see :mod:`brdffit.cli._signals`). ``--debug`` shows tracebacks.

Standard output goes through :class:`_Stdout`: a reader that closes the pipe early
(``brdffit models | head -1``) silences the rest of the output without an error, and any other
failure to write it (``/dev/full``) is one line and exit code 2. NumPy's floating-point
RuntimeWarnings never reach stderr: the readers and commands check values themselves; any
other warning is one line, ``brdffit COMMAND: warning: ...``.

The commands set float64 (``jax_enable_x64``) and the per-user persistent compilation cache
(:mod:`brdffit.compilation_cache`) before any JAX work; the library turns the cache on at its
first fit.
JAX and the fitter are imported only inside the commands that need them.
"""

from __future__ import annotations

import argparse
import atexit
import functools
import os
import sys
import traceback
import warnings
from typing import NoReturn

from . import batch, catalog, compare, demo, export, fitting, info, plotting, render, synth

__all__ = ["main", "run", "build_parser"]

COMMANDS = (fitting, compare, batch, info, synth, plotting, catalog, demo, export, render)
EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors in one line that points to ``--help`` (exit code 2)."""

    def error(self, message):
        text = " ".join(str(message).split())
        self.exit(EXIT_USAGE, f"{self.prog}: error: {text} (see `{self.prog} --help`)\n")


class StdoutError(OSError):
    """Standard output could not be written (other than a reader closing the pipe)."""


class _Stdout:
    """A proxy of ``sys.stdout``: ``BrokenPipeError`` silences it, other write errors raise
    :class:`StdoutError` (one line, exit code 2)."""

    def __init__(self, stream):
        self._stream, self.closed_by_reader = stream, False

    def _guard(self, fn, *args):
        if self.closed_by_reader:
            return None
        try:
            return fn(*args)
        except BrokenPipeError:
            self.closed_by_reader = True
            _silence(self._stream)
            return None
        except OSError as exc:
            raise StdoutError(exc.errno, f"cannot write to standard output "
                              f"({exc.strerror or exc})") from None

    def write(self, text):
        return self._guard(self._stream.write, text)

    def flush(self):
        return self._guard(self._stream.flush)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _silence(stream) -> None:
    """Point the stream's descriptor at /dev/null so the interpreter's final flush is quiet."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # not a real file (e.g. captured in tests)
        pass


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="brdffit",
        allow_abbrev=False,
        description="Fit analytic BRDF models to measured reflectance (MERL tables, sample lists).",
        epilog="Run `brdffit demo` for a complete example; `brdffit COMMAND --help` for details.",
    )
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"brdffit {__version__}")
    common = argparse.ArgumentParser(add_help=False)
    talk = common.add_mutually_exclusive_group()
    talk.add_argument("--quiet", "-q", action="store_true", help="no progress messages")
    talk.add_argument("--verbose", "-v", action="store_true",
                      help="every progress event of a fit on a line (solver steps included), "
                           "also when stderr is not a terminal; by default a terminal shows one "
                           "progress bar per fit")
    common.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    _global_options(parser, common)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS:
        module.add_parser(sub, [common])
    return parser


def _global_options(parser, common) -> None:
    """Make every option of ``common`` (the options all commands share) global: accepted
    before the command (``brdffit --quiet fit ...``) as well as after it.

    ``parser`` gets a copy of each, with its default; the commands' copies (``common`` is their
    parent) default to ``argparse.SUPPRESS``, so that a command whose line omits the option
    keeps what was given before the command instead of resetting it to the default.
    """
    import copy

    for action in common._actions:
        parser._add_action(copy.copy(action))
        action.default = argparse.SUPPRESS


def _user_errors() -> tuple[type[BaseException], ...]:
    """Exception types that mean "the user can fix this": one line, exit code 2."""
    from data_formats.samplelist import SampleListFormatError
    from data_formats.tensorfile import TensorFileError

    from ..errors import BrdffitError

    # the readers' own error types (brdffit.io.READERS); TensorFileError covers RGLFormatError
    errors: list = [BrdffitError, SampleListFormatError, TensorFileError, OSError]
    try:
        from data_formats.merl import MERLFormatError

        errors.append(MERLFormatError)
    except ImportError:  # pragma: no cover - the MERL module is part of the package
        pass
    return tuple(errors)


def _enable_x64() -> None:
    """float64, and the persistent compilation cache (:mod:`brdffit.compilation_cache`)."""
    import jax

    from .. import compilation_cache

    jax.config.update("jax_enable_x64", True)
    compilation_cache.enable()


def main(argv: list[str] | None = None, *, handle_signals: bool | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit code.

    ``handle_signals`` (default: when ``argv`` is None, i.e. run as a program) installs the
    SIGINT/SIGTERM watcher of :mod:`brdffit.cli._signals`, which ends the process itself
    (exit code 130 / 143) after removing every temporary file.
    """
    from ._signals import SignalExit

    handle = argv is None if handle_signals is None else handle_signals
    watcher = SignalExit("") if handle else None
    if watcher is not None:
        watcher.__enter__()
    saved, sys.stdout = sys.stdout, _Stdout(sys.stdout)
    try:
        return _main(argv, watcher)
    finally:
        sys.stdout = saved
        if watcher is not None:
            watcher.__exit__(None, None, None)


def run() -> NoReturn:
    """The ``brdffit`` program (the console script, ``cli.py``): :func:`main` on ``sys.argv``,
    then the end of the process without the interpreter's teardown.

    When the command has returned (its files written and closed, its threads joined), the
    standard streams are flushed, the exit handlers run (``atexit``: JAX's clean-up of its
    backends, logging, multiprocessing's children) and the process ends with ``os._exit``.
    Skipped is only the interpreter's finalisation, which frees every module, compiled program
    and jaxpr one object at a time: a noticeable part of a second after a fit, paid by every
    command for nothing. An exception that escapes :func:`main` (a bug) ends the process the
    usual way.
    """
    code = main()
    from ._signals import finish_on_signal

    finish_on_signal(code)  # a signal from here on: the command's status, no traceback
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a reader that closed the pipe, a closed stream
            pass
    atexit._run_exitfuncs()  # CPython's own exit-handler runner (what a normal exit calls)
    os._exit(code)


def _main(argv, watcher) -> int:
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # reported by the command's parser, so the pointer is to its --help
            _command_parser(parser, args.command).error(
                f"unrecognized arguments: {' '.join(extra)}")
        if args.quiet and getattr(args, "verbose", False):  # one before, one after the command
            _command_parser(parser, args.command).error(
                "argument --verbose/-v: not allowed with argument --quiet/-q")
    except SystemExit as exc:  # --help, --version (0) and usage errors (2)
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    if watcher is not None:
        watcher.command = args.command
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # NumPy's overflow/invalid notes
            warnings.showwarning = functools.partial(_warning_line, args.command)
            if getattr(args, "needs_jax", True):
                _enable_x64()
            code = int(args.run(args) or 0)
            sys.stdout.flush()
            return code
    except _user_errors() as exc:
        return _fail(args, _one_line(exc))
    except MemoryError:
        return _fail(args, OUT_OF_MEMORY)
    except Exception as exc:  # noqa: BLE001 (only an accelerator's or XLA's out-of-memory)
        if not _out_of_memory(exc):
            raise
        return _fail(args, OUT_OF_MEMORY)
    except KeyboardInterrupt:  # in-process use without the signal watcher
        print(f"brdffit {args.command}: interrupted", file=sys.stderr)
        return 130


#: The one line of an allocation that failed, in Python or in XLA (host or accelerator).
OUT_OF_MEMORY = ("out of memory; the input is too large for this machine (see the input limits "
                 "in docs/formats.md; --subsample or --cutoff fit fewer cells)")


def _out_of_memory(exc: BaseException) -> bool:
    """``exc``, or an exception it was raised from, is a failed allocation: a ``MemoryError``,
    or XLA's status ``RESOURCE_EXHAUSTED`` (which JAX raises as a ``JaxRuntimeError``, or as
    a ``ValueError`` from a transfer such as ``jax.device_put``), or XLA's ``INTERNAL: Error
    dispatching computation: Out of memory allocating …`` (a program that ran out)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        text = str(exc).lstrip()
        if (isinstance(exc, MemoryError) or text.startswith("RESOURCE_EXHAUSTED")
                or "out of memory allocating" in text.lower()):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def _warning_line(command, message, category, filename, lineno, file=None, line=None):
    """``warnings.showwarning`` of the commands: one line on stderr, without the source
    location (a library warning, e.g. masked corrupt cells, is advice for the user)."""
    text = " ".join(str(message).split())
    print(f"brdffit {command}: warning: {text}", file=sys.stderr)


def _command_parser(parser, command):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            return action.choices[command]
    return parser


def _fail(args, text: str) -> int:
    if args.debug:
        traceback.print_exc()
    print(f"brdffit {args.command}: error: {text}", file=sys.stderr)
    return EXIT_USAGE


def _one_line(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    elif isinstance(exc, OSError) and exc.strerror:
        text = exc.strerror
    return " ".join(text.split())
