"""Specular-peak curves: log f_r against θh at a few θd, φd = 90°, measured and fitted.

These are the cartesian plots of Burley's BRDF Explorer (2012 §3.2) through the image slice: one
panel per θd (a horizontal line of the slice), θh on MERL's warped axis ``sqrt(θh/90°)`` so the
peak's core and its tail are both visible, f_r on a log axis, one colour per RGB channel.

* Measured (markers): from a MERL table, the cells of the row ``θd`` at the φd = 90° cell (each
  at its lower-corner θh); from a sample set, the samples with ``|φd − 90°| < phi_tol_deg`` and
  ``|θd − θd_target| < theta_d_tol_deg``, at their own θh.
* Fitted (lines): the model at 300 θh values evenly spaced in the warped coordinate, at exactly
  that θd and φd (the model needs no data).

Non-positive values cannot be shown on the log axis and are left out.
"""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import NullFormatter

from . import _style
from ._eval import data_name, evaluate_model, is_table, sample_view, warped_coords

#: Default θd rows (degrees).
THETA_D_DEG = (1.0, 30.0, 60.0, 80.0)


def _measured_row(data, theta_d_deg, phi_d_deg, td_tol, pd_tol):
    """``(θh_deg (N,), rgb (N, 3))`` of the measured points of one curve."""
    if is_table(data):
        from data_formats.merl import cell_angles

        n_th, n_td, n_pd = np.shape(data.valid)
        j = int(np.clip(np.floor(theta_d_deg / 90.0 * n_td), 0, n_td - 1))
        k = int(np.clip(np.floor(phi_d_deg / 180.0 * n_pd), 0, n_pd - 1))
        i = np.arange(n_th)
        th = np.degrees(cell_angles(i, np.full_like(i, j), np.full_like(i, k), data.valid.shape)[0])
        rgb = np.asarray(data.rgb, float)[:, j, k]
        ok = np.asarray(data.valid, bool)[:, j, k]
        return th[ok], rgb[ok]
    data = sample_view(data)
    ok = np.asarray(data.valid, bool) & np.all(np.isfinite(data.rgb), axis=-1)
    u = warped_coords(data.wi[ok], data.wo[ok])
    near = np.abs(u[:, 1] * 90.0 - theta_d_deg) < td_tol
    near &= np.abs(u[:, 2] * 180.0 - phi_d_deg) < pd_tol
    order = np.argsort(u[near, 0])
    return _style.unwarp_theta_h(u[near, 0][order]), np.asarray(data.rgb, float)[ok][near][order]


def _fitted_row(model, params, theta_d_deg, phi_d_deg, n: int = 300):
    """``(θh_deg (n,), rgb (n, 3))`` of the model along one row of the slice."""
    from data_formats.rusinkiewicz import dirs_from_half_diff

    th = _style.unwarp_theta_h(np.linspace(0.0, 1.0, n, endpoint=False))
    wi, wo = dirs_from_half_diff(np.radians(th), np.full(n, np.radians(theta_d_deg)),
                                 np.full(n, np.radians(phi_d_deg)))
    return th, evaluate_model(model, params, wi, wo)


def _draw_panel(ax, meas, fit, theta_d_deg):
    for c, color in enumerate(_style.CHANNEL_COLORS):
        th, rgb = meas
        pos = rgb[:, c] > 0
        ax.plot(_style.warp_theta_h(th[pos]), rgb[pos, c], "o", ms=3.0, mfc="none", mew=0.8,
                color=color, alpha=0.85)
        if fit is not None:
            th_f, rgb_f = fit
            pos = rgb_f[:, c] > 0
            ax.plot(_style.warp_theta_h(th_f[pos]), rgb_f[pos, c], "-", lw=1.3, color=color)
    ax.set_yscale("log")
    ax.yaxis.set_minor_formatter(NullFormatter())  # crowded, and slow to lay out
    ax.set_xlim(0.0, 1.0)
    _style.set_warped_theta_h_axis(ax)
    ax.set_ylabel("f_r  [1/sr]")
    ax.set_title(f"θd = {theta_d_deg:g}°", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)

def figure_size(n: int = len(THETA_D_DEG)) -> tuple[float, float]:
    """``(width, height)`` in inches of the peak figure of ``n`` panels (two a row)."""
    cols = 2 if n > 1 else 1
    return 5.2 * cols, 3.6 * int(np.ceil(n / cols))


def plot_peaks(data, model=None, params=None, *, theta_d_deg=THETA_D_DEG, phi_d_deg: float = 90.0,
               error: str | None = None, title: str | None = None, theta_d_tol_deg: float = 2.0,
               phi_tol_deg: float = 10.0, fig=None):
    """The specular-peak figure (module docstring); one panel per entry of ``theta_d_deg``.

    ``model``/``params`` are optional (measured only without them); ``error`` is title text;
    ``fig`` a figure or sub-figure to draw into (default: a new one). Returns the figure.
    """
    n = len(theta_d_deg)
    cols = 2 if n > 1 else 1
    rows = int(np.ceil(n / cols))
    fig = _style.new_figure(*figure_size(n), fig)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, td in zip(axes, theta_d_deg):
        meas = _measured_row(data, td, phi_d_deg, theta_d_tol_deg, phi_tol_deg)
        fit = None if model is None else _fitted_row(model, params, td, phi_d_deg)
        _draw_panel(ax, meas, fit, td)
    for ax in axes[n:]:
        ax.set_visible(False)
    handles = [Line2D([], [], color="k", marker="o", mfc="none", ls="none", label="measured")]
    if model is not None:
        handles.append(Line2D([], [], color="k", lw=1.3, label="fitted"))
    handles += [Line2D([], [], color=c, lw=3, label=ch)
                for c, ch in zip(_style.CHANNEL_COLORS, _style.CHANNEL_NAMES)]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9,
               frameon=False)
    name = getattr(model, "name", model) if model is not None else None
    fig.suptitle(title or _style.figure_title(
        data_name(data), name, error, f"Specular peak, φd = {phi_d_deg:g}°"))
    return fig
