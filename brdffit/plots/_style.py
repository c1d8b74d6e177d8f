"""Shared looks of the diagnostic figures: tone mapping, the warped θh axis, titles, saving.

Figures are built with :class:`matplotlib.figure.Figure` directly (never ``pyplot``), so no GUI
backend and no global figure registry are involved; PNGs are written by the Agg canvas. They are
:class:`InlineFigure` objects, which a notebook shows inline as the value of a cell (IPython shows a
``pyplot`` figure by itself, but a plain ``Figure`` only as ``<Figure size ...>``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from data_formats.files import atomic_write

#: Colour of cells or pixels without a measurement.
MISSING_RGB = (0.55, 0.0, 0.55)
#: Line/marker colours of the R, G, B channels.
CHANNEL_COLORS = ("#d62728", "#2ca02c", "#1f77b4")
CHANNEL_NAMES = ("R", "G", "B")
#: Rec. 709 luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])
DPI = 110


#: Display value of the reference (median) luminance in :func:`log_tonemap`.
LOG_MID = 0.4
#: Percentile of the luminance that :func:`log_tonemap` maps to white (the peak, not a spike).
LOG_TOP_PERCENTILE = 99.9


def log_levels(rgb, percentile: float = LOG_TOP_PERCENTILE) -> tuple[float, float]:
    """``(ref, top)`` for :func:`log_tonemap`: the median and the ``percentile`` of the finite
    positive Rec. 709 luminances of ``rgb`` (``(1, 10)`` if there are none)."""
    y = np.tensordot(np.asarray(rgb, float), LUMA, axes=([-1], [0])).ravel()
    y = y[np.isfinite(y) & (y > 0)]
    if y.size == 0:
        return 1.0, 10.0
    ref, top = float(np.median(y)), float(np.percentile(y, percentile))
    return ref, max(top, 10.0 * ref)


def log_tonemap(rgb, ref: float, top: float, mid: float = LOG_MID) -> np.ndarray:
    r"""Logarithmic tone mapping of the luminance, hue kept: peak and diffuse visible at once.

    Measured BRDFs span four to five decades between the diffuse body and the specular peak
    (a MERL gold paint: 0.06 to 4000 /sr), which no exposure shows together: one that makes
    the diffuse readable saturates the peak, one that keeps the peak dark hides the diffuse.
    The display value is linear in ``log Y`` (Rec. 709 luminance):

    .. math::

        D(Y) = \mathrm{clip}\Bigl(m + (1 - m)\,\frac{\log(Y/Y_\mathrm{ref})}
               {\log(Y_\mathrm{top}/Y_\mathrm{ref})},\ 0,\ 1\Bigr),
        \qquad \mathrm{rgb}_\mathrm{out} = \mathrm{rgb}\,\frac{D(Y)}{Y},

    with ``Y_ref`` the median (at display ``m = 0.4``) and ``Y_top`` the 99.9th percentile (at
    white; :func:`log_levels`), so equal ratios of reflectance are equal steps of brightness
    anywhere from the diffuse floor to the peak. Scaling the RGB triple by ``D/Y`` keeps each
    pixel's chromaticity; where that pushes a channel above 1, the channels are clipped and the
    missing luminance is added as white (``c + s(1 - c)`` with ``s`` restoring ``Y = D``), so
    the brightest part of a coloured peak turns towards white and keeps getting brighter
    instead of flattening at its most saturated colour.
    ``D`` is already perceptually spaced: no gamma curve is applied on top. Zero and missing
    values are black.
    """
    rgb = np.nan_to_num(np.asarray(rgb, float), nan=0.0).clip(0.0, None)
    y = np.tensordot(rgb, LUMA, axes=([-1], [0]))
    span = np.log(max(top, ref * (1 + 1e-9)) / ref)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.clip(mid + (1.0 - mid) * np.log(y / ref) / span, 0.0, 1.0)
        out = np.where(y[..., None] > 0, rgb * (d / y)[..., None], 0.0)
    clipped = np.minimum(out, 1.0)
    y_c = np.tensordot(clipped, LUMA, axes=([-1], [0]))
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip((d - y_c) / np.maximum(1.0 - y_c, 1e-12), 0.0, 1.0)
    return clipped + s[..., None] * (1.0 - clipped)


def readable(value: float) -> str:
    """A positive number to three significant digits as people write it: ``0.302``, ``1290``,
    ``0.00412``; powers of ten (``2.1×10⁻⁵``) only outside ``[10⁻³, 10⁶)``."""
    value = float(f"{float(value):.3g}")
    if not np.isfinite(value) or value == 0:
        return f"{value:g}"
    exp = int(np.floor(np.log10(abs(value))))
    if -3 <= exp < 6:
        return f"{value:.{max(0, 2 - exp)}f}"
    sup = str(exp).translate(str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹"))
    return f"{value / 10.0**exp:.3g}×10{sup}"


def tonemap_label(ref: float, top: float) -> str:
    """How :func:`log_tonemap` mapped an image, for a figure's caption, in words (two lines,
    to fit over one panel): brightness
    follows the logarithm of the luminance, the median at mid-grey (display ``LOG_MID``), ``top``
    (:func:`log_levels`) and above at white; values in BRDF units, 1/sr."""
    return (f"log brightness scale: median {readable(ref)} /sr mid-grey,\n"
            f"{readable(top)} /sr and above white")


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


class InlineFigure(Figure):
    """A matplotlib :class:`~matplotlib.figure.Figure` that shows itself inline in a notebook.

    IPython displays an object through its ``_repr_png_``; matplotlib registers that for plain
    figures only when ``pyplot`` is in use, which this package never imports. Everything else is
    the base class's: ``savefig``, ``subfigures``, embedding in a GUI.
    """

    def _repr_png_(self) -> bytes:
        import io

        buf = io.BytesIO()
        self.savefig(buf, format="png", dpi=self.dpi, bbox_inches="tight")
        return buf.getvalue()


def new_figure(width: float, height: float, fig=None):
    """A figure of ``width × height`` inches at :data:`DPI`, with a constrained layout; or
    ``fig`` itself when given (a figure or sub-figure to draw into, whose size it keeps)."""
    if fig is not None:
        return fig
    return InlineFigure(figsize=(width, height), dpi=DPI, layout="constrained")


def save_png(fig: Figure, path) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically (temporary file in the folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=fig.dpi))
    return path
