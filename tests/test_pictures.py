"""Figures a person can read: the tone mapping shows the specular peak and the diffuse body at
once, and the corner plot's titles and labels are legible (digits follow the uncertainty, no
text overlaps). NumPy-built tables: no fitting, no JAX programs."""

import types

import matplotlib.image as mpimg
import numpy as np
import pytest

from brdffit.plots import plot_slice, plot_spheres
from brdffit.plots._style import log_tonemap, save_png
from brdffit.posterior.plot import corner_plot, interval_digits
from data_formats.merl import MERLTable


def shiny_table():
    """A gold-paint-like table: diffuse 0.02–0.1 /sr, a sharp peak of ~4000 /sr at θh = 0
    (falling with θh over the first few cells), a Fresnel rise towards grazing θd."""
    i = np.arange(90)[:, None, None, None]
    j = np.arange(90)[None, :, None, None]
    theta_h = (i / 90.0) ** 2 * 90.0
    diffuse = np.array([0.10, 0.06, 0.02]) / np.pi
    peak = 4000.0 * np.exp(-(theta_h / 3.0) ** 2) * np.array([0.9, 0.6, 0.3])
    fresnel = 0.5 * (j / 89.0) ** 8
    rgb = np.broadcast_to(diffuse + peak + fresnel, (90, 90, 180, 3)).copy()
    return MERLTable.from_rgb(rgb, np.ones((90, 90, 180), bool), name="gold-like")


def panel_pixels(fig, png, k):
    ax = fig.axes[k]
    h = png.shape[0]
    x0, y0, x1, y1 = ax.get_window_extent().extents
    return png[int(h - y1) + 2 : int(h - y0) - 2, int(x0) + 2 : int(x1) - 2, :3]


def test_slice_shows_peak_and_diffuse_at_once(tmp_path):
    fig = plot_slice(shiny_table())
    png = mpimg.imread(save_png(fig, tmp_path / "slice.png"))
    panel = panel_pixels(fig, png, 0)
    lum = panel @ np.array([0.2126, 0.7152, 0.0722])  # displayed luminance
    rows, cols = lum.shape
    at = lambda theta_h: lum[rows // 2 :, int(np.sqrt(theta_h / 90.0) * cols)].mean()  # noqa: E731
    # inside the peak (θh < 8°, all white under an exposure set by the diffuse body) the
    # brightness still falls with θh: the peak's shape is visible
    assert at(3.0) < 0.97 and at(3.0) > at(5.0) + 0.05 and at(5.0) > at(7.0) + 0.05
    # the diffuse body (θh > 40°) is neither black nor white
    assert 0.15 < lum[rows // 2 :, -cols // 3 :].mean() < 0.7


def test_lit_sphere_of_a_shiny_material_is_not_black_apart_from_its_highlight(tmp_path):
    fig = plot_spheres(shiny_table(), size=96)
    png = mpimg.imread(save_png(fig, tmp_path / "sphere.png"))
    panel = panel_pixels(fig, png, 0)
    lum = panel.max(axis=-1)
    lit = lum > 0.02  # the sphere's lit part (the background and the unlit crescent are black)
    assert lit.mean() > 0.3
    assert np.median(lum[lit]) > 0.25  # the diffuse body reads, not only the highlight


def test_log_tonemap_keeps_hue_and_orders_brightness():
    rgb = np.array([[0.0, 0.0, 0.0], [0.03, 0.02, 0.01], [0.3, 0.2, 0.1], [3000.0, 2000.0, 1000.0]])
    out = log_tonemap(rgb, ref=0.02, top=2000.0)
    assert np.all(out[0] == 0)
    np.testing.assert_allclose(out[1] / out[1].max(), [1, 2 / 3, 1 / 3])  # chromaticity kept
    y = out @ np.array([0.2126, 0.7152, 0.0722])
    assert y[3] == pytest.approx(1.0)  # the peak: clipped channels topped up with white
    assert out[1].max() < out[2].max() < out[3].max() <= 1.0


def test_interval_digits_follow_the_uncertainty():
    assert interval_digits(0.0799904, 0.08, 0.08000958) == ("0.0800000", "0.0000096", "0.0000096")
    assert interval_digits(0.0987, 0.1000, 0.1012) == ("0.1000", "0.0012", "0.0013")
    assert interval_digits(119.0, 123.4, 130.0) == ("123.4", "6.6", "4.4")
    assert interval_digits(100.0, 150.0, 200.0) == ("150", "50", "50")


def test_corner_plot_text_does_not_overlap(tmp_path):
    rng = np.random.default_rng(0)
    names = ["diffuse[0]", "diffuse[1]", "diffuse[2]", "f0[0]", "alpha"]
    centre = np.array([0.1, 0.06, 0.02, 0.9, 0.08])
    samples = centre + rng.normal(size=(4000, 5)) * np.array([1e-3, 1e-3, 5e-4, 6e-4, 1e-5])
    pct = np.percentile(samples, [16, 50, 84], axis=0)
    result = types.SimpleNamespace(
        sampled=names, names=names, x_ls=centre, samples=samples, model_name="ggx",
        table="t", percentiles={n: list(pct[:, k]) for k, n in enumerate(names)})
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = corner_plot(result, tmp_path / "corner.png")
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    texts = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        drawn = [t for t in ax.get_xticklabels() if x0 <= t.get_position()[0] <= x1]
        drawn += [t for t in ax.get_yticklabels() if y0 <= t.get_position()[1] <= y1]
        for t in [ax.title, ax.xaxis.label, ax.yaxis.label, *drawn]:  # ticks in view only
            if t.get_visible() and t.get_text():
                texts.append((t.get_text(), t.get_window_extent(renderer)))
    assert any("alpha" in s and "^{+0.0000" in s for s, _ in texts)  # digits of the error
    clashes = [(a, b) for k, (a, ba) in enumerate(texts) for b, bb in texts[k + 1 :]
               if ba.overlaps(bb)]
    assert not clashes, clashes[:5]
