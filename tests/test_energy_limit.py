"""The energy constraint (:mod:`brdffit.fitting.constraints`): a fit whose directional albedo
exceeds 1 is solved again with it held at most 1.

* Data that break the constraint themselves (a ``ggx`` with a Lambertian albedo 0.9 beside an
  ``F0`` of 0.6: albedo 1.54 at 89°): the unconstrained optimum is the truth (cost 0), the
  default fit ends on the constraint (albedo 1 within the quadrature's error, not below it: the constraint
  active, no more given up than it takes) at a cost above 0, and the verdict passes it.
* The penalty's derivatives, which the solver's ``JᵀJ`` and ``Jᵀr`` are made of, against
  central differences of the penalty itself.
* A fit that holds the constraint already is untouched: no penalty, no note, the same numbers
  as with ``energy="free"``.
"""

from __future__ import annotations

import numpy as np
import pytest

import brdffit
from brdffit.cli.synth import synthesize_samples
from brdffit.fitting.constraints import EnergyLimit, limited
from brdffit.fitting.fitter import prepare
from brdffit.fitting.options import Settings, fit_options
from brdffit.models.albedo import max_albedo

BRIGHT = {"diffuse": [0.9, 0.85, 0.3], "f0": [0.6, 0.6, 0.6], "alpha": 0.3, "grazing": 1.0}
PLAIN = {"diffuse": [0.3, 0.2, 0.1], "f0": [0.04, 0.04, 0.04], "alpha": 0.2, "grazing": 1.0}


@pytest.fixture(scope="module")
def bright():
    return synthesize_samples(brdffit.get_model("ggx"), BRIGHT, 4000, seed=3, name="bright")


def test_data_that_create_light_are_fitted_on_the_constraint(bright):
    assert max_albedo("ggx", BRIGHT)[0] > 1.4
    free = brdffit.fit(bright, "ggx", energy="free")
    assert free.success and free.cost < 1e-12
    assert "energy" in {c["name"] for c in free.plausibility["checks"] if c["passed"] is False}
    held = brdffit.fit(bright, "ggx")
    rho, _ = max_albedo("ggx", held.params)
    assert held.success and held.cost > 1e-3, held.message
    assert 1.0 - 2e-3 < rho <= 1.0 + 1e-3  # on the constraint: active, and held
    assert "energy held: the unconstrained optimum's directional albedo was 1.54" in held.message
    energy = {c["name"]: c for c in held.plausibility["checks"]}["energy"]
    assert energy["passed"] is True


def test_the_penalty_derivatives_are_its_own(bright):
    """``J`` of the penalty by forward mode, against central differences of ``½ Σ r²``
    (``Jᵀr``) and of ``r`` itself (``JᵀJ``), at a point where it is active."""
    settings = Settings.of(fit_options(None))
    prep = prepare(bright, brdffit.get_model("ggx"), settings)
    problem = limited(prep.problem, 10.0)
    assert isinstance(problem.energy, EnergyLimit)
    inside = {**BRIGHT, "grazing": 0.7}  # off every bound: the box map is smooth there
    u = np.asarray(prep.scalars.to_box(brdffit.get_model("ggx").flatten(inside)))
    sum_r2, jtj, jtr = (np.asarray(a) for a in problem.penalty_sums(u))
    assert sum_r2 > 0

    def residual(v):
        import jax.numpy as jnp
        params = problem.model.unflatten(problem.full_vector(problem.physical(jnp.asarray(v))))
        return np.asarray(problem.energy.residual(problem.model, params, jnp.float64))

    h = 1e-6
    jac = np.stack([(residual(u + h * e) - residual(u - h * e)) / (2 * h)
                    for e in np.eye(len(u))], 1)
    np.testing.assert_allclose(jtr, jac.T @ residual(u), rtol=1e-5, atol=1e-6 * np.abs(jtr).max())
    np.testing.assert_allclose(jtj, jac.T @ jac, rtol=1e-5, atol=1e-6 * np.abs(jtj).max())


def test_a_fit_within_the_constraint_is_untouched():
    data = synthesize_samples(brdffit.get_model("ggx"), PLAIN, 2000, seed=4, name="plain")
    held, free = brdffit.fit(data, "ggx"), brdffit.fit(data, "ggx", energy="free")
    assert "energy held" not in held.message and held.cost == free.cost
    for k in PLAIN:
        np.testing.assert_array_equal(held.params[k], free.params[k])
