"""APS 2000 generator: consistency with the Smith microfacet lobe, energy (§5.3), total albedo
with the coupled diffuse term (eq. 30), reciprocity of every variant, the general (non-heightfield,
unnormalized, tabulated, user-function) distributions, and g(k) against a brute-force NumPy
integral.

Albedos are computed here independently of the library's R(k) route: a plain midpoint rule over
half vectors with θh warped as (π/2)u² (the MERL warp), dωo = 4 (wo·h) dωh.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from half_vector_rule import half_vector_rule

from brdffit.models import get_model
from brdffit.models.aps import ANISO_RESOLUTION
from brdffit.terms.aps import (
    COARSE,
    CORRELATED,
    UNCORRELATED,
    AnisotropicGaussian,
    Correlated,
    FunctionDistribution,
    NDFDistribution,
    Resolution,
    TabulatedDistribution,
    Velvet,
    aps_brdf,
    aps_specular,
    build_g_table,
    satin,
    v_groove,
)
from brdffit.terms.fresnel import schlick
from brdffit.terms.masking import G2_separable
from brdffit.terms.microfacet import microfacet_specular
from brdffit.terms.ndf import GGX
from brdffit.terms.ndf.beckmann import Beckmann

F64 = jnp.float64


def hemi(n, seed, min_cos=0.05):
    rng = np.random.default_rng(seed)
    z = rng.uniform(min_cos, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z**2)
    return jnp.asarray(np.stack([r * np.cos(phi), r * np.sin(phi), z], -1))


def albedo(f, theta_i, phi_i=0.3, n_th=300, n_ph=200):
    """``∫ f(wi, wo) cosθo dωo`` over half vectors (:mod:`half_vector_rule`)."""
    wi, wo, w = half_vector_rule(theta_i, n_th, n_ph, phi_i)
    val = np.asarray(f(jnp.asarray(wi), jnp.asarray(wo)))
    return (val * w[..., None]).sum(axis=(0, 1))


# -- consistency with the microfacet lobe ------------------------------------------------------
@pytest.mark.parametrize("ndf", [GGX(0.25), GGX(0.6), Beckmann(0.3)], ids=["ggx.25", "ggx.6", "beckmann.3"])
def test_aps_with_a_smith_ndf_is_the_lobe_with_separable_g2(ndf):
    """p = D (normalized heightfield): P(k) = G1 (APS eq. 25 vs RTR 9.24), so eq. 26 = RTR 9.34 + 9.27."""
    wi, wo = hemi(400, 1), hemi(400, 2)
    f0 = jnp.asarray([0.9, 0.5, 0.04])
    dist = NDFDistribution(ndf)
    table = build_g_table(dist, F64, Resolution())
    got = aps_specular(dist, table, f0, wi, wo)
    ref = microfacet_specular(ndf, partial(schlick, f0), wi, wo, g2=G2_separable)
    np.testing.assert_allclose(table.hn, 1.0, rtol=1e-6)
    np.testing.assert_allclose(got, ref, rtol=2e-3)


def test_p_need_not_be_normalized_eq_26():
    wi, wo = hemi(100, 3), hemi(100, 4)
    a = aps_brdf(AnisotropicGaussian(0.2, 0.4), jnp.full(3, 0.3), jnp.full(3, 0.5), wi, wo, resolution=COARSE)
    scaled = FunctionDistribution(lambda h, s: 7.3 * AnisotropicGaussian(*s).p(h), (0.2, 0.4))
    b = aps_brdf(scaled, jnp.full(3, 0.3), jnp.full(3, 0.5), wi, wo, resolution=COARSE)
    np.testing.assert_allclose(a, b, rtol=1e-10)


def _numpy_g(p_np, k, n=1200):
    """Brute force: ∫_{h_z>0} (h·k)⁺ p(h) dω on a midpoint (θ, φ) grid (second order at the kink)."""
    th = (np.arange(n) + 0.5) * (np.pi / 2) / n
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1)
    w = np.sin(TH) * (np.pi / 2 / n) * (np.pi / n)
    return [float(np.sum(np.maximum(h @ kk, 0) * p_np(h) * w)) for kk in k]


def test_g_table_matches_brute_force_integral_anisotropic():
    sx, sy = 0.25, 0.5

    def p_np(h):
        return np.exp(-((h[..., 0] / sx) ** 2 + (h[..., 1] / sy) ** 2) / h[..., 2] ** 2)

    k = np.asarray(hemi(12, 5, min_cos=0.1))
    table = build_g_table(AnisotropicGaussian(sx, sy), F64, Resolution(n_u=33, n_phi=48))
    np.testing.assert_allclose(table.g(jnp.asarray(k)), _numpy_g(p_np, k), rtol=5e-3)
    np.testing.assert_allclose(table.mean_normal[:2], 0.0, atol=1e-12)


# -- energy (APS §5.3) and the coupled diffuse term ----------------------------------------------
DISTS = {
    "gaussian": (AnisotropicGaussian(0.2, 0.5), UNCORRELATED),
    "gaussian-corr": (AnisotropicGaussian(0.2, 0.5), Correlated(width=1e3)),  # t = 1: worst case
    "velvet": (Velvet(0.5), CORRELATED),
    "satin": (satin(), UNCORRELATED),
    "vgroove": (v_groove(0.35, 0.15), UNCORRELATED),
}


@pytest.mark.parametrize("name", DISTS)
def test_specular_albedo_at_most_one_with_f0_one(name):
    dist, shadowing = DISTS[name]
    # The registered models' tables: COARSE's 16 azimuth nodes overshoot by ~1% at 85° for the
    # narrow V-groove lobes (bilinear interpolation of g in φ), the models' 24 do not.
    f = jax.jit(lambda wi, wo: aps_brdf(dist, jnp.ones(3), None, wi, wo, shadowing=shadowing, resolution=ANISO_RESOLUTION))
    for theta in np.radians([0.0, 40.0, 75.0, 85.0]):
        a = albedo(f, theta)[0]
        assert 0.0 < a <= 1.0 + 3e-3, (name, np.degrees(theta), a)


@pytest.mark.parametrize("name", ["gaussian", "velvet"])
def test_total_albedo_is_one_with_unit_diffuse_albedo(name):
    dist, shadowing = DISTS[name]
    f0 = jnp.asarray([0.04, 0.5, 1.0])
    f = jax.jit(lambda wi, wo: aps_brdf(dist, f0, jnp.ones(3), wi, wo, shadowing=shadowing))
    for theta in np.radians([0.0, 50.0, 80.0]):
        np.testing.assert_allclose(albedo(f, theta), 1.0, atol=3e-3)
    spec = jax.jit(lambda wi, wo: aps_brdf(dist, f0, None, wi, wo, shadowing=shadowing))
    assert np.all(albedo(spec, 0.9) < 0.99)  # the diffuse term really contributes


def test_metal_variant_albedo_is_R_plus_f0_times_leftover():
    """Metal (§5.1): diffuse albedo f0 (f0 - R)⁺, with R the specular albedo; zero where R > f0."""
    dist, f0 = AnisotropicGaussian(0.3, 0.3), jnp.asarray([0.95, 0.6, 0.2])
    spec = jax.jit(lambda wi, wo: aps_brdf(dist, f0, None, wi, wo))
    full = jax.jit(lambda wi, wo: aps_brdf(dist, f0, None, wi, wo, metal=True))
    for theta in np.radians([0.0, 60.0]):
        r = albedo(spec, theta)
        np.testing.assert_allclose(albedo(full, theta), r + np.asarray(f0) * np.maximum(np.asarray(f0) - r, 0), atol=5e-3)


# -- reciprocity, shadowing forms, general distributions ------------------------------------------
def _nonheightfield(h, s):
    # A full-sphere p that vanishes below the horizon: must equal the heightfield result.
    return jnp.where(h[..., 2] > 0, AnisotropicGaussian(s).p(h), 0.0)


VARIANTS = {
    "uncorrelated": dict(dist=AnisotropicGaussian(0.2, 0.4)),
    "correlated": dict(dist=AnisotropicGaussian(0.2, 0.4), shadowing=CORRELATED),
    "metal": dict(dist=AnisotropicGaussian(0.2, 0.4), metal=True),
    "velvet": dict(dist=Velvet(0.6), shadowing=CORRELATED),
    "satin": dict(dist=satin()),
    "vgroove": dict(dist=v_groove()),
    "non-heightfield": dict(dist=FunctionDistribution(_nonheightfield, 0.3, heightfield=False)),
    "tabulated": dict(dist=TabulatedDistribution(jnp.asarray(np.random.default_rng(0).uniform(0.5, 1, (10, 8))))),
}


@pytest.mark.parametrize("name", VARIANTS)
def test_reciprocity_every_variant(name):
    kw = dict(VARIANTS[name])
    dist = kw.pop("dist")
    wi, wo = hemi(200, 6), hemi(200, 7)
    f = lambda a, b: aps_brdf(dist, jnp.asarray([0.8, 0.4, 0.05]), jnp.full(3, 0.6), a, b, resolution=COARSE, **kw)
    np.testing.assert_allclose(f(wi, wo), f(wo, wi), rtol=1e-10, atol=1e-14)
    assert np.all(np.asarray(f(wi, wo)) >= 0)


def test_non_heightfield_path_equals_heightfield_when_p_vanishes_below():
    wi, wo = hemi(100, 8), hemi(100, 9)
    args = (jnp.full(3, 0.3), jnp.full(3, 0.5), wi, wo)
    a = aps_brdf(AnisotropicGaussian(0.3), *args, resolution=COARSE)
    b = aps_brdf(FunctionDistribution(_nonheightfield, 0.3, heightfield=False), *args, resolution=COARSE)
    np.testing.assert_allclose(a, b, rtol=2e-3)


def test_non_heightfield_mean_normal_includes_the_lower_hemisphere():
    """<<hn>> is the full-sphere average (APS eq. 22): facets facing down subtract from it."""
    def up(h):  # eq. 34 is even in h_z; keep the upper half only
        return jnp.where(h[..., 2] > 0, AnisotropicGaussian(0.3).p(h), 0.0)

    both = FunctionDistribution(lambda h, s: up(h) + s * up(h * jnp.asarray([1.0, 1.0, -1.0])), 0.25, heightfield=False)
    t_up = build_g_table(AnisotropicGaussian(0.3), F64, COARSE)
    t_both = build_g_table(both, F64, COARSE)
    np.testing.assert_allclose(t_both.hn, 0.75 * t_up.hn, rtol=1e-6)
    k = hemi(20, 10)
    assert np.all(np.asarray(t_both.P(k)) <= np.asarray(t_up.P(k)) + 1e-9)  # more self-shadowing


def test_tabulated_distribution_reproduces_the_analytic_one():
    sx, sy = 0.35, 0.6
    th = np.linspace(0, np.pi / 2, 181)
    ph = np.arange(72) * 2 * np.pi / 72
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    vals = np.exp(-np.tan(np.minimum(TH, 1.5706)) ** 2 * (np.cos(PH) ** 2 / sx**2 + np.sin(PH) ** 2 / sy**2))
    wi, wo = hemi(200, 11, min_cos=0.2), hemi(200, 12, min_cos=0.2)
    args = (jnp.full(3, 0.3), jnp.full(3, 0.5), wi, wo)
    a = aps_brdf(AnisotropicGaussian(sx, sy), *args, resolution=COARSE)
    b = aps_brdf(TabulatedDistribution(jnp.asarray(vals)), *args, resolution=COARSE)
    np.testing.assert_allclose(b, a, rtol=3e-2)


def test_correlated_form_raises_retroreflection_only():
    dist = Velvet(0.5)
    table = build_g_table(dist, F64)
    th = np.radians(60.0)
    k = jnp.asarray([[np.sin(th), 0.0, np.cos(th)]])
    far = jnp.asarray([[-np.sin(th), 0.0, np.cos(th)]])  # φ = π: t ≈ 0
    f0 = jnp.full(3, 0.05)
    assert aps_specular(dist, table, f0, k, k, CORRELATED)[0, 0] > 1.5 * aps_specular(dist, table, f0, k, k)[0, 0]
    np.testing.assert_allclose(aps_specular(dist, table, f0, k, far, CORRELATED), aps_specular(dist, table, f0, k, far), rtol=1e-12)


def test_gradient_through_the_tables_matches_finite_differences():
    wi, wo = hemi(32, 13), hemi(32, 14)

    @jax.jit
    def scalar(s):
        d = FunctionDistribution(_nonheightfield, s, heightfield=False)
        return jnp.sum(aps_brdf(d, jnp.full(3, 0.2), jnp.full(3, 0.5), wi, wo, resolution=COARSE))

    x = jnp.asarray(0.3)
    g = float(jax.jit(jax.grad(scalar))(x))
    fd = (float(scalar(x + 1e-6)) - float(scalar(x - 1e-6))) / 2e-6
    assert g == pytest.approx(fd, rel=1e-5)


def test_registered_models_declare_anisotropy_and_bounds():
    assert get_model("aps-velvet").isotropic
    for name in ("aps-gaussian", "aps-satin", "aps-vgroove"):
        assert not get_model(name).isotropic
    assert get_model("aps-gaussian").param("sigma_x").log


@pytest.mark.parametrize("name", ["aps-velvet", "aps-gaussian", "aps-satin", "aps-vgroove"])
def test_staged_evaluation_equals_the_model_function(name):
    """``evaluate_model`` runs a registered APS model as prepare / per-pair / combine (tables built
    once, two programs); it must give what the one-program ``fn`` (which fits use) gives,
    across chunk boundaries and padding."""
    from brdffit.models.evaluate import evaluate_model

    model = get_model(name)
    assert model.stages is not None
    rng = np.random.default_rng(5)
    params = {p.name: rng.uniform(max(p.lower, 0.1), min(p.upper, 0.9), p.shape) for p in model.params}
    wi, wo = np.asarray(hemi(700, 1)), np.asarray(hemi(700, 2))
    staged = evaluate_model(model, params, wi, wo, chunk=256)
    full = {k: jnp.asarray(v) for k, v in model.complete(params).items()}
    whole = np.asarray(jax.jit(model.fn)(full, jnp.asarray(wi), jnp.asarray(wo)))
    np.testing.assert_allclose(staged, whole, rtol=1e-12, atol=1e-14)
    assert np.all(staged > 0)


def test_azimuth_matches_atan2():
    """The table lookups' azimuth (octant-reduced arctan) is ``atan2`` wrapped to [0, 2π)."""
    from brdffit.terms._math import azimuth

    rng = np.random.default_rng(3)
    xy = rng.normal(size=(20000, 2))
    xy[:8] = [[1, 0], [0, 1], [-1, 0], [0, -1], [1, 1], [-1, -1], [1, -1], [-1, 1]]
    got = np.asarray(azimuth(jnp.asarray(xy[:, 0]), jnp.asarray(xy[:, 1])))
    want = np.mod(np.arctan2(xy[:, 1], xy[:, 0]), 2 * np.pi)
    diff = np.abs(got - want)
    assert np.all(np.minimum(diff, 2 * np.pi - diff) < 4e-15)
    assert np.all((got >= 0) & (got < 2 * np.pi))
    assert float(azimuth(jnp.asarray(0.0), jnp.asarray(0.0))) == 0.0
