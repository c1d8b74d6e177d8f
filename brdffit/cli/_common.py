"""Helpers shared by the commands: ``p=v`` parsing, inputs, safe outputs, progress.

Nothing here imports JAX; the commands import it (and the fitter) only when they run.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Iterable
from pathlib import Path

from ..errors import BrdffitError

from ..io import read_path


class UsageError(BrdffitError):
    """A command-line mistake the user can fix (bad ``p=v``, existing output, ...)."""


# -- values -----------------------------------------------------------------------------------
def parse_value(text: str, where: str):
    """``0.9,0.6,0.3`` → a 3-tuple; ``0.5`` → a float (fills all three channels of an RGB param)."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise UsageError(
            f"{where}: {text!r} is not a number or an RGB triple like 0.9,0.6,0.3"
        ) from None
    if not all(math.isfinite(v) for v in values):
        raise UsageError(f"{where}: {text!r} is not finite; give finite numbers")
    if len(values) == 1:
        return values[0]
    if len(values) == 3:
        return tuple(values)
    raise UsageError(f"{where}: {text!r} has {len(values)} values; give one number or three (r,g,b)")


def number(text: str) -> int | float:
    """An ``argparse`` type for a numeric option: ``"1e8"`` → ``100000000`` (an ``int`` when the
    value is whole), ``"0.1"``, ``"nan"``, ``"inf"`` → a ``float``. It accepts every number so
    that the option's range check names the range in its message."""
    value = float(text)
    if math.isfinite(value) and value == int(value) and abs(value) < 2**63:
        return int(value)
    return value


def parse_assignments(items: Iterable[str] | None, flag: str) -> dict:
    """``["alpha=0.1", "f0=0.9,0.6,0.3"]`` → ``{"alpha": 0.1, "f0": (0.9, 0.6, 0.3)}``.

    A name given twice is an error (which value was meant is not ours to guess).
    """
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise UsageError(f"{flag} {item!r}: expected NAME=VALUE, e.g. {flag} alpha=0.1")
        if name.strip() in out:
            raise UsageError(f"{flag} {name.strip()} is given twice; give each parameter once")
        out[name.strip()] = parse_value(value, f"{flag} {name.strip()}")
    return out


def check_no_conflict(init: dict, fixed: dict) -> None:
    """A parameter both started (``--init``) and held (``--fix``) is a contradiction."""
    both = sorted(set(init) & set(fixed))
    if both:
        raise UsageError(f"--init and --fix both name {', '.join(both)}; a parameter is either "
                         f"fitted from a start value (--init) or held fixed (--fix): keep one")


def check_params(model, values: dict, flag: str) -> dict:
    """Names and values of ``values`` checked against ``model``'s declared parameters."""
    for name, value in values.items():
        param = model.param(name)  # UnknownNameError lists the model's parameters
        try:
            param.check_bounds(value)
        except BrdffitError as exc:
            raise UsageError(f"{flag}: {exc}") from None
    return values


# -- inputs -----------------------------------------------------------------------------------
def read_input(path: str):
    """The input at ``path`` (any format of :data:`brdffit.io.READERS`), read by its suffix
    (:func:`brdffit.io.read_path`, the reader dispatch ``brdffit.fit`` uses for a path); only
    a regular file is opened (:func:`check_readable`)."""
    p = Path(path)
    if p.exists():
        check_readable(p)
    return read_path(path)


def check_readable(path: Path) -> None:
    """Refuse, before opening, anything that is not a regular file (a FIFO blocks ``open``)."""
    import stat

    from data_formats.files import describe_mode

    mode = path.stat().st_mode
    if not stat.S_ISREG(mode):
        raise UsageError(f"{path}: is {describe_mode(mode)}, not a regular file; copy the data "
                         f"into a file and pass that")


# -- outputs ----------------------------------------------------------------------------------
def check_outputs(paths: Iterable[str | None], force: bool, sizes: dict | None = None):
    """The :class:`~brdffit.cli._outputs.OutputSet` of ``paths``, checked before any work.

    Use it as a context manager (``with check_outputs(...) as outputs:``): its staging folders
    exist only inside the block, files are written with ``outputs.write`` and appear with
    ``outputs.publish()``; leaving the block removes whatever was not published.
    """
    from ._outputs import OutputSet

    return OutputSet(paths, force, sizes)


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path``: a staged path of an output set, which is private
    until published, so no temporary of its own is needed."""
    Path(path).write_text(text, encoding="utf-8")
    return Path(path)


# -- progress ---------------------------------------------------------------------------------
class Progress:
    """Progress on stderr for a command, only when stderr is a terminal and ``--quiet`` is not
    given (``force``: whatever the stream is).

    Calling it prints a message (or any event) as a line of its own. A fit's events go to
    :attr:`fit_events`, the ``progress`` callback to hand to the fit: by default one
    :class:`brdffit.progress.Bar` per fit, which counts the solver's steps on one line;
    with ``verbose`` (``--verbose``), the progress object itself: a line per event, the
    solver's step events overwriting one line on a terminal (on another stream, where
    ``--verbose`` also prints them, a line each).
    """

    def __init__(self, quiet: bool = False, stream=None, force: bool | None = None,
                 verbose: bool = False):
        self.stream = stream or sys.stderr
        self.tty = getattr(self.stream, "isatty", lambda: False)()
        if force is None:
            force = self.tty or verbose
        self.enabled = force and not quiet
        self.verbose = verbose
        self.start = time.perf_counter()
        self._inline = False
        self._bar = None

    @classmethod
    def of(cls, args) -> Progress:
        """The progress of a command run with ``args`` (its ``--quiet`` and ``--verbose``)."""
        return cls(quiet=args.quiet, verbose=getattr(args, "verbose", False))

    @property
    def fit_events(self):
        """The ``progress`` argument for a fit: ``None`` when disabled, this object with
        ``verbose``, else a bar (:class:`brdffit.progress.Bar`) on the stream."""
        if not self.enabled:
            return None
        if self.verbose:
            return self
        if self._bar is None:
            from ..progress import Bar

            self._bar = Bar(file=self.stream)
        return self._bar

    def __call__(self, *event) -> None:
        """Print one event: a message, or whatever the fitter's ``progress`` callback passes."""
        if not self.enabled:
            return
        text = f"[{time.perf_counter() - self.start:6.1f}s] " + " ".join(map(_describe, event))
        if self._bar is not None and self._bar.bar is not None:  # a fit's bar is on the line
            self._bar.bar.write(text, file=self.stream)
            return
        if self.tty and event and str(event[0]).endswith("step"):
            self.stream.write("\r" + text + "\x1b[K")
            self._inline = True
        else:
            self.stream.write(("\n" if self._inline else "") + text + "\n")
            self._inline = False
        self.stream.flush()


def _describe(event) -> str:
    if isinstance(event, dict):
        return " ".join(f"{k}={_short(v)}" for k, v in event.items())
    return _short(event)


def _short(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
