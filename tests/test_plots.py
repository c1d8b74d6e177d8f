"""Diagnostic plots: the numbers behind each figure against independent references, and the PNGs.

Tables are synthesized in memory (never written as .binary); PNGs go to ``tmp_path``.
"""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest

from brdffit import get_model
from brdffit.models import Model, Param
from brdffit.plots import (
    diagnostics,
    directional_albedo,
    evaluate_model,
    figure_paths,
    measured_albedo,
    measured_lookup,
    model_albedo,
    plot_peaks,
    plot_slice,
    render_sphere,
    rms_log_error,
    save_png,
    slice_data,
)
from brdffit.plots.sphere import DEFAULT_LIGHT, sphere_directions
from brdffit.terms.diffuse import lambert
from data_formats import MERLTable, SampleSet, synthesize

RHO = np.array([0.2, 0.5, 0.8])
GGX = get_model("ggx")
GGX_TRUE = {"diffuse": np.array([0.3, 0.12, 0.05]), "f0": np.full(3, 0.05), "alpha": 0.1}
# A plain Lambert model (not registered): albedo exactly ρ, used as a closed-form reference.
LAMBERT = Model("lambert-only", "Lambert", (Param("diffuse", (3,), 0.0, 1.0, 0.5, "albedo"),),
                fn=lambda p, wi, wo: lambert(p["diffuse"], wi, wo))


@pytest.fixture(scope="module")
def lambert_table():
    return synthesize(lambda wi, wo: np.broadcast_to(RHO / np.pi, wi.shape), name="lambert")


@pytest.fixture(scope="module")
def ggx_table():
    return synthesize(lambda wi, wo: evaluate_model(GGX, GGX_TRUE, wi, wo), name="ggx-synth")


def test_evaluate_model_chunks_and_padding_match_direct_call():
    rng = np.random.default_rng(1)
    wi = rng.normal(size=(23, 3)) * [1, 1, 0.3] + [0, 0, 1]
    wo = rng.normal(size=(23, 3)) * [1, 1, 0.3] + [0, 0, 1]
    wi, wo = (w / np.linalg.norm(w, axis=-1, keepdims=True) for w in (wi, wo))
    direct = np.asarray(GGX(GGX_TRUE, wi, wo))
    np.testing.assert_allclose(evaluate_model(GGX, GGX_TRUE, wi, wo, chunk=7), direct, rtol=1e-12)


# -- directional albedo ---------------------------------------------------------------------------

def test_albedo_of_lambertian_table_is_rho(lambert_table):
    theta = np.linspace(0.0, 89.0, 30)
    got = measured_albedo(lambert_table, theta)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, np.broadcast_to(RHO, got.shape), atol=2e-3)


def test_albedo_of_lambert_model_is_rho_closely():
    got = model_albedo(LAMBERT, {"diffuse": RHO}, np.array([0.0, 45.0, 80.0, 89.0]))
    np.testing.assert_allclose(got, np.broadcast_to(RHO, got.shape), atol=1e-3)


def test_albedo_of_ggx_table_matches_the_model(ggx_table):
    theta = np.array([0.0, 35.0, 70.0])
    np.testing.assert_allclose(measured_albedo(ggx_table, theta),
                               model_albedo(GGX, GGX_TRUE, theta), atol=2e-3)


def _albedo_in_omega_o(fn, theta_i_deg, n=250):
    """Independent reference: Gauss–Legendre in θo × midpoint in φo over the outgoing hemisphere."""
    x, w = np.polynomial.legendre.leggauss(n)
    th, wt = (x + 1) * np.pi / 4, w * np.pi / 4
    ph = (np.arange(n) + 0.5) * 2 * np.pi / n
    wo = np.stack(np.broadcast_arrays(np.sin(th)[:, None] * np.cos(ph),
                                      np.sin(th)[:, None] * np.sin(ph), np.cos(th)[:, None]), -1)
    weight = (wt * np.sin(th) * np.cos(th))[:, None] * np.full(n, 2 * np.pi / n)
    out = []
    for t in np.radians(theta_i_deg):
        wi = np.broadcast_to([np.sin(t), 0.0, np.cos(t)], (n * n, 3))
        out.append(weight.ravel() @ fn(wi, wo.reshape(-1, 3)))
    return np.array(out)


@pytest.mark.parametrize("alpha", [0.15, 0.5])
def test_albedo_of_ggx_model_matches_omega_o_quadrature(alpha):
    params = {"diffuse": np.array([0.3, 0.1, 0.0]), "f0": np.array([0.9, 0.5, 0.04]),
              "alpha": alpha}
    theta = np.array([0.0, 40.0, 70.0])
    got = model_albedo(GGX, params, theta)
    ref = _albedo_in_omega_o(lambda wi, wo: evaluate_model(GGX, params, wi, wo), theta)
    np.testing.assert_allclose(got, ref, atol=1e-3)
    assert np.all(got[:, 0] > got[:, 2])  # the redder f0 and diffuse reflect more red


def test_albedo_coverage_reports_missing_data():
    def half_known(wi, wo):  # a white Lambertian with data only where wo_y > 0
        return np.where(wo[:, 1:2] > 0, 1 / np.pi, np.nan) * np.ones(3)

    albedo, coverage = directional_albedo(half_known, np.array([0.0]))
    np.testing.assert_allclose(coverage, [0.5], atol=1e-3)  # φo in (0, π): half the hemisphere
    np.testing.assert_allclose(albedo, [[0.5, 0.5, 0.5]], atol=1e-3)


# -- lit sphere ----------------------------------------------------------------------------------

def test_sphere_of_lambertian_table_is_rho_over_pi_cos(lambert_table):
    size = 64
    img = render_sphere(measured_lookup(lambert_table), size)
    light = np.asarray(DEFAULT_LIGHT) / np.linalg.norm(DEFAULT_LIGHT)
    for row, col in [(32, 32), (10, 32), (40, 20), (25, 50), (55, 32)]:
        x, y = (col + 0.5) / size * 2 - 1, 1 - (row + 0.5) / size * 2
        n = np.array([x, y, np.sqrt(1 - x * x - y * y)])
        np.testing.assert_allclose(img[row, col], RHO / np.pi * max(n @ light, 0.0), rtol=2e-3)
    assert np.all(img[0, 0] == 0) and np.all(img[63, 63] == 0)  # background is black


def test_sphere_shading_frames_are_orthonormal_and_keep_angles():
    inside, n, wi, wo = sphere_directions(48, (0.3, -0.2, 0.9))
    light = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    np.testing.assert_allclose(np.linalg.norm(wi, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(wi[..., 2], n @ light, atol=1e-12)  # cos θi = n·l
    np.testing.assert_allclose(wo[..., 2], n[..., 2], atol=1e-12)  # cos θo = n·v, v = z
    np.testing.assert_allclose(np.sum(wi * wo, -1), np.broadcast_to(light[2], inside.shape),
                               atol=1e-12)  # the frame is a rotation: l·v is preserved


def test_sphere_brightest_where_normal_meets_light():
    size = 128
    img = render_sphere(lambda wi, wo: evaluate_model(LAMBERT, {"diffuse": RHO}, wi, wo), size)
    row, col = np.unravel_index(np.argmax(img[..., 1]), img.shape[:2])
    light = np.asarray(DEFAULT_LIGHT) / np.linalg.norm(DEFAULT_LIGHT)
    expect_col, expect_row = (light[0] + 1) / 2 * size, (1 - light[1]) / 2 * size
    assert abs(col + 0.5 - expect_col) <= 1.0 and abs(row + 0.5 - expect_row) <= 1.0


# -- image slice and peaks ------------------------------------------------------------------------

def test_slice_fitted_equals_measured_for_the_true_model(ggx_table):
    meas, valid, fit = slice_data(ggx_table, GGX, GGX_TRUE)
    assert meas.shape == fit.shape == (90, 90, 3) and valid.all()
    np.testing.assert_allclose(fit, meas, rtol=1e-12)
    assert rms_log_error(ggx_table, GGX, GGX_TRUE) < 1e-10


def test_error_figure_is_the_rms_log_ratio(lambert_table):
    scaled = {"diffuse": 1.1 * RHO}
    f = RHO / np.pi
    expect = np.sqrt(np.mean(np.log((1.1 * f + 1e-3) / (f + 1e-3)) ** 2))
    np.testing.assert_allclose(rms_log_error(lambert_table, LAMBERT, scaled), expect, rtol=1e-9)


def test_slice_puts_a_known_peak_in_the_right_place(tmp_path):
    i0, j0 = 30, 60  # θh = (30/90)² · 90° = 10°, θd = 60°
    rgb = np.full((90, 90, 180, 3), 0.02)
    rgb[i0 - 1 : i0 + 2, j0 - 1 : j0 + 2] = 50.0
    valid = np.ones((90, 90, 180), bool)
    valid[70:75, 10:15] = False
    table = MERLTable.from_rgb(rgb, valid, name="bump")
    meas, ok, _ = slice_data(table)
    assert np.unravel_index(np.argmax(meas[..., 0]), meas.shape[:2]) == (i0 - 1, j0 - 1)
    assert not ok[70:75, 10:15].any() and ok.sum() == 90 * 90 - 25
    binned, have, _ = slice_data(table.to_samples())  # 45 × 45 bins of the samples near φd = 90°
    peak = np.unravel_index(np.nanargmax(binned[..., 0]), binned.shape[:2])
    assert abs(peak[0] - 15) <= 1 and abs(peak[1] - 30) <= 1 and have[peak]
    assert not have[36, 6] and np.isnan(binned[36, 6]).all()  # inside the missing patch
    fig = plot_slice(table)
    png = mpimg.imread(save_png(fig, tmp_path / "slice.png"))
    ax = fig.axes[0]
    height = png.shape[0]
    x0, y0, x1, y1 = ax.get_window_extent().extents
    panel = png[int(height - y1) + 1 : int(height - y0) - 1, int(x0) + 1 : int(x1) - 1, :3]
    lum = panel.mean(axis=-1)
    rows, cols = np.nonzero(lum > 0.98 * lum.max())
    px, py = ax.transData.transform((i0 / 90 + 0.5 / 90, j0 + 0.5))  # bump centre, display px
    top, left = int(height - y1) + 1, int(x0) + 1  # the panel's corner in PNG rows/columns
    assert abs(cols.mean() + left - px) < 3 and abs(rows.mean() + top - (height - py)) < 3
    missing = panel[np.all(np.abs(panel - np.array([0.55, 0.0, 0.55])) < 0.02, axis=-1)]
    assert len(missing) > 50  # the missing cells are drawn in their own colour


def test_peak_curves_pass_through_the_cells_of_the_true_model(ggx_table):
    fig = plot_peaks(ggx_table, GGX, GGX_TRUE, theta_d_deg=(30.0,))
    lines = fig.axes[0].get_lines()
    markers, curve = lines[0], lines[1]  # red: measured markers, then the fitted line
    x_m, y_m = markers.get_xdata(), markers.get_ydata()
    assert y_m.size == 90  # every cell of the row is valid and positive
    np.testing.assert_allclose(y_m, ggx_table.rgb[:, 30, 90, 0], rtol=1e-12)
    y_c = np.interp(x_m, curve.get_xdata(), np.log(curve.get_ydata()))
    inner = (x_m > 0.05) & (x_m < 0.95)  # the interpolated line is accurate away from the ends
    np.testing.assert_allclose(y_c[inner], np.log(y_m[inner]), atol=0.02)


# -- files ----------------------------------------------------------------------------------------

def test_figure_paths_names():
    assert [p.name for p in figure_paths("out/fig.png")] == [
        "fig-slice.png", "fig-peaks.png", "fig-albedo.png", "fig-spheres.png"]


def test_diagnostics_unknown_figure_name_lists_choices(lambert_table, tmp_path):
    with pytest.raises(ValueError, match="unknown figure 'slices'.*valid choices: albedo, peaks"):
        diagnostics(lambert_table, path=tmp_path / "f.png", only=["slices"])


def test_measured_only_figures(lambert_table, tmp_path):
    paths = diagnostics(lambert_table, path=tmp_path / "m.png", only=("peaks", "albedo", "spheres"))
    assert [p.name for p in paths] == ["m-peaks.png", "m-albedo.png", "m-spheres.png"]
    assert _check_png(paths[2], min_size=(300, 300)).shape[:2] == (506, 451)  # one sphere
    fig = plot_peaks(lambert_table)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["measured", "R", "G", "B"] and "lambert" in fig.get_suptitle()


def test_sparse_samples_leave_honest_holes():
    rng = np.random.default_rng(3)
    wi, wo = (np.abs(rng.normal(size=(40, 3))) for _ in range(2))
    wi, wo = (w / np.linalg.norm(w, axis=-1, keepdims=True) for w in (wi, wo))
    sparse = SampleSet(wi, wo, np.full((40, 3), 0.1), np.ones(40, bool), name="sparse")
    assert np.isnan(measured_albedo(sparse, [0.0, 60.0])).all()  # coverage far below 0.9
    meas, have, fit = slice_data(sparse, GGX, GGX_TRUE)
    assert have.sum() <= 40 and np.isnan(meas[~have]).all() and fit.shape == meas.shape
    img = render_sphere(measured_lookup(sparse), 32)
    assert np.isfinite(img).all() and (img == 0).all(axis=-1).mean() > 0.5  # holes are black


def _check_png(path, min_size=(300, 500)):
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] >= min_size[0] and img.shape[1] >= min_size[1]
    assert img[..., :3].std() > 0.05  # not blank
    return img


def test_diagnostics_writes_four_readable_pngs(ggx_table, tmp_path):
    fit = dict(GGX_TRUE, alpha=0.12)
    paths = diagnostics(ggx_table, GGX, fit, path=tmp_path / "fig.png")
    assert [p.name for p in paths] == [p.name for p in figure_paths(tmp_path / "fig.png")]
    sizes = {p.name: _check_png(p).shape[:2] for p in paths}
    assert sizes["fig-slice.png"] == (506, 1606)  # 14.6 × 4.6 in at 110 dpi
    assert sizes["fig-spheres.png"] == (506, 902)
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind


def test_diagnostics_from_a_sample_set(ggx_table, tmp_path):
    s = ggx_table.to_samples()
    idx = np.random.default_rng(0).choice(len(s), 150_000, replace=False)
    samples = SampleSet(s.wi[idx], s.wo[idx], s.rgb[idx], s.valid[idx], name="subsampled")
    np.testing.assert_allclose(measured_albedo(samples, [0.0, 45.0])[:, 0],
                               model_albedo(GGX, GGX_TRUE, [0.0, 45.0])[:, 0], rtol=0.03)
    paths = diagnostics(samples, GGX, GGX_TRUE, path=tmp_path)
    assert [p.name for p in paths] == ["slice.png", "peaks.png", "albedo.png", "spheres.png"]
    for p in paths:
        _check_png(p)
