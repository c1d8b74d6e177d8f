"""The BRDF image slice at φd = 90° (Burley 2012 §3.3, Fig. 3): measured, fitted, log ratio.

Layout follows Burley: θh runs left to right in MERL's stored (warped) coordinate
``sqrt(θh/90°)``, so the specular peak is the left edge; θd runs bottom to top, so the top edge is
the Fresnel peak (grazing) and the bottom edge retroreflection. Burley notes that all the
interesting features of the MERL materials are visible in this one slice.

* From a MERL table the slice is the table's own cells ``[:, :, k]`` with ``k`` the φd cell
  (90 for φd = 90°); the fit is evaluated at the same cells' lower-corner directions.
* From a sample set (no grid) the view is *binned*: samples with ``|φd − 90°| < phi_tol_deg``
  are averaged on a coarse (warped θh, θd) grid, and the fit is evaluated at the same samples and
  binned the same way, so both panels see identical coverage. Empty bins count as missing.
* From a measurement that evaluates itself (an RGL material, ``eval``) the slice is evaluated
  at the centres of a (warped θh, θd) grid with the half vector's azimuth φh = 0 (the plane of
  the file's x axis; an anisotropic material has other slices at other φh), measured and
  fitted at the same directions; cells with a direction below the horizon are missing.

Display: both images share one logarithmic tone mapping of the luminance
(:func:`._style.log_tonemap`: the measured median at 0.4, the measured 99.9th percentile at
white, hue kept), so the diffuse body, the Fresnel peak and the whole specular peak are all
readable; Burley's Fig. 1 uses an exposure and gamma instead, which saturates the peak (every
cell with θh below about 8° is white on a shiny MERL material). The ratio panel is
``log10((fit + ε)/(measured + ε))`` (ε of :mod:`.error`),
the Rec. 709-weighted mean over the channels, on a diverging colormap with symmetric limits; its
colour bar is labelled in factors (``×2``, ``×0.5``), what a person reads off a ratio.
Missing cells are drawn in :data:`._style.MISSING_RGB`.
"""

from __future__ import annotations

import numpy as np
from matplotlib.patches import Patch

from . import _style
from ._eval import (data_name, evaluate_model, is_table, measured_lookup, sample_view,
                    warped_coords)
from .error import log_ratio


def _table_slice(table, model, params, k: int):
    from data_formats.merl import cell_angles
    from data_formats.rusinkiewicz import dirs_from_half_diff

    n_th, n_td = np.shape(table.valid)[:2]
    i, j = np.meshgrid(np.arange(n_th), np.arange(n_td), indexing="ij")
    meas = np.asarray(table.rgb, float)[:, :, k]
    valid = np.asarray(table.valid, bool)[:, :, k] & np.all(np.isfinite(meas), axis=-1)
    fit = None
    if model is not None:
        wi, wo = dirs_from_half_diff(*cell_angles(i, j, np.full_like(i, k), np.shape(table.valid)))
        fit = evaluate_model(model, params, wi, wo)
    return meas, valid, fit


def _binned_slice(samples, model, params, phi_d_deg: float, tol_deg: float, bins: int):
    ok = np.asarray(samples.valid, bool) & np.all(np.isfinite(samples.rgb), axis=-1)
    wi, wo, rgb = samples.wi[ok], samples.wo[ok], np.asarray(samples.rgb, float)[ok]
    u = warped_coords(wi, wo)
    near = np.abs(u[:, 2] * 180.0 - phi_d_deg) < tol_deg
    u, wi, wo, rgb = u[near], wi[near], wo[near], rgb[near]
    ih = np.clip((u[:, 0] * bins).astype(int), 0, bins - 1)
    jd = np.clip((u[:, 1] * bins).astype(int), 0, bins - 1)
    flat = ih * bins + jd
    count = np.bincount(flat, minlength=bins * bins).reshape(bins, bins)

    def binned(values):
        sums = [np.bincount(flat, values[:, c], minlength=bins * bins) for c in range(3)]
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.stack(sums, axis=-1).reshape(bins, bins, 3) / count[..., None]

    fit = None
    if model is not None and len(wi):
        fit = binned(evaluate_model(model, params, wi, wo))
    elif model is not None:  # no samples near the slice: an all-missing fitted panel, not none
        fit = np.full((bins, bins, 3), np.nan)
    return binned(rgb), count > 0, fit


def _evaluated_slice(data, model, params, phi_d_deg: float, bins: int):
    from data_formats.rusinkiewicz import dirs_from_half_diff

    centre = (np.arange(bins) + 0.5) / bins
    uh, ud = np.meshgrid(centre, centre, indexing="ij")
    th, td = np.radians(_style.unwarp_theta_h(uh)), ud * np.pi / 2
    wi, wo = (np.asarray(w, float) for w in
              dirs_from_half_diff(th, td, np.full_like(th, np.radians(phi_d_deg))))
    meas = measured_lookup(data)(wi, wo)
    valid = np.all(np.isfinite(meas), axis=-1)
    fit = evaluate_model(model, params, wi, wo) if model is not None else None
    return np.where(valid[..., None], meas, 0.0), valid, fit


def slice_data(data, model=None, params=None, *, phi_d_deg: float = 90.0, phi_tol_deg: float = 10.0,
               bins: int = 45):
    """``(measured, valid, fitted)`` of the slice, each indexed ``[θh cell, θd cell]``.

    ``measured`` and ``fitted`` are ``(n_th, n_td, 3)`` (``fitted`` is None without a model);
    ``valid`` ``(n_th, n_td)``. Cell ``(i, j)`` spans warped θh ``[i, i+1]/n_th`` and θd
    ``[j, j+1]·90°/n_td``. Tables give their own cells; sample sets a ``bins × bins`` binning.
    """
    if is_table(data):
        n_pd = np.shape(data.valid)[2]
        k = int(np.clip(np.floor(phi_d_deg / 180.0 * n_pd), 0, n_pd - 1))
        return _table_slice(data, model, params, k)
    if callable(getattr(data, "eval", None)):
        return _evaluated_slice(data, model, params, phi_d_deg, bins)
    return _binned_slice(sample_view(data), model, params, phi_d_deg, phi_tol_deg, bins)


def _show_rgb(ax, rgb, valid, levels, title):
    img = _style.log_tonemap(rgb, *levels)
    img[~valid] = _style.MISSING_RGB
    ax.imshow(np.transpose(img, (1, 0, 2)), origin="lower", extent=(0, 1, 0, 90),
              aspect="auto", interpolation="nearest")
    _decorate(ax, title)


def _decorate(ax, title):
    ax.set_title(title, fontsize=10)
    _style.set_warped_theta_h_axis(ax)
    ax.set_ylabel("θd")
    ax.set_yticks([0, 15, 30, 45, 60, 75, 90], [f"{t}°" for t in range(0, 91, 15)])


def _show_ratio(fig, ax, meas, fit, valid):
    ratio = log_ratio(fit, meas) / np.log(10.0)
    lum = np.where(valid, np.tensordot(ratio, _style.LUMA, axes=([-1], [0])), np.nan)
    finite = np.abs(lum[np.isfinite(lum)])
    vlim = max(float(np.percentile(finite, 99)) if finite.size else 0.0, 0.02)
    cmap = _style.diverging_cmap()
    im = ax.imshow(lum.T, origin="lower", extent=(0, 1, 0, 90), aspect="auto",
                   interpolation="nearest", cmap=cmap, vmin=-vlim, vmax=vlim)
    _decorate(ax, "fitted ÷ measured, per cell (log scale)")
    bar = fig.colorbar(im, ax=ax, label="fitted ÷ measured  (red: fit too bright)", shrink=0.9)
    ticks = ratio_ticks(vlim)
    bar.set_ticks(ticks, labels=[f"×{10.0 ** t:.3g}" for t in ticks])


#: Factors a ratio's colour bar may mark (and their inverses).
RATIO_FACTORS = (1.01, 1.02, 1.05, 1.1, 1.2, 1.5, 2.0, 3.0, 5.0, 10.0, 30.0, 100.0, 1000.0)


def ratio_ticks(vlim: float, per_side: int = 3) -> list[float]:
    """log10 positions of the colour bar's ticks within ``±vlim``: 1 and the ``per_side``
    largest :data:`RATIO_FACTORS` that fit, with their inverses."""
    up = [float(np.log10(f)) for f in RATIO_FACTORS if np.log10(f) <= vlim * (1 + 1e-9)]
    up = up[-per_side:]
    return [-t for t in reversed(up)] + [0.0] + up

def figure_size(fitted: bool) -> tuple[float, float]:
    """``(width, height)`` in inches of the slice figure, with or without the fit's panels."""
    return (3 * 4.6 + 0.8, 4.6) if fitted else (4.6, 4.6)


def plot_slice(data, model=None, params=None, *, error: str | None = None,
               phi_d_deg: float = 90.0, title: str | None = None, fig=None):
    """The image-slice figure (see the module docstring); returns a matplotlib ``Figure``.

    Args:
        data: a MERL table or a :class:`data_formats.SampleSet`.
        model, params: a fitted model (a :class:`brdffit.Model` or registry name) and its
            parameters; without them only the measured slice is drawn.
        error: text for the title (default: none; :func:`brdffit.plots.diagnostics` passes the
            fit's ``rmse_log``, :mod:`.error`).
        phi_d_deg: the φd of the slice. title: replaces the generated title.
        fig: a figure or sub-figure to draw into (default: a new one of this view's size).
    """
    meas, valid, fit = slice_data(data, model, params, phi_d_deg=phi_d_deg)
    levels = _style.log_levels(meas[valid])
    kind = ("" if is_table(data) else " (evaluated, φh = 0°)"
            if callable(getattr(data, "eval", None))
            else f" (samples binned, |φd−{phi_d_deg:g}°|<10°)")
    panels = 1 if fit is None else 3
    fig = _style.new_figure(*figure_size(fit is not None), fig)
    axes = np.atleast_1d(fig.subplots(1, panels))
    _show_rgb(axes[0], meas, valid, levels, f"measured{kind}\n{_style.tonemap_label(*levels)}")
    if fit is not None:
        _show_rgb(axes[1], fit, valid, levels, "fitted\n(same tone mapping)")
        _show_ratio(fig, axes[2], meas, fit, valid)
    if not valid.all():
        axes[0].legend(handles=[Patch(color=_style.MISSING_RGB, label="no measurement")],
                       loc="lower right", fontsize=8)
    name = getattr(model, "name", model) if model is not None else None
    fig.suptitle(title or _style.figure_title(
        data_name(data), name, error, f"Image slice φd = {phi_d_deg:g}°"))
    return fig
