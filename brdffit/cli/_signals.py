"""SIGINT and SIGTERM: clean up, say so in one line, exit 130 / 143, never crash on the way out.

Why not the default ``KeyboardInterrupt``: a signal that arrives during a fit lands while XLA's
worker threads are still running the jitted computation. Unwinding ``main`` then returns to the
interpreter, whose shutdown tears down JAX's client and modules under those threads: the
process died with SIGSEGV after printing "interrupted" in 7 of 12 trials. And a Python handler
runs only when the main thread next executes bytecode, which during a long jitted call can be
many seconds later.

So, while a command runs, both signals get a no-op Python handler plus a wakeup file
descriptor (:func:`signal.set_wakeup_fd`): the C-level handler writes the signal number into a
pipe at once, and a watcher thread blocked on that pipe wakes immediately, whatever the main
thread is doing. Then, in this order:

1. **Writes are closed** (:func:`data_formats.files.close_writes`): no new write starts (a
   writer that tries waits until the process ends), and the watcher waits for the writes in
   flight (a figure, a table, an output set's publication) to finish, for at most
   :data:`WRITE_GRACE` seconds or until a second signal. Only then is anything removed: a
   writer half-way through can no longer re-create a staging folder or a temporary after
   the clean-up (before, a figure writer made its folder again behind the clean-up and left
   it with a partial figure).
2. Under :data:`brdffit.cli._outputs.LOCK`: if the command has **published** its outputs
   since it started (:func:`brdffit.cli._outputs.published_count`), the signal came too late
   to stop it: writes are opened again, the signal is ignored and the command ends with its
   own exit status (0; 1 for a fit that did not converge). Otherwise every live output set
   is aborted (its staging folder and every temporary in it removed; it can no longer
   publish), the registered cleanups run, one line goes to stderr and the process ends with
   ``os._exit(128 + signum)``: no interpreter teardown under running XLA threads, hence no
   segfault.

So a signal gives one of two outcomes, never a mix: the outputs published and the command's
own exit status, or nothing published and exit status 130 (``SIGINT``) / 143 (``SIGTERM``).
A signal that is ignored when the command starts (``nohup``, a shell's background job) stays
ignored. After the command has returned, :func:`finish_on_signal` covers the program's last
steps (a signal ends it with the command's own status).
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading

from data_formats.files import close_writes, open_writes

from . import _outputs

__all__ = ["SignalExit", "add_cleanup", "remove_cleanup", "finish_on_signal"]

_CLEANUPS: list = []
#: Seconds a signal waits for the writes in flight before it removes what they were writing.
WRITE_GRACE = 10.0
_NAMES = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated"}


def add_cleanup(fn) -> None:
    """Run ``fn()`` (e.g. removing a temporary folder) if a signal ends the command."""
    with _outputs.LOCK:
        _CLEANUPS.append(fn)


def remove_cleanup(fn) -> None:
    with _outputs.LOCK:
        if fn in _CLEANUPS:
            _CLEANUPS.remove(fn)


def finish_on_signal(code: int) -> None:
    """For the program's last steps after the command has returned (flushing, the exit
    handlers that tear JAX down): a signal then ends the process at once with the command's
    own status ``code``, without a ``KeyboardInterrupt`` traceback from an exit handler (the
    command's outputs are complete by then)."""

    def handler(signum, frame):
        os._exit(code)

    for s in _NAMES:
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, handler)


def _noop(signum, frame) -> None:  # the watcher thread does the work
    pass


def _close_progress_bars() -> None:
    """Close the progress bars still drawn (tqdm's: a fit's, a batch's), so that the signal's
    line comes after the bar's last line and no redraw follows it: the bar's line has no end
    of line until the bar closes, and a closed bar ignores the updates the running fit still
    sends."""
    tqdm = getattr(sys.modules.get("tqdm"), "tqdm", None)  # a command without a bar: no import
    for bar in list(getattr(tqdm, "_instances", ())):
        try:
            bar.close()
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass


class SignalExit:
    """Context manager installing the watcher (main thread only; a no-op elsewhere)."""

    def __init__(self, command: str):
        self.command = command
        self._saved = None
        self._published = _outputs.published_count()

    def __enter__(self) -> "SignalExit":
        if threading.current_thread() is not threading.main_thread():
            return self
        self._published = _outputs.published_count()
        self._read, self._write = os.pipe()
        os.set_blocking(self._write, False)
        self._old_fd = signal.set_wakeup_fd(self._write, warn_on_full_buffer=False)
        self._saved = {s: signal.signal(s, _noop) for s in _NAMES
                       if signal.getsignal(s) is not signal.SIG_IGN}  # nohup, a background job
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

    def _another_signal(self) -> bool:
        """True when a further signal (or the end of the command) is waiting in the pipe."""
        return bool(select.select([self._read], [], [], 0)[0])

    def _exit(self, signum: int) -> None:
        close_writes(WRITE_GRACE, stop=self._another_signal)
        with _outputs.LOCK:  # never lifted when the process ends inside
            if _outputs.published_count() > self._published:  # too late to stop the command
                open_writes()
                return
            for output_set in _outputs.live_sets():
                output_set.abort()
            for fn in list(_CLEANUPS):
                try:
                    fn()
                except Exception:  # noqa: BLE001 - best effort on the way out
                    pass
            _close_progress_bars()
            try:
                prog = f"brdffit {self.command}" if self.command else "brdffit"
                os.write(2, f"{prog}: {_NAMES[signum]}\n".encode())
            except OSError:
                pass
            os._exit(128 + signum)
