"""Atomic file output shared by every writer: the file appears complete or not at all.

Bytes go to a temporary file in the destination's folder (same file system, so the final
``os.replace`` is atomic), are flushed to disk, and only then replace ``path``. On any failure
the temporary file is removed, so an interrupted or failed write leaves no partial output and
an existing file untouched. The new file gets the mode a plain ``open`` would give it (the
umask's), or keeps the mode of the file it replaces.

Writes in flight (:func:`writing`): every atomic write, and any other stretch of code that
creates files (a caller wraps it in :func:`writing`), is counted while it runs. A program that
must end at once (the command line on ``SIGINT``/``SIGTERM``) calls :func:`close_writes`:
writes that have not started wait (for ever: the process is ending), and the call returns when
those in flight have finished, so that what it then removes cannot be re-created behind its
back by a writer that was half-way through (a figure writer making its folder again, a
temporary created just after the clean-up listed the folder). Nested :func:`writing` blocks of
one thread count once. A library user who never calls :func:`close_writes` sees no difference.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

__all__ = ["atomic_path", "atomic_write", "writing", "close_writes", "open_writes"]

_GATE = threading.Condition(threading.Lock())
_STATE = {"closed": False, "active": 0}
_DEPTH = threading.local()


@contextlib.contextmanager
def writing() -> Iterator[None]:
    """Count the block as a write in flight (module docstring); waits while writes are closed."""
    depth = getattr(_DEPTH, "n", 0)
    if depth == 0:
        with _GATE:
            while _STATE["closed"]:
                _GATE.wait()
            _STATE["active"] += 1
    _DEPTH.n = depth + 1
    try:
        yield
    finally:
        _DEPTH.n = depth
        if depth == 0:
            with _GATE:
                _STATE["active"] -= 1
                _GATE.notify_all()


def close_writes(timeout: float, stop: Callable[[], bool] | None = None) -> bool:
    """Let no new write start; wait until none is in flight. Returns ``True`` when none is,
    ``False`` after ``timeout`` seconds or as soon as ``stop()`` is true (polled every 50 ms).
    Must not be called from inside :func:`writing`."""
    deadline = time.monotonic() + timeout
    with _GATE:
        _STATE["closed"] = True
        while _STATE["active"]:
            left = deadline - time.monotonic()
            if left <= 0 or (stop is not None and stop()):
                return False
            _GATE.wait(min(left, 0.05))
        return True


def open_writes() -> None:
    """Undo :func:`close_writes`: the writes that wait go on."""
    with _GATE:
        _STATE["closed"] = False
        _GATE.notify_all()


def _final_mode(path: Path) -> int:
    if path.is_file():
        return path.stat().st_mode & 0o7777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``.

    The temporary name keeps ``path``'s suffix, for writers that choose a format by it. The
    whole block is a write in flight (:func:`writing`).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    with writing():
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix or ".tmp",
                                   dir=folder)
        os.close(fd)
        tmp = Path(tmp)
        try:
            yield tmp
            os.chmod(tmp, _final_mode(path))
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise


def atomic_write(path, write: Callable[[BinaryIO], object]) -> Path:
    """Call ``write(f)`` on a binary file object, then put the file at ``path`` atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)
