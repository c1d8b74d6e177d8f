"""Reading measured reflectance by file name: one reader dispatch for Python and the CLI.

:func:`read_path` picks the reader from the suffix (:data:`READERS`): ``.binary`` is a MERL
table (:func:`data_formats.merl.read_merl`), ``.csv`` and ``.npz`` are sample lists
(:func:`data_formats.samplelist.read_samples`). A new format is one entry here. NumPy only: no
JAX is imported.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from .errors import BrdffitError

#: Suffix (lower case) → (what it holds, the reader's module and function).
READERS = {
    ".binary": ("MERL table", "data_formats.merl", "read_merl"),
    ".csv": ("sample list", "data_formats.samplelist", "read_samples"),
    ".npz": ("sample list", "data_formats.samplelist", "read_samples"),
}
INPUT_SUFFIXES = {suffix: kind for suffix, (kind, _, _) in READERS.items()}


class InputFormatError(BrdffitError):
    """A path whose suffix names no known reader, or that does not exist."""


def is_path(value) -> bool:
    """True for a ``str`` or an ``os.PathLike`` (what :func:`read_path` accepts)."""
    return isinstance(value, (str, os.PathLike))


def read_path(path):
    """The table or sample list at ``path`` (a ``str`` or ``PathLike``), read by its suffix.

    Raises :class:`InputFormatError` for an unknown suffix or a missing file; a malformed file
    raises its format's own error (``MERLFormatError``, ``SampleListFormatError``).
    """
    import importlib

    p = Path(os.fspath(path))
    entry = READERS.get(p.suffix.lower())
    if entry is None:
        known = ", ".join(f"{s} ({k})" for s, (k, _, _) in READERS.items())
        raise InputFormatError(
            f"{p}: unknown input format {p.suffix or '(no suffix)'!r}; expected {known}"
        )
    if not p.exists():
        raise InputFormatError(f"{p}: no such file")
    _, module, function = entry
    return getattr(importlib.import_module(module), function)(p)


def sha256(path, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of the file at ``path`` (read in ``chunk``-byte pieces)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()
