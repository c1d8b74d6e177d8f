"""Masking near the horizon: Λ follows its closed form down to the readers' horizon.

The MERL reader keeps directions with ``cos θ > 1e-9`` (``data_formats.merl.HORIZON_EPS``);
GGX's Λ grows like ``α tan θ / 2`` there, so any saturation of ``tan² θ`` above that horizon
makes grazing cells too bright (``G2`` too large).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import erfc

from brdffit.terms.ndf import GGX, Beckmann
from data_formats.merl import HORIZON_EPS

COS = np.array([1.7e-7, 1e-7, 1e-8, 3e-9, 1.01 * HORIZON_EPS])


def _directions(cos_theta, phi=0.3):
    sin_theta = np.sqrt(1.0 - cos_theta**2)
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1)


def _closed_form(kind, cos_theta, alpha):
    """RTR eq. 9.42 (GGX) and 9.38 (Beckmann) with ``a = cos θ / (α sin θ)`` (eq. 9.37)."""
    a = cos_theta / (alpha * np.sqrt(1.0 - cos_theta**2))
    if kind == "ggx":
        return 0.5 * (np.sqrt(1.0 + 1.0 / a**2) - 1.0)
    return 0.5 * (np.exp(-a * a) / (a * np.sqrt(np.pi)) - erfc(a))


@pytest.mark.parametrize("kind, ndf", [("ggx", GGX), ("beckmann", Beckmann)])
@pytest.mark.parametrize("alpha", [0.05, 0.3])
def test_lambda_follows_its_closed_form_down_to_the_reader_horizon(kind, ndf, alpha):
    lam = np.asarray(ndf(jnp.asarray(alpha)).Lambda(jnp.asarray(_directions(COS))))
    np.testing.assert_allclose(lam, _closed_form(kind, COS, alpha), rtol=1e-6)


def test_ggx_lambda_keeps_growing_towards_the_horizon():
    lam = np.asarray(GGX(jnp.asarray(0.2)).Lambda(jnp.asarray(_directions(COS))))
    assert np.all(np.diff(lam) > 0)  # COS decreases, so Λ ∝ tan θ must increase
    assert lam[-1] > 1e7  # α tan θ / 2 at cos θ = 1e-9 is ~1e8; a saturated tan² gives 1e5
