"""Inputs of a batch: globs, paths and lists of paths → named materials; input checksums.

A *material* is one input table, named by its file stem (``gold-metallic-paint.binary`` →
``gold-metallic-paint``) or, for a table given in memory, by its ``name``. Every material needs
its own name, because its results go to ``OUTDIR/<material>/``. A name comes from data, so it is
made one safe folder name first (:func:`safe_name`): never ``..``, a path or a hidden name.

A list of paths is UTF-8 text of at most :data:`LIST_MAX_BYTES` bytes, read line by line (no
line longer than :data:`LINE_MAX_BYTES`); anything else is refused with the line it stopped at.
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import os
from pathlib import Path

import numpy as np

from ..errors import BrdffitError
from ..io import INPUT_SUFFIXES, formats_text, suffixes_text

_GLOB_CHARS = set("*?[")
#: The largest list of paths read (64 MiB: a million paths of 64 bytes); a larger one is
#: refused before it is read.
LIST_MAX_BYTES = 64 << 20
#: The longest line of a list of paths (Linux's PATH_MAX).
LINE_MAX_BYTES = 4096
#: The longest material name, in UTF-8 bytes: a folder name, with room under NAME_MAX (255)
#: for the file names a job writes in it.
NAME_MAX_BYTES = 128


class BatchInputError(BrdffitError):
    """Inputs that cannot make a batch (nothing matched, a missing path, two equal names)."""


@dataclasses.dataclass(frozen=True)
class Material:
    """One input: ``name`` and either ``path`` (a file) or ``table`` (in memory)."""

    name: str
    path: str | None = None
    table: object = None

    @property
    def label(self) -> str:
        """The input as the results table records it: the path, or ``<memory>``."""
        return self.path if self.path is not None else "<memory>"


def expand(items) -> list[str]:
    """Paths named by ``items``, in order, each once.

    An item with ``*``, ``?`` or ``[`` is a glob (``**`` recurses; sorted); an existing file whose
    suffix is not an input format (:data:`brdffit.io.READERS`) is a list of paths, one per
    line (blank lines and ``#`` comments skipped, relative paths taken from the list's folder);
    anything else is a path. A glob that matches nothing or a path that does not exist raises
    :class:`BatchInputError`.
    """
    out: list[str] = []
    for item in items:
        item = str(item)
        if _GLOB_CHARS & set(item):
            found = sorted(glob.glob(item, recursive=True))
            if not found:
                raise BatchInputError(f"{item!r} matches no file; check the pattern (quote it "
                                      "so the shell does not expand it)")
            out += found
        elif Path(item).is_file() and Path(item).suffix.lower() not in INPUT_SUFFIXES:
            out += _read_list(Path(item))
        elif Path(item).is_file():
            out.append(item)
        else:
            raise BatchInputError(f"{item}: no such file (inputs are {formats_text()} files, "
                                  "globs, or a text file of paths)")
    return list(dict.fromkeys(out))


def _read_list(path: Path) -> list[str]:
    out = []
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size > LIST_MAX_BYTES:
                raise BatchInputError(f"{path}: a list of {size:,} bytes; a list of paths holds "
                                      f"at most {LIST_MAX_BYTES:,} bytes: split it, or give a "
                                      "glob")
            n, total = 0, 0
            while raw := f.readline(LINE_MAX_BYTES + 2):
                n, total = n + 1, total + len(raw)
                if total > LIST_MAX_BYTES:  # grew while read
                    raise BatchInputError(f"{path}: longer than {LIST_MAX_BYTES:,} bytes; a "
                                          "list of paths holds no more: split it")
                line = _list_line(path, n, raw)
                if not line or line.startswith("#"):
                    continue
                p = Path(line) if Path(line).is_absolute() else path.parent / line
                if not p.is_file():
                    raise BatchInputError(f"{path}, line {n}: {line}: no such file")
                out.append(str(p))
    except OSError as exc:
        raise BatchInputError(f"{path}: cannot read the list ({exc.strerror or exc})") from None
    return out


def _list_line(path, n: int, raw: bytes) -> str:
    """Line ``n`` of a list, decoded and stripped; :class:`BatchInputError` if it is not a
    line of UTF-8 text that can name a path."""
    text = raw.rstrip(b"\r\n")
    if len(text) > LINE_MAX_BYTES:
        raise BatchInputError(f"{path}, line {n}: longer than {LINE_MAX_BYTES} bytes, so not a "
                              "path; a list of paths has one path per line")
    try:
        line = text.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BatchInputError(
            f"{path}, line {n}: not UTF-8 text (byte 0x{text[exc.start]:02x} at column "
            f"{exc.start + 1}); a list of paths is a UTF-8 text file, one path per line, and "
            f"tables need the suffix {suffixes_text()}") from None
    if "\0" in line:
        raise BatchInputError(f"{path}, line {n}: contains a NUL byte, so not a path; a list of "
                              "paths is a text file, one path per line")
    return line.removeprefix("\ufeff").strip() if n == 1 else line.strip()


def materials(paths_or_tables) -> list[Material]:
    """:class:`Material` for each input (a path, a glob, a list file, or a table in memory).

    Raises :class:`BatchInputError` when two inputs share a name (``a/x.binary`` and
    ``b/x.binary``), since their results would go to the same folder.
    """
    if isinstance(paths_or_tables, (str, Path)) or hasattr(paths_or_tables, "to_samples"):
        paths_or_tables = [paths_or_tables]
    out: list[Material] = []
    for i, item in enumerate(paths_or_tables):
        if hasattr(item, "to_samples"):
            name = safe_name(getattr(item, "name", "") or f"table{i}")
            out.append(Material(name, table=item))
        else:
            out += [Material(safe_name(Path(p).stem), path=p) for p in expand([item])]
    seen: dict[str, str] = {}
    for m in out:
        if m.name in seen:
            raise BatchInputError(f"two inputs are both named {m.name!r} ({seen[m.name]} and "
                                  f"{m.label}); their results would share OUTDIR/{m.name}/: "
                                  "rename one")
        seen[m.name] = m.label
    if not out:
        raise BatchInputError("no inputs given")
    return out


def safe_name(name) -> str:
    """``name`` as one safe folder name: letters, digits and ``-_.+`` kept, anything else
    (a separator, a control character, an undecodable byte) ``_``; leading dots ``_`` (never
    ``.``, ``..`` or a hidden name); at most :data:`NAME_MAX_BYTES` bytes; ``table`` if empty.
    Different names can map to one; :func:`materials` refuses such a clash."""
    text = "".join(c if c.isalnum() or c in "-_.+" else "_" for c in str(name))
    stripped = text.lstrip(".")
    text = ("_" * (len(text) - len(stripped)) + stripped)[:NAME_MAX_BYTES]
    while len(text.encode("utf-8", "replace")) > NAME_MAX_BYTES:
        text = text[:-1]
    return text or "table"


def file_checksum(path) -> str:
    """``sha256:<hex>`` of the file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return "sha256:" + h.hexdigest()


def table_checksum(table) -> str:
    """``sha256:<hex>`` of a table's samples (directions, values, validity), for in-memory input."""
    s = table.to_samples()
    h = hashlib.sha256()
    for a in (s.wi, s.wo, s.rgb, s.valid):
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return "sha256:" + h.hexdigest()


def read(path):
    """The table, sample list or material in ``path``, read by its suffix
    (:func:`brdffit.io.read_path`); an unknown suffix raises :class:`BatchInputError`."""
    from ..io import InputFormatError, read_path

    try:
        return read_path(path)
    except InputFormatError as exc:
        raise BatchInputError(str(exc)) from None
