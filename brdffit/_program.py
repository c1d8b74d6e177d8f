"""The ``brdffit`` program's first lines: an interrupt during start-up ends it quietly.

Importing the command line (argparse, every command's module, what they import) takes a
moment before :func:`brdffit.cli.main` installs its signal watcher (:mod:`brdffit.cli._signals`);
an interrupt in that window printed a ``KeyboardInterrupt`` traceback from the middle of an
import. Nothing has been read or written yet, so :func:`run` ends the process at once with the
signal's status (130 for ``SIGINT``, 143 for ``SIGTERM``) until the command line is imported,
then puts the handlers back for :func:`brdffit.cli.run`. Signals ignored at start (``nohup``)
stay ignored. This module imports nothing of brdffit before the handlers are in place.

A local ``brdffit batch`` starts its worker processes with multiprocessing's "spawn", which
imports the program as the worker's main module first (``__mp_main__``): such a process ignores
``SIGINT`` from then on (:func:`ignore_interrupts_in_workers`). A Ctrl-C at a terminal reaches
the whole process group; the command's own process stops its workers
(:func:`brdffit.batch.runner.close_local_clusters`), and a worker interrupted in its imports
printed a ``KeyboardInterrupt`` traceback.
"""

from __future__ import annotations

import os
import signal
import sys

__all__ = ["run"]

SIGNALS = (signal.SIGINT, signal.SIGTERM)


def ignore_interrupts_in_workers() -> bool:
    """Ignore ``SIGINT`` when this process is a multiprocessing "spawn" child that is importing
    the program as its main module (which it then runs under the name ``__mp_main__``, the
    parent's under ``__main__``); True if so."""
    main = sys.modules.get("__mp_main__")
    if getattr(main, "__name__", None) == "__mp_main__":
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        return True
    return False


def _end(signum, frame) -> None:
    os._exit(128 + signum)


def run() -> None:
    """The console script: :func:`brdffit.cli.run`, with start-up interrupts handled."""
    saved = {s: signal.signal(s, _end) for s in SIGNALS
             if signal.getsignal(s) is not signal.SIG_IGN}
    from .cli import run as command_line

    for s, handler in saved.items():
        signal.signal(s, handler)
    command_line()


ignore_interrupts_in_workers()
