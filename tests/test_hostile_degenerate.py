"""Hostile input that the solver can 'fit' without the data saying anything: all zeros, a
constant, data at an absurd scale, a lobe switched off. The verdict must say so
(``success=False``, status ``degenerate`` or ``implausible``) and a parameter the data do not
identify gets no error bar; no NaN in the values, the metrics or the JSON."""

import json
import math

import jax.numpy as jnp
import numpy as np
import pytest

import brdffit
from brdffit.cli import main
from brdffit.errors import FitError
from data_formats import SampleSet
from data_formats.samplelist import write_samples

import realistic

N = 5000


@pytest.fixture(scope="module")
def cells():
    return realistic.merl_cells("nickel", N, seed=3)


def _table(cells, rgb, name):
    rgb = np.broadcast_to(rgb, cells.rgb.shape).copy()
    return SampleSet(cells.wi, cells.wo, rgb, cells.valid, name=name)


def _assert_no_nan_values(res):
    """Values, metrics, cost, covariance: finite (only a missing error bar may be NaN)."""
    assert np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.cov))
    assert math.isfinite(res.cost) and math.isfinite(res.optimality)
    assert all(math.isfinite(v) for v in res.metrics.values()), res.metrics


def _strict_json(res) -> dict:
    def refuse(token):
        raise AssertionError(f"{token} in the result's JSON")

    return json.loads(res.to_json(), parse_constant=refuse)


@pytest.mark.parametrize("value", [0.0, 0.3])
def test_information_free_data_is_degenerate_not_a_success(cells, value):
    """All zeros, or one constant: no angular information, so no lobe is determined."""
    res = brdffit.fit(_table(cells, value, "flat"), "ggx", throw=False)
    assert not res.success and res.status == "degenerate", (res.status, res.message)
    assert "no angular information" in res.message
    _assert_no_nan_values(res)
    assert "alpha" in res.not_identified and math.isnan(res.stderr["alpha"])
    d = _strict_json(res)
    assert d["success"] is False and d["stderr"]["alpha"] is None
    assert "alpha" in d["not_identified"]
    assert brdffit.FitResult.from_json(res.to_json()).not_identified == res.not_identified


def test_information_free_data_raise_with_throw(cells):
    with pytest.raises(FitError, match="is degenerate: the data are zero"):
        brdffit.fit(_table(cells, 0.0, "zero"), "ggx")


def test_a_switched_off_lobe_has_no_error_bar(cells):
    """f0 = 0 with no grazing rise switches ggx's lobe off: α changes nothing and gets no standard error
    (it had ``0.0225 ± 3.1e-5``); the diffuse albedo the data determine keeps its."""
    res = brdffit.fit(cells, "ggx", fixed={"f0": [0.0, 0.0, 0.0], "grazing": 0.0}, throw=False)
    assert res.success, res.message  # the fit itself converged; the data are not flat
    assert res.not_identified == ["alpha"] and math.isnan(res.stderr["alpha"])
    assert "not identified by the data" in res.message and "alpha" in res.message
    alpha_line = next(line for line in res.summary().splitlines() if " alpha =" in line)
    assert "±" not in alpha_line and "(not identified)" in alpha_line
    row = next(r for r in res.rows() if r["name"] == "alpha")
    assert row["status"] == "not identified" and math.isnan(row["stderr"])
    i = res.names.index("alpha")
    assert not np.any(res.cov[i]) and not np.any(res.cov[:, i])
    free_diffuse = [r for r in res.rows() if r["name"].startswith("diffuse") and r["status"] == "free"]
    assert free_diffuse and all(0 < r["stderr"] < 1 for r in free_diffuse)
    assert _strict_json(res)["stderr"]["alpha"] is None


def test_a_handful_of_distinct_cells_is_degenerate():
    """Two directions, each measured 15 times: six values for eight scalars. The solver
    interpolates them exactly with two scalars on bounds ('converged', error bars of 1e-13)."""
    wi = np.repeat([[0.17, 0.0, 0.985], [0.64, 0.0, 0.77]], 15, axis=0)
    wo = np.repeat([[-0.34, 0.0, 0.94], [-0.64, 0.0, 0.77]], 15, axis=0)
    rgb = np.repeat([[0.5, 0.4, 0.3], [2.5, 2.4, 2.3]], 15, axis=0)
    res = brdffit.fit(SampleSet(wi, wo, rgb, np.ones(30, bool), name="two"), "ggx", throw=False)
    assert not res.success and res.status == "degenerate", (res.status, res.message)
    assert "only 2 distinct direction pairs, 6 values for 8 free parameters" in res.message
    _assert_no_nan_values(res)


def test_a_table_at_an_absurd_scale_is_refused(cells):
    """A table times 1e30 (finite) ended with every amplitude on its upper bound, rmse_log 66,
    ``success: true`` and no message. Every cell is above any measurable BRDF: the table is
    refused before the fit, naming units and scale (not masked cell by cell)."""
    big = SampleSet(cells.wi, cells.wo, cells.rgb * 1e30, cells.valid, name="big")
    with pytest.raises(FitError, match="beyond any physical reflectance.*units and scale"):
        brdffit.fit(big, "ggx", throw=False)


def test_data_beyond_any_physical_reflectance_are_implausible(cells):
    """Values below the corrupt-cell bound (1e7/sr) but with ρ·cos θo above 1e6 in most cells:
    no surface reflects that, the fit ends ``implausible`` with a message about units."""
    rgb = np.clip(cells.rgb / np.median(cells.rgb[cells.valid]) * 5e6, 2e6, 9e6)
    big = SampleSet(cells.wi, cells.wo, rgb, cells.valid, name="big")
    res = brdffit.fit(big, "ggx", throw=False)
    assert not res.success and res.status == "implausible"
    assert "units" in res.message and "beyond any physical reflectance" in res.message
    _assert_no_nan_values(res)
    with pytest.raises(FitError, match="is implausible"):
        brdffit.fit(big, "ggx")


def test_an_exact_synthetic_table_is_a_clean_success(cells):
    """Zero residual: no 0/0 anywhere, every free scalar off its bounds identified."""
    model = brdffit.get_model("ggx")
    truth = {"diffuse": [0.2, 0.3, 0.4], "f0": [0.9, 0.6, 0.3], "alpha": 0.2, "grazing": 0.8}
    p = model.unflatten(jnp.asarray(model.flatten(truth)))
    rgb = np.asarray(model.fn(p, jnp.asarray(cells.wi), jnp.asarray(cells.wo)))
    # energy="free": this truth reflects 1.09 at 89°; the constraint would leave it
    res = brdffit.fit(_table(cells, rgb, "exact"), "ggx", throw=False, energy="free")
    assert res.success and res.not_identified == [] and res.at_bound == {}
    _assert_no_nan_values(res)
    assert all(math.isfinite(s) for v in res.stderr.values() for s in np.atleast_1d(v))
    np.testing.assert_allclose(res.params["alpha"], 0.2, rtol=1e-8)


def test_a_realistic_fit_identifies_every_free_parameter():
    res = brdffit.fit(realistic.merl_cells("pink-plastic", N), "ggx", throw=False)
    assert res.success and res.not_identified == [], res.message


def test_cli_zero_sample_list_exits_1_with_a_marked_result(tmp_path, capsys):
    rng = np.random.default_rng(0)

    def dirs(n):
        c, phi = rng.uniform(0.05, 1.0, n), rng.uniform(0, 2 * np.pi, n)
        s = np.sqrt(1 - c**2)
        return np.stack([s * np.cos(phi), s * np.sin(phi), c], -1)

    n = 200
    samples = SampleSet(dirs(n), dirs(n), np.zeros((n, 3)), np.ones(n, bool))
    path = write_samples(tmp_path / "zero.csv", samples)
    out = tmp_path / "r.json"
    code = main(["fit", str(path), "-m", "ggx", "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 1, captured.err
    assert "FAILED" in captured.out and "Traceback" not in captured.err
    d = json.loads(out.read_text(), parse_constant=lambda t: pytest.fail(f"{t} in the JSON"))
    assert d["success"] is False and d["status"] == "degenerate"
    assert all(v is not None for v in d["metrics"].values())
    assert "warning: the fit is degenerate (" in captured.err  # not "did not converge"
    assert "did not converge" not in captured.err


def test_a_batch_row_names_the_verdict_and_the_parameters_not_identified(cells):
    from brdffit.batch.table import OUTCOMES, result_row

    res = brdffit.fit(cells, "ggx", fixed={"f0": 0.0, "grazing": 0.0, "diffuse": 0.0}, throw=False)
    row = result_row(res)
    assert row["outcome"] == "degenerate" in OUTCOMES and row["not_identified"] == "alpha"
    assert row["success"] is False
    from brdffit.fitting.outcome import DATA_VERDICTS

    assert set(DATA_VERDICTS) <= set(OUTCOMES)  # the batch table spells them without JAX
