"""The output folder of a batch: checked before any work, written without following links.

Layout: ``OUTDIR/<material>/<model>.json``, ``<model>.meta.json`` and figures (see
:mod:`brdffit.batch.jobs`); ``OUTDIR/results.parquet`` and ``results.csv``; with
``compare``, ``OUTDIR/leaderboard.parquet`` and ``leaderboard.csv``.

* **OUTDIR** is the user's own path: it may be, or pass through, a symbolic link. It is created
  if needed and proven writable (a file created in it and removed) before any work:
  :func:`prepare`.
* **Below OUTDIR** only real folders and regular files are accepted. Each name below it is one
  path component: a material name (made safe by :func:`brdffit.batch.inputs.safe_name`) or a
  file name made from a registered model name; anything else (``..``, a separator, a NUL) is
  refused (:func:`check_component`). A symbolic link, FIFO, device or socket where a material
  folder or a result file belongs is refused before any work (:func:`prepare`), and never
  followed later, even if it appears during the batch: a material folder is opened relative to
  OUTDIR's descriptor with ``O_NOFOLLOW`` (:class:`Folder`), files are created in it with
  ``O_NOFOLLOW | O_EXCL`` under a temporary name and renamed into place by descriptor (a rename
  replaces a name, it never writes through a link), and reads use ``O_NOFOLLOW`` too.

Refusals raise :class:`BatchOutputError` (one line, exit code 2 on the command line; inside a
job, the job's row records it).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from pathlib import Path

from ..errors import BrdffitError

#: Files a batch writes at the top of OUTDIR.
TABLE_FILES = ("results.parquet", "results.csv", "leaderboard.parquet", "leaderboard.csv")
NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_DIRECTORY = getattr(os, "O_DIRECTORY", 0)
CLOEXEC = getattr(os, "O_CLOEXEC", 0)


class BatchOutputError(BrdffitError):
    """An output folder or file of a batch that cannot be written (read-only, not a folder,
    a symbolic link or special file where a result belongs, an unsafe name)."""


def check_component(name: str) -> str:
    """``name`` if it is one safe path component, else :class:`BatchOutputError`."""
    if (not name or name in (".", "..") or "/" in name or "\0" in name
            or (os.altsep and os.altsep in name)):
        raise BatchOutputError(f"{name!r} cannot name a file or folder in the output folder "
                               "(it must be one plain name, not '.', '..' or a path)")
    return name


def _kind(st) -> str:
    from data_formats.files import describe_mode

    return "a symbolic link" if stat.S_ISLNK(st.st_mode) else describe_mode(st.st_mode)


def _lstat(name, dir_fd=None):
    try:
        return os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except FileNotFoundError:
        return None


def _refuse(where, st, what: str) -> BatchOutputError:
    return BatchOutputError(f"{where}: is {_kind(st)}, where the batch writes {what}; batch "
                            "outputs are never written through links or into special files: "
                            "remove it or choose another --outdir")


def _check_file(folder_fd: int, name: str, where) -> None:
    st = _lstat(name, folder_fd)
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise _refuse(where, st, "a result file")


def prepare(outdir, folders: dict) -> tuple[str, list]:
    """Create ``outdir`` if needed, prove it writable, and check the tree below it.

    ``folders`` maps each material name to the file names its jobs will write. Returns the
    absolute path of ``outdir`` and the folders created for it (innermost first; see
    :func:`remove_empty`). Raises :class:`BatchOutputError` before any work is done, leaving
    no folder it created.
    """
    outdir = os.path.abspath(outdir)
    created, parent = [], outdir
    while not os.path.lexists(parent) and parent != os.path.dirname(parent):
        created.append(parent)
        parent = os.path.dirname(parent)
    try:
        _check_tree(outdir, folders)
    except BaseException:
        remove_empty(created)
        raise
    return outdir, created


def remove_empty(folders) -> None:
    """Remove each of ``folders`` (in order) that is still empty; for a batch that never ran."""
    for folder in folders:
        with contextlib.suppress(OSError):
            os.rmdir(folder)


def _check_tree(outdir: str, folders: dict) -> None:
    try:
        os.makedirs(outdir, exist_ok=True)
    except FileExistsError:
        raise BatchOutputError(f"{outdir}: exists and is not a folder; give a folder for the "
                               "results") from None
    except OSError as exc:
        raise BatchOutputError(f"{outdir}: cannot create the output folder "
                               f"({exc.strerror or exc})") from None
    with _open_dir(outdir, None, follow=True) as root:
        _probe(root, outdir)
        for name in TABLE_FILES:
            _check_file(root, name, os.path.join(outdir, name))
        for material, files in folders.items():
            where = os.path.join(outdir, check_component(material))
            st = _lstat(material, root)
            if st is None:
                continue
            if not stat.S_ISDIR(st.st_mode):
                raise _refuse(where, st, "a material's folder")
            with _open_dir(material, root, where=where) as fd:
                for name in files:
                    _check_file(fd, check_component(name), os.path.join(where, name))


def _probe(root: int, outdir: str) -> None:
    name = f".brdffit-probe-{secrets.token_hex(4)}"
    try:
        fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | NOFOLLOW | CLOEXEC, 0o600,
                     dir_fd=root)
    except OSError as exc:
        raise BatchOutputError(f"{outdir}: cannot write into the output folder "
                               f"({exc.strerror or exc}); nothing was run") from None
    os.close(fd)
    os.unlink(name, dir_fd=root)


@contextlib.contextmanager
def _open_dir(name, dir_fd, follow: bool = False, where=None):
    """A descriptor of folder ``name`` (relative to ``dir_fd``); ``where``: its path for
    messages."""
    flags = os.O_RDONLY | _DIRECTORY | CLOEXEC | (0 if follow else NOFOLLOW)
    where = where or name
    try:
        fd = os.open(name, flags, dir_fd=dir_fd)
    except OSError as exc:
        st = None if follow else _lstat(name, dir_fd)
        if st is not None and not stat.S_ISDIR(st.st_mode):
            raise _refuse(where, st, "a material's folder") from None
        raise BatchOutputError(f"{where}: cannot open the folder ({exc.strerror or exc})") \
            from None
    try:
        yield fd
    finally:
        os.close(fd)


class Folder:
    """``OUTDIR/<material>`` opened without following links (see the module docstring).

    ``create``: make the folder if it does not exist; else a missing folder is ``None``
    (:meth:`open`). All names are single components inside this folder.
    """

    def __init__(self, fd: int, path: Path):
        self.fd, self.path = fd, path

    @classmethod
    @contextlib.contextmanager
    def open(cls, outdir, material: str, create: bool):
        check_component(material)
        path = Path(outdir) / material
        with _open_dir(os.fspath(outdir), None, follow=True) as root:
            if create:
                with contextlib.suppress(FileExistsError):
                    os.mkdir(material, dir_fd=root)
            elif _lstat(material, root) is None:
                yield None
                return
            with _open_dir(material, root, where=path) as fd:
                yield cls(fd, path)

    def read(self, name: str) -> bytes | None:
        """The bytes of regular file ``name``; None if it is missing or not a regular file."""
        try:
            fd = os.open(check_component(name), os.O_RDONLY | NOFOLLOW | CLOEXEC,
                         dir_fd=self.fd)
        except OSError:
            return None
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                return None
            return f.read()

    def is_file(self, name: str) -> bool:
        st = _lstat(check_component(name), self.fd)
        return st is not None and stat.S_ISREG(st.st_mode)

    def write(self, name: str, data: bytes) -> Path:
        """Put ``data`` at ``name`` atomically: a new temporary file, then a rename."""
        tmp = self._temporary(name)
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | NOFOLLOW | CLOEXEC,
                         0o666, dir_fd=self.fd)
            with os.fdopen(fd, "wb") as f:
                old = _lstat(name, self.fd)
                if old is not None and stat.S_ISREG(old.st_mode):
                    os.fchmod(f.fileno(), old.st_mode & 0o7777)  # keep the replaced file's mode
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            self._replace(tmp, name)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp, dir_fd=self.fd)
            raise
        return self.path / name

    def move_in(self, source, name: str) -> Path:
        """Move the file at path ``source`` (same file system) to ``name`` in this folder."""
        self._replace(os.fspath(source), name, src_dir_fd=None)
        return self.path / name

    def _temporary(self, name: str) -> str:
        stem, dot, suffix = check_component(name).rpartition(".")
        return f".{name}.{secrets.token_hex(4)}{'.' + suffix if dot else '.tmp'}"

    def _replace(self, src: str, name: str, src_dir_fd: int | None = -1) -> None:
        _check_file(self.fd, check_component(name), self.path / name)
        os.replace(src, name, src_dir_fd=self.fd if src_dir_fd == -1 else src_dir_fd,
                   dst_dir_fd=self.fd)

    def remove(self, patterns) -> None:
        """Remove the entries matching any of the glob ``patterns`` (links themselves, never
        what they point to)."""
        import fnmatch

        for entry in os.listdir(self.fd):
            if any(fnmatch.fnmatchcase(entry, p) for p in patterns):
                with contextlib.suppress(OSError):
                    os.unlink(entry, dir_fd=self.fd)
