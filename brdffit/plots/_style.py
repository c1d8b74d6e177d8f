"""Shared looks of the diagnostic figures: tone mapping, the warped θh axis, titles, saving.

Figures are built with :class:`matplotlib.figure.Figure` directly (never ``pyplot``), so no GUI
backend and no global figure registry are involved; PNGs are written by the Agg canvas.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from data_formats._atomic import atomic_write

#: Colour of cells or pixels without a measurement.
MISSING_RGB = (0.55, 0.0, 0.55)
#: Line/marker colours of the R, G, B channels.
CHANNEL_COLORS = ("#d62728", "#2ca02c", "#1f77b4")
CHANNEL_NAMES = ("R", "G", "B")
#: Rec. 709 luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])
DPI = 110


def robust_exposure(values, percentile: float = 99.0, *, target: float = 0.9) -> float:
    """Exposure that maps the ``percentile`` of the finite positive ``values`` to ``target``.

    A percentile rather than the maximum keeps a thin specular peak from darkening everything
    else (the peak then clips, as in Burley 2012 Fig. 1). Returns 1 when there is nothing positive.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return 1.0
    ref = np.percentile(v, percentile)
    return float(target / ref) if ref > 0 else 1.0


def gamma_tonemap(rgb, exposure: float, gamma: float = 2.2) -> np.ndarray:
    """``clip(exposure · rgb, 0, 1) ** (1/gamma)``: the image-slice display (Burley 2012 §3.3)."""
    x = np.clip(np.nan_to_num(np.asarray(rgb, float) * exposure, nan=0.0), 0.0, 1.0)
    return x ** (1.0 / gamma)


def srgb_tonemap(rgb, exposure: float) -> np.ndarray:
    """Exposure, clip to [0, 1], then the sRGB transfer function (IEC 61966-2-1)."""
    x = np.clip(np.nan_to_num(np.asarray(rgb, float) * exposure, nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def diverging_cmap():
    """``RdBu_r`` (blue: fit too dark, red: too bright) with missing values in neutral grey."""
    import matplotlib

    return matplotlib.colormaps["RdBu_r"].with_extremes(bad=(0.6, 0.6, 0.6))


def warp_theta_h(theta_h_deg):
    """MERL's warped θh coordinate in [0, 1]: ``sqrt(θh / 90°)`` (θh ≤ 0 → 0)."""
    return np.sqrt(np.clip(np.asarray(theta_h_deg, float), 0.0, None) / 90.0)


def unwarp_theta_h(u):
    """Inverse of :func:`warp_theta_h`: θh in degrees from the warped coordinate."""
    return 90.0 * np.clip(np.asarray(u, float), 0.0, None) ** 2


#: θh ticks (degrees) for a warped axis: dense near the specular peak, like the data.
THETA_H_TICKS = (0, 1, 5, 10, 20, 40, 60, 90)


def set_warped_theta_h_axis(ax, *, scale: float = 1.0, axis: str = "x") -> None:
    """Label an axis whose coordinate is ``scale · sqrt(θh/90°)`` with θh in degrees."""
    pos = [scale * float(warp_theta_h(t)) for t in THETA_H_TICKS]
    labels = [f"{t}°" for t in THETA_H_TICKS]
    if axis == "x":
        ax.set_xticks(pos, labels)
        ax.set_xlabel("θh (warped: √(θh/90°), as stored)")
    else:
        ax.set_yticks(pos, labels)
        ax.set_ylabel("θh (warped)")


def figure_title(material: str, model_name: str | None, error: str | None, what: str) -> str:
    """``"<what>: <material> · fit: <model> · <error>"``; the fit parts only when a fit is shown."""
    title = f"{what}: {material}"
    if model_name:
        title += f"  ·  fit: {model_name}"
    if error:
        title += f"  ·  {error}"
    return title


def new_figure(width: float, height: float) -> Figure:
    """A figure of ``width × height`` inches at :data:`DPI`, with a constrained layout."""
    return Figure(figsize=(width, height), dpi=DPI, layout="constrained")


def save_png(fig: Figure, path) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically (temporary file in the folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=fig.dpi))
    return path
