"""Masking-shadowing: every G2 form against a NumPy transcription of its RTR equation, the
orderings and limits that tie the forms together, Lagarde's GGX form (RTR 9.43), gradients,
float32 and NaN safety."""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import erfc

from brdffit.terms._math import half_vector
from brdffit.terms.masking import (
    G1,
    G2_direction_correlated,
    G2_height_correlated,
    G2_height_direction_correlated,
    G2_separable,
    lambda_ashikhmin,
    lambda_van_ginneken,
    relative_azimuth,
)
from brdffit.terms.microfacet import microfacet_specular
from brdffit.terms.ndf import GGX, Beckmann

FORMS = [G2_separable, G2_height_correlated, G2_direction_correlated, G2_height_direction_correlated]


def _np_lambda(kind, w, alpha):
    """RTR eq. 9.42 (GGX) or 9.38 (Beckmann) with a of eq. 9.37."""
    c = w[..., 2]
    s = np.sqrt(np.maximum(1 - c * c, 0))
    a = c / (alpha * s)
    if kind == "ggx":
        return (-1 + np.sqrt(1 + 1 / a**2)) / 2
    return -erfc(a) / 2 + np.exp(-a * a) / (2 * a * np.sqrt(np.pi))


def _np_phi(wi, wo):
    pi, po = wi[..., :2], wo[..., :2]
    cos = np.sum(pi * po, -1) / (np.linalg.norm(pi, axis=-1) * np.linalg.norm(po, axis=-1))
    return np.arccos(np.clip(cos, -1, 1))


def _np_forms(kind, wi, wo, wm, alpha, lam_fn):
    """RTR eqs. 9.24, 9.27, 9.28, 9.31, 9.32 written out."""
    Li, Lo = _np_lambda(kind, wi, alpha), _np_lambda(kind, wo, alpha)
    chi = (np.sum(wi * wm, -1) > 0) * (np.sum(wo * wm, -1) > 0)
    g1i, g1o = chi / (1 + Li), chi / (1 + Lo)
    lam = lam_fn(_np_phi(wi, wo))
    return {
        G2_separable: g1i * g1o,
        G2_height_correlated: chi / (1 + Li + Lo),
        G2_direction_correlated: lam * g1i * g1o + (1 - lam) * np.minimum(g1i, g1o),
        G2_height_direction_correlated: chi / (1 + np.maximum(Li, Lo) + lam * np.minimum(Li, Lo)),
    }


def _pairs(n, seed, min_cos=0.02):
    rng = np.random.default_rng(seed)

    def hemi():
        z = rng.uniform(min_cos, 1, n)
        p = rng.uniform(0, 2 * np.pi, n)
        r = np.sqrt(1 - z * z)
        return np.stack([r * np.cos(p), r * np.sin(p), z], -1)

    return hemi(), hemi()


NP_LAMBDAS = {
    lambda_ashikhmin: lambda phi: 1 - np.exp(-7.3 * phi**2),  # RTR eq. 9.29
    lambda_van_ginneken: lambda phi: 4.41 * phi / (4.41 * phi + 1),  # RTR eq. 9.30
}


@pytest.mark.parametrize("kind,cls", [("ggx", GGX), ("beckmann", Beckmann)])
@pytest.mark.parametrize("lam_fn", list(NP_LAMBDAS), ids=["9.29", "9.30"])
def test_forms_match_numpy_transcriptions(kind, cls, lam_fn):
    wi, wo = _pairs(300, 0)
    wm = np.array(half_vector(jnp.asarray(wi), jnp.asarray(wo)))
    wm[:20] = -wm[:20]  # back-facing microfacets: χ⁺ must zero them
    wm[20:40, :2] *= 30  # tilted microfacets: some face away from one of the directions
    wm /= np.linalg.norm(wm, axis=-1, keepdims=True)
    ref = _np_forms(kind, wi, wo, wm, 0.35, NP_LAMBDAS[lam_fn])
    ndf = cls(0.35)
    args = (ndf, jnp.asarray(wi), jnp.asarray(wo), jnp.asarray(wm))
    for form in FORMS:
        got = form(*args, lambda_fn=lam_fn) if "direction" in form.__name__ else form(*args)
        np.testing.assert_allclose(got, ref[form], rtol=1e-9, atol=1e-15, err_msg=form.__name__)
    assert np.all(np.asarray(G2_separable(*args))[:20] == 0)


def test_relative_azimuth_matches_arccos_and_is_zero_at_the_pole():
    wi, wo = _pairs(200, 1)
    np.testing.assert_allclose(relative_azimuth(jnp.asarray(wi), jnp.asarray(wo)), _np_phi(wi, wo), atol=1e-7)
    pole = jnp.asarray([0.0, 0.0, 1.0])
    assert float(relative_azimuth(pole, jnp.asarray(wo[0]))) == 0.0


def test_orderings_between_the_forms():
    """separable ≤ height-corr. ≤ height-dir. corr. ≤ min(G1); direction-corr. in [separable, min]."""
    wi, wo = (jnp.asarray(v) for v in _pairs(500, 2))
    wm = half_vector(wi, wo)
    for ndf in (GGX(0.6), Beckmann(0.2)):
        sep, hc = G2_separable(ndf, wi, wo, wm), G2_height_correlated(ndf, wi, wo, wm)
        hdc, dc = G2_height_direction_correlated(ndf, wi, wo, wm), G2_direction_correlated(ndf, wi, wo, wm)
        mn = jnp.minimum(G1(ndf, wi, wm), G1(ndf, wo, wm))
        tol = 1e-12
        assert bool(jnp.all(sep <= hc + tol) & jnp.all(hc <= hdc + tol) & jnp.all(hdc <= mn + tol))
        assert bool(jnp.all(sep <= dc + tol) & jnp.all(dc <= mn + tol))
        assert float(jnp.max(hdc - hc)) > 1e-3 and float(jnp.max(hc - sep)) > 1e-3  # forms differ


def test_limits_same_azimuth_opposite_azimuth_and_identical_directions():
    ndf = GGX(0.5)
    t1, t2 = np.radians(70.0), np.radians(40.0)
    same = jnp.asarray([np.sin(t1), 0, np.cos(t1)]), jnp.asarray([np.sin(t2), 0, np.cos(t2)])
    opposite = same[0], jnp.asarray([-np.sin(t2), 0, np.cos(t2)])
    # φ = 0: λ = 0, both correlated forms give min(G1(l), G1(v)) (RTR p. 335).
    wm = half_vector(*same)
    mn = jnp.minimum(G1(ndf, same[0], wm), G1(ndf, same[1], wm))
    for form in (G2_direction_correlated, G2_height_direction_correlated):
        assert float(form(ndf, *same, wm)) == pytest.approx(float(mn), rel=1e-12)
    # φ = π: λ(π) = 1 − e^(−72): 9.28 → separable 9.27, 9.32 → height-correlated 9.31.
    wm = half_vector(*opposite)
    assert float(G2_direction_correlated(ndf, *opposite, wm)) == pytest.approx(float(G2_separable(ndf, *opposite, wm)), rel=1e-12)
    assert float(G2_height_direction_correlated(ndf, *opposite, wm)) == pytest.approx(
        float(G2_height_correlated(ndf, *opposite, wm)), rel=1e-12
    )
    # l = v: "G2 should be equal to G1" (RTR p. 334); the separable form gives G1².
    w = same[0]
    g1 = float(G1(ndf, w, w))
    assert float(G2_direction_correlated(ndf, w, w, w)) == pytest.approx(g1, rel=1e-12)
    assert float(G2_separable(ndf, w, w, w)) == pytest.approx(g1**2, rel=1e-12)


def test_lagarde_form_equals_height_correlated_visibility_for_ggx():
    """RTR eq. 9.43 = G2 (9.31) / (4 |n·l| |n·v|) for GGX."""
    wi, wo = _pairs(400, 3)
    wm = np.asarray(half_vector(jnp.asarray(wi), jnp.asarray(wo)))
    for alpha in (0.01, 0.2, 0.9):
        mi, mo, a2 = wi[:, 2], wo[:, 2], alpha**2
        lagarde = 0.5 / (mo * np.sqrt(a2 + mi * (mi - a2 * mi)) + mi * np.sqrt(a2 + mo * (mo - a2 * mo)))
        g2 = G2_height_correlated(GGX(alpha), jnp.asarray(wi), jnp.asarray(wo), jnp.asarray(wm))
        np.testing.assert_allclose(g2 / (4 * mi * mo), lagarde, rtol=1e-10)


def test_forms_plug_into_the_specular_lobe_as_partials():
    wi, wo = (jnp.asarray(v) for v in _pairs(200, 4))
    ndf, fresnel = GGX(0.3), lambda c: jnp.ones(c.shape + (1,))
    for g2 in (G2_separable, partial(G2_direction_correlated, lambda_fn=lambda_van_ginneken), G2_height_direction_correlated):
        f = microfacet_specular(ndf, fresnel, wi, wo, g2=g2)[..., 0]
        np.testing.assert_allclose(f, microfacet_specular(ndf, fresnel, wo, wi, g2=g2)[..., 0], rtol=1e-12)  # reciprocity
        ref = ndf.D(half_vector(wi, wo)) * g2(ndf, wi, wo, half_vector(wi, wo)) / (4 * wi[:, 2] * wo[:, 2])
        np.testing.assert_allclose(f, ref, rtol=1e-12)


@pytest.mark.parametrize("form", FORMS, ids=lambda f: f.__name__)
def test_gradients_finite_differences_and_nan_safety(form):
    wi, wo = (jnp.asarray(v) for v in _pairs(32, 5))
    wm = half_vector(wi, wo)

    def f(a, wi=wi, wo=wo, wm=wm):
        return jnp.sum(form(Beckmann(a[0], a[1]), wi, wo, wm))

    x0 = np.array([0.2, 0.45])
    g = np.asarray(jax.grad(f)(jnp.asarray(x0)))
    for i in range(2):
        e = np.zeros(2)
        e[i] = 1e-6
        fd = (float(f(jnp.asarray(x0 + e))) - float(f(jnp.asarray(x0 - e)))) / 2e-6
        assert g[i] == pytest.approx(fd, rel=1e-6)
    # Grazing, pole, identical, below-horizon and back-facing configurations; α at the clamp.
    wi = jnp.asarray([[1.0, 0, 0], [0, 0, 1.0], [0, 0, 1.0], [0.6, 0, 0.8], [0.6, 0, -0.8], [0.6, 0, 0.8]])
    wo = jnp.asarray([[0.0, 1, 0], [0, 0, 1.0], [0.6, 0, 0.8], [0.6, 0, 0.8], [0.0, 0.6, 0.8], [-0.6, 0, 0.8]])
    wm = half_vector(wi, wo).at[5].set(jnp.asarray([0.0, 0.0, -1.0]))
    for a in ([1e-6, 1e-6], [0.3, 0.1]):
        val, g = jax.value_and_grad(lambda x: f(x, wi, wo, wm))(jnp.asarray(a))
        assert np.isfinite(float(val)) and np.all(np.isfinite(np.asarray(g))), a
    g32 = form(GGX(jnp.float32(0.3)), wi.astype(jnp.float32), wo.astype(jnp.float32), wm.astype(jnp.float32))
    assert g32.dtype == jnp.float32 and bool(jnp.all(jnp.isfinite(g32)))
    np.testing.assert_allclose(g32, form(GGX(0.3), wi, wo, wm), rtol=1e-5, atol=1e-7)
