"""The MERL binary BRDF format (Matusik et al. 2003): read, write, index, look up, synthesize.

NumPy only. Facts implemented here (``../shared/reference/merl-format.md``, Burley 2012 §3.1):

* Header: three little-endian ``int32`` ``n_th, n_td, n_pd`` (90, 90, 180 in the database).
  Body: ``3 * n_th * n_td * n_pd`` little-endian ``float64``, the red block, then green, then
  blue; within a block the flat index is ``(i_th * n_td + i_td) * n_pd + i_pd``. The file size is
  exactly ``12 + 8 * 3 * n_th * n_td * n_pd`` (34,992,012 bytes for the database).
* ``BRDF = stored * SCALE[channel]``; a negative stored value marks a cell without measurement.
  In memory a :class:`MERLTable` keeps the BRDF (scales applied) channel-last, a per-cell
  ``valid`` mask (a cell is valid when all three stored values are ``>= 0``), and ``0.0`` in the
  rgb of missing cells (never data; writers store ``-1`` there).
* Cell ``(i, j, k)`` covers ``theta_h`` in ``[(i/n)^2, ((i+1)/n)^2) * 90 deg`` (warped to put
  samples near the specular peak), ``theta_d`` in ``[j, j+1) * 90/n_td deg`` and the folded
  ``phi_d`` in ``[k, k+1) * 180/n_pd deg``; the value stands for the cell's *lower corner*.

Angles and directions follow :mod:`data_formats.rusinkiewicz` (``z`` is the normal, ``phi_h = 0``).
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import functools
import os

import numpy as np

from ._atomic import atomic_write
from ._files import NotRegularFileError, open_regular
from .rusinkiewicz import dirs_from_half_diff, fold_phi_d, half_diff_from_dirs
from .samples import SampleSet

__all__ = [
    "N_TH", "N_TD", "N_PD", "MERL_SHAPE", "SCALE", "MAX_DIM", "MAX_CELLS", "HORIZON_EPS",
    "MERLFormatError", "MERLTable", "read_merl", "write_merl", "expected_file_size", "snap_to_file",
    "merl_index", "cell_angles", "cell_directions", "above_horizon",
    "lookup_nearest", "lookup_linear", "lookup_nearest_angles", "lookup_linear_angles",
    "synthesize",
]

N_TH, N_TD, N_PD = 90, 90, 180
MERL_SHAPE = (N_TH, N_TD, N_PD)
#: Per-channel factors from stored values to BRDF units (``BRDFRead.cpp``: RED/GREEN/BLUE_SCALE).
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
#: Largest header dimension the reader accepts (the database uses at most 180).
MAX_DIM = 10_000
#: Most cells (``n_th * n_td * n_pd``) the reader accepts: 2^23, 5.75x the database grid. The
#: body is then 192 MiB; reading it peaks near 2.1x that (body plus channel-last rgb) and
#: ``brdffit info`` near 3x (its statistics copy the valid cells). A header asking for more is
#: refused before anything is allocated. (At 2^24 the fuzz run saw ``info`` peak at 1.1 GB.)
MAX_CELLS = 2**23
#: A direction is above the horizon when ``cos(theta) > HORIZON_EPS`` (see ``above_horizon``).
HORIZON_EPS = 1e-9
_HEADER_BYTES = 12
_CHANNELS = "RGB"


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


# --------------------------------------------------------------------------------------------
# Indices and angles
# --------------------------------------------------------------------------------------------

def _u_theta_h(theta_h, n_th: int):
    """Warped ``theta_h`` coordinate, ``BRDFRead.cpp``'s ``sqrt(theta_h/(pi/2)*90*90)``."""
    th = np.maximum(np.asarray(theta_h, dtype=np.float64), 0.0)  # theta_h <= 0 -> cell 0
    return np.sqrt(th / (np.pi / 2) * n_th * n_th)


def _v_theta_d(theta_d, n_td: int):
    """Linear ``theta_d`` coordinate, ``BRDFRead.cpp``'s ``theta_diff / (M_PI * 0.5) * 90``."""
    return np.asarray(theta_d, dtype=np.float64) / (np.pi / 2) * n_td


def _w_phi_d(phi_d_folded, n_pd: int):
    """Linear coordinate of a folded ``phi_d``, ``BRDFRead.cpp``'s ``phi_diff / M_PI * 180``."""
    return phi_d_folded / np.pi * n_pd


def _grid_coords(theta_h, theta_d, phi_d, shape):
    """Continuous cell coordinates ``(u, v, w)``; ``floor`` of each is the MERL cell index.

    The same floating-point operations, in the same order, as ``BRDFRead.cpp``, so that the
    nearest cell agrees with the database reader to the last bit.
    """
    n_th, n_td, n_pd = shape
    return _u_theta_h(theta_h, n_th), _v_theta_d(theta_d, n_td), _w_phi_d(fold_phi_d(phi_d), n_pd)


def _clamped_floor(x, n: int):
    """``floor(x)`` clamped to ``[0, n-1]``; NaN maps to 0 (callers mask it)."""
    return np.fmin(np.fmax(x, 0.0), n - 1).astype(np.intp)


def merl_index(theta_h, theta_d, phi_d, shape=MERL_SHAPE):
    """Cell ``(i, j, k)`` holding ``(theta_h, theta_d, phi_d)``, exactly as the database reader.

    ``i = floor(sqrt(theta_h / (pi/2)) * n_th)`` computed as ``BRDFRead.cpp`` does
    (``sqrt(theta_h/(pi/2)*90*90)``), ``j = floor(theta_d / (pi/2) * n_td)``,
    ``k = floor(phi_d / pi * n_pd)`` after folding ``phi_d`` into ``[0, pi)``; each clamped to
    its range. So ``theta_h`` = 0, 1, 45, 90 deg fall in cells 0, 9, 63, 89. The one departure:
    ``phi_d = pi`` folds to cell 0 (its reciprocal twin), where the database clamps it to 179
    (see :func:`~data_formats.rusinkiewicz.fold_phi_d`). Arrays broadcast; returns ``intp``.
    """
    theta_h, theta_d, phi_d = np.broadcast_arrays(theta_h, theta_d, phi_d)
    u, v, w = _grid_coords(theta_h, theta_d, phi_d, shape)
    return _clamped_floor(u, shape[0]), _clamped_floor(v, shape[1]), _clamped_floor(w, shape[2])


def _smallest_in_cell(coord, naive):
    """Per cell ``c``, the smallest double ``x >= 0`` with ``floor(coord(x)) == c``.

    Starts at the closed-form corner ``naive[c]`` and steps by one ulp until the reader's own
    arithmetic agrees (a few steps at most): the closed form rounds to either side.
    """
    target = np.arange(len(naive))
    x = np.asarray(naive, dtype=np.float64).copy()
    for _ in range(1000):
        low = np.floor(coord(x)) < target
        if not low.any():
            break
        x = np.where(low, np.nextafter(x, np.inf), x)
    for _ in range(1000):
        prev = np.nextafter(x, -np.inf)
        down = (target > 0) & (np.floor(coord(prev)) == target)
        if not down.any():
            break
        x = np.where(down, prev, x)
    return x


@functools.lru_cache(maxsize=8)
def _corner_axes(shape):
    """Float lower corners along each axis: ``(theta_h[n_th], theta_d[n_td], phi_d[n_pd])``."""
    n_th, n_td, n_pd = shape
    th = _smallest_in_cell(lambda x: _u_theta_h(x, n_th),
                           (np.arange(n_th) / n_th) ** 2 * (np.pi / 2))
    td = _smallest_in_cell(lambda x: _v_theta_d(x, n_td), np.arange(n_td) / n_td * (np.pi / 2))
    pd = _smallest_in_cell(lambda x: _w_phi_d(x, n_pd), np.arange(n_pd) / n_pd * np.pi)
    for a in (th, td, pd):
        a.flags.writeable = False
    return th, td, pd


def cell_angles(i, j, k, shape=MERL_SHAPE):
    """Lower-corner angles ``(theta_h, theta_d, phi_d)`` of cells ``(i, j, k)`` (radians).

    The corner is ``((i/n_th)^2 * 90 deg, j * 90/n_td deg, k * 180/n_pd deg)``, taken as the
    smallest double that :func:`merl_index` puts in the cell (within a few ulps of the closed
    form, which itself can round into the cell below), so ``merl_index(*cell_angles(i, j, k))``
    is ``(i, j, k)`` for every cell. Indices broadcast.
    """
    th, td, pd = _corner_axes(_shape_key(shape))
    return th[np.asarray(i)], td[np.asarray(j)], pd[np.asarray(k)]


def _shape_key(shape) -> tuple[int, int, int]:
    """A grid shape as a hashable ``(n_th, n_td, n_pd)`` of ints (one cache entry per grid)."""
    n_th, n_td, n_pd = (int(n) for n in shape)
    return n_th, n_td, n_pd


def cell_directions(shape=MERL_SHAPE):
    """Direction pairs ``(wi, wo)`` of every cell's lower corner, each ``(n_th, n_td, n_pd, 3)``.

    ``phi_h = 0`` (the half vector lies in the ``xz`` plane). Cached per shape (the two most
    recent) and returned read-only (2 x 35 MB for the database grid): copy before modifying.
    Cells with ``theta_d = 0`` have ``wi = wo`` for every ``k`` (``phi_d`` is undefined there).
    """
    return _cell_directions(_shape_key(shape))


@functools.lru_cache(maxsize=2)
def _cell_directions(shape):
    th, td, pd = _corner_axes(shape)
    wi, wo = dirs_from_half_diff(th[:, None, None], td[None, :, None], pd[None, None, :])
    wi.flags.writeable = False
    wo.flags.writeable = False
    return wi, wo


def above_horizon(shape=MERL_SHAPE):
    """``(n_th, n_td, n_pd)`` bool: both corner directions strictly above the horizon.

    "Strictly" means ``cos(theta) > HORIZON_EPS`` for ``wi`` and ``wo``: corners that lie on the
    horizon mathematically (e.g. ``theta_h + theta_d = 90 deg`` at ``phi_d = 0``) compute to
    ``cos ~ +-1e-17`` and are excluded rather than left to rounding. Read-only, cached.
    """
    return _above_horizon(_shape_key(shape))


@functools.lru_cache(maxsize=2)
def _above_horizon(shape):
    wi, wo = _cell_directions(shape)
    mask = (wi[..., 2] > HORIZON_EPS) & (wo[..., 2] > HORIZON_EPS)
    mask.flags.writeable = False
    return mask


# --------------------------------------------------------------------------------------------
# The table
# --------------------------------------------------------------------------------------------

@dataclasses.dataclass(eq=False, repr=False)
class MERLTable:
    """A MERL-layout BRDF table in memory.

    Attributes:
        rgb: ``(n_th, n_td, n_pd, 3)`` float64 BRDF values (scales applied, channel-last);
            ``0.0`` in missing cells by convention (:meth:`from_rgb` and :func:`read_merl` ensure
            it; the interpolating lookup relies on it being finite).
        valid: ``(n_th, n_td, n_pd)`` bool, ``False`` for cells without a measurement.
        path: the file the table came from, if any.
        name: a short label (the file stem for tables read from disk).

    A table is immutable. Build one with :meth:`from_rgb`, :func:`read_merl` or
    :func:`synthesize`: their arrays are read-only (copy to edit, then call ``from_rgb``), and
    every value is on the file's grid (:func:`snap_to_file`), so writing the table and reading
    it back returns it bit for bit.
    """

    rgb: np.ndarray
    valid: np.ndarray
    path: str | None = None
    name: str = ""

    def __post_init__(self):
        rgb, valid = self.rgb, self.valid
        if not (isinstance(rgb, np.ndarray) and rgb.ndim == 4 and rgb.shape[-1] == 3
                and rgb.dtype == np.float64):
            raise ValueError(
                "MERLTable.rgb must be a float64 array of shape (n_th, n_td, n_pd, 3), got "
                f"{getattr(rgb, 'dtype', type(rgb).__name__)} {getattr(rgb, 'shape', '')}; "
                "use MERLTable.from_rgb(...) to convert"
            )
        if not (isinstance(valid, np.ndarray) and valid.dtype == np.bool_
                and valid.shape == rgb.shape[:3]):
            raise ValueError(
                f"MERLTable.valid must be a bool array of shape {rgb.shape[:3]}, got "
                f"{getattr(valid, 'dtype', type(valid).__name__)} {getattr(valid, 'shape', '')}"
            )

    @classmethod
    def from_rgb(cls, rgb, valid=None, name: str = "") -> "MERLTable":
        """A table from BRDF values ``(n_th, n_td, n_pd, 3)`` and an optional ``valid`` mask.

        ``valid=None`` marks every cell valid. Valid cells must hold finite values ``>= 0``
        (a negative value cannot be stored: the file format reads it as missing); missing
        cells may hold anything and are set to 0. Values are copied and snapped to the file's
        grid (:func:`snap_to_file`, at most one ulp of change) so that a write/read round trip
        is exact.
        """
        rgb = np.array(rgb, dtype=np.float64)
        if rgb.ndim != 4 or rgb.shape[-1] != 3 or min(rgb.shape) < 1:
            raise ValueError(
                f"MERLTable.from_rgb: expected rgb of shape (n_th, n_td, n_pd, 3), got {rgb.shape}"
            )
        if valid is None:
            valid = np.ones(rgb.shape[:3], dtype=bool)
        else:
            valid = np.array(valid, dtype=bool)
            if valid.shape != rgb.shape[:3]:
                raise ValueError(
                    f"MERLTable.from_rgb: expected valid of shape {rgb.shape[:3]} (the rgb grid), "
                    f"got {valid.shape}"
                )
        rgb[~valid] = 0.0
        rgb = snap_to_file(rgb, valid)
        rgb.flags.writeable = False
        valid.flags.writeable = False
        return cls(rgb, valid, None, name)

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(n_th, n_td, n_pd)``."""
        return tuple(int(n) for n in self.valid.shape)

    def __repr__(self) -> str:
        frac = float(np.mean(self.valid)) if self.valid.size else 0.0
        return (f"MERLTable(name={self.name!r}, shape={self.shape}, valid={frac:.1%}, "
                f"path={self.path!r})")

    def __str__(self) -> str:
        return self.info_text()

    def info(self) -> dict:
        """Summary figures as plain Python values (JSON-serializable); see :func:`_table_info`."""
        return _table_info(self)

    def info_text(self) -> str:
        """:meth:`info` as a few aligned lines of text (what ``brdffit info`` prints)."""
        return _info_text(self.info())

    def to_samples(self) -> SampleSet:
        """The whole grid as a :class:`SampleSet`, flattened in file order (``(i*n_td+j)*n_pd+k``).

        Directions are each cell's lower corner (:func:`cell_directions`, ``phi_h = 0``);
        ``valid`` is the stored mask AND both directions strictly above the horizon
        (:func:`above_horizon`): a cell whose corner lies on or below the horizon cannot be
        compared with a model even when the file holds an (extrapolated) value for it.
        Nothing is dropped, so every table of the same shape yields arrays of the same shape.
        The arrays are views of the table and of cached read-only grids: copy to modify.
        """
        wi, wo = cell_directions(self.shape)
        n = int(np.prod(self.shape))
        valid = self.valid.reshape(n) & above_horizon(self.shape).reshape(n)
        return SampleSet(wi.reshape(n, 3), wo.reshape(n, 3), self.rgb.reshape(n, 3), valid,
                         name=self.name, path=self.path)

    def lookup(self, wi, wo, method: str = "nearest"):
        """BRDF at direction pairs ``(..., 3)``: ``method`` is ``"nearest"``
        (:func:`lookup_nearest`) or ``"linear"`` (:func:`lookup_linear`). NaN where missing."""
        fns = {"nearest": lookup_nearest, "linear": lookup_linear}
        if method not in fns:
            raise ValueError(
                f"MERLTable.lookup: unknown method {method!r}; expected one of {sorted(fns)}"
            )
        return fns[method](self, wi, wo)


def _table_info(table: MERLTable) -> dict:
    """Dims, valid fraction, per-channel min/median/max over valid cells, and the peak.

    The peak is the largest single channel value over valid cells; it is reported with its
    channel, cell index and lower-corner angles in degrees. Figures are ``None`` when no cell
    is valid.
    """
    n_cells = int(table.valid.size)
    flat_valid = np.flatnonzero(table.valid.reshape(-1))
    vals = table.rgb.reshape(-1, 3)[flat_valid]
    info = {
        "name": table.name, "path": table.path, "dims": list(table.shape), "n_cells": n_cells,
        "n_valid": int(flat_valid.size),
        "valid_fraction": float(flat_valid.size / n_cells) if n_cells else 0.0,
        "channels": {}, "peak": None,
    }
    for c, ch in enumerate(_CHANNELS):
        col = vals[:, c]
        stats = (col.min(), np.median(col), col.max()) if col.size else (None,) * 3
        info["channels"][ch] = {
            key: None if v is None else float(v) for key, v in zip(("min", "median", "max"), stats)
        }
    if vals.size:
        row, c = np.unravel_index(int(np.argmax(vals)), vals.shape)
        ijk = np.unravel_index(int(flat_valid[row]), table.shape)
        angles = cell_angles(*ijk, shape=table.shape)
        info["peak"] = {
            "value": float(vals[row, c]), "channel": _CHANNELS[c], "index": [int(x) for x in ijk],
            **{f"{a}_deg": float(np.degrees(v))
               for a, v in zip(("theta_h", "theta_d", "phi_d"), angles)},
        }
    return info


def _info_text(info: dict) -> str:
    """Render :func:`_table_info`'s dict as aligned text."""
    n_th, n_td, n_pd = info["dims"]
    lines = [
        f"MERL table {info['name']!r}" + (f" ({info['path']})" if info["path"] else ""),
        f"  dims         {n_th} x {n_td} x {n_pd} (theta_h x theta_d x phi_d), "
        f"{info['n_cells']:,} cells",
        f"  valid cells  {info['n_valid']:,} ({info['valid_fraction']:.1%})",
        "  channel      min          median       max",
    ]
    fmt = lambda v: "-" if v is None else f"{v:<12.5g}"  # noqa: E731
    for ch, st in info["channels"].items():
        lines.append(f"  {ch}            {fmt(st['min'])} {fmt(st['median'])} {fmt(st['max'])}")
    pk = info["peak"]
    if pk is None:
        lines.append("  peak         - (no valid cells)")
    else:
        lines.append(
            f"  peak         {pk['value']:.6g} ({pk['channel']}) at cell {tuple(pk['index'])}: "
            f"theta_h={pk['theta_h_deg']:.3f} deg, theta_d={pk['theta_d_deg']:.3f} deg, "
            f"phi_d={pk['phi_d_deg']:.3f} deg"
        )
    return "\n".join(line.rstrip() for line in lines)


# --------------------------------------------------------------------------------------------
# Scale: BRDF <-> stored values
# --------------------------------------------------------------------------------------------

def _stored_values(rgb, valid):
    """Stored (unscaled) values, channel-last, ``-1`` in missing cells: ``rgb / SCALE``.

    Raises ``ValueError`` when a valid cell holds a value the format cannot carry (negative,
    NaN, infinite, or so large that ``rgb / SCALE`` overflows).
    """
    stored = rgb / SCALE
    ok = np.all(np.isfinite(stored) & (stored >= 0.0), axis=-1) | ~valid
    if not ok.all():
        cell = tuple(int(x) for x in np.argwhere(~ok)[0])
        raise ValueError(
            f"{int(np.count_nonzero(~ok))} valid cells hold values a MERL file cannot store "
            f"(first: cell {cell} = {rgb[cell].tolist()}): expected finite BRDF values >= 0 "
            f"and below {np.finfo(np.float64).max * SCALE[0]:.3g}. Mark such cells missing "
            "(valid=False) or fix the values"
        )
    stored[~valid] = -1.0
    return stored


def snap_to_file(rgb, valid=None):
    """The BRDF values a MERL reader gets back after ``rgb`` is written: ``(rgb/SCALE)*SCALE``.

    The reader multiplies the stored double by ``SCALE`` (format fact), and multiplication by
    a scale that is not a power of two does not reach every double: about 10-16% of arbitrary
    doubles (depending on the channel) have no stored value that reads back as themselves.
    Snapping moves those by one ulp (a relative change below ``2.3e-16``) and leaves every other
    value alone: a value ``x`` is reachable exactly when ``(x/SCALE)*SCALE == x`` (checked in the
    tests from subnormals to 1e300), so snapping is idempotent and every snapped
    table round-trips bit for bit. Values in cells where ``valid`` is False are returned as 0.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    valid = np.ones(rgb.shape[:-1], dtype=bool) if valid is None else np.asarray(valid, bool)
    out = _stored_values(rgb, valid) * SCALE
    out[~valid] = 0.0
    return out


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------

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
        f"{_CHANNELS[c]} at cell {cell} (byte offset {12 + 8 * (c * blocks.shape[1] + flat):,})",
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


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

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
    body = np.ascontiguousarray(np.moveaxis(_stored_values(table.rgb, table.valid), -1, 0),
                                dtype="<f8")
    header = np.asarray(table.shape, dtype="<i4").tobytes()

    def write(f):
        f.write(header)
        body.tofile(f)

    atomic_write(p, write)


# --------------------------------------------------------------------------------------------
# Lookup
# --------------------------------------------------------------------------------------------

#: Lookups run in chunks of this many pairs so that every temporary stays in cache.
_CHUNK = 32768
#: Worker threads for lookups of more than one chunk (the cores this process may use, at most 8).
_THREADS = min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def _over_chunks(run, n: int) -> None:
    """Call ``run(slice)`` on consecutive chunks of ``range(n)``, on up to :data:`_THREADS` threads.

    The kernels are gathers and elementwise NumPy work, which release the GIL, and their
    random reads of the table are bound by memory latency: a second core nearly halves the time.
    Each chunk writes its own slice of the output, so the threads share nothing else.
    """
    slices = [slice(s, s + _CHUNK) for s in range(0, n, _CHUNK)]
    if len(slices) < 2 or _THREADS < 2:
        for sl in slices:
            run(sl)
        return
    with concurrent.futures.ThreadPoolExecutor(min(_THREADS, len(slices))) as pool:
        for future in [pool.submit(run, sl) for sl in slices]:
            future.result()


def _nan_angles(theta_h, theta_d, phi_d):
    """True where any angle is NaN (a NaN direction); such lookups return NaN."""
    return np.isnan(theta_h) | np.isnan(theta_d) | np.isnan(phi_d)


def _by_angles(kernel, prepared, shape, theta_h, theta_d, phi_d):
    """Run ``kernel(prepared, shape, th, td, pd) -> (n, 3)`` over broadcast angles, in chunks."""
    angles = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                   for a in (theta_h, theta_d, phi_d)))
    batch = angles[0].shape
    th, td, pd = (a.reshape(-1) for a in angles)
    out = np.empty((th.size, 3))

    def run(sl):
        out[sl] = kernel(prepared, shape, th[sl], td[sl], pd[sl])

    _over_chunks(run, th.size)
    return out.reshape(batch + (3,))


def _by_dirs(kernel, prepared, shape, wi, wo):
    """Run ``kernel`` over direction pairs ``(..., 3)``, converting each chunk to angles."""
    wi, wo = np.broadcast_arrays(np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64))
    if wi.ndim == 0 or wi.shape[-1] != 3:
        raise ValueError(f"lookup: expected directions of shape (..., 3), got {wi.shape}")
    batch = wi.shape[:-1]
    wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
    out = np.empty((len(wi), 3))

    def run(sl):
        out[sl] = kernel(prepared, shape, *half_diff_from_dirs(wi[sl], wo[sl]))

    _over_chunks(run, len(wi))
    return out.reshape(batch + (3,))


def _nearest_kernel(prepared, shape, th, td, pd):
    """Nearest-cell rgb ``(n, 3)`` for flat angle arrays; NaN for missing cells/NaN angles."""
    rgb, valid = prepared
    n_th, n_td, n_pd = shape
    i, j, k = merl_index(th, td, pd, shape)
    flat = (i * n_td + j) * n_pd + k
    out = np.take(rgb, flat, axis=0)
    missing = ~np.take(valid, flat) | _nan_angles(th, td, pd)
    if missing.any():
        out[missing] = np.nan
    return out


def _nearest_prepared(table: MERLTable):
    return table.rgb.reshape(-1, 3), table.valid.reshape(-1)


def lookup_nearest_angles(table: MERLTable, theta_h, theta_d, phi_d):
    """BRDF ``(..., 3)`` of the cell :func:`merl_index` picks for broadcast angles; NaN where
    that cell is missing or an angle is NaN."""
    return _by_angles(_nearest_kernel, _nearest_prepared(table), table.shape,
                      theta_h, theta_d, phi_d)


def lookup_nearest(table: MERLTable, wi, wo):
    """The database reader's lookup (``lookup_brdf_val``): the BRDF of the cell holding the
    pair's half/difference angles, for direction pairs ``(..., 3)``; returns ``(..., 3)``.

    Missing cells give NaN (never the stored ``-1 * SCALE``). Like the database reader it does
    not test the horizon: a pair below it gets whatever its cell holds. Directions are not
    renormalised. Note that a cell's own corner direction (:func:`cell_directions`) sits on
    the cell's lower boundary, so rounding in the direction -> angle conversion puts about half
    of them in the cell below; look up ``cell_angles`` with :func:`lookup_nearest_angles` for
    exact cells.
    """
    return _by_dirs(_nearest_kernel, _nearest_prepared(table), table.shape, wi, wo)


def _axis_weights(x, n: int):
    """Lower cell, upper cell and upper weight along a clamped axis of continuous coordinate ``x``.

    Past the last sample (``x >= n - 1``) both cells are the last one: the value is held.
    """
    lo = _clamped_floor(x, n)
    return lo, np.minimum(lo + 1, n - 1), np.clip(x - lo, 0.0, 1.0)


def _interp_grid(table: MERLTable):
    """Per-table gather array for the linear lookup, built once and cached on the table.

    ``(n_th * n_td * (n_pd + 1), 4)`` float64 rows ``(r, g, b, valid)`` (rgb zeroed where
    missing) in file order, with ``phi_d`` cell 0 repeated at ``k = n_pd`` (the periodic wrap),
    so a corner is one 32-byte row and ``k + 1`` never needs a modulo. Costs 1.35x the table's
    rgb in memory (47 MB for the database grid). The cache is keyed by the identity of
    ``table.rgb`` and ``table.valid``: replacing them is seen, editing them in place is not
    (the arrays of tables from ``read_merl``, ``from_rgb`` and ``synthesize`` are read-only).
    """
    cached = table.__dict__.get("_interp_cache")
    if cached is not None and cached[0] is table.rgb and cached[1] is table.valid:
        return cached[2]
    n_th, n_td, n_pd = table.shape
    grid = np.empty((n_th, n_td, n_pd + 1, 4))
    grid[:, :, :n_pd, :3] = table.rgb
    grid[:, :, :n_pd, 3] = table.valid
    grid[:, :, :n_pd, :3][~table.valid] = 0.0
    grid[:, :, n_pd] = grid[:, :, 0]
    grid = grid.reshape(-1, 4)
    table._interp_cache = (table.rgb, table.valid, grid)
    return grid


def _linear_kernel(grid, shape, th, td, pd):
    """Trilinear rgb ``(n, 3)`` for flat angle arrays (see :func:`lookup_linear_angles`)."""
    n_th, n_td, n_pd = shape
    u, v, w = _grid_coords(th, td, pd, shape)
    i0, i1, fi = _axis_weights(u, n_th)
    j0, j1, fj = _axis_weights(v, n_td)
    k0 = _clamped_floor(w, n_pd)
    fk = np.clip(w - k0, 0.0, 1.0)
    acc = np.zeros((th.size, 4))  # (r, g, b, weight of the valid corners)
    rec = np.empty((th.size, 4))
    for ii, wgt_i in ((i0, 1.0 - fi), (i1, fi)):
        for jj, wgt_j in ((j0, 1.0 - fj), (j1, fj)):
            row = (ii * n_td + jj) * (n_pd + 1) + k0
            wgt_ij = wgt_i * wgt_j
            for dk, wgt_k in ((0, 1.0 - fk), (1, fk)):
                np.take(grid, row + dk, axis=0, out=rec)
                rec *= (wgt_ij * wgt_k)[:, None]
                acc += rec
    ok = acc[:, 3] > 0.0  # False for NaN weights too
    out = acc[:, :3] / np.where(ok, acc[:, 3], 1.0)[:, None]
    out[~ok] = np.nan
    return out


def lookup_linear_angles(table: MERLTable, theta_h, theta_d, phi_d):
    """Trilinear interpolation ``(..., 3)`` in the warped coordinates ``(u, v, w)``.

    With ``u = sqrt(theta_h/(pi/2)) n_th``, ``v = theta_d/(pi/2) n_td``, ``w = phi_d/pi n_pd``
    (``phi_d`` folded), cell ``(i, j, k)`` is the sample at ``(u, v, w) = (i, j, k)``, its lower
    corner, so the result equals the stored value there (bit for bit when the coordinates are
    exactly integral) and is linear along each axis in between. ``phi_d`` is periodic (the fold
    by reciprocity): between the last cell and ``phi_d = pi`` it blends towards cell 0, so the
    result is continuous across ``phi_d = 0 = pi``. Past the last ``theta_h`` or ``theta_d``
    sample it is held constant.

    Missing cells: their weights are dropped and the rest renormalised, so the result is the
    weighted mean of the valid corners among the eight; NaN when no corner with non-zero weight
    is valid (in particular exactly at a missing cell's corner), or where an angle is NaN.
    """
    return _by_angles(_linear_kernel, _interp_grid(table), table.shape, theta_h, theta_d, phi_d)


def lookup_linear(table: MERLTable, wi, wo):
    """Trilinear lookup of direction pairs ``(..., 3)``; see :func:`lookup_linear_angles`."""
    return _by_dirs(_linear_kernel, _interp_grid(table), table.shape, wi, wo)


# --------------------------------------------------------------------------------------------
# Synthetic tables
# --------------------------------------------------------------------------------------------

def synthesize(fn, name: str = "", shape=MERL_SHAPE) -> MERLTable:
    """A table from a NumPy BRDF ``fn(wi, wo) -> rgb``, evaluated at every cell's lower corner.

    ``fn`` receives the read-only grids of :func:`cell_directions` (each ``(*shape, 3)``) and
    must return ``(*shape, 3)`` (or something that broadcasts to it). Cells whose corner is not
    strictly above the horizon (:func:`above_horizon`) are marked missing, as in the real
    database, and ``fn``'s values there are ignored (NaN is fine). Values are snapped to the
    file grid, so writing the table and reading it back gives it exactly.
    """
    shape = tuple(int(n) for n in shape)
    wi, wo = cell_directions(shape)
    rgb = np.broadcast_to(np.asarray(fn(wi, wo), dtype=np.float64), shape + (3,))
    valid = np.array(above_horizon(shape))
    ok = np.all(np.isfinite(rgb) & (rgb >= 0.0), axis=-1) | ~valid
    if not ok.all():
        cell = tuple(int(x) for x in np.argwhere(~ok)[0])
        raise ValueError(
            f"synthesize: fn returned {int(np.count_nonzero(~ok))} negative or non-finite "
            f"values above the horizon (first: cell {cell}, wi={wi[cell].tolist()}, "
            f"wo={wo[cell].tolist()}: {rgb[cell].tolist()}); a BRDF must be finite and >= 0"
        )
    return MERLTable.from_rgb(rgb, valid, name=name)
