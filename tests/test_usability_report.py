"""A fit in a notebook: figures returned and shown inline (``result.plot()``, ``post.corner()``),
lmfit's report (``fit_report``, the HTML view, correlations, AIC/BIC) and one vocabulary of
error metrics (:mod:`brdffit.metrics`) in the summary, the report, the figures and the JSON.

One small synthetic table written to disk and one fit of it, shared by the module."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from matplotlib.figure import Figure

import brdffit
from data_formats.merl import read_merl, synthesize, write_merl

TRUTH = {"diffuse": (0.10, 0.06, 0.02), "f0": (0.90, 0.60, 0.30), "alpha": 0.12}
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def table_path(tmp_path_factory):
    from brdffit.models.evaluate import evaluate_model

    rng = np.random.default_rng(0)
    ggx = brdffit.get_model("ggx")

    def noisy(wi, wo):
        clean = evaluate_model(ggx, TRUTH, wi, wo)
        return clean * (1 + 0.02 * rng.standard_normal((*wi.shape[:-1], 3)))

    path = tmp_path_factory.mktemp("usability") / "gold-small.binary"
    write_merl(path, synthesize(noisy, name=path.stem, shape=(16, 16, 32)))
    return path


@pytest.fixture(scope="module")
def result(table_path):
    return brdffit.fit(table_path, "ggx")


def shown_inline(obj) -> dict:
    """What IPython's display formatters make of ``obj`` (the mime bundle of a cell's value)."""
    from IPython.core.formatters import DisplayFormatter

    return DisplayFormatter().format(obj)[0]


# -- figures returned, shown inline (the CLI's files unchanged) --------------------------------
def test_result_plot_returns_one_figure_of_the_four_views_shown_inline(result):
    fig = result.plot()
    assert isinstance(fig, Figure)
    titles = [sub.get_suptitle() for sub in fig.subfigs for sub in (sub.subfigs or [sub])]
    views = ("Image slice", "Specular peak", "Directional albedo", "Lit sphere")
    assert [any(t.startswith(v) for t in titles) for v in views] == [True] * 4, titles
    assert shown_inline(fig)["image/png"][:8] == PNG  # not "<Figure size ...>"


def test_result_plot_of_data_in_memory_asks_for_them(result, table_path):
    in_memory = dataclasses.replace(result, provenance={})
    with pytest.raises(brdffit.BrdffitError, match=r"pass the data: result.plot\(table\)"):
        in_memory.plot()
    fig = in_memory.plot(read_merl(table_path), only="albedo")
    (row,) = fig.subfigs
    assert "Directional albedo" in row.subfigs[0].get_suptitle()


def test_a_single_view_figure_is_shown_inline_without_pyplot(table_path):
    from brdffit.plots import plot_albedo

    fig = plot_albedo(read_merl(table_path), "ggx", TRUTH)
    assert shown_inline(fig)["image/png"][:8] == PNG


def test_posterior_corner_returns_a_figure_and_corner_plot_still_writes_one(tmp_path):
    from brdffit.posterior import Diagnostics, PosteriorResult

    rng = np.random.default_rng(1)
    samples = rng.normal([0.12, 0.9], [0.001, 0.01], size=(400, 2))
    post = PosteriorResult(
        model_name="ggx", table="t", names=["alpha", "f90"], free=["alpha", "f90"], fixed=[],
        sampled=["alpha", "f90"], params={"alpha": 0.12, "f90": 0.9},
        percentiles={n: list(np.percentile(samples[:, i], [16, 50, 84]))
                     for i, n in enumerate(["alpha", "f90"])},
        std={"alpha": 0.001, "f90": 0.01}, x_ls=np.array([0.12, 0.9]),
        stderr_ls={"alpha": 0.001, "f90": 0.01}, samples=samples, chain=samples[None],
        log_prob=np.zeros((1, 400)), noise={"mode": "fixed", "sigma": 0.02}, prior={},
        diagnostics=Diagnostics(0.3, 0.2, 0.4, {}, {}, 400, 50, False, ()), settings={},
        wall_time=0.0, timings={})
    fig = post.corner()
    assert isinstance(fig, Figure) and len(fig.axes) == 4
    assert shown_inline(fig)["image/png"][:8] == PNG
    written = post.corner_plot(tmp_path / "corner.png")
    assert isinstance(written, Figure)
    assert (tmp_path / "corner.png").read_bytes()[:8] == PNG


# -- one vocabulary of metrics -----------------------------------------------------------------
def test_the_metric_table_names_every_metric_of_a_fit_in_its_order(result):
    from brdffit.metrics import METRICS, metrics_text

    assert set(result.metrics) == set(METRICS)
    summary_line = next(line for line in result.summary().splitlines() if "rmse_log" in line)
    assert summary_line.strip() == metrics_text(result.metrics)
    assert [n for n in METRICS if n in summary_line] == list(METRICS)
    back = json.loads(result.to_json())["metrics"]
    assert set(back) == set(METRICS)
    report = result.report()
    for m in METRICS.values():  # the report says what each metric is
        assert m.label in report and m.formula in report


def test_the_relative_floor_is_the_fitters(result):
    from brdffit.fitting.losses import RELATIVE_FLOOR
    from brdffit.metrics import RELATIVE_FLOOR as METRIC_FLOOR

    assert METRIC_FLOOR == RELATIVE_FLOOR


def test_figure_titles_state_the_summarys_rmse_log(result, table_path, tmp_path, monkeypatch):
    """Titles said ``RMS ln-ratio 0.0197`` beside a summary's ``rmse_log 0.01011``: another
    metric, another value. A figure of a result states the result's own value; a figure of a
    model without a result computes the same formula, equal to the fit's over the same cells."""
    from brdffit import plots
    from brdffit.metrics import metric_text

    stated = metric_text("rmse_log", result.metrics["rmse_log"])
    assert stated in result.summary() and stated in result.report()
    fig = result.plot(only=("slice", "spheres"))
    titles = [sub.get_suptitle() for row in fig.subfigs for sub in (row.subfigs or [row])]
    assert titles and all(stated in t for t in titles if t), titles


def test_written_figures_state_the_same_rmse_log(result, table_path, tmp_path, monkeypatch):
    """The PNGs of a model and its parameters (``brdffit.plots.diagnostics``, no result) and
    those of the command line (``brdffit plot --fit``) state the fit's ``rmse_log``."""
    from brdffit import plots
    from brdffit.cli.plotting import write_figures

    stated = f"rmse_log {result.metrics['rmse_log']:.4g}"
    seen = []
    monkeypatch.setattr(plots, "save_png", lambda f, p: seen.append(f.get_suptitle()) or p)
    plots.diagnostics(read_merl(table_path), "ggx", result.params, path=tmp_path / "f.png")
    assert len(seen) == 4 and all(stated in t for t in seen), (stated, seen)
    seen.clear()
    failed = dataclasses.replace(result, success=False)
    try:  # the command line's writer takes the result
        write_figures(read_merl(table_path), tmp_path / "g.png", failed)
    except TypeError:  # its old signature: model=, params=, converged=
        write_figures(read_merl(table_path), tmp_path / "g.png", model=brdffit.get_model("ggx"),
                      params=result.params, converged=False)
    assert len(seen) == 4 and all(f"{stated} (fit NOT converged)" in t for t in seen), seen


def test_captions_are_written_for_people(table_path):
    from brdffit.plots import plot_slice, plot_spheres

    table = read_merl(table_path)
    texts = []
    for fig in (plot_slice(table, "ggx", TRUTH), plot_spheres(table, "ggx", TRUTH, size=32)):
        texts += [t.get_text() for t in fig.findobj(match=lambda a: hasattr(a, "get_text"))]
    captions = [t for t in texts if "brightness" in t or "luminance" in t]
    assert captions, texts
    for text in captions:
        assert "mid-grey" in text and "/sr" in text, text
        assert "e+" not in text and "→ 0.4" not in text, text


# -- the report ----------------------------------------------------------------------------------
def test_fit_report_text_has_lmfits_sections(result):
    text = brdffit.fit_report(result)
    assert text == result.report()
    for part in ("[[Fit]]", "[[Metrics]]", "[[Variables]]", "[[Correlations]]", "χ²",
                 "AIC, BIC", "same data only", f"in {result.steps} step"):
        assert part in text, part
    alpha = next(line for line in text.splitlines() if line.strip().startswith("alpha"))
    init = result.init["alpha"]
    assert f"init {init:.4g}" in alpha and "[0.001, 1]" in alpha and "free" in alpha
    assert "±" in alpha


def test_html_report_holds_what_lmfit_shows_in_about_5_kb(result):
    page = result._repr_html_()
    assert 3_000 < len(page.encode()) < 10_000, len(page.encode())
    for part in ("initial", "bounds", "status", "AIC", "BIC", "χ²", "reduced χ²", "step",
                 "correlation", "same data only", *result.metrics):
        assert part in page, part
    assert page.count("<tr><td>") >= len(result.names)  # a row per scalar


def test_correlation_comes_from_the_covariance_and_is_nan_without_an_error(result):
    from brdffit.fitting.report import strongest_correlations

    corr = result.correlation
    n = len(result.names)
    assert corr.shape == (n, n) and np.allclose(corr, corr.T, equal_nan=True)
    se = np.sqrt(np.diag(result.cov))
    ok = [result.names.index(f) for f in result.free  # the free scalars with an error bar
          if f not in result.at_bound and f not in result.not_identified]
    assert len(ok) >= 7
    expect = result.cov[np.ix_(ok, ok)] / np.outer(se[ok], se[ok])
    np.testing.assert_allclose(corr[np.ix_(ok, ok)], expect, rtol=1e-12)
    assert np.all(np.diag(corr)[ok] == 1.0)
    bound = dataclasses.replace(result, at_bound={"grazing": "upper"})  # no standard error
    k = result.names.index("grazing")
    assert np.all(np.isnan(bound.correlation[k])) and np.all(np.isnan(bound.correlation[:, k]))
    pairs = {(a, b): r for a, b, r in strongest_correlations(bound)}
    assert pairs and not any("grazing" in key for key in pairs)
    assert list(map(abs, pairs.values())) == sorted(map(abs, pairs.values()), reverse=True)


def test_aic_and_bic_are_lmfits_over_the_residuals(result):
    n, k = 3 * result.n_cells, len(result.free)
    chi2 = 2 * result.cost
    assert result.aic == pytest.approx(n * math.log(chi2 / n) + 2 * k, rel=1e-12)
    assert result.bic == pytest.approx(n * math.log(chi2 / n) + k * math.log(n), rel=1e-12)
