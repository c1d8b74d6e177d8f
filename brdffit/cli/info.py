"""``brdffit info FILE``: the figures of a MERL table, a sample list or an RGL material (no
fitting, no JAX).

An RGL material (``.bsdf``) is described by its own fields (symmetry, incidence slices, table
sizes, channels, the file's description) followed by the figures of the direction pairs a fit
reads (its ``to_samples()``: the file's measurement pattern), laid out as a sample list's.

A sample list is read piece by piece (:func:`data_formats.samplelist.iter_samples`) and its
figures gathered as the pieces pass: ``info`` holds the valid colour values (for the exact
medians) and one piece, never the directions of the whole list (about a fifth of what
reading it whole takes).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._columns import columns
from ..io import formats_text, is_table
from ._common import check_readable, read_input


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "info",
        parents=parents,
        allow_abbrev=False,
        help="print a table's figures (dims, valid fraction, channel ranges, peak)",
        description=f"Print the figures of FILE ({formats_text()}): dimensions, valid "
        "fraction, per-channel min/median/max over valid samples, the peak; for an RGL "
        "material also its symmetry, grid sizes, channels and description.",
    )
    p.add_argument("file", metavar="FILE", help=f"a {formats_text()}")
    p.add_argument("--json", action="store_true", help="print the figures as JSON on stdout")
    p.set_defaults(run=run, needs_jax=False)


def sample_info(samples) -> dict:
    """Figures of a sample list, in the spirit of ``MERLTable.info()``."""
    return streamed_info([samples])


class _Figures:
    """The figures of a sample list, gathered piece by piece (:func:`streamed_info`): counts,
    per-channel min and max, the peak (the largest ``r+g+b``) and its directions; the valid
    colour values are kept, one contiguous row per channel, for the exact medians."""

    def __init__(self, first, n: int):
        self.path, self.channels = first.path, int(getattr(first, "channels", 3))
        self.sigma = getattr(first, "sigma", None) is not None
        self.seen, self.valid = 0, 0
        self.values = np.empty((3, n))  # valid values, channel-major (partitioned in place)
        self.low, self.high = np.full(3, np.inf), np.full(3, -np.inf)
        self.peak = None  # (r+g+b, rgb, wi, wo)

    def add(self, piece) -> None:
        keep = np.asarray(piece.valid, bool)
        rgb = np.asarray(piece.rgb, float)[keep]
        k = len(rgb)
        self.seen += len(keep)
        if k:
            self.values[:, self.valid:self.valid + k] = rgb.T
            self.low, self.high = np.minimum(self.low, rgb.min(0)), np.maximum(self.high, rgb.max(0))
            i = int(np.argmax(rgb.sum(axis=1)))
            if self.peak is None or rgb[i].sum() > self.peak[0]:
                row = np.flatnonzero(keep)[i]
                self.peak = (rgb[i].sum(), rgb[i], piece.wi[row], piece.wo[row])
        self.valid += k

    def medians(self) -> list[float]:
        """``np.median`` of each channel's valid values, by partitioning them in place."""
        m, out = self.valid, []
        for row in self.values[:, :m]:
            lo, hi = (m - 1) // 2, m // 2
            row.partition((lo, hi))
            out.append(float((row[lo] + row[hi]) / 2))
        return out

    def result(self) -> dict:
        out = {"format": "sample list", "path": self.path, "samples": self.seen,
               "valid": self.valid,
               "valid_fraction": self.valid / self.seen if self.seen else 0.0,
               "channels": self.channels, "sigma": self.sigma}
        if self.valid:
            for c, (name, mid) in enumerate(zip("rgb", self.medians())):
                out[f"{name}_min"], out[f"{name}_median"], out[f"{name}_max"] = (
                    float(self.low[c]), mid, float(self.high[c]))
            _, rgb, wi, wo = self.peak
            out["peak_rgb"] = [float(v) for v in rgb]
            out["peak_theta_i_deg"], out["peak_theta_o_deg"] = (
                float(np.degrees(np.arccos(np.clip(w[2], -1, 1)))) for w in (wi, wo))
        return out


def streamed_info(pieces, n: int | None = None) -> dict:
    """:func:`sample_info` of a sample list given as pieces (``SampleSet``s, in order, e.g.
    :func:`data_formats.samplelist.iter_samples`) of ``n`` samples in all (``None``: the
    pieces are a list). Memory: the valid colour values (for the medians) and one piece."""
    pieces = iter(pieces) if n is not None else list(pieces)
    if n is None:
        n = sum(len(p) for p in pieces)
    figures = None
    for piece in pieces:
        figures = figures or _Figures(piece, n)
        figures.add(piece)
    if figures is None:  # no pieces: no samples
        return {"format": "sample list", "path": None, "samples": 0, "valid": 0,
                "valid_fraction": 0.0, "channels": 3, "sigma": False}
    return figures.result()


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return "(" + ", ".join(_fmt(v) for v in value) + ")"
    if isinstance(value, dict):
        return ", ".join(f"{k}={_fmt(v)}" for k, v in value.items())
    return str(value)


def format_info(figures: dict) -> str:
    """A sample list's figures as aligned text, laid out as a MERL table's
    (:meth:`data_formats.merl.MERLTable.info_text`): header, counts, a channel table, the peak."""
    f = figures
    channels = "1 (monochrome: the value in R, G and B)" if f.get("channels") == 1 else "3 (RGB)"
    sigma = "sigma given per sample" if f.get("sigma") else "none (no sigma columns)"
    name = Path(f["path"]).stem if f.get("path") else ""
    lines = [
        f"sample list {name!r}" + (f" ({f['path']})" if f.get("path") else ""),
        f"  samples      {f['samples']:,} direction pairs",
        f"  valid        {f['valid']:,} ({f['valid_fraction']:.1%})",
        f"  channels     {channels}",
        f"  uncertainty  {sigma}",
    ]
    rows = [("channel", "min", "median", "max")] + [
        (ch.upper(), *(f"{f[f'{ch}_{k}']:.5g}" for k in ("min", "median", "max")))
        for ch in "rgb" if f"{ch}_min" in f]
    lines += columns(rows, "<<<<", indent="  ", gap=" ", minimum=(12, 12, 12))
    if "peak_rgb" in f:
        lines.append(f"  peak         {_fmt(f['peak_rgb'])} (largest r+g+b) at "
                     f"theta_i={f['peak_theta_i_deg']:.3f} deg, "
                     f"theta_o={f['peak_theta_o_deg']:.3f} deg")
    else:
        lines.append("  peak         - (no valid samples)")
    return "\n".join(line.rstrip() for line in lines)


def figures_of(data) -> dict:
    if is_table(data):
        return {"format": "MERL table", **_jsonable(data.info())}
    if not hasattr(data, "wi"):  # a measurement that makes its samples (an RGL material)
        return material_info(data)
    return sample_info(data)


def material_info(material) -> dict:
    """Figures of an RGL material: its fields (what a user needs to know about the file) and
    :func:`sample_info` of the pairs a fit reads, under ``"samples_read"``."""
    theta = np.degrees(np.asarray(material.theta_i, float))
    spectral = material.rgb is None
    n = material.resolution
    out = {
        "format": "RGL material", "path": material.path, "name": material.name,
        "isotropic": bool(material.isotropic), "reduction": int(material.reduction),
        "theta_i_slices": int(len(theta)),
        "theta_i_range_deg": [float(theta.min()), float(theta.max())] if len(theta) else [],
        "phi_i_slices": int(len(material.phi_i)),
        "ndf_shape": list(np.shape(material.ndf)), "sigma_shape": list(np.shape(material.sigma)),
        "vndf_shape": list(np.shape(material.vndf)[-2:]), "table_resolution": [n, n],
        "channels": "spectral" if spectral else "rgb",
        "jacobian": bool(material.jacobian), "description": str(material.description),
    }
    if spectral:
        wl = np.asarray(material.wavelengths, float)
        out["wavelengths"] = int(len(wl))
        out["wavelength_range_nm"] = [float(wl.min()), float(wl.max())] if len(wl) else []
    samples = sample_info(material.to_samples())
    out["samples_read"] = {k: v for k, v in samples.items() if k not in ("format", "path")}
    return out


def format_material(f: dict) -> str:
    """An RGL material's figures (:func:`material_info`) as aligned text: the file's fields, then
    the pairs a fit reads, laid out as a sample list's (:func:`format_info`)."""
    kind = ("isotropic" if f["isotropic"]
            else f"anisotropic (φi folded by {f['reduction']})" if f["reduction"] > 1
            else "anisotropic")
    lo, hi = f["theta_i_range_deg"] or (0.0, 0.0)
    if f["channels"] == "spectral":
        wl = f.get("wavelength_range_nm") or (0.0, 0.0)
        channels = (f"spectral, {f['wavelengths']} wavelengths {wl[0]:g}-{wl[1]:g} nm "
                    "(reduced to RGB)")
    else:
        channels = "3 (RGB)"
    size = "x".join(map(str, f["table_resolution"]))
    lines = [
        f"RGL material {f['name']!r}" + (f" ({f['path']})" if f.get("path") else ""),
        f"  symmetry     {kind}",
        f"  incidence    {f['theta_i_slices']} theta_i slices ({lo:.4g}-{hi:.4g} deg) x "
        f"{f['phi_i_slices']} phi_i slices",
        f"  tables       reflectance {size} per slice; ndf {'x'.join(map(str, f['ndf_shape']))}, "
        f"sigma {'x'.join(map(str, f['sigma_shape']))}, vndf {'x'.join(map(str, f['vndf_shape']))}",
        f"  channels     {channels}",
        f"  jacobian     {'yes (tables divided by D/(4 sigma))' if f['jacobian'] else 'no'}",
        f"  description  {' '.join(f['description'].split()) or '-'}",
        "  read as      the file's measurement pattern (what a fit reads):",
    ]
    pairs = format_info({**f["samples_read"], "path": None}).splitlines()[1:]
    return "\n".join([*lines, *("  " + line for line in pairs)])


def _sample_list_figures(path: str) -> dict | None:
    """The figures of the sample list at ``path``, streamed (:func:`streamed_info`), or
    ``None`` if ``path`` names no sample list."""
    from data_formats.samplelist import sample_count_and_pieces

    from ..io import INPUT_SUFFIXES

    if INPUT_SUFFIXES.get(Path(path).suffix.lower()) != "sample list" or not Path(path).exists():
        return None
    check_readable(Path(path))
    return streamed_info(*reversed(sample_count_and_pieces(path)))


def run(args) -> int:
    figures = _sample_list_figures(args.file)
    data = None
    if figures is None:  # a MERL table (its reader bounds its size), or an error to report
        data = read_input(args.file)
        figures = figures_of(data)
    figures = _jsonable(figures)
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        if data is not None and is_table(data):
            print(data.info_text())
        elif figures.get("format") == "RGL material":
            print(format_material(figures))
        else:
            print(format_info(figures))
    return 0
