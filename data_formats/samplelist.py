"""Gonioreflectometer-style sample lists: one measured direction pair per row (CSV or NPZ).

NumPy only. A sample list is the second input format beside MERL tables: a flat list of
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

from pathlib import Path

import numpy as np

from ._atomic import atomic_write
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


def _read_csv(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Header names, the data as an ``(N, C)`` float array, and the header's line number."""
    with open(path, encoding="utf-8", newline="") as fh:
        lines = fh.read().splitlines()
    first = 0
    while first < len(lines) and (not lines[first].strip() or lines[first].lstrip().startswith("#")):
        first += 1
    if first == len(lines):
        raise SampleListFormatError(
            f"{path}: no header row; a CSV sample list needs a header naming {_layout_text()}"
        )
    header = [c.strip().lower() for c in lines[first].split(",")]
    if any(_is_number(c) for c in header):
        raise SampleListFormatError(
            f"{path}: line {first + 1} looks like data, not a header; the first row must name "
            f"the columns: {_layout_text()}"
        )
    _pick_layout(path, header)
    data_lines = [
        (lineno, line)
        for lineno, line in enumerate(lines[first + 1 :], start=first + 2)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    line_numbers = np.array([lineno for lineno, _ in data_lines], dtype=int)
    if not data_lines:
        return header, np.empty((0, len(header))), line_numbers
    try:  # fast path; on failure, the slow path below finds and names the bad field
        data = np.loadtxt([line for _, line in data_lines], delimiter=",", ndmin=2)
        if data.shape == (len(data_lines), len(header)):
            return header, data, line_numbers
    except ValueError:
        pass
    return header, _parse_slowly(path, header, data_lines), line_numbers


def _parse_slowly(path, header, data_lines) -> np.ndarray:
    data = np.empty((len(data_lines), len(header)))
    for n, (lineno, line) in enumerate(data_lines):
        fields = line.split(",")
        if len(fields) != len(header):
            raise SampleListFormatError(
                f"{path}: line {lineno} has {len(fields)} fields, expected {len(header)} "
                f"({','.join(header)})"
            )
        for c, text in enumerate(fields):
            try:
                data[n, c] = float(text)
            except ValueError:
                raise SampleListFormatError(
                    f"{path}: line {lineno}, column {header[c]!r}: {text.strip()!r} is not a number"
                ) from None
    return data


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_npz(path: Path) -> tuple[list[str], np.ndarray]:
    try:
        archive = np.load(path, allow_pickle=False)
    except Exception as exc:  # zipfile.BadZipFile, ValueError, OSError, ...
        raise SampleListFormatError(f"{path}: not a readable NPZ archive ({exc})") from None
    with archive:
        names = [k.strip().lower() for k in archive.files]
        arrays = [np.asarray(archive[k]) for k in archive.files]
    for name, arr in zip(names, arrays):
        if arr.ndim != 1 or not np.issubdtype(arr.dtype, np.number):
            raise SampleListFormatError(
                f"{path}: array {name!r} must be a 1-D numeric array, got shape {arr.shape} "
                f"dtype {arr.dtype}"
            )
    lengths = {len(a) for a in arrays}
    if len(lengths) > 1:
        detail = ", ".join(f"{n}: {len(a)}" for n, a in zip(names, arrays))
        raise SampleListFormatError(f"{path}: arrays differ in length ({detail})")
    n = lengths.pop() if lengths else 0
    data = np.stack([a.astype(float) for a in arrays], axis=1) if arrays else np.empty((n, 0))
    return names, data
def _where(path, rows, i) -> str:
    """``path: line L`` (CSV) or ``path: row R`` (NPZ, 0-based array index) for sample ``i``."""
    return f"{path}: line {rows[i]}" if rows is not None else f"{path}: row {i}"


def _first_bad(mask) -> int:
    return int(np.flatnonzero(mask)[0])


def _check_finite(path, columns, data, rows) -> None:
    bad = ~np.isfinite(data)
    if bad.any():
        i, c = np.argwhere(bad)[0]
        raise SampleListFormatError(
            f"{_where(path, rows, i)}, column {columns[c]!r}: value {float(data[i, c])} is not finite; "
            f"every sample needs finite numbers (remove or repair the row)"
        )


def _directions(path, cols: dict, rows, side: str) -> np.ndarray:
    """Unit directions for ``side`` ('i' or 'o') from angle or vector columns, checked."""
    if f"theta_{side}" in cols:
        theta, phi = cols[f"theta_{side}"], cols[f"phi_{side}"]
        for bad, what in ((theta < 0, "negative"), (theta > 90, "below the horizon (> 90°)")):
            if bad.any():
                i = _first_bad(bad)
                raise SampleListFormatError(
                    f"{_where(path, rows, i)}, column 'theta_{side}': {theta[i]:g}° is {what}; "
                    f"θ is measured from the normal in degrees, 0 ≤ θ ≤ 90"
                )
        t, p = np.radians(theta), np.radians(phi)
        cos_t = np.where(theta == 90, 0.0, np.cos(t))  # cos(π/2) is 6e-17 in floating point
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), cos_t], axis=-1)
    names = [f"w{side}x", f"w{side}y", f"w{side}z"]
    w = np.stack([cols[n] for n in names], axis=-1)
    if (w[:, 2] < 0).any():
        i = _first_bad(w[:, 2] < 0)
        raise SampleListFormatError(
            f"{_where(path, rows, i)}, column 'w{side}z': {w[i, 2]:g} < 0, the direction is below "
            f"the horizon; directions point away from the surface with z along the normal"
        )
    norm = np.linalg.norm(w, axis=-1)
    bad = np.abs(norm - 1.0) > UNIT_TOLERANCE
    if bad.any():
        i = _first_bad(bad)
        raise SampleListFormatError(
            f"{_where(path, rows, i)}, columns {','.join(names)}: length {norm[i]:.6g} is not 1 "
            f"(tolerance {UNIT_TOLERANCE:g}); give unit vectors"
        )
    return w / norm[:, None]


def _to_sample_set(path: Path, columns, data, rows) -> SampleSet:
    _pick_layout(path, columns)
    if len(data) == 0:
        raise SampleListFormatError(f"{path}: no samples (the file has a header but no rows)")
    _check_finite(path, columns, data, rows)
    cols = {name: data[:, c] for c, name in enumerate(columns)}
    mono = "value" in cols
    colour = MONO_COLUMNS * 3 if mono else RGB_COLUMNS
    rgb = np.stack([cols[c] for c in colour], axis=-1)
    if (rgb < 0).any():
        i, c = np.argwhere(rgb < 0)[0]
        raise SampleListFormatError(
            f"{_where(path, rows, i)}, column {colour[c]!r}: {rgb[i, c]:g} is negative; "
            f"a BRDF is ≥ 0 (clip noise to 0 or drop the row)"
        )
    wi, wo = _directions(path, cols, rows, "i"), _directions(path, cols, rows, "o")
    valid = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    sigma = _sigma(path, cols, rows)
    return SampleSet(wi=wi, wo=wo, rgb=rgb, valid=valid, name=path.stem, path=str(path),
                     sigma=sigma, channels=1 if mono else 3)


def _sigma(path, cols: dict, rows) -> np.ndarray | None:
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
            f"{_where(path, rows, i)}, column {group[min(c, len(group) - 1)]!r}: "
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


def read_samples(path) -> SampleSet:
    """Read a CSV or NPZ sample list (layout in the module docstring) into a :class:`SampleSet`.

    Raises :class:`SampleListFormatError` for a missing file, a wrong suffix, wrong columns, and
    any bad value, naming the path, line (CSV, 1-based as an editor shows it) or row (NPZ, 0-based
    array index), and the column.
    """
    path = _check_path(path)
    if path.is_dir():
        raise SampleListFormatError(f"{path}: is a directory, expected a sample-list file")
    if not path.exists():
        raise SampleListFormatError(f"{path}: no such file")
    if path.suffix.lower() == ".csv":
        try:
            columns, data, rows = _read_csv(path)
        except UnicodeDecodeError as exc:
            raise SampleListFormatError(f"{path}: not a text CSV file ({exc.reason})") from None
    else:
        (columns, data), rows = _read_npz(path), None
    return _to_sample_set(path, columns, data, rows)


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
