"""The ``.binary`` file: reading (header checked before anything is allocated) and writing.

Header: three little-endian ``int32`` ``n_th, n_td, n_pd`` (90, 90, 180 in the database).
Body: ``3 * n_th * n_td * n_pd`` little-endian ``float64``, the red block, then green, then blue;
within a block the flat index is ``(i_th * n_td + i_td) * n_pd + i_pd``. The file size is exactly
``12 + 8 * 3 * n_th * n_td * n_pd`` (34,992,012 bytes for the database).
"""

from __future__ import annotations

import os

import numpy as np

from .._atomic import atomic_write
from .._files import NotRegularFileError, open_regular
from ._scale import CHANNELS, SCALE, stored_values
from ._table import MERLTable

#: Largest header dimension the reader accepts (the database uses at most 180).
MAX_DIM = 10_000
#: Most cells (``n_th * n_td * n_pd``) the reader accepts: 2^23, 5.75x the database grid. The
#: body is then 192 MiB; reading it peaks near 2.1x that (body plus channel-last rgb) and
#: ``brdffit info`` near 3x (its statistics copy the valid cells). A header asking for more is
#: refused before anything is allocated. (At 2^24 the fuzz run saw ``info`` peak at 1.1 GB.)
MAX_CELLS = 2**23
_HEADER_BYTES = 12


class MERLFormatError(ValueError):
    """A file that is not a well-formed MERL table. ``path`` names it; the message says what was
    expected, what was found and what to do."""

    def __init__(self, path, problem: str, expected: str, found: str, todo: str):
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {problem}: expected {expected}, found {found}. {todo}")


def expected_file_size(dims) -> int:
    """``12 + 8 * 3 * n_th * n_td * n_pd``, in exact integer arithmetic."""
    n_th, n_td, n_pd = (int(d) for d in dims)
    return _HEADER_BYTES + 8 * 3 * n_th * n_td * n_pd


_FIX = "Use a complete MERL .binary file (90 x 90 x 180: 34,992,012 bytes), e.g. re-download it"


def _open_for_reading(path: str):
    """Open ``path`` in binary mode, turning every OS-level failure into a MERLFormatError.

    Only regular files are opened (:func:`data_formats._files.open_regular`): a FIFO would block
    and a device such as ``/dev/zero`` never ends.
    """
    if os.path.isdir(path):
        raise MERLFormatError(path, "is a directory", "a MERL .binary file", "a directory",
                              "Pass the path of one .binary file inside it")
    try:
        return open_regular(path, "rb")
    except NotRegularFileError as exc:
        raise MERLFormatError(path, "not a regular file", "a MERL .binary file", exc.what,
                              "Copy the data into a file and pass that") from None
    except FileNotFoundError:
        raise MERLFormatError(path, "no such file", "an existing MERL .binary file",
                              "nothing at this path", "Check the path and the working directory"
                              ) from None
    except OSError as exc:
        raise MERLFormatError(path, "cannot be opened", "a readable file",
                              f"{type(exc).__name__}: {exc.strerror or exc}",
                              "Check the permissions") from None


def _check_header(path: str, header: bytes, size: int):
    """Validate the 12-byte header against the file size, before anything is allocated."""
    if size < _HEADER_BYTES:
        problem = "empty file" if size == 0 else "file too short for the header"
        raise MERLFormatError(path, problem, "a 12-byte header (three int32 dims) and a body",
                              f"{size} bytes", _FIX)
    dims = tuple(int(d) for d in np.frombuffer(header, dtype="<i4", count=3))
    if not all(1 <= d <= MAX_DIM for d in dims):
        raise MERLFormatError(path, "bad header dims", f"three dims between 1 and {MAX_DIM} "
                              "(the database has 90, 90, 180)", f"dims {dims}",
                              "The file is not a MERL table or is corrupt. " + _FIX)
    want = expected_file_size(dims)
    if size != want:
        how = f"truncated by {want - size:,}" if size < want else f"padded by {size - want:,}"
        raise MERLFormatError(path, f"file size does not match its header ({how} bytes)",
                              f"12 + 8*3*{dims[0]}*{dims[1]}*{dims[2]} = {want:,} bytes",
                              f"{size:,} bytes", _FIX)
    cells = dims[0] * dims[1] * dims[2]
    if cells > MAX_CELLS:
        raise MERLFormatError(path, "header asks for too many cells",
                              f"at most {MAX_CELLS:,} cells (the database has 1,458,000)",
                              f"dims {dims} = {cells:,} cells ({8 * 3 * cells / 2**30:.1f} GiB)",
                              "The reader refuses tables this large before allocating memory")
    return dims


def _nonfinite_error(path: str, blocks, dims) -> MERLFormatError:
    """Describe the first NaN/inf value of a body ``(3, n_cells)``."""
    bad = ~np.isfinite(blocks)
    c, flat = (int(x) for x in np.argwhere(bad)[0])
    cell = tuple(int(x) for x in np.unravel_index(flat, dims))
    return MERLFormatError(
        path, "non-finite values in the body",
        "finite float64 values (negative ones mark missing cells)",
        f"{int(np.count_nonzero(bad)):,} NaN/inf values, the first {blocks[c, flat]} in channel "
        f"{CHANNELS[c]} at cell {cell} (byte offset {12 + 8 * (c * blocks.shape[1] + flat):,})",
        "Regenerate the file storing missing cells as -1, not NaN or inf")


def _decode_body(path: str, body, dims):
    """Stored channel blocks -> (rgb channel-last with scales applied, valid mask).

    A min and a max over the body check finiteness (NaN propagates through both) without
    allocating; a cell is valid when no stored channel is negative, and missing cells get rgb 0.
    """
    n = int(np.prod(dims))
    blocks = body.reshape(3, n)
    lowest = blocks.min()
    if not (np.isfinite(lowest) and np.isfinite(blocks.max())):
        raise _nonfinite_error(path, blocks, dims)
    if lowest >= 0.0:
        valid = np.ones(n, dtype=bool)
    else:
        valid = blocks[0] >= 0.0
        valid &= blocks[1] >= 0.0
        valid &= blocks[2] >= 0.0
    rgb = np.empty((n, 3))
    np.multiply(blocks.T, SCALE, out=rgb)
    if not valid.all():
        rgb[~valid] = 0.0
    return rgb.reshape(*dims, 3), valid.reshape(dims)


def read_merl(path, *, mmap: bool = False) -> MERLTable:
    """Read a MERL ``.binary`` file into a :class:`MERLTable` (rgb in BRDF units, channel-last).

    The header is checked against the file size before anything is allocated; every malformed
    input (missing path, directory, empty, truncated or padded file, absurd dims, NaN/inf values)
    raises :class:`MERLFormatError` naming the path, what was expected and what was found.

    Memory (database grid, measured with ``tracemalloc``): the default reads the body into one
    buffer (35 MB) and builds the channel-last rgb (35 MB) and mask (1.5 MB) from it, a peak of
    about 76 MB of which 36.5 MB is kept. ``mmap=True`` maps the body with ``np.memmap``
    instead, so no process buffer is filled: the peak is about 41 MB, plus page cache shared
    with other readers of the file. The rgb is built eagerly in both cases: channel-last and
    scaled, it cannot be a view of the file's channel blocks. The map is released before
    returning (no file handle is kept open).
    """
    p = os.fspath(path)
    with _open_for_reading(p) as f:
        size = os.fstat(f.fileno()).st_size
        dims = _check_header(p, f.read(_HEADER_BYTES), size)
        n = 3 * int(np.prod(dims))
        if mmap:
            body = np.memmap(f, dtype="<f8", mode="r", offset=_HEADER_BYTES, shape=(n,))
        else:
            body = np.fromfile(f, dtype="<f8", count=n)
            if body.size != n:  # the file shrank between stat and read
                raise MERLFormatError(p, "file changed while reading", f"{n:,} values",
                                      f"{body.size:,}", "Read it again once it is written")
    try:
        rgb, valid = _decode_body(p, body, dims)
    finally:
        del body
    name = os.path.splitext(os.path.basename(p))[0]
    rgb.flags.writeable = False
    valid.flags.writeable = False
    return MERLTable(rgb, valid, p, name)


def write_merl(path, table: MERLTable) -> None:
    """Write ``table`` as a MERL ``.binary`` file, atomically.

    The exact inverse of :func:`read_merl`: stored value ``rgb / SCALE`` in valid cells, ``-1``
    in all three channels of missing cells, channel blocks R, G, B, little-endian. For tables
    built by :meth:`MERLTable.from_rgb`, :func:`synthesize` or :func:`read_merl`,
    ``read_merl(path)`` afterwards returns the same rgb and valid bit for bit (see
    :func:`snap_to_file` for what is exact for other values). The bytes go to a temporary
    file in the same folder, are flushed to disk, then ``os.replace`` puts it in place, so
    readers never see a partial file. Raises ``ValueError`` (before touching the disk) if a
    valid cell holds a value the format cannot carry.
    """
    if not isinstance(table, MERLTable):
        raise TypeError(f"write_merl: expected a MERLTable, got {type(table).__name__}; "
                        "build one with MERLTable.from_rgb(rgb, valid)")
    p = os.fspath(path)
    body = np.ascontiguousarray(np.moveaxis(stored_values(table.rgb, table.valid), -1, 0),
                                dtype="<f8")
    header = np.asarray(table.shape, dtype="<i4").tobytes()

    def write(f):
        f.write(header)
        body.tofile(f)

    atomic_write(p, write)
