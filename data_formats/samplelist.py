"""Gonioreflectometer-style sample lists: one measured direction pair per row (CSV or NPZ).

NumPy only (CSV bodies are parsed by pyarrow's C++ reader, imported when a CSV is read). A sample list is the second input format beside MERL tables: a flat list of
measurements, each an incident direction, an outgoing direction and an RGB BRDF value.

Column layout
-------------
Every file holds exactly one of two direction layouts plus the three colour columns:

=====================  ===========================================================================
``theta_i, phi_i,``    angles in **degrees**: θ from the normal (z), 0 ≤ θ ≤ 90; φ the azimuth
``theta_o, phi_o``     from the x axis towards y (any finite value; 360° periodic).
                       ``w = (sin θ cos φ, sin θ sin φ, cos θ)``.
``wix, wiy, wiz,``     unit direction vectors in the shading frame (z is the normal), pointing
``wox, woy, woz``      away from the surface; length 1 within 1e-3 (renormalized on reading).
``r, g, b``            the BRDF f_r in 1/sr, **without** the cosine factor (what MERL stores); ≥ 0.
*or* ``value``         one monochrome f_r per row (a single-channel gonioreflectometer): the
                       :class:`~data_formats.samples.SampleSet` holds it in all three channels
                       and says ``channels == 1``; a fit then fits a grey model.
=====================  ===========================================================================

* **CSV**: comma-separated, a header row naming the columns is required (any order, names
  case-insensitive, surrounding spaces ignored); lines starting with ``#`` before the header are
  comments. Numbers in any form Python's ``float`` reads.
* **NPZ**: one 1-D array per column, stored under the column's name (``np.savez(path, theta_i=...,
  ...)``), all of the same length.

Optional measurement uncertainty (a gonioreflectometer's error bars): either one column
``sigma`` (the standard deviation of all three channels of the row) or three columns
``sigma_r, sigma_g, sigma_b``, in the units of ``r, g, b``, every value finite and > 0. The
:class:`~data_formats.samples.SampleSet` then carries ``sigma`` ``(N, 3)``, and a fit weights
each residual by it.

Limits: at most :data:`MAX_SAMPLES` (2^24) rows; lines of at most :data:`MAX_LINE` bytes (a
longer one is refused as it is read); only regular files are read (a FIFO or a device such as
``/dev/zero`` is refused before it is opened); an NPZ member's declared shape, dtype and size
are checked against the archive and the limit before anything is decompressed. The values are
checked, and can be read (:func:`iter_samples`), in pieces of :data:`PIECE_ROWS` rows, so
memory holds the result (or one piece) and, for a CSV, its parsed columns.

No other columns are accepted (a misspelt column must not be ignored silently). Every row must be
usable: a NaN/inf, a negative colour value, a direction below the horizon (θ > 90°, ``z < 0``) or
a direction vector that is not unit length is an error (:class:`SampleListFormatError`, naming
the path, the line or row, and the column), never a silently dropped sample.

Convention: a direction exactly on the horizon (θ = 90°, ``z = 0``) is accepted but marked
``valid = False`` in the :class:`~data_formats.samples.SampleSet`, as MERL cells are (its cosine
weight is zero and f_r there is not measurable).

Writing (:func:`write_samples`) stores only the valid rows of a sample set (invalid rows carry no
measurement), in the angle layout by default, with 17 significant digits, atomically. Reading
what was written gives back the same directions (to ~1e-15 through the angles; bit for bit for
the colours and, with ``angles=False``, to within renormalization for the vectors).
"""

from __future__ import annotations

import os
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ._atomic import atomic_write
from ._files import NotRegularFileError, open_regular
from .samples import SampleSet

ANGLE_COLUMNS = ("theta_i", "phi_i", "theta_o", "phi_o")
VECTOR_COLUMNS = ("wix", "wiy", "wiz", "wox", "woy", "woz")
RGB_COLUMNS = ("r", "g", "b")
MONO_COLUMNS = ("value",)
LAYOUTS = {
    "angles": ANGLE_COLUMNS + RGB_COLUMNS, "vectors": VECTOR_COLUMNS + RGB_COLUMNS,
    "angles, monochrome": ANGLE_COLUMNS + MONO_COLUMNS,
    "vectors, monochrome": VECTOR_COLUMNS + MONO_COLUMNS,
}
SIGMA_COLUMNS = (("sigma",), ("sigma_r", "sigma_g", "sigma_b"))
SUFFIXES = (".csv", ".npz")
UNIT_TOLERANCE = 1e-3


class SampleListFormatError(ValueError):
    """A malformed sample list: the message names the path, the row or line, and the column."""


def _layout_text() -> str:
    return " or ".join(",".join(cols) for cols in LAYOUTS.values())


def _sigma_columns(path, names: set) -> tuple[str, ...]:
    """The uncertainty columns among ``names`` (one of :data:`SIGMA_COLUMNS`, or none)."""
    given = [c for group in SIGMA_COLUMNS for c in group if c in names]
    for group in SIGMA_COLUMNS:
        if set(given) == set(group):
            return group
    if given:
        raise SampleListFormatError(
            f"{path}: uncertainty columns {', '.join(given)}; give either sigma (all channels) "
            f"or all three of sigma_r, sigma_g, sigma_b"
        )
    return ()


def _pick_layout(path, columns) -> str:
    """The layout whose column set equals ``columns`` (less any uncertainty columns);
    otherwise a precise error."""
    names = set(columns)
    if len(names) != len(columns):
        dup = sorted({c for c in columns if columns.count(c) > 1})
        raise SampleListFormatError(f"{path}: duplicate column(s) {', '.join(dup)} in the header")
    names -= set(_sigma_columns(path, names))
    for layout, cols in LAYOUTS.items():
        if names == set(cols):
            return layout
    unknown = sorted(names - set(ANGLE_COLUMNS + VECTOR_COLUMNS + RGB_COLUMNS + MONO_COLUMNS))
    best = min(LAYOUTS.values(), key=lambda cols: len(set(cols) ^ names))
    missing = [c for c in best if c not in names]
    detail = []
    if unknown:
        detail.append(f"unknown column(s) {', '.join(unknown)}")
    if missing:
        detail.append(f"missing column(s) {', '.join(missing)}")
    if not unknown and not missing:
        detail.append("angle and vector columns mixed")
    raise SampleListFormatError(
        f"{path}: wrong columns ({'; '.join(detail)}); got {','.join(columns)}; "
        f"expected exactly {_layout_text()} (see data_formats.samplelist)"
    )


#: Most samples (rows) a sample list may hold: 2^24, the same bound as MERL cells
#: (``data_formats.merl.MAX_CELLS``); its data then takes 1.2 GiB (9 float64 columns).
MAX_SAMPLES = 2**24
#: Longest line accepted anywhere in a CSV (a comment, the header, a data row: a row of 12
#: numbers is well under 1 KiB). Longer lines are refused as they are read, so a file whose
#: body is one huge line costs no more memory than this.
MAX_LINE = 1 << 20
#: Bytes per block of the streaming CSV parser (and per chunk of the fallback parser).
_BLOCK = 1 << 22


def _too_many(path, n) -> SampleListFormatError:
    return SampleListFormatError(
        f"{path}: more than {MAX_SAMPLES:,} samples ({n:,} so far); the reader refuses larger "
        f"sample lists: split the file or subsample it"
    )


def _lines(path, fh, lineno: int = 0, where: str = ""):
    """``(1-based line number, raw bytes)`` of the lines of ``fh`` from its position (the
    first one numbered ``lineno + 1``), each read with at most :data:`MAX_LINE` bytes: a longer
    line is a :class:`SampleListFormatError` before it is held in memory."""
    while raw := fh.readline(MAX_LINE):
        lineno += 1
        if len(raw) >= MAX_LINE and not raw.endswith(b"\n"):
            raise SampleListFormatError(
                f"{path}: line {lineno} is longer than {MAX_LINE:,} bytes{where}; a sample list "
                f"has one short row of numbers per line"
            )
        yield lineno, raw


def _read_preamble(path, fh) -> tuple[list[str], int]:
    """Skip comment and blank lines, read the header; returns its names and 1-based line."""
    for lineno, raw in _lines(path, fh, where=" before any header"):
        line = raw.decode("utf-8")
        if line.strip() and not line.lstrip().startswith("#"):
            break
    else:
        raise SampleListFormatError(
            f"{path}: no header row; a CSV sample list needs a header naming {_layout_text()}"
        )
    header = [c.strip().lower() for c in line.rstrip("\r\n").split(",")]
    if any(_is_number(c) for c in header):
        raise SampleListFormatError(
            f"{path}: line {lineno} looks like data, not a header; the first row must name "
            f"the columns: {_layout_text()}"
        )
    _pick_layout(path, header)
    return header, lineno


class _LineNumbers:
    """``rows[i]``: the 1-based line of data row ``i``, found by scanning the file on demand.

    Data rows are the non-blank lines after the header that do not start with ``#``; the
    numbers are needed only for an error message, so nothing is kept while reading.
    """

    def __init__(self, path, header_line: int):
        self.path, self.header_line = path, header_line

    def __getitem__(self, i) -> int:
        with open_regular(self.path, "rb") as fh:
            for lineno, raw in _lines(self.path, fh):
                if lineno > self.header_line and _is_data(raw):
                    if i == 0:
                        return lineno
                    i -= 1
        raise IndexError(i)


def _is_data(raw: bytes) -> bool:
    text = raw.strip()
    return bool(text) and not text.startswith(b"#")


def _read_csv(path: Path) -> tuple[list[str], np.ndarray, _LineNumbers]:
    """Header names, the data as an ``(N, C)`` float array, and where each row is in the file.

    The body is parsed by pyarrow's streaming CSV reader, typed float64 and block by block, so
    memory stays near the size of the result: the ``(N, C)`` array is sized from the first
    block's bytes per row and filled in place (``benchmarks/bench_csv.py`` measures the time and
    peak memory of ``read_samples`` on a large file). Anything it does not take (a
    malformed row, a number written as Python's ``float`` reads it but pyarrow does not, such
    as ``1_000``, a comment or blank-but-spaced line between rows) is re-read line by line by
    :func:`_parse_slowly`, which gives the same values or names the bad line and column.
    pyarrow allocates from its system pool (``malloc``), not its default mimalloc pool, which
    reserves 1 GiB of address space at first use: a reader under ``ulimit -v`` ran out of
    address space before it could name a bad line (``benchmarks/bench_csv.py``: the same
    speed, 10 % less peak memory). (No
    pyarrow ``invalid_row_handler``: it decodes the row as UTF-8 before calling back and
    prints an "Exception ignored" traceback for any other byte.)
    """
    with open_regular(path, "rb") as fh:
        header, header_line = _read_preamble(path, fh)
        rows = _LineNumbers(path, header_line)
        start = fh.tell()
        try:
            data = _parse_fast(path, fh, header)
        except (SampleListFormatError, UnicodeDecodeError):
            raise
        except Exception:  # pyarrow.ArrowInvalid and friends: find and name the bad field
            fh.seek(start)
            data = _parse_slowly(path, fh, header, header_line)
    return header, data, rows


def _parse_fast(path, fh, header) -> np.ndarray:
    try:
        import pyarrow as pa
        import pyarrow.csv as pacsv
    except ImportError:  # pragma: no cover - pyarrow is a dependency; the slow path is complete
        raise RuntimeError("pyarrow is not installed") from None

    names = [f"c{k}" for k in range(len(header))]
    reader = pacsv.open_csv(
        fh,
        read_options=pacsv.ReadOptions(column_names=names, block_size=_BLOCK, use_threads=False),
        parse_options=pacsv.ParseOptions(delimiter=",", quote_char=False, escape_char=False,
                                         newlines_in_values=False, ignore_empty_lines=True),
        convert_options=pacsv.ConvertOptions(column_types={n: pa.float64() for n in names},
                                             null_values=[], strings_can_be_null=False),
        memory_pool=pa.system_memory_pool(),
    )
    remaining = max(os.fstat(fh.fileno()).st_size - fh.tell(), 1)
    data, n = np.empty((0, len(header))), 0
    for batch in reader:
        k = batch.num_rows
        if n + k > MAX_SAMPLES:
            raise _too_many(path, n + k)
        if n + k > len(data):  # sized from the first block's bytes per row, grown if short
            guess = int(remaining * k / min(_BLOCK, remaining) * 1.1) + k if n == 0 else 0
            data = _grown(data, n, max(n + k, guess, int(1.25 * len(data))))
        for c in range(len(header)):
            data[n:n + k, c] = batch.column(c).to_numpy(zero_copy_only=False)
        n += k
        del batch
    return data[:n]


def _grown(data: np.ndarray, n: int, rows: int) -> np.ndarray:
    """An uninitialized ``(rows, C)`` array holding ``data[:n]`` (untouched pages cost nothing)."""
    out = np.empty((min(rows, MAX_SAMPLES), data.shape[1]))
    out[:n] = data[:n]
    return out


def _concatenate(chunks, width) -> np.ndarray:
    if not chunks:
        return np.empty((0, width))
    return chunks[0] if len(chunks) == 1 else np.concatenate(chunks)


def _parse_slowly(path, fh, header, header_line) -> np.ndarray:
    """Line by line with Python's ``float``, in bounded chunks; names the first bad field."""
    chunks, block, n = [], [], 0
    for lineno, raw in _lines(path, fh, header_line):
        if not _is_data(raw):
            continue
        fields = raw.decode("utf-8").rstrip("\r\n").split(",")
        if len(fields) != len(header):
            raise SampleListFormatError(
                f"{path}: line {lineno} has {len(fields)} fields, expected {len(header)} "
                f"({','.join(header)})"
            )
        row = []
        for c, text in enumerate(fields):
            try:
                row.append(float(text))
            except ValueError:
                raise SampleListFormatError(
                    f"{path}: line {lineno}, column {header[c]!r}: {text.strip()!r} is not a number"
                ) from None
        block.append(row)
        n += 1
        if n > MAX_SAMPLES:
            raise _too_many(path, n)
        if len(block) == 65536:
            chunks.append(np.array(block, dtype=float))
            block = []
    if block:
        chunks.append(np.array(block, dtype=float))
    return _concatenate(chunks, len(header))


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


#: Errors that a damaged or hostile NPZ archive raises from :mod:`zipfile` and ``numpy.lib.format``.
_NPZ_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, RuntimeError,
               NotImplementedError, KeyError)
#: The largest ``.npy`` header accepted (NumPy's own reading limit).
_MAX_NPY_HEADER = 10_000
#: Rows per piece: the checks run, and :func:`iter_samples` yields, this many rows at a time
#: (56 MiB of float64 columns at most), so no check allocates more than a piece's worth.
PIECE_ROWS = 1 << 20


def _npz_error(path, exc) -> SampleListFormatError:
    return SampleListFormatError(
        f"{path}: not a readable NPZ archive ({type(exc).__name__}: {exc}); write it with "
        f"numpy.savez(path, theta_i=..., ...)"
    )


def _npz_pieces(path: Path, rows: int):
    """The NPZ archive at ``path`` as ``(names, n, start, piece)``: first ``(names, n, None,
    None)``, then the ``(k, C)`` float64 rows ``start … start + k`` (``k ≤ rows``).

    Nothing is decompressed before the member names form a layout and each member's declared
    size (the zip directory's and the ``.npy`` header's shape and dtype) is within
    :data:`MAX_SAMPLES` and equal to the others': a zip bomb or a header declaring
    ``shape=(10**15,)`` is refused before any allocation. Then every member is decompressed
    side by side, ``rows`` values at a time, so memory holds one piece, never a whole column.
    Object, complex, datetime, timedelta, bool, string and structured dtypes are refused (only
    real integers and floats are numbers here). Pickles are never loaded.
    """
    with open_regular(path, "rb") as fh:
        try:
            with zipfile.ZipFile(fh) as archive:
                members = archive.infolist()
                names = [_column_name(path, info) for info in members]
                _pick_layout(path, names)
                heads = [_member_header(path, archive, info, name)
                         for info, name in zip(members, names)]
                lengths = {n for n, _, _ in heads}
                if len(lengths) > 1:
                    detail = ", ".join(f"{name}: {n}" for name, (n, _, _) in zip(names, heads))
                    raise SampleListFormatError(f"{path}: arrays differ in length ({detail})")
                n = lengths.pop() if lengths else 0
                yield names, n, None, None
                streams = [archive.open(info) for info in members]
                for stream, (_, _, skip) in zip(streams, heads):
                    stream.read(skip)
                for start in range(0, n, rows):
                    k = min(rows, n - start)
                    piece = np.empty((k, len(names)))
                    for c, (stream, (_, dtype, _)) in enumerate(zip(streams, heads)):
                        raw = stream.read(k * dtype.itemsize)
                        if len(raw) != k * dtype.itemsize:
                            raise SampleListFormatError(f"{path}: array {names[c]!r} is truncated")
                        piece[:, c] = np.frombuffer(raw, dtype=dtype)
                    yield names, n, start, piece
                for stream in streams:
                    stream.read()  # to the end: zipfile checks the CRC there
                    stream.close()
        except SampleListFormatError:
            raise
        except _NPZ_ERRORS as exc:
            raise _npz_error(path, exc) from None


def _column_name(path, info) -> str:
    if not info.filename.endswith(".npy"):
        raise SampleListFormatError(
            f"{path}: archive member {info.filename!r} is not a .npy array; an NPZ sample list "
            f"holds one array per column (numpy.savez)"
        )
    return info.filename[:-4].strip().lower()


def _member_header(path, archive, info, name) -> tuple[int, np.dtype, int]:
    """``(length, dtype, header bytes)`` of one member, its ``.npy`` header checked against
    the limits and the zip directory (only the header is decompressed)."""
    limit = MAX_SAMPLES * 8 + _MAX_NPY_HEADER
    if info.file_size > limit:
        raise SampleListFormatError(
            f"{path}: array {name!r} expands to {info.file_size:,} bytes; the reader accepts at "
            f"most {MAX_SAMPLES:,} samples ({limit:,} bytes per array)"
        )
    with archive.open(info) as member:
        version = np.lib.format.read_magic(member)
        read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                       else np.lib.format.read_array_header_2_0)
        shape, _fortran, dtype = read_header(member, max_header_size=_MAX_NPY_HEADER)
        _check_member(path, name, shape, dtype)
        nbytes = int(shape[0]) * dtype.itemsize
        header_bytes = member.tell()
    if header_bytes + nbytes != info.file_size:
        raise SampleListFormatError(
            f"{path}: array {name!r} declares {shape[0]:,} values of {dtype} ({nbytes:,} "
            f"bytes) but the archive holds {info.file_size - header_bytes:,} bytes for it"
        )
    return int(shape[0]), dtype, header_bytes


def _check_member(path, name, shape, dtype) -> None:
    if len(shape) != 1 or dtype.hasobject or dtype.kind not in "iuf" or dtype.fields:
        what = {"c": "complex", "m": "timedelta", "M": "datetime", "b": "bool", "O": "object"}
        kind = what.get(dtype.kind, str(dtype))
        raise SampleListFormatError(
            f"{path}: array {name!r} must be a 1-D array of real numbers (integer or float), "
            f"got shape {tuple(shape)} dtype {dtype} ({kind})"
        )
    if shape[0] > MAX_SAMPLES:
        raise SampleListFormatError(
            f"{path}: array {name!r} declares {shape[0]:,} samples; the reader accepts at most "
            f"{MAX_SAMPLES:,}"
        )


def _csv_pieces(path: Path, rows: int):
    """The CSV at ``path`` as :func:`_npz_pieces` gives an archive: ``(names, n, None,
    None)``, then views of ``rows`` rows of the parsed ``(N, C)`` data at a time."""
    columns, data, _lines_of = _read_csv(path)
    yield columns, len(data), None, None
    for start in range(0, len(data), rows):
        yield columns, len(data), start, data[start:start + rows]


def _where(path, rows, i) -> str:
    """``path: line L`` (CSV) or ``path: row R`` (NPZ, 0-based array index) for sample ``i``."""
    return f"{path}: line {rows[i]}" if rows is not None else f"{path}: row {i}"


def _first_bad(mask) -> int:
    return int(np.flatnonzero(mask)[0])


def _check_finite(path, columns, data, rows, start=0) -> None:
    bad = ~np.isfinite(data)
    if bad.any():
        i, c = np.argwhere(bad)[0]
        raise SampleListFormatError(
            f"{_where(path, rows, start + i)}, column {columns[c]!r}: value "
            f"{float(data[i, c])} is not finite; every sample needs finite numbers (remove or "
            f"repair the row)"
        )


def _directions(path, cols: dict, rows, side: str, start=0) -> np.ndarray:
    """Unit directions for ``side`` ('i' or 'o') from angle or vector columns, checked."""
    if f"theta_{side}" in cols:
        theta, phi = cols[f"theta_{side}"], cols[f"phi_{side}"]
        for bad, what in ((theta < 0, "negative"), (theta > 90, "below the horizon (> 90°)")):
            if bad.any():
                i = _first_bad(bad)
                raise SampleListFormatError(
                    f"{_where(path, rows, start + i)}, column 'theta_{side}': {theta[i]:g}° is "
                    f"{what}; θ is measured from the normal in degrees, 0 ≤ θ ≤ 90"
                )
        t, p = np.radians(theta), np.radians(phi)
        cos_t = np.where(theta == 90, 0.0, np.cos(t))  # cos(π/2) is 6e-17 in floating point
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), cos_t], axis=-1)
    names = [f"w{side}x", f"w{side}y", f"w{side}z"]
    w = np.stack([cols[n] for n in names], axis=-1)
    if (w[:, 2] < 0).any():
        i = _first_bad(w[:, 2] < 0)
        raise SampleListFormatError(
            f"{_where(path, rows, start + i)}, column 'w{side}z': {w[i, 2]:g} < 0, the direction "
            f"is below the horizon; directions point away from the surface with z along the normal"
        )
    norm = np.linalg.norm(w, axis=-1)
    bad = np.abs(norm - 1.0) > UNIT_TOLERANCE
    if bad.any():
        i = _first_bad(bad)
        raise SampleListFormatError(
            f"{_where(path, rows, start + i)}, columns {','.join(names)}: length {norm[i]:.6g} is "
            f"not 1 (tolerance {UNIT_TOLERANCE:g}); give unit vectors"
        )
    return w / norm[:, None]


def _checked_piece(path: Path, columns, data, rows, start: int) -> SampleSet:
    """Rows ``start …`` of a sample list (``data``, ``(k, C)``), every value checked, as a
    :class:`SampleSet` (errors name the row or line in the whole file)."""
    _check_finite(path, columns, data, rows, start)
    cols = {name: data[:, c] for c, name in enumerate(columns)}
    mono = "value" in cols
    colour = MONO_COLUMNS * 3 if mono else RGB_COLUMNS
    rgb = np.stack([cols[c] for c in colour], axis=-1)
    if (rgb < 0).any():
        i, c = np.argwhere(rgb < 0)[0]
        raise SampleListFormatError(
            f"{_where(path, rows, start + i)}, column {colour[c]!r}: {rgb[i, c]:g} is negative; "
            f"a BRDF is ≥ 0 (clip noise to 0 or drop the row)"
        )
    wi = _directions(path, cols, rows, "i", start)
    wo = _directions(path, cols, rows, "o", start)
    valid = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    sigma = _sigma(path, cols, rows, start)
    return SampleSet(wi=wi, wo=wo, rgb=rgb, valid=valid, name=path.stem, path=str(path),
                     sigma=sigma, channels=1 if mono else 3)


def _sigma(path, cols: dict, rows, start=0) -> np.ndarray | None:
    """``(N, 3)`` standard deviations from the ``sigma`` or ``sigma_r/g/b`` columns, checked
    positive; ``None`` without them."""
    group = _sigma_columns(path, set(cols))
    if not group:
        return None
    sigma = np.stack([cols[c] for c in (group * 3 if len(group) == 1 else group)], axis=-1)
    bad = ~(sigma > 0)
    if bad.any():
        i, c = np.argwhere(bad)[0]
        raise SampleListFormatError(
            f"{_where(path, rows, start + i)}, column {group[min(c, len(group) - 1)]!r}: "
            f"{sigma[i, c]:g} is not a positive standard deviation; give sigma > 0"
        )
    return sigma


def _check_path(path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise SampleListFormatError(
            f"{path}: unknown sample-list suffix {path.suffix!r}; expected one of "
            f"{', '.join(SUFFIXES)}"
        )
    return path


def _pieces(path, rows: int):
    """``(n, pieces)`` of the sample list at ``path``: its number of samples (its layout
    checked, at least one sample), and a generator of its checked :class:`SampleSet` pieces of
    at most ``rows`` samples with the row each starts at, ``(start, piece)``."""
    path = _check_path(path)
    if path.is_dir():
        raise SampleListFormatError(f"{path}: is a directory, expected a sample-list file")
    if not path.exists():
        raise SampleListFormatError(f"{path}: no such file")
    csv = path.suffix.lower() == ".csv"
    rows = max(1, int(rows))
    source = _csv_pieces(path, rows) if csv else _npz_pieces(path, rows)
    with _format_errors(path):
        columns, n, _, _ = next(source)
        _pick_layout(path, columns)
    if n == 0:
        source.close()
        raise SampleListFormatError(f"{path}: no samples (the file has a header but no rows)")
    lines = _LineNumbers(path, _header_line(path)) if csv else None

    def pieces():
        with _format_errors(path), np.errstate(all="ignore"):
            # e.g. a 1e308 vector: its length overflows to inf and is refused by name, without
            # a warning
            for _, _, start, data in source:
                yield start, _checked_piece(path, columns, data, lines, start)

    return n, pieces()


def _header_line(path) -> int:
    with open_regular(path, "rb") as fh:
        return _read_preamble(path, fh)[1]


class _format_errors:
    """Turn a reader's non-format failures into :class:`SampleListFormatError`."""

    def __init__(self, path):
        self.path = path

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if isinstance(exc, UnicodeDecodeError):
            raise SampleListFormatError(f"{self.path}: not a text CSV file ({exc.reason})") from None
        if isinstance(exc, NotRegularFileError):
            raise SampleListFormatError(str(exc)) from None
        return False


def sample_count_and_pieces(path, rows: int = PIECE_ROWS):
    """``(n, pieces)``: the number of samples of the sample list at ``path`` (its layout
    checked) and :func:`iter_samples` of it."""
    n, pieces = _pieces(path, rows)
    return n, (piece for _start, piece in pieces)


def iter_samples(path, rows: int = PIECE_ROWS):
    """The sample list at ``path`` as :class:`SampleSet` pieces of at most ``rows`` samples, in
    file order, each checked as :func:`read_samples` checks the whole (the same errors, naming
    the row or line in the file). Memory: one piece for an NPZ archive (its members are
    decompressed side by side); for a CSV, the parsed columns (about the file's size) and one
    piece. A consumer that needs only figures (``brdffit info``) never holds the whole list."""
    _n, pieces = _pieces(path, rows)
    for _start, piece in pieces:
        yield piece


def read_samples(path) -> SampleSet:
    """Read a CSV or NPZ sample list (layout in the module docstring) into a :class:`SampleSet`.

    Raises :class:`SampleListFormatError` for a missing file, a wrong suffix, wrong columns, and
    any bad value, naming the path, line (CSV, 1-based as an editor shows it) or row (NPZ, 0-based
    array index), and the column. The values are checked piece by piece
    (:data:`PIECE_ROWS`) into the arrays of the result, so reading holds the result, one piece
    and (for a CSV) the parsed columns.
    """
    path = Path(path)
    n, pieces = _pieces(path, PIECE_ROWS)
    out = None
    for start, piece in pieces:
        if out is None:
            out = _empty_like(piece, n)
        stop = start + len(piece)
        for name in ("wi", "wo", "rgb", "valid", "sigma"):
            part = getattr(piece, name)
            if part is not None:
                getattr(out, name)[start:stop] = part
    return out


def _empty_like(piece: SampleSet, n: int) -> SampleSet:
    """An uninitialized :class:`SampleSet` of ``n`` samples shaped as ``piece``."""
    sigma = None if piece.sigma is None else np.empty((n, 3))
    return SampleSet(wi=np.empty((n, 3)), wo=np.empty((n, 3)), rgb=np.empty((n, 3)),
                     valid=np.empty(n, bool), name=piece.name, path=piece.path, sigma=sigma,
                     channels=piece.channels)


def _columns_of(samples: SampleSet, angles: bool) -> tuple[tuple[str, ...], np.ndarray]:
    keep = np.asarray(samples.valid, bool)
    wi, wo, rgb = (np.asarray(a, float)[keep] for a in (samples.wi, samples.wo, samples.rgb))
    extra_names, extra = (), np.empty((len(rgb), 0))
    mono = getattr(samples, "channels", 3) == 1
    if samples.sigma is not None:
        extra_names, extra = SIGMA_COLUMNS[1], np.asarray(samples.sigma, float)[keep]
        if mono:
            extra_names, extra = SIGMA_COLUMNS[0], extra[:, :1]
    if mono:
        rgb = rgb[:, :1]
    layout = ", monochrome" if mono else ""
    if not angles:
        return LAYOUTS["vectors" + layout] + extra_names, np.concatenate([wi, wo, rgb, extra], 1)

    def theta_phi(w):
        theta = np.degrees(np.arctan2(np.hypot(w[:, 0], w[:, 1]), w[:, 2]))
        return theta, np.degrees(np.arctan2(w[:, 1], w[:, 0])) % 360.0

    (ti, pi), (to, po) = theta_phi(wi), theta_phi(wo)
    return LAYOUTS["angles" + layout] + extra_names, np.column_stack([ti, pi, to, po, rgb, extra])


def write_samples(path, samples: SampleSet, *, angles: bool = True) -> Path:
    """Write the valid rows of ``samples`` as a CSV or NPZ sample list (by suffix), atomically.

    ``angles=True`` writes ``theta_i, phi_i, theta_o, phi_o`` in degrees (φ in [0, 360)),
    ``angles=False`` the direction vectors. The file appears complete or not at all: it is
    written to a temporary file in the same folder, then renamed over ``path``.
    """
    path = _check_path(path)
    columns, data = _columns_of(samples.to_samples(), angles)

    def write(fh):
        if path.suffix.lower() == ".csv":
            fh.write((",".join(columns) + "\n").encode())
            np.savetxt(fh, data, delimiter=",", fmt="%.17g")
        else:
            np.savez(fh, **{c: data[:, k] for k, c in enumerate(columns)})

    atomic_write(path, write)
    return path
