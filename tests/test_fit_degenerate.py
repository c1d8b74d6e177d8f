"""Honest verdicts on degenerate data: success only where the optimality test holds at a
point the data determine, never at a start the cost cannot tell from any other point."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import brdffit
from brdffit.errors import ConfigError, FitError
from data_formats import SampleSet

import realistic

N = 5000
LAMBERT = np.array([0.5, 0.4, 0.3])


@pytest.fixture(scope="module")
def cells():
    return realistic.merl_cells("nickel", N, seed=3)


def _table(cells, rgb, name):
    return SampleSet(cells.wi, cells.wo, np.broadcast_to(rgb, cells.rgb.shape).copy(), cells.valid,
                     name=name)


def _cost_at(result, table, params):
    """The linear or cosine cost of ``params`` on ``table``, written out in NumPy."""
    model = brdffit.get_model(result.model_name)
    pred = np.asarray(jax.jit(model.fn)(model.unflatten(jnp.asarray(model.flatten(params))),
                                        jnp.asarray(table.wi), jnp.asarray(table.wo)))
    ci, co = table.wi[:, 2:3], table.wo[:, 2:3]
    if result.loss == "linear":
        r = pred - table.rgb
    else:
        r = (pred - table.rgb) * ci * co
    return 0.5 * np.sum(r**2)


@pytest.mark.parametrize("loss", ["linear", "cosine"])
def test_lambertian_table_is_reproduced_by_ggx_with_f0_and_f90_at_zero(cells, loss):
    """ggx is Lambertian only with ``F0 = F90 = 0`` (``F0 = 0`` and no grazing rise: plain
    Schlick's grazing term would stay), so the optimum has ``f0`` and ``grazing`` on their
    lower bounds (``α`` then changes nothing) and
    reproduces the table. A constant table determines no lobe: the verdict says so."""
    table = _table(cells, LAMBERT / np.pi, "lambert")
    res = brdffit.fit(table, "ggx", loss=loss, throw=False)
    assert not res.success and res.status == "degenerate" and res.optimality <= 1e-9
    assert res.not_identified == ["alpha"]
    assert res.params["f0"] == [0.0, 0.0, 0.0] and res.params["grazing"] == 0.0
    assert res.at_bound["grazing"] == "lower" and res.derived["f90"] == [0.0, 0.0, 0.0]
    np.testing.assert_allclose(res.params["diffuse"], LAMBERT, rtol=1e-6)
    assert res.cost < 1e-20  # the Lambertian table itself, to rounding


def test_a_cost_that_depends_on_nothing_is_not_a_success(cells):
    """Every reflecting term held at zero, α left free: the model is 0 whatever α, the
    gradient and JᵀJ vanish; the start is a 'stationary point' the data do not determine."""
    res = brdffit.fit(cells, "ggx", fixed={"f0": 0.0, "grazing": 0.0, "diffuse": 0.0}, throw=False)
    assert not res.success and res.status == "degenerate"
    assert "determine nothing" in res.message
    assert res.not_identified == ["alpha"] and math.isnan(res.stderr["alpha"])


def test_a_table_beyond_any_measurable_value_is_refused(cells):
    """Values of 1e300 (finite): not a few corrupt cells but a table at the wrong scale."""
    with pytest.raises(FitError, match="units and scale"):
        brdffit.fit(_table(cells, 1e300, "huge"), "ggx", loss="relative", throw=False)


def test_an_all_zero_table_ends_on_the_bounds_it_belongs_on(cells):
    res = brdffit.fit(_table(cells, 0.0, "zero"), "ggx", loss="linear", throw=False)
    assert not res.success and res.status == "degenerate"  # zeros determine no parameter
    assert res.params["diffuse"] == [0.0, 0.0, 0.0] and res.params["f0"] == [0.0, 0.0, 0.0]
    assert res.params["grazing"] == 0.0  # no reflection at all: α then changes nothing


@pytest.mark.parametrize("option", [dict(rtol=9223372036854775807), dict(ftol=2.0),
                                    dict(max_steps=0), dict(multistart=-1)])
def test_absurd_tolerances_are_refused_before_any_work(cells, option):
    with pytest.raises(ConfigError, match="must be"):
        brdffit.fit(cells, "ggx", **option)
