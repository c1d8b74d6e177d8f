"""Fresnel terms against the complex Fresnel equations written in plain NumPy, and their limits."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from brdffit.terms import fresnel

#: Complex indices (η, k) at R, G, B, rounded from refractiveindex.info (Johnson & Christy;
#: Rakić for Al). Only their plausibility matters here; the oracle takes the same numbers.
METALS = {
    "gold": ([0.18, 0.42, 1.37], [3.42, 2.35, 1.77]),
    "copper": ([0.27, 0.68, 1.22], [3.61, 2.63, 2.29]),
    "aluminium": ([1.66, 0.88, 0.52], [8.07, 6.35, 4.97]),
}

COS = np.concatenate([[0.0, 1e-6, 1e-3], np.linspace(0.01, 1.0, 60)])


def fresnel_np(n_complex, cos_i):
    """Unpolarised reflectance from the textbook complex Fresnel equations (Born & Wolf §13.4).

    ``n_complex = η + i k`` relative to the incident medium; numpy's principal complex square root
    gives ``|r| = 1`` by itself past the critical angle (``cos θ_t`` purely imaginary).
    """
    n = np.asarray(n_complex, dtype=complex)[None, :]
    c = np.asarray(cos_i, dtype=float)[:, None]
    cos_t = np.sqrt(1.0 - (1.0 - c**2) / n**2)
    r_s = (c - n * cos_t) / (c + n * cos_t)
    r_p = (n * c - cos_t) / (n * c + cos_t)
    return 0.5 * (np.abs(r_s) ** 2 + np.abs(r_p) ** 2)


@pytest.mark.parametrize("metal", sorted(METALS))
def test_conductor_matches_complex_fresnel_equations(metal):
    eta, k = METALS[metal]
    got = fresnel.conductor(jnp.asarray(eta), jnp.asarray(k), jnp.asarray(COS))
    want = fresnel_np(np.asarray(eta) + 1j * np.asarray(k), COS)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("eta", [1.0001, 1.33, 1.5, 2.4, 1 / 1.5, 0.8])
def test_dielectric_matches_complex_fresnel_equations_including_tir(eta):
    got = fresnel.dielectric(eta, jnp.asarray(COS))[..., 0]
    want = fresnel_np([eta], COS)[:, 0]
    ok = COS > 0  # at exactly cos = 0 the oracle is 0/0 for eta ~ 1; covered by the grazing test
    np.testing.assert_allclose(np.asarray(got)[ok], want[ok], rtol=1e-10, atol=1e-12)


def test_conductor_with_zero_k_is_the_dielectric():
    eta = jnp.asarray([1.2, 1.5, 2.0])
    c = jnp.asarray(COS)
    np.testing.assert_allclose(fresnel.conductor(eta, 0.0, c), fresnel.dielectric(eta, c), atol=1e-12)


@pytest.mark.parametrize("eta", [1.33, 1.5, 1.8, 3.0])
def test_dielectric_limits(eta):
    f = np.asarray(fresnel.dielectric(eta, jnp.asarray([1.0, 0.0, 1e-5])))[:, 0]
    assert f[0] == pytest.approx(((eta - 1) / (eta + 1)) ** 2, rel=1e-12)
    assert f[0] == pytest.approx(float(fresnel.f0_from_ior(eta)), rel=1e-12)
    assert f[1] == pytest.approx(1.0, abs=1e-12)
    assert f[2] == pytest.approx(1.0, abs=1e-4)
    # Monotone from normal to grazing incidence for eta > 1.
    curve = np.asarray(fresnel.dielectric(eta, jnp.linspace(1.0, 0.0, 200)))[:, 0]
    assert np.all(np.diff(curve) >= -1e-15)


def test_total_internal_reflection_and_light_from_inside():
    eta = 1 / 1.5  # glass to air
    critical = np.sqrt(1 - eta**2)  # cos of the critical angle
    c = jnp.asarray([critical - 1e-3, 0.3, 0.0])
    np.testing.assert_array_equal(np.asarray(fresnel.dielectric(eta, c))[:, 0], 1.0)
    assert float(fresnel.dielectric(eta, critical + 1e-3)[0]) < 1.0
    # A negative cosine flips the interface: eta -> 1/eta, as in pbrt.
    c = jnp.linspace(0.0, 1.0, 50)
    np.testing.assert_allclose(fresnel.dielectric(1.5, -c), fresnel.dielectric(1 / 1.5, c), atol=1e-14)


def test_schlick_is_close_to_exact_for_dielectrics():
    c = np.linspace(0.0, 1.0, 2001)
    for eta in (1.33, 1.5, 1.8, 2.4):
        exact = np.asarray(fresnel.dielectric(eta, jnp.asarray(c)))[:, 0]
        approx = np.asarray(fresnel.schlick(fresnel.f0_from_ior(eta), jnp.asarray(c)))[:, 0]
        assert approx[-1] == pytest.approx(exact[-1], rel=1e-12)  # equal at normal incidence
        assert approx[0] == pytest.approx(1.0) and exact[0] == pytest.approx(1.0)
        # Measured: the largest absolute error is 0.036 (eta 1.5) to 0.074 (eta 2.4), near
        # 84-85 degrees incidence; the cosine-weighted averages (RTR eq. 9.58) differ by < 0.01.
        assert np.max(np.abs(approx - exact)) < 0.08, eta
        mean_exact = 2 * np.trapezoid(exact * c, c)
        mean_schlick = 2 * np.trapezoid(approx * c, c)
        assert abs(mean_exact - mean_schlick) < 0.01, eta
        # ...and Schlick's average has the closed form of RTR eq. 9.60.
        f0 = float(fresnel.f0_from_ior(eta))
        assert mean_schlick == pytest.approx(20 / 21 * f0 + 1 / 21, abs=1e-6)


def test_schlick_with_rgb_f0_and_its_weight():
    f0 = jnp.asarray([0.9, 0.5, 0.1])
    c = jnp.asarray([1.0, 0.5, 0.0, -0.2])
    got = np.asarray(fresnel.schlick(f0, c))
    m = np.clip(1 - np.asarray(c), 0, 1)[:, None] ** 5
    np.testing.assert_allclose(got, np.asarray(f0) + (1 - np.asarray(f0)) * m, rtol=1e-14)
    np.testing.assert_allclose(fresnel.schlick_weight(c), m[:, 0], rtol=1e-14)


@pytest.mark.parametrize("f90", [0.0, 0.25, 1.0])
def test_generalized_schlick_is_rtr_9_18(f90):
    """``F0 + (F90 − F0)(1 − cos)^5``: ``F0`` at normal incidence, ``F90`` at grazing, within
    ``[min, max](F0, F90)`` between, and RTR eq. 9.16 at ``F90 = 1``."""
    f0 = np.array([0.9, 0.5, 0.02])
    c = np.linspace(0.0, 1.0, 101)
    got = np.asarray(fresnel.schlick(jnp.asarray(f0), jnp.asarray(c), f90=f90))
    w = (1 - c)[:, None] ** 5
    np.testing.assert_allclose(got, f0 + (f90 - f0) * w, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(got[-1], f0, rtol=1e-14)
    np.testing.assert_allclose(got[0], f90, rtol=1e-14)
    assert np.all(got >= np.minimum(f0, f90) - 1e-15) and np.all(got <= np.maximum(f0, f90) + 1e-15)
    if f90 == 1.0:
        np.testing.assert_array_equal(got, np.asarray(fresnel.schlick(jnp.asarray(f0), jnp.asarray(c))))


def test_conversions_round_trip():
    eta = jnp.asarray([1.0, 1.33, 1.5, 2.4])
    f0 = fresnel.f0_from_ior(eta)
    np.testing.assert_allclose(fresnel.ior_from_f0(f0), eta, rtol=1e-12)
    assert float(fresnel.ior_from_f0(0.04)) == pytest.approx(1.5)
    for eta, k in METALS.values():
        eta, k = jnp.asarray(eta), jnp.asarray(k)
        np.testing.assert_allclose(
            fresnel.f0_from_conductor(eta, k), fresnel.conductor(eta, k, 1.0), rtol=1e-12
        )


def test_gradients_match_finite_differences_in_eta_and_k():
    c = jnp.asarray(COS)

    def loss(x):
        return jnp.sum(fresnel.conductor(x[:3], x[3:], c)) + jnp.sum(fresnel.dielectric(x[:3], c))

    eta, k = METALS["copper"]
    x0 = np.asarray(eta + k, dtype=float)
    x0[:3] += 1.0  # keep eta > 1 so the dielectric term has no kink in the sample
    g = np.asarray(jax.grad(loss)(jnp.asarray(x0)))
    for i in range(6):
        e = np.zeros(6)
        e[i] = 1e-6
        fd = (float(loss(jnp.asarray(x0 + e))) - float(loss(jnp.asarray(x0 - e)))) / 2e-6
        assert g[i] == pytest.approx(fd, rel=1e-6, abs=1e-9), i


def test_no_nan_gradients_at_grazing_normal_tir_and_zero_k():
    c = jnp.asarray([0.0, 1.0, 1e-9, 0.5])

    def loss(x):
        cond = fresnel.conductor(x[0], x[1], c)  # x[1] = k = 0 exactly
        tir = fresnel.dielectric(x[2], c)  # eta < 1: TIR at the grazing samples
        return jnp.sum(cond) + jnp.sum(tir)

    g = jax.grad(loss)(jnp.asarray([1.5, 0.0, 1 / 1.5]))
    assert np.all(np.isfinite(np.asarray(g)))
    gc = jax.grad(lambda c: jnp.sum(fresnel.dielectric(1.5, c) + fresnel.conductor(0.2, 3.0, c)))(c)
    assert np.all(np.isfinite(np.asarray(gc)))


def test_jit_matches_eager_and_float32_is_finite():
    eta, k = (jnp.asarray(v) for v in METALS["gold"])
    c = jnp.asarray(COS)
    fns = [
        lambda e, k, c: fresnel.conductor(e, k, c),
        lambda e, k, c: fresnel.dielectric(e + 1.0, c),
        lambda e, k, c: fresnel.schlick(fresnel.f0_from_conductor(e, k), c),
    ]
    for fn in fns:
        eager = fn(eta, k, c)
        np.testing.assert_allclose(jax.jit(fn)(eta, k, c), eager, rtol=1e-13, atol=1e-15)
        f32 = fn(eta.astype(jnp.float32), k.astype(jnp.float32), c.astype(jnp.float32))
        assert f32.dtype == jnp.float32 and bool(jnp.all(jnp.isfinite(f32)))
        np.testing.assert_allclose(f32, eager, atol=2e-5)
        assert bool(jnp.all((eager >= 0) & (eager <= 1 + 1e-12)))
