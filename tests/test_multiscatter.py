"""Multiple scattering (RTR 9.56–9.60) and the coupled diffuse term (RTR 9.65).

The albedo table is checked against an independent quadrature in outgoing directions; the white
furnace test and the total-albedo test integrate the whole BRDF the same independent way.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_aps import albedo, hemi

from brdffit.terms.energy.albedo_table import albedo_table
from brdffit.terms.energy.coupled_diffuse import coupled_diffuse
from brdffit.terms.energy.multiscatter import kulla_conty, multiscatter_specular, schlick_average
from brdffit.terms.fresnel import schlick
from brdffit.terms.microfacet import microfacet_specular
from brdffit.terms.ndf import GGX


@pytest.fixture(scope="module")
def table():
    return albedo_table(GGX)


def test_table_matches_independent_albedo_between_nodes(table):
    """E₁ = R_sF1 and E₀ at off-node (α, μ) against the white-lobe albedo integrated over ωo."""
    for alpha in (0.07, 0.33, 0.85):
        ndf = GGX(alpha)
        for theta in np.radians([5.0, 47.0, 78.0]):
            f1 = jax.jit(lambda wi, wo, ndf=ndf: microfacet_specular(ndf, partial(schlick, jnp.ones(3)), wi, wo))
            f0 = jax.jit(lambda wi, wo, ndf=ndf: microfacet_specular(ndf, partial(schlick, jnp.zeros(3)), wi, wo))
            e0, e1 = table.lookup(jnp.asarray(alpha), jnp.asarray(np.cos(theta)))
            assert float(e1) == pytest.approx(albedo(f1, theta)[0], abs=5e-3), (alpha, theta)
            assert float(e0) == pytest.approx(albedo(f0, theta)[0], abs=5e-3), (alpha, theta)


def test_average_is_the_cosine_weighted_mean(table):
    """Ē = 2∫E μ dμ (RTR 9.57), here by the trapezoid rule on a fine μ grid of table lookups."""
    mu = np.linspace(0, 1, 2001)
    for alpha in (0.05, 0.4, 1.0):
        _, e1 = table.lookup(jnp.asarray(alpha), jnp.asarray(mu))
        _, a1 = table.average(jnp.asarray(alpha))
        assert float(a1) == pytest.approx(np.trapezoid(2 * np.asarray(e1) * mu, mu), abs=2e-3)


def test_schlick_average_closed_form_rtr_9_60():
    mu = np.linspace(0, 1, 20001)
    for f0 in (0.04, 0.5, 0.95):
        numeric = np.trapezoid(2 * mu * (f0 + (1 - f0) * (1 - mu) ** 5), mu)  # RTR eq. 9.58
        assert float(schlick_average(f0)) == pytest.approx(numeric, abs=1e-7)


def test_white_furnace_rough_conductor(table):
    """F = 1, α = 0.8: single scattering loses > 5 % of the energy; with f_ms the albedo is ≈ 1."""
    alpha, f0 = 0.8, jnp.ones(3)
    single = jax.jit(lambda wi, wo: microfacet_specular(GGX(alpha), partial(schlick, f0), wi, wo))
    both = jax.jit(lambda wi, wo: multiscatter_specular(GGX, jnp.asarray(alpha), f0, wi, wo, table=table))
    for theta in np.radians([0.0, 30.0, 60.0, 80.0]):
        assert albedo(single, theta)[0] < 0.95
        np.testing.assert_allclose(albedo(both, theta), 1.0, atol=6e-3)


def test_colored_fresnel_multiple_scattering_is_bounded_and_saturates(table):
    """With F < 1 the term adds less than with F = 1, and the F̄² form (Kulla–Conty) less still."""
    wi, wo = hemi(300, 1), hemi(300, 2)
    a = jnp.asarray(0.6)
    white = kulla_conty(table, a, jnp.ones(3), wi, wo)
    gold = kulla_conty(table, a, jnp.asarray([1.0, 0.78, 0.34]), wi, wo)
    squared = kulla_conty(table, a, jnp.asarray([1.0, 0.78, 0.34]), wi, wo, fresnel_power=2)
    np.testing.assert_allclose(gold[:, 0], white[:, 0], rtol=1e-12)
    assert np.all(np.asarray(gold[:, 1:]) < np.asarray(white[:, 1:]))
    assert np.all(np.asarray(squared[:, 1:]) < np.asarray(gold[:, 1:]))
    np.testing.assert_allclose(kulla_conty(table, a, jnp.ones(3), wo, wi), white, rtol=1e-12)


def test_coupled_diffuse_total_albedo_is_one(table):
    """RTR 9.65 with ρ = 1: lobe + diffuse has directional albedo 1 for every F₀ and direction."""
    alpha, f0 = jnp.asarray(0.35), jnp.asarray([0.04, 0.3, 0.9])
    f = jax.jit(
        lambda wi, wo: microfacet_specular(GGX(alpha), partial(schlick, f0), wi, wo)
        + coupled_diffuse(table, alpha, f0, jnp.ones(3), wi, wo)
    )
    for theta in np.radians([0.0, 45.0, 80.0]):
        np.testing.assert_allclose(albedo(f, theta), 1.0, atol=5e-3)


def test_coupled_diffuse_reciprocal_and_zero_below_horizon(table):
    wi, wo = hemi(200, 3), hemi(200, 4)
    args = (table, jnp.asarray(0.2), jnp.asarray([0.04, 0.5, 0.9]), jnp.asarray([0.5, 0.2, 0.8]))
    np.testing.assert_allclose(coupled_diffuse(*args, wi, wo), coupled_diffuse(*args, wo, wi), rtol=1e-12)
    below = wo * jnp.asarray([1.0, 1.0, -1.0])
    np.testing.assert_array_equal(np.asarray(coupled_diffuse(*args, wi, below)), 0.0)


def test_gradient_in_alpha_through_the_table(table):
    wi, wo = hemi(16, 5), hemi(16, 6)

    @jax.jit
    def scalar(a):
        return jnp.sum(multiscatter_specular(GGX, a, jnp.full(3, 0.7), wi, wo, table=table))

    x = jnp.asarray(0.41)
    g = float(jax.jit(jax.grad(scalar))(x))
    fd = (float(scalar(x + 1e-6)) - float(scalar(x - 1e-6))) / 2e-6
    assert np.isfinite(g) and g == pytest.approx(fd, rel=1e-5)
