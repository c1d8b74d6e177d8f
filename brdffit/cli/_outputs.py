"""A command's output files as one set: checked before the work, published together or not at all.

:class:`OutputSet` is the one staging mechanism of the command line: a context manager that
owns its staging folders, so that they exist only inside its ``with`` block. Contract (what
``fit``, ``plot``, ``synth``, ``demo``, ``export`` and ``render`` rely on):

* **Before any work** (``OutputSet(paths, force)``, nothing created yet): every output must
  have an existing folder, must not be a folder, must not exist unless ``force``, and must
  never be anything but a regular file (a device such as ``/dev/full``, a FIFO or a symlink is
  never replaced, even with ``force``). Each destination folder is proved writable (a private
  folder is made there and removed at once: ``EROFS``, ``EACCES`` are reported now, not after
  a long fit), and the free space and the file-size limit (``RLIMIT_FSIZE``) are compared
  with the expected sizes.
* **Entering** the ``with`` block creates, in each destination folder, a private staging
  folder (``.brdffit-XXXXXXXX``); **leaving** it, however (return, exception), removes them and
  every temporary in them. Staged paths exist only inside the block.
* **Writing** goes to :meth:`OutputSet.staged` paths inside the staging folders, through
  :meth:`OutputSet.write`, a write in flight (:func:`data_formats.files.writing`); a failed
  write (``ENOSPC``, ``EFBIG``, ...) raises :class:`OutputError` and nothing is published.
* **Publishing** (:meth:`OutputSet.publish`) moves every staged file into place. Without
  ``force`` each file is hard-linked to its name (``link`` fails if the name exists), so "no
  overwrite without ``--force``" holds at the moment of publishing even when another process
  created the file during the fit; if any link fails, the files already linked by this set
  are removed again, so the set appears whole or not at all. With ``force`` existing regular
  files are replaced by ``rename`` (keeping their mode), one after the other. A command
  publishes one set, as its last piece of work: publishing is its point of no return (see
  *Signals*).
* **Signals** (``SIGINT``/``SIGTERM``, :mod:`brdffit.cli._signals`): the watcher lets no new
  write start, waits for the writes in flight to finish, then, under :data:`LOCK` (which
  :meth:`~OutputSet.publish` holds while it publishes), either finds that a set has been
  published, and lets the command finish with its own exit status (the signal is ignored), or
  aborts every live set (staging folders removed; a later ``publish`` is refused) and ends the
  process with 130 / 143. So the outputs are published and the exit status is the command's
  (0; 1 for a fit that did not converge), or nothing is published and the status is 130 / 143:
  never both.
"""

from __future__ import annotations

import contextlib
import errno
import os
import resource
import shutil
import stat
import tempfile
import threading
from collections.abc import Iterable
from pathlib import Path

from data_formats.files import writing

from ..errors import BrdffitError

__all__ = ["OutputError", "OutputSet", "LOCK", "live_sets", "published_count", "remove_tree"]

#: Held while a set publishes or is discarded; the signal watcher takes it before cleaning up.
LOCK = threading.RLock()
_LIVE: set = set()
_PUBLISHED = [0]  # sets published in this process (the signal watcher compares it)
#: Bytes assumed for an output whose size is not known in advance (a figure, a JSON result):
#: a lower bound, so that the check before the work never refuses what would fit; a write
#: that runs out of space later still fails cleanly (nothing is published).
DEFAULT_SIZE = 16 << 10
_STAGING_PREFIX = ".brdffit-"


class OutputError(BrdffitError):
    """An output that cannot be written (exists, not a regular file, read-only, disk full)."""


def live_sets() -> list:
    """The sets inside their ``with`` block and not yet published or discarded."""
    return list(_LIVE)


def published_count() -> int:
    """How many sets this process has published (the signal watcher's point of no return)."""
    return _PUBLISHED[0]


def remove_tree(folder) -> None:
    """Remove ``folder`` and all it holds, again while something re-creates entries in it
    (``rmtree`` alone gives up when a file appears between its listing and its ``rmdir``)."""
    for _ in range(50):
        shutil.rmtree(folder, ignore_errors=True)
        if not os.path.lexists(folder):
            return


def _describe(path: Path, st) -> str:
    from data_formats.files import describe_mode

    return "a symbolic link" if stat.S_ISLNK(st.st_mode) else describe_mode(st.st_mode)


def _check_one(path: Path, force: bool) -> None:
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        st = None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{path}: is a directory; give a file name for the output")
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise OutputError(f"{path}: exists and is {_describe(path, st)}, not a regular file; "
                          f"outputs never replace one (even with --force): choose another name")
    if st is not None and not force:
        raise OutputError(f"{path}: already exists; pass --force to overwrite it")
    folder = path.parent
    if not folder.is_dir():
        raise OutputError(f"{path}: folder {str(folder)!r} does not exist; create it first")


def _probe(folder: Path) -> None:
    """Prove ``folder`` writable before any work, leaving nothing there."""
    with writing():
        try:
            os.rmdir(tempfile.mkdtemp(prefix=_STAGING_PREFIX, dir=folder))
        except OSError as exc:
            raise _os_error(folder, exc, "write into this folder") from None


def _os_error(path, exc: OSError, when: str) -> OutputError:
    reason = exc.strerror or type(exc).__name__
    return OutputError(f"{path}: cannot {when} ({reason}); nothing was written")


class OutputSet:
    """The outputs of one command (see the module docstring), a context manager owning its
    staging folders. ``sizes`` maps a path to the bytes it will take (default
    :data:`DEFAULT_SIZE`), for the free-space check."""

    def __init__(self, paths: Iterable, force: bool, sizes: dict | None = None):
        self.paths = [Path(p) for p in paths if p is not None]
        self.force, self.aborted, self._staging = force, False, {}
        self._entered = self._closed = False
        self._published: list[Path] = []
        if len({os.path.abspath(p) for p in self.paths}) != len(self.paths):
            raise OutputError("two outputs name the same file; give each output its own path")
        for p in self.paths:
            _check_one(p, force)
        folders = {os.path.abspath(p.parent): p.parent for p in self.paths}
        for folder in folders.values():
            _probe(folder)
        self._check_room({Path(k): v for k, v in (sizes or {}).items() if k is not None})

    def __enter__(self) -> "OutputSet":
        with writing(), LOCK:
            if self._entered:
                raise RuntimeError("an OutputSet is entered once")
            self._entered = True
            _LIVE.add(self)
            try:
                for p in self.paths:
                    self._folder(p.parent)
            except BaseException:
                self.discard()
                raise
        return self

    def __exit__(self, *exc) -> None:
        self.discard()

    def _folder(self, folder: Path) -> Path:
        with LOCK:
            if not self._entered or self._closed:
                raise OutputError("interrupted before the outputs were published"
                                  if self.aborted else
                                  "internal error: outputs are staged only inside the "
                                  "OutputSet's with block")
            key = os.path.abspath(folder)
            if key not in self._staging:
                try:
                    self._staging[key] = Path(tempfile.mkdtemp(prefix=_STAGING_PREFIX,
                                                               dir=folder))
                except OSError as exc:
                    raise _os_error(folder, exc, "write into this folder") from None
            return self._staging[key]

    def _check_room(self, sizes: dict) -> None:
        need: dict = {}
        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        for p in self.paths:
            size = int(sizes.get(p, DEFAULT_SIZE))
            if limit != resource.RLIM_INFINITY and size > limit:
                raise OutputError(f"{p}: needs about {size:,} bytes but the file-size limit "
                                  f"(ulimit -f) is {limit:,} bytes; nothing was written")
            key = os.path.abspath(p.parent)
            need[key] = need.get(key, 0) + size
        for folder, size in need.items():
            st = os.statvfs(folder)
            free = st.f_bavail * st.f_frsize
            if free < size:
                raise OutputError(f"{folder}: {free:,} bytes free, the outputs need about "
                                  f"{size:,}; free some space or write elsewhere")

    def staged(self, path) -> Path:
        """Where to write the output ``path`` now (inside this set's staging folder)."""
        path = Path(path)
        return self._folder(path.parent) / path.name

    def staged_base(self, path) -> Path:
        """The staged counterpart of a base path (a figure prefix, or a folder for figures)."""
        path = Path(path)
        if path.is_dir() or str(path).endswith(("/", "\\")):
            return self._folder(path)
        return self.staged(path)

    def write(self, path, fill, base: bool = False) -> Path:
        """``fill(staged_path)``, a write in flight, with write failures turned into
        :class:`OutputError`.

        ``base=True``: ``path`` is a base for several outputs (figures), staged by
        :meth:`staged_base`.
        """
        with writing():
            target = self.staged_base(path) if base else self.staged(path)
            try:
                fill(target)
            except OSError as exc:
                raise _os_error(path, exc, "write it") from None
        return Path(path)

    def publish(self) -> list[Path]:
        """Move every staged output into place, all or nothing (module docstring)."""
        with writing(), LOCK:
            if self.aborted:
                raise OutputError("interrupted before the outputs were published")
            try:
                for p in self.paths:
                    self._publish_one(p)
            except BaseException:
                for q in self._published:
                    q.unlink(missing_ok=True)
                self._published.clear()
                raise
            finally:
                self.discard()
            _PUBLISHED[0] += 1
        return list(self.paths)

    def _publish_one(self, path: Path) -> None:
        staged = self.staged(path)
        if not staged.is_file():
            raise OutputError(f"{path}: was not written (internal error); nothing was published")
        if self.force:
            _check_one(path, True)  # still not a device, FIFO or link at this moment
            with contextlib.suppress(FileNotFoundError):  # a replaced file keeps its mode
                os.chmod(staged, os.stat(path).st_mode & 0o7777)
            os.replace(staged, path)
            return
        try:
            os.link(staged, path)
        except FileExistsError:
            raise OutputError(f"{path}: appeared while this command ran (another process wrote "
                              f"it); nothing was published: pass --force to overwrite") from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV):
                raise _os_error(path, exc, "publish it") from None
            self._publish_without_links(staged, path)
        self._published.append(path)

    @staticmethod
    def _publish_without_links(staged: Path, path: Path) -> None:
        """For file systems without hard links: claim the name with ``O_EXCL``, then rename."""
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        except FileExistsError:
            raise OutputError(f"{path}: appeared while this command ran; nothing was published: "
                              f"pass --force to overwrite") from None
        os.replace(staged, path)

    def discard(self) -> None:
        """Remove the staging folders and all they hold (idempotent; published files stay);
        the set takes no more writes."""
        with LOCK:
            self._closed = True
            for folder in self._staging.values():
                remove_tree(folder)
            self._staging.clear()
            _LIVE.discard(self)

    def abort(self) -> None:
        """On a signal: remove the staging folders; the set can no longer publish."""
        with LOCK:
            self.aborted = True
            self.discard()
