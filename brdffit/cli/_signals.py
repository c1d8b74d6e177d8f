"""SIGINT and SIGTERM: clean up, say so in one line, exit 130 / 143, never crash on the way out.

Why not the default ``KeyboardInterrupt``: a signal that arrives during a fit lands while XLA's
worker threads are still running the jitted computation (and calling back into Python for
progress). Unwinding ``main`` then returns to the interpreter, whose shutdown tears down JAX's
client and modules under those threads: the process died with SIGSEGV after printing
"interrupted" in 7 of 12 trials. And a Python handler runs only when the main thread next
executes bytecode, which during a long jitted call can be many seconds later.

So, while a command runs, both signals get a no-op Python handler plus a wakeup file
descriptor (:func:`signal.set_wakeup_fd`): the C-level handler writes the signal number into a
pipe at once, and a watcher thread blocked on that pipe wakes immediately, whatever the main
thread is doing. The watcher takes :data:`brdffit.cli._outputs.LOCK` (so a set that is being
published finishes first: outputs appear whole or not at all), aborts every live output set
(removing its staging folder and every temporary in it), runs the registered cleanups, writes
one line to stderr and ends the process with ``os._exit(128 + signum)``: no interpreter
teardown under running XLA threads, hence no segfault.
"""

from __future__ import annotations

import os
import signal
import threading

from . import _outputs

__all__ = ["SignalExit", "add_cleanup", "remove_cleanup"]

_CLEANUPS: list = []
_NAMES = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated"}


def add_cleanup(fn) -> None:
    """Run ``fn()`` (e.g. removing a temporary folder) if a signal ends the command."""
    with _outputs.LOCK:
        _CLEANUPS.append(fn)


def remove_cleanup(fn) -> None:
    with _outputs.LOCK:
        if fn in _CLEANUPS:
            _CLEANUPS.remove(fn)


def _noop(signum, frame) -> None:  # the watcher thread does the work
    pass


class SignalExit:
    """Context manager installing the watcher (main thread only; a no-op elsewhere)."""

    def __init__(self, command: str):
        self.command = command
        self._saved = None

    def __enter__(self) -> "SignalExit":
        if threading.current_thread() is not threading.main_thread():
            return self
        self._read, self._write = os.pipe()
        os.set_blocking(self._write, False)
        self._old_fd = signal.set_wakeup_fd(self._write, warn_on_full_buffer=False)
        self._saved = {s: signal.signal(s, _noop) for s in _NAMES}
        self._thread = threading.Thread(target=self._watch, name="brdffit-signals", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is None:
            return
        for s, handler in self._saved.items():
            signal.signal(s, handler)
        signal.set_wakeup_fd(self._old_fd)
        os.write(self._write, b"\0")  # wakes the watcher, which returns
        self._thread.join(timeout=5)
        os.close(self._write)
        os.close(self._read)
        self._saved = None

    def _watch(self) -> None:
        while True:
            data = os.read(self._read, 1)
            if not data or data == b"\0":
                return
            if data[0] in _NAMES:
                self._exit(data[0])

    def _exit(self, signum: int) -> None:
        with _outputs.LOCK:  # never lifted: the process ends inside
            for output_set in _outputs.live_sets():
                output_set.abort()
            for fn in list(_CLEANUPS):
                try:
                    fn()
                except Exception:  # noqa: BLE001 - best effort on the way out
                    pass
            try:
                prog = f"brdffit {self.command}" if self.command else "brdffit"
                os.write(2, f"{prog}: {_NAMES[signum]}\n".encode())
            except OSError:
                pass
            os._exit(128 + signum)
