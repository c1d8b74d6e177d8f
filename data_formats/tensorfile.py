"""Mitsuba's tensor file: named n-dimensional arrays in one binary file (read, write).

The container of the RGL material database (``.bsdf``, Dupuy & Jakob 2018) and of other
Mitsuba data (``include/mitsuba/core/tensor.h`` and ``mitsuba/python/tensor_io.py`` of
Mitsuba 3). All integers are little-endian:

* 12 bytes ``b"tensor_file\\0"``; 2 bytes version ``uint8`` major, minor = ``1, 0``;
  ``uint32`` field count.
* Per field: ``uint16`` name length and the UTF-8 name; ``uint16`` ndim; ``uint8`` dtype
  (:data:`DTYPES`: 1 ``uint8`` … 10 ``float32``, 11 ``float64``, Mitsuba's ``Struct::Type``);
  ``uint64`` byte offset of the data from the start of the file; ``ndim`` × ``uint64`` shape.
* The data of each field: C order, little-endian, at its offset (the writers align it to 8).

Reading validates everything the header asks for before anything is allocated: the header is
parsed from at most :data:`MAX_HEADER_BYTES`, field count and ndim are bounded, every field must
lie inside the file, and the fields together may not ask for more bytes than the file holds (so
a hostile header cannot make the reader allocate more than the file's size, in total). Every
malformed input raises :class:`TensorFileError`, one line naming the path and what is wrong.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Mapping

import numpy as np

from ._atomic import atomic_write
from ._files import NotRegularFileError, open_regular

__all__ = ["TensorFileError", "read_tensor_file", "write_tensor_file", "DTYPES", "MAGIC",
           "MAX_FIELDS", "MAX_NDIM", "MAX_HEADER_BYTES", "MAX_FILE_BYTES"]

MAGIC = b"tensor_file\0"
VERSION = (1, 0)
#: Mitsuba's ``Struct::Type`` codes as the tensor file stores them (``tensor_io.py``).
DTYPES = {1: "<u1", 2: "<i1", 3: "<u2", 4: "<i2", 5: "<u4", 6: "<i4", 7: "<u8", 8: "<i8",
          9: "<f2", 10: "<f4", 11: "<f8"}
_CODES = {np.dtype(v): k for k, v in DTYPES.items()}
#: Most fields a header may declare (an RGL file has 11).
MAX_FIELDS = 1024
#: Most dimensions a field may have (an RGL file uses at most 5).
MAX_NDIM = 16
#: The header (magic to the last field's shape) may be at most this long.
MAX_HEADER_BYTES = 1 << 20
#: Largest file the reader accepts, 1 GiB (RGL files are a few MB, spectral ones up to a few
#: hundred). What a format makes of the arrays is the format's to bound: an RGL evaluation's
#: warps take up to about 10 times the bytes of the ``vndf`` table while they are built.
MAX_FILE_BYTES = 1 << 30
_PREFIX = struct.Struct("<12sBBI")


class TensorFileError(ValueError):
    """A file that is not a well-formed tensor file: ``path`` names it; the message (one line)
    says what is wrong and what was found."""

    def __init__(self, path, problem: str):
        self.path = None if path is None else os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


def _open(path: str, error):
    if os.path.isdir(path):
        raise error(path, "is a directory, not a tensor file; pass the path of one file inside it")
    try:
        return open_regular(path, "rb")
    except NotRegularFileError as exc:
        raise error(path, f"is {exc.what}, not a regular file; copy the data into a file") from None
    except FileNotFoundError:
        raise error(path, "no such file; check the path and the working directory") from None
    except OSError as exc:
        raise error(path, f"cannot be opened ({type(exc).__name__}: {exc.strerror or exc}); "
                    "check the permissions") from None


class _Header:
    """A cursor over the header bytes that raises ``error`` when the header runs out."""

    def __init__(self, data: bytes, path: str, size: int, error):
        self.data, self.pos, self.path, self.size, self.error = data, 0, path, size, error

    def take(self, fmt: str, what: str):
        n = struct.calcsize(fmt)
        if self.pos + n > len(self.data):
            where = ("the file ends" if len(self.data) >= self.size
                     else f"the header exceeds {MAX_HEADER_BYTES:,} bytes")
            raise self.error(self.path, f"truncated header: {what} at byte {self.pos:,} but "
                             f"{where} (file size {self.size:,} bytes)")
        out = struct.unpack_from(fmt, self.data, self.pos)
        self.pos += n
        return out


def _parse_field(h: _Header, index: int, names: set):
    (n_name,) = h.take("<H", f"field {index}'s name length")
    (raw,) = h.take(f"<{n_name}s", f"field {index}'s name ({n_name} bytes)")
    try:
        name = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise h.error(h.path, f"field {index}'s name is not UTF-8 ({raw[:40]!r})") from None
    if not name or name in names:
        raise h.error(h.path, f"field {index}'s name {name!r} is "
                      + ("empty" if not name else "declared twice"))
    ndim, code, offset = h.take("<HBQ", f"field {name!r}'s ndim, dtype and offset")
    if ndim > MAX_NDIM:
        raise h.error(h.path, f"field {name!r} declares {ndim} dimensions (at most {MAX_NDIM})")
    if code not in DTYPES:
        raise h.error(h.path, f"field {name!r} has unknown dtype code {code} (known: 1-11, "
                      "uint8 ... float64)")
    shape = h.take(f"<{ndim}Q", f"field {name!r}'s shape ({ndim} dims)") if ndim else ()
    return name, np.dtype(DTYPES[code]), int(offset), tuple(int(s) for s in shape)


def _check_extents(path, fields, header_end: int, size: int, error):
    """Every field inside the file, after the header; all together at most the file's size."""
    total = 0
    for name, dtype, offset, shape in fields:
        nbytes = dtype.itemsize
        for s in shape:  # exact integers; stop early once absurd
            nbytes *= s
            if nbytes > size:
                break
        if nbytes > size or offset + nbytes > size:
            raise error(path, f"field {name!r} ({dtype.name} {shape}) asks for "
                        f"{_human(nbytes)} at byte offset {offset:,} but the file has "
                        f"{size:,} bytes (truncated or corrupt)")
        if nbytes and offset < header_end:
            raise error(path, f"field {name!r}'s data at byte offset {offset:,} overlaps the "
                        f"header (which ends at byte {header_end:,})")
        total += nbytes
    if total > size:
        raise error(path, f"the fields together ask for {_human(total)} but the file has "
                    f"{size:,} bytes (fields overlap: corrupt file)")


def _human(n: int) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if n < 1024 or unit == "EiB":
            return f"{n:,} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return str(n)


def read_header(f, path: str, size: int, error=None):
    """Parse and validate the header of the open file ``f`` (``size`` bytes): a list of
    ``(name, dtype, offset, shape)``. Nothing but the header bytes is read."""
    error = error or TensorFileError
    if size == 0:
        raise error(path, "empty file (0 bytes); expected a tensor file (e.g. an RGL .bsdf)")
    if size > MAX_FILE_BYTES:
        raise error(path, f"file of {_human(size)} exceeds the reader's limit of "
                    f"{_human(MAX_FILE_BYTES)}")
    data = f.read(min(size, MAX_HEADER_BYTES))
    head = data[:12]
    if head != MAGIC[:len(head)]:
        raise error(path, f"not a tensor file: starts with {head!r}, expected {MAGIC!r} "
                    "(a Mitsuba tensor file such as an RGL .bsdf)")
    if len(data) < _PREFIX.size:
        raise error(path, f"truncated header: the file has {size} bytes, a tensor file header "
                    f"needs at least {_PREFIX.size}")
    h = _Header(data, path, size, error)
    _, major, minor, count = h.take(_PREFIX.format, "the prefix")
    if (major, minor) != VERSION:
        raise error(path, f"unsupported tensor file version {major}.{minor} (this reader "
                    "reads 1.0)")
    if count > MAX_FIELDS:
        raise error(path, f"header declares {count:,} fields (at most {MAX_FIELDS:,})")
    names: set = set()
    fields = []
    for i in range(count):
        field = _parse_field(h, i, names)
        names.add(field[0])
        fields.append(field)
    _check_extents(path, fields, h.pos, size, error)
    return fields


def read_tensor_file(path, *, error=None) -> dict[str, np.ndarray]:
    """Read a tensor file into ``{name: array}`` (native-endian copies, the file's dtypes).

    The header is validated against the file size before any field is read (module
    docstring). ``error`` is the exception class raised (default :class:`TensorFileError`;
    format readers built on this container pass their subclass).
    """
    error = error or TensorFileError
    p = os.fspath(path)
    out = {}
    with _open(p, error) as f:
        size = os.fstat(f.fileno()).st_size
        fields = read_header(f, p, size, error)
        for name, dtype, offset, shape in fields:
            count = int(np.prod(shape, dtype=object))
            f.seek(offset)
            arr = np.fromfile(f, dtype=dtype, count=count)
            if arr.size != count:  # the file shrank between stat and read
                raise error(p, f"file changed while reading field {name!r}; read it again "
                            "once it is written")
            out[name] = arr.astype(dtype.newbyteorder("="), copy=False).reshape(shape)
    return out


def _as_array(name, value) -> np.ndarray:
    if isinstance(value, str):
        value = value.encode("utf-8")
    if isinstance(value, bytes | bytearray):
        return np.frombuffer(bytes(value), dtype=np.uint8)
    arr = np.asarray(value)
    dtype = arr.dtype.newbyteorder("<") if arr.dtype.byteorder not in "|" else arr.dtype
    if dtype not in _CODES:
        raise TypeError(f"write_tensor_file: field {name!r} has dtype {arr.dtype}, which a tensor "
                        "file cannot hold; use one of " + ", ".join(
                            np.dtype(v).name for v in DTYPES.values()))
    return np.ascontiguousarray(arr, dtype=dtype)


def write_tensor_file(path, fields: Mapping[str, object], *, align: int = 8) -> None:
    """Write ``{name: array}`` as a tensor file, atomically (``data_formats._atomic``).

    Arrays keep their dtype (one of :data:`DTYPES`, stored little-endian); a ``str`` or
    ``bytes`` value is stored as a ``uint8`` vector (as Mitsuba's ``tensor_io.write`` does).
    Field data start at multiples of ``align`` bytes. Raises ``TypeError``/``ValueError``
    before touching the disk for a value the format cannot hold.
    """
    if len(fields) > MAX_FIELDS:
        raise ValueError(f"write_tensor_file: {len(fields)} fields, at most {MAX_FIELDS}")
    arrays, header = {}, bytearray(_PREFIX.pack(MAGIC, *VERSION, len(fields)))
    for name, value in fields.items():
        arr = _as_array(name, value)
        label = name.encode("utf-8")
        if not label or len(label) > 0xFFFF or arr.ndim > MAX_NDIM:
            raise ValueError(f"write_tensor_file: field {name!r}: the name must have 1-65535 "
                             f"bytes and the array at most {MAX_NDIM} dimensions")
        arrays[name] = arr
        header += struct.pack("<H", len(label)) + label
        header += struct.pack("<HBQ", arr.ndim, _CODES[arr.dtype], 0)
        header += struct.pack(f"<{arr.ndim}Q", *arr.shape)
    # Second pass: offsets, now that the header's length is known.
    pos, offsets, cursor = len(header), {}, len(_PREFIX.pack(MAGIC, 1, 0, 0))
    for name, arr in arrays.items():
        cursor += 2 + len(name.encode("utf-8")) + 2 + 1
        pos = -(-pos // align) * align
        offsets[name] = pos
        struct.pack_into("<Q", header, cursor, pos)
        cursor += 8 + 8 * arr.ndim
        pos += arr.nbytes

    def write(f):
        f.write(bytes(header))
        for name, arr in arrays.items():
            f.write(b"\0" * (offsets[name] - f.tell()))
            f.write(arr.tobytes())

    atomic_write(os.fspath(path), write)
