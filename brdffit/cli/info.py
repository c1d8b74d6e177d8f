"""``brdffit info FILE``: the figures of a MERL table or a sample list (no fitting, no JAX)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ._common import is_table, read_input


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "info",
        parents=parents,
        allow_abbrev=False,
        help="print a table's figures (dims, valid fraction, channel ranges, peak)",
        description="Print the figures of a MERL table (.binary) or a sample list (.csv, .npz): "
        "dimensions, valid fraction, per-channel min/median/max over valid samples, the peak.",
    )
    p.add_argument("file", metavar="FILE", help="a .binary MERL table or a .csv/.npz sample list")
    p.add_argument("--json", action="store_true", help="print the figures as JSON on stdout")
    p.set_defaults(run=run, needs_jax=False)


def sample_info(samples) -> dict:
    """Figures of a sample list, in the spirit of ``MERLTable.info()``."""
    valid = np.asarray(samples.valid, bool)
    rgb = np.asarray(samples.rgb, float)[valid]
    out = {"format": "sample list", "path": samples.path, "samples": len(samples),
           "valid": int(valid.sum()), "valid_fraction": float(valid.mean()) if len(valid) else 0.0,
           "channels": int(getattr(samples, "channels", 3)),
           "sigma": getattr(samples, "sigma", None) is not None}
    if rgb.size:
        for c, name in enumerate("rgb"):
            out[f"{name}_min"], out[f"{name}_median"], out[f"{name}_max"] = (
                float(rgb[:, c].min()), float(np.median(rgb[:, c])), float(rgb[:, c].max()))
        k = int(np.argmax(rgb.sum(axis=1)))
        wi, wo = samples.wi[valid][k], samples.wo[valid][k]
        out["peak_rgb"] = [float(v) for v in rgb[k]]
        out["peak_theta_i_deg"], out["peak_theta_o_deg"] = (
            float(np.degrees(np.arccos(np.clip(w[2], -1, 1)))) for w in (wi, wo))
    return out


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
        "  channel      min          median       max",
    ]
    for ch in "rgb":
        if f"{ch}_min" in f:
            low, mid, high = (f[f"{ch}_{k}"] for k in ("min", "median", "max"))
            lines.append(f"  {ch.upper()}            {low:<12.5g} {mid:<12.5g} {high:<12.5g}")
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
    return sample_info(data)


def run(args) -> int:
    data = read_input(args.file)
    figures = _jsonable(figures_of(data))
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        print(data.info_text() if is_table(data) else format_info(figures))
    return 0
