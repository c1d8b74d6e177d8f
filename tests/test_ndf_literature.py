"""The NDFs of the MERL studies: Löw 2012's ABC, Bagher 2012's SGD, Ribardière 2017's Student-t.

Normalization (RTR eq. 9.21) against closed forms and scipy quadratures; the Student-t's limits
(``γ = 2`` is GGX exactly, ``γ → ∞`` Beckmann) in ``D`` and ``Λ``; its numerical ``Λ`` against the
closed form (incomplete beta, scipy); each numerical ``Λ`` against the weak white furnace
``∫ D(m)(ω·m)⁺ dm = (1 + Λ(ω)) cos θ`` (RTR eqs. 9.23, 9.24) computed by scipy quadrature,
independent of :mod:`brdffit.terms.ndf.numerical`; Bagher's fitted ``G1`` against bbm's form.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate, special

from brdffit.terms.ndf import ABC, GGX, SGD, Beckmann, StudentT, bagher_g1


def _unit(theta):
    theta = np.atleast_1d(np.asarray(theta, float))
    return jnp.asarray(np.stack([np.sin(theta), 0 * theta, np.cos(theta)], -1))


def _d_of_theta(ndf):
    """``D(θm)`` of an isotropic NDF as a scalar NumPy function (for scipy quadrature)."""
    return lambda t: float(ndf.D(_unit(t))[0])


def _azimuthal(a, b):
    """``∫₀^{2π} max(0, a cos φ + b) dφ`` in closed form (a ≥ 0)."""
    if b >= a:
        return 2 * np.pi * b
    if b <= -a:
        return 0.0
    phi0 = np.arccos(-b / a)
    return 2 * (a * np.sin(phi0) + b * phi0)


def _projected_area(d_of_theta, theta, peak):
    """``g(ω) = ∫ D(m)(ω·m)⁺ dm`` by scipy (azimuth in closed form), ``θ`` the polar angle of ω."""
    s, c = np.sin(theta), np.cos(theta)

    def integrand(t):
        return d_of_theta(t) * np.sin(t) * _azimuthal(np.sin(t) * s, np.cos(t) * c)

    kink = np.pi / 2 - theta
    pts = sorted({p for p in (kink, peak, 3 * peak) if 0 < p < np.pi / 2})
    return integrate.quad(integrand, 0, np.pi / 2, points=pts, limit=500, epsabs=0, epsrel=1e-11)[0]


# --- normalization ---------------------------------------------------------------------------


@pytest.mark.parametrize("b,c", [(30.0, 1.5), (1e3, 1.0), (2e4, 0.3), (5e5, 2.2), (1e7, 0.02)])
def test_abc_normalization_against_closed_form(b, c):
    """``g(n) = 2π ∫₀¹ (1 + B(1 − μ))^{−C} μ dμ = 2π/B² [(1 + B) I(C) − I(C − 1)]`` with
    ``I(C) = ∫₁^{1+B} u^{−C} du``; ``D = S/g(n)`` then integrates to 1."""

    def i(e):
        return np.log1p(b) if abs(e - 1) < 1e-12 else ((1 + b) ** (1 - e) - 1) / (1 - e)

    g = 2 * np.pi / b**2 * ((1 + b) * i(c) - i(c - 1))
    ndf = ABC(b, c)
    assert float(ndf.normalization()) == pytest.approx(g, rel=1e-7)  # 2e-8 at C = 0.02
    np.testing.assert_allclose(ndf.D(_unit([0.0])), 1.0 / g, rtol=1e-7)


@pytest.mark.parametrize("alpha,p", [(2e-4, 0.4), (0.01, 0.0), (0.05, 0.5), (0.3, 1.0), (0.6, 1.4)])
def test_sgd_normalization_is_bagher_k(alpha, p):
    """``1/g(n) = K = 1/(α Γ(1 − p, α))`` (the integral ``α ∫_α^∞ x^{−p} e^{−x} dx``, by scipy)."""
    upper = integrate.quad(lambda x: x**-p * np.exp(-x), alpha, np.inf, epsrel=1e-12, limit=200)[0]
    assert float(SGD(alpha, p).normalization()) == pytest.approx(alpha * upper, rel=3e-6)


@pytest.mark.parametrize("alpha,gamma", [(0.02, 1.7), (0.1, 2.0), (0.3, 4.0), (0.6, 30.0)])
def test_student_t_is_normalized(alpha, gamma):
    ndf = StudentT(alpha, gamma)
    d = _d_of_theta(ndf)
    g = integrate.quad(lambda t: 2 * np.pi * d(t) * np.cos(t) * np.sin(t), 0, np.pi / 2,
                       points=[alpha, 3 * alpha], limit=500, epsrel=1e-11)[0]
    assert g == pytest.approx(1.0, rel=1e-8)


# --- the Student-t's limits ------------------------------------------------------------------


def test_student_t_at_gamma_2_is_ggx():
    rng = np.random.default_rng(0)
    m = rng.normal(size=(200, 3))
    m[:, 2] = np.abs(m[:, 2])
    m = jnp.asarray(m / np.linalg.norm(m, axis=-1, keepdims=True))
    w = _unit(np.linspace(0.0, 1.55, 40))
    for alpha in (0.01, 0.2, 0.7):
        np.testing.assert_allclose(StudentT(alpha, 2.0).D(m), GGX(alpha).D(m), rtol=1e-12)
        np.testing.assert_allclose(1 / (1 + StudentT(alpha, 2.0).Lambda(w)),
                                   1 / (1 + GGX(alpha).Lambda(w)), rtol=1e-6)


def test_student_t_tends_to_beckmann():
    """``(1 + x/(γ − 1))^{−γ} = e^{−x}(1 + O(x²/γ))``: at ``γ = 1e7`` ``D`` is within 1e-5 of
    Beckmann for slopes up to 3α (``x ≤ 9``), and ``G1`` within 1e-5."""
    alpha = 0.2
    m = _unit(np.arctan(alpha * np.linspace(0.0, 3.0, 30)))
    np.testing.assert_allclose(StudentT(alpha, 1e7).D(m), Beckmann(alpha).D(m), rtol=1e-5)
    w = _unit(np.linspace(0.0, 1.55, 40))
    np.testing.assert_allclose(1 / (1 + StudentT(alpha, 1e7).Lambda(w)),
                               1 / (1 + Beckmann(alpha).Lambda(w)), rtol=1e-5)


def student_t_lambda(cot_over_alpha, gamma):
    """Smith ``Λ`` of the Student-t in closed form (:mod:`brdffit.terms.ndf.student_t`), scipy."""
    mu, s = cot_over_alpha, gamma - 1.0
    c = special.gamma(gamma - 0.5) / (np.sqrt(np.pi) * special.gamma(gamma)) * np.sqrt(s)
    first = s / (2 * gamma - 3) * (1 + mu * mu / s) ** (1.5 - gamma)
    x = s / (s + mu * mu)
    second = 0.5 * mu * np.sqrt(s) * special.beta(gamma - 1, 0.5) * special.betainc(gamma - 1, 0.5, x)
    return c / mu * (first - second)


@pytest.mark.parametrize("gamma", [1.8, 2.0, 3.0, 10.0])
@pytest.mark.parametrize("alpha", [0.05, 0.4])
def test_student_t_numerical_lambda_matches_closed_form(alpha, gamma):
    theta = np.linspace(0.05, 1.56, 60)
    got = np.asarray(StudentT(alpha, gamma).Lambda(_unit(theta)))
    want = student_t_lambda(1 / (np.tan(theta) * alpha), gamma)
    np.testing.assert_allclose(1 / (1 + got), 1 / (1 + want), rtol=1e-6)
    big = want > 1e-3
    np.testing.assert_allclose(got[big], want[big], rtol=1e-4)
    if gamma == 2.0:  # the closed form itself is GGX's there (RTR eq. 9.42)
        np.testing.assert_allclose(want, 0.5 * (np.sqrt(1 + (alpha * np.tan(theta)) ** 2) - 1), rtol=1e-10)


# --- Λ against the weak white furnace, by quadrature -----------------------------------------


@pytest.mark.parametrize(
    "ndf,peak",
    [(ABC(1e3, 1.0), 0.045), (ABC(5e4, 0.4), 0.006), (SGD(0.01, 0.5), 0.01), (SGD(0.2, 1.2), 0.2),
     (StudentT(0.15, 1.7), 0.15)],
    ids=["abc-broad", "abc-sharp-long-tail", "sgd-sharp", "sgd-broad", "student-t"],
)
def test_lambda_satisfies_the_weak_white_furnace(ndf, peak):
    """``1 + Λ(ω) = g(ω)/(cos θ · g(n))`` (RTR eqs. 9.23, 9.24; ``g(n) = 1`` normalised)."""
    d = _d_of_theta(ndf)
    g_n = _projected_area(d, 0.0, peak)
    assert g_n == pytest.approx(1.0, rel=1e-7)  # D is normalised
    for theta in (0.3, 0.9, 1.3, 1.5):
        want = _projected_area(d, theta, peak) / (np.cos(theta) * g_n) - 1
        got = float(ndf.Lambda(_unit(theta))[0])
        assert 1 / (1 + got) == pytest.approx(1 / (1 + want), rel=1e-6), theta


def test_lambda_gradients_match_finite_differences():
    """``∂G1/∂γ`` of the Student-t and ``∂G1/∂(B, C)`` of ABC through the quadrature."""
    w = _unit([0.7, 1.3])

    def check(f, x0):
        g = np.asarray(jax.grad(f)(jnp.asarray(x0)))
        for i in range(len(x0)):
            e = np.zeros(len(x0))
            e[i] = 1e-6 * abs(x0[i])
            fd = (float(f(jnp.asarray(x0 + e))) - float(f(jnp.asarray(x0 - e)))) / (2 * e[i])
            assert fd == pytest.approx(g[i], rel=1e-5)

    check(lambda x: jnp.sum(1 / (1 + StudentT(x[0], x[1]).Lambda(w))), np.array([0.2, 2.5]))
    check(lambda x: jnp.sum(1 / (1 + ABC(x[0], x[1]).Lambda(w))), np.array([300.0, 1.2]))


# --- Bagher's fitted masking term ------------------------------------------------------------


def test_bagher_g1_is_bbm_form_with_width_and_clamped():
    """``1 + Λ(1 − exp(c (θ − θ0)^k))`` past ``θ0`` with ``c = w^{−k}``, 1 before, never below 0."""
    theta = np.linspace(0.0, 1.55, 200)
    lam, theta0, width, k = 3.3, 0.53, 1.048, 35.0
    c = width**-k
    bbm = np.where(theta > theta0, 1 + lam * (1 - np.exp(c * np.abs(theta - theta0) ** k)), 1.0)
    got = np.asarray(bagher_g1(jnp.asarray(theta), lam, theta0, width, k))
    np.testing.assert_allclose(got, np.maximum(bbm, 0.0), rtol=1e-12, atol=1e-15)
    assert np.any(bbm < 0) and np.all(got >= 0)  # the published kind of values do go negative
    # far past the cap: exactly 0, finite gradients
    grad = jax.grad(lambda t: bagher_g1(t, 1e-6, -0.6, 0.4, 800.0))(1.5)
    assert float(bagher_g1(1.5, 1e-6, -0.6, 0.4, 800.0)) == 0.0 and np.isfinite(float(grad))
