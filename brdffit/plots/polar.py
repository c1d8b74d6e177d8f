"""The lobe over the outgoing hemisphere, in polar coordinates: where anisotropy shows.

For each of a few incidences ``θi`` (azimuth ``φi = 0``, the light along ``+x``), the
luminance of ``f_r(ωi, ωo)`` over the outgoing hemisphere: angle ``φo``, radius ``θo`` (degrees,
linear, 0 at the normal), measured beside fitted. An isotropic lobe is symmetric about the
plane of incidence (the line ``φo = 0°–180°``); an anisotropic one is an ellipse whose axes are
the material's, turned with its tangent frame. One logarithmic colour scale (``log10`` of the
luminance, Rec. 709) per row, set by the measurement (its 1st to 99.9th percentiles); the
contour of half the row's measured peak is drawn on both panels, solid for the measurement and
dashed for the fit, so a lobe of the wrong width, shape or orientation stands out.

Works for every input: a measurement that evaluates itself (an RGL material) is evaluated at
the grid; a MERL table is looked up trilinearly; a sample set by its nearest sample
(:func:`._eval.measured_lookup`), with holes where it has no data.
"""

from __future__ import annotations

import numpy as np

from . import _style
from ._eval import data_name, evaluate_model, measured_lookup

#: Default incidences (degrees from the normal).
THETA_I_DEG = (0.0, 30.0, 60.0)


def hemisphere_grid(n_theta: int = 72, n_phi: int = 144):
    """``(phi_edges, theta_edges_deg, wo)``: cell edges of the polar grid and the outgoing
    direction at each cell centre, ``wo`` ``(n_theta, n_phi, 3)``."""
    phi_e = np.linspace(0.0, 2 * np.pi, n_phi + 1)
    th_e = np.linspace(0.0, 89.0, n_theta + 1)
    phi, th = 0.5 * (phi_e[1:] + phi_e[:-1]), np.radians(0.5 * (th_e[1:] + th_e[:-1]))
    t, p = np.meshgrid(th, phi, indexing="ij")
    wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    return phi_e, th_e, wo


def lobe_maps(data, model=None, params=None, theta_i_deg=THETA_I_DEG, *, n_theta: int = 72,
              n_phi: int = 144):
    """``(phi_edges, theta_edges_deg, measured, fitted)``: luminance ``(n_i, n_theta, n_phi)``
    of the measurement and the fit (``None`` without a model) at each incidence."""
    phi_e, th_e, wo = hemisphere_grid(n_theta, n_phi)
    look = measured_lookup(data)
    measured, fitted = [], []
    for t in np.radians(np.asarray(theta_i_deg, float)):
        wi = np.broadcast_to([np.sin(t), 0.0, np.cos(t)], wo.shape)
        measured.append(np.asarray(look(wi, wo), float) @ _style.LUMA)
        if model is not None:
            fitted.append(np.asarray(evaluate_model(model, params, wi, wo), float) @ _style.LUMA)
    return phi_e, th_e, np.array(measured), (np.array(fitted) if model is not None else None)


def _levels(lum):
    y = lum[np.isfinite(lum) & (lum > 0)]
    if y.size == 0:
        return -1.0, 1.0
    lo, hi = np.log10(np.percentile(y, 1.0)), np.log10(np.percentile(y, 99.9))
    return float(lo), float(max(hi, lo + 1.0))


def figure_size(fitted: bool, rows: int = len(THETA_I_DEG)) -> tuple[float, float]:
    """``(width, height)`` in inches of the polar figure, with or without the fit's column."""
    return 3.3 * (2 if fitted else 1) + 0.8, 3.0 * rows + 0.6


def plot_polar(data, model=None, params=None, *, theta_i_deg=THETA_I_DEG,
               error: str | None = None, title: str | None = None, fig=None):
    """The polar figure (module docstring): one row per incidence, measured | fitted.
    ``fig``: a figure or sub-figure to draw into (default: a new one of this view's size)."""
    phi_e, th_e, meas, fit = lobe_maps(data, model, params, theta_i_deg)
    cols = 1 if fit is None else 2
    fig = _style.new_figure(*figure_size(fit is not None, len(meas)), fig)
    axes = np.asarray(fig.subplots(len(meas), cols, squeeze=False,
                                   subplot_kw={"projection": "polar"}))
    phi_c = 0.5 * (phi_e[1:] + phi_e[:-1])
    th_c = 0.5 * (th_e[1:] + th_e[:-1])
    cmap = _style_cmap()
    for row, t in enumerate(theta_i_deg):
        lo, hi = _levels(meas[row])
        finite = meas[row][np.isfinite(meas[row])]
        half = 0.5 * float(finite.max()) if finite.size else None
        panels = [("measured", meas[row])] + ([("fitted", fit[row])] if fit is not None else [])
        for col, (label, lum) in enumerate(panels):
            ax = axes[row, col]
            with np.errstate(divide="ignore", invalid="ignore"):
                img = np.log10(np.where(lum > 0, lum, np.nan))
            mesh = ax.pcolormesh(phi_e, th_e, img, cmap=cmap, vmin=lo, vmax=hi, shading="flat")
            if half is not None and half > 0:
                _contour(ax, phi_c, th_c, meas[row], half, "-")
                if fit is not None:
                    _contour(ax, phi_c, th_c, fit[row], half, "--")
            ax.set_ylim(0, 90)
            ax.set_yticks([30, 60, 90], ["30°", "60°", "θo 90°"], fontsize=7)
            ax.tick_params(axis="x", labelsize=7)
            ax.grid(alpha=0.3)
            ax.set_title(f"{label}, θi = {t:g}° (φi = 0°)", fontsize=9)
        fig.colorbar(mesh, ax=list(axes[row]), shrink=0.8, label="log10 luminance (1/sr)")
    name = getattr(model, "name", model) if model is not None else None
    fig.suptitle(title or _style.figure_title(data_name(data), name, error, "Lobe (polar)"))
    fig.supxlabel("angle: outgoing azimuth φo; radius: θo. Contour at half the measured peak: "
                  "solid measured, dashed fitted", fontsize=8)
    return fig


def _style_cmap():
    import matplotlib

    return matplotlib.colormaps["magma"].with_extremes(bad=_style.MISSING_RGB)


def _contour(ax, phi_c, th_c, lum, level, style):
    z = np.where(np.isfinite(lum), lum, 0.0)
    if z.max() <= level or z.min() >= level:
        return
    # close the azimuth: repeat the first column after the last
    ax.contour(np.append(phi_c, phi_c[0] + 2 * np.pi), th_c, np.concatenate([z, z[:, :1]], 1),
               levels=[level], colors="white" if style == "-" else "cyan", linestyles=style,
               linewidths=1.0)
