"""The MERL table type in memory, and its summary (what ``brdffit info`` prints)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..samples import SampleSet
from ._grid import above_horizon, cell_angles, cell_directions, shape_key, theta_h_weights
from ._lookup import gather_grid, lookup_linear, lookup_nearest
from ._scale import CHANNELS, snap_to_file


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
        self._grid = None  # (rgb, valid, gather grid): see gather_grid

    def gather_grid(self) -> np.ndarray:
        """The linear lookup's gather array (:func:`~data_formats.merl._lookup.gather_grid`),
        built at the first linear lookup and kept by the table. It is rebuilt when ``rgb`` or
        ``valid`` is replaced by another array (editing one in place is not seen: the arrays of
        tables from ``read_merl``, ``from_rgb`` and ``synthesize`` are read-only)."""
        if self._grid is None or self._grid[0] is not self.rgb or self._grid[1] is not self.valid:
            self._grid = (self.rgb, self.valid, gather_grid(self.rgb, self.valid))
        return self._grid[2]

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
        ``weight`` is each cell's width in ``theta_h`` relative to the mean
        (:func:`~data_formats.merl.theta_h_weights`: the warp's cell density undone);
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
                         name=self.name, path=self.path, weight=_cell_weights(self.shape))

    def lookup(self, wi, wo, method: str = "nearest"):
        """BRDF at direction pairs ``(..., 3)``: ``method`` is ``"nearest"``
        (:func:`lookup_nearest`) or ``"linear"`` (:func:`lookup_linear`). NaN where missing."""
        fns = {"nearest": lookup_nearest, "linear": lookup_linear}
        if method not in fns:
            raise ValueError(
                f"MERLTable.lookup: unknown method {method!r}; expected one of {sorted(fns)}"
            )
        return fns[method](self, wi, wo)


def _cell_weights(shape) -> np.ndarray:
    """``theta_h_weights`` of every cell, flattened in file order (read-only, cached)."""
    return _flat_cell_weights(shape_key(shape))


@functools.lru_cache(maxsize=2)
def _flat_cell_weights(shape):
    n_th, n_td, n_pd = shape
    w = np.repeat(theta_h_weights(shape), n_td * n_pd)
    w.flags.writeable = False
    return w


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
    for c, ch in enumerate(CHANNELS):
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
            "value": float(vals[row, c]), "channel": CHANNELS[c], "index": [int(x) for x in ijk],
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
