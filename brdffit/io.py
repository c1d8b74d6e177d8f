"""Reading measured reflectance by file name: the one owner of the input formats.

:data:`READERS` maps each input suffix to what it holds and its reader; everything that names
the input formats takes them from here: :func:`read_path` (``brdffit.fit``, the command line,
``brdffit batch``), the help texts and messages (:func:`formats_text`, :func:`suffixes_text`,
:func:`suffixes_of`), and the tests, which are parametrized over it. A new format is one entry here.

===========  ==============  ==============================================
suffix       holds           reader
===========  ==============  ==============================================
``.binary``  MERL table      :func:`data_formats.merl.read_merl`
``.csv``     sample list     :func:`data_formats.samplelist.read_samples`
``.npz``     sample list     :func:`data_formats.samplelist.read_samples`
``.bsdf``    RGL material    :func:`data_formats.rgl.read_rgl`
===========  ==============  ==============================================

Every reader returns an object with ``.to_samples()`` (a :class:`data_formats.SampleSet` of
direction pairs), which is all the fitter needs. :func:`is_table` tells a MERL-layout table
(a regular grid the figures can slice) from the other kinds. NumPy only: no JAX is imported.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from pathlib import Path

from .errors import BrdffitError

#: Suffix (lower case) → (what it holds, the reader's module and function).
READERS = {
    ".binary": ("MERL table", "data_formats.merl", "read_merl"),
    ".csv": ("sample list", "data_formats.samplelist", "read_samples"),
    ".npz": ("sample list", "data_formats.samplelist", "read_samples"),
    ".bsdf": ("RGL material", "data_formats.rgl", "read_rgl"),
}


class _Kinds(Mapping):
    """Suffix → what it holds, read from :data:`READERS` at each use (so it never disagrees)."""

    def __getitem__(self, suffix: str) -> str:
        return READERS[suffix][0]

    def __iter__(self):
        return iter(READERS)

    def __len__(self) -> int:
        return len(READERS)


#: Suffix → what it holds (``".binary"`` → ``"MERL table"``): a live view of :data:`READERS`.
INPUT_SUFFIXES = _Kinds()
#: The kinds whose reader gives a measurement that evaluates itself at any direction pair
#: (``eval(wi, wo)``) and can be anisotropic; the figures add the polar view of the lobe
#: (:func:`brdffit.plots.figure_names`).
SELF_EVALUATING = frozenset({"RGL material"})


class InputFormatError(BrdffitError):
    """A path whose suffix names no known reader, or that does not exist."""


def kind_of(path) -> str | None:
    """What a file of ``path``'s suffix holds (``"MERL table"``...), ``None`` for no input format."""
    return INPUT_SUFFIXES.get(Path(os.fspath(path)).suffix.lower())


def suffixes_text(conjunction: str = "or") -> str:
    """The input suffixes as prose: ``".binary, .csv, .npz or .bsdf"``."""
    names = list(READERS)
    return ", ".join(names[:-1]) + f" {conjunction} {names[-1]}" if len(names) > 1 else names[0]


def suffixes_of(*kinds: str) -> str:
    """The suffixes of the files holding any of ``kinds``, for a help text:
    ``suffixes_of("sample list")`` is ``".csv/.npz"``."""
    return "/".join(suffix for suffix, kind in INPUT_SUFFIXES.items() if kind in kinds)


def formats_text() -> str:
    """The input formats for a help text or a message, suffixes grouped by what they hold:
    ``".binary MERL table, .csv/.npz sample list, .bsdf RGL material"``."""
    groups: dict[str, list[str]] = {}
    for suffix, kind in INPUT_SUFFIXES.items():
        groups.setdefault(kind, []).append(suffix)
    return ", ".join(f"{'/'.join(suffixes)} {kind}" for kind, suffixes in groups.items())


def is_path(value) -> bool:
    """True for a ``str`` or an ``os.PathLike`` (what :func:`read_path` accepts)."""
    return isinstance(value, (str, os.PathLike))


def is_table(data) -> bool:
    """Whether ``data`` is a MERL-layout table: ``rgb`` of shape ``(n_th, n_td, n_pd, 3)`` and a
    ``valid`` mask (a regular isotropic grid the figures can slice); ``False`` for a sample list
    and an RGL material."""
    import numpy as np

    rgb = getattr(data, "rgb", None)
    return rgb is not None and np.ndim(rgb) == 4 and hasattr(data, "valid")


def read_path(path):
    """The table, sample list or material at ``path`` (a ``str`` or ``PathLike``), read by its
    suffix (:data:`READERS`).

    Raises :class:`InputFormatError` for an unknown suffix or a missing file; a malformed file
    raises its format's own error (``MERLFormatError``, ``SampleListFormatError``,
    ``RGLFormatError``...).
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
    with open(path, "rb") as fh:
        return sha256_of(fh, chunk)


def sha256_of(fh, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of what remains in the binary file object ``fh`` (read in pieces): for a
    file the caller opened its own way (without following links, say)."""
    h = hashlib.sha256()
    while block := fh.read(chunk):
        h.update(block)
    return h.hexdigest()
