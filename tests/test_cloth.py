"""Cloth: the velvet (RTR 9.73) and Imageworks sheen (RTR 9.75) NDFs, the RTR 9.74 cloth BRDF and
the sheen lobe, each against a plain NumPy transcription or a numerical integral.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_aps import albedo, hemi

from brdffit.models import get_model
from brdffit.models.cloth import velvet_cloth
from brdffit.terms.ndf.sheen import GeneralizedVelvet, ImageworksSheen


def _polar(n=1600, m=8):
    th = (np.arange(n) + 0.5) * (np.pi / 2) / n
    ph = (np.arange(m) + 0.5) * 2 * np.pi / m
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1)
    return h, np.sin(TH) * (np.pi / 2 / n) * (2 * np.pi / m)


def np_velvet(c, alpha, k):
    """Ashikhmin & Premože 2007 / Neubelt & Pettineo 2013, exponent −cot²θ/α² (see the module)."""
    s2 = 1 - c**2
    return (1 + k * np.exp(-(c**2) / (alpha**2 * s2)) / s2**2) / (np.pi * (1 + k * alpha**2))


def np_sheen(c, alpha):
    return (2 + 1 / alpha) * (1 - c**2) ** (1 / (2 * alpha)) / (2 * np.pi)


NDFS = {
    "velvet": (lambda: GeneralizedVelvet(0.35, 3.0), lambda c: np_velvet(c, 0.35, 3.0)),
    "velvet-wide": (lambda: GeneralizedVelvet(0.8, 0.5), lambda c: np_velvet(c, 0.8, 0.5)),
    "sheen": (lambda: ImageworksSheen(0.3), lambda c: np_sheen(c, 0.3)),
    "sheen-rough": (lambda: ImageworksSheen(1.0), lambda c: np_sheen(c, 1.0)),
}


@pytest.mark.parametrize("name", NDFS)
def test_ndf_matches_numpy_and_is_normalized(name):
    make, ref = NDFS[name]
    ndf = make()
    h, w = _polar()
    d = np.asarray(ndf.D(jnp.asarray(h)))
    np.testing.assert_allclose(d, ref(h[..., 2]), rtol=1e-10)
    assert np.sum(d * h[..., 2] * w) == pytest.approx(1.0, abs=2e-4)  # RTR eq. 9.21
    assert float(ndf.D(jnp.asarray([0.0, 0.0, -1.0]))) == 0.0


@pytest.mark.parametrize("name", NDFS)
def test_lambda_satisfies_the_weak_white_furnace(name):
    """(1 + Λ(ω)) cos θ = ∫ D(m)(ω·m)⁺ dm (RTR 9.23/9.24), integrated here by brute force."""
    make, ref = NDFS[name]
    ndf = make()
    h, w = _polar(1200, 720)
    dh = ref(h[..., 2]) * w
    for theta in np.radians([10.0, 45.0, 75.0, 88.0]):
        k = np.array([np.sin(theta), 0.0, np.cos(theta)])
        proj = np.sum(np.maximum(h @ k, 0) * dh)
        lam = float(ndf.Lambda(jnp.asarray(k)))
        assert (1 + lam) * np.cos(theta) == pytest.approx(proj, rel=2e-3), np.degrees(theta)


def test_velvet_cloth_brdf_matches_rtr_9_74():
    wi, wo = hemi(300, 1), hemi(300, 2)
    f0, rho, alpha, k = np.array([0.04, 0.2, 0.6]), np.array([0.5, 0.3, 0.1]), 0.4, 2.0
    got = velvet_cloth(GeneralizedVelvet(alpha, k), f0, rho, wi, wo)
    a, b = np.asarray(wi), np.asarray(wo)
    h = (a + b) / np.linalg.norm(a + b, axis=-1, keepdims=True)
    F = f0 + (1 - f0) * (1 - np.sum(a * h, -1, keepdims=True)) ** 5
    nl, nv = a[:, 2:], b[:, 2:]
    ref = (1 - F) * rho / np.pi + F * np_velvet(h[:, 2:], alpha, k) / (4 * (nl + nv - nl * nv))
    np.testing.assert_allclose(got, ref, rtol=1e-10)
    np.testing.assert_allclose(velvet_cloth(GeneralizedVelvet(alpha, k), f0, rho, wo, wi), got, rtol=1e-12)


def test_sheen_lobe_conserves_energy_and_velvet_retroreflects():
    model = get_model("cloth-sheen")
    f = jax.jit(lambda wi, wo: model(dict(diffuse=0.0, sheen=1.0, alpha=0.5), wi, wo))
    for theta in np.radians([0.0, 60.0, 85.0]):
        assert 0.0 < albedo(f, theta)[0] <= 1.0 + 2e-3
    # Sheen grows towards grazing (its whole point): grazing reflection >> normal reflection.
    assert albedo(f, np.radians(80.0))[0] > 3 * albedo(f, 0.0)[0]
