"""The Disney principled BRDF against a plain NumPy transcription of Burley's reference shader.

The oracle below is written from Burley 2012 §5, App. B eqs. 4 and 13, the 2014 addenda and the
BRDF Explorer ``disney.brdf`` shader it accompanies (``smithG_GGX`` there is ``G1 / (2 n·v)``, so
``Gs * Fs * Ds`` already holds the ``1/(4 n·l n·v)``). It shares no code with the library.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from half_vector_rule import half_vector_rule

from brdffit.models import disney as dm
from brdffit.models import get_model
from brdffit.terms.diffuse import disney_diffuse

MODEL = get_model("disney")
PI = np.pi


# ---- the oracle ------------------------------------------------------------------------------------


def _mix(a, b, t):
    return a * (1 - t) + b * t


def _schlick_w(u):
    return np.clip(1 - u, 0, 1) ** 5


def _gtr1(ndoth, a):
    a2 = a * a
    return (a2 - 1) / (PI * np.log(a2) * (1 + (a2 - 1) * ndoth**2))


def _gtr2_aniso(ndoth, hx, hy, ax, ay):
    return 1 / (PI * ax * ay * ((hx / ax) ** 2 + (hy / ay) ** 2 + ndoth**2) ** 2)


def _smith_g_ggx(ndotv, alpha_g):
    a, b = alpha_g**2, ndotv**2
    return 1 / (ndotv + np.sqrt(a + b - a * b))


def _smith_g_ggx_aniso(ndotv, vx, vy, ax, ay):
    return 1 / (ndotv + np.sqrt((vx * ax) ** 2 + (vy * ay) ** 2 + ndotv**2))


def oracle(p, L, V):
    """Returns the four lobes (diffuse, sheen, specular, clearcoat) and the whole, each (n, 3)."""
    p = {k: np.asarray(v, dtype=float) for k, v in p.items()}
    H = (L + V) / np.linalg.norm(L + V, axis=-1, keepdims=True)
    nl, nv, nh, lh = L[:, 2:3], V[:, 2:3], H[:, 2:3], np.sum(L * H, -1, keepdims=True)
    c = p["base_color"] * np.ones(3)
    lum = 0.3 * c[0] + 0.6 * c[1] + 0.1 * c[2]
    tint = c / lum if lum > 0 else np.ones(3)
    spec0 = _mix(p["specular"] * 0.08 * _mix(np.ones(3), tint, p["specular_tint"]), c, p["metallic"])
    sheen_c = _mix(np.ones(3), tint, p["sheen_tint"])
    fl, fv = _schlick_w(nl), _schlick_w(nv)
    fd90 = 0.5 + 2 * lh**2 * p["roughness"]
    fd = _mix(1, fd90, fl) * _mix(1, fd90, fv)
    fss90 = lh**2 * p["roughness"]
    fss = _mix(1, fss90, fl) * _mix(1, fss90, fv)
    ss = 1.25 * (fss * (1 / (nl + nv) - 0.5) + 0.5)
    diffuse = (1 / PI) * _mix(fd, ss, p["subsurface"]) * c
    fh = _schlick_w(lh)
    sheen = fh * p["sheen"] * sheen_c
    aspect = np.sqrt(1 - 0.9 * p["anisotropic"])
    ax, ay = p["roughness"] ** 2 / aspect, p["roughness"] ** 2 * aspect
    ds = _gtr2_aniso(nh, H[:, :1], H[:, 1:2], ax, ay)
    fs = _mix(spec0, 1.0, fh)
    gs = _smith_g_ggx_aniso(nl, L[:, :1], L[:, 1:2], ax, ay) * _smith_g_ggx_aniso(nv, V[:, :1], V[:, 1:2], ax, ay)
    specular = gs * fs * ds
    dr = _gtr1(nh, _mix(0.1, 0.001, p["clearcoat_gloss"]))
    fr = _mix(0.04, 1.0, fh)
    gr = _smith_g_ggx(nl, 0.25) * _smith_g_ggx(nv, 0.25)
    clearcoat = 0.25 * p["clearcoat"] * gr * fr * dr * np.ones(3)
    whole = (diffuse + sheen) * (1 - p["metallic"]) + specular + clearcoat
    return diffuse, sheen, specular, clearcoat, whole


# ---- helpers -------------------------------------------------------------------------------------


def _hemi(rng, n, min_cos=0.02):
    z = rng.uniform(min_cos, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z**2)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def _pairs(n, seed, min_cos=0.02):
    rng = np.random.default_rng(seed)
    return _hemi(rng, n, min_cos), _hemi(rng, n, min_cos)


def _random_params(seed):
    rng = np.random.default_rng(seed)
    p = {q.name: rng.uniform(q.lower + 0.1 * (q.upper - q.lower), q.upper - 0.1 * (q.upper - q.lower), q.shape)
         for q in MODEL.params}
    return {k: np.asarray(v) for k, v in p.items()}


PARAM_SETS = [
    MODEL.defaults(),
    _random_params(0),
    _random_params(1),
    {**_random_params(2), "anisotropic": 1.0, "metallic": 1.0, "clearcoat_gloss": 0.0, "roughness": 0.02},
    {**_random_params(3), "base_color": np.zeros(3), "specular_tint": 1.0, "sheen_tint": 1.0, "roughness": 1.0},
    {**_random_params(4), "subsurface": 1.0, "sheen": 1.0, "clearcoat": 1.0, "clearcoat_gloss": 1.0},
]


def _p(p):
    """Every parameter as a float64 array of its declared shape: one jit trace serves all sets."""
    return {q.name: jnp.asarray(q.coerce(v)) for q, v in zip(MODEL.params, MODEL.complete(p).values())}


#: The model compiled once per input shape; the tests below reuse it (eager mode is only
#: exercised in the jit-vs-eager test, since op-by-op dispatch is slow on a loaded machine).
FN = jax.jit(MODEL.fn)


@jax.jit
def _lobes(p, L, V):
    c = p["base_color"]
    return (
        disney_diffuse(c, p["roughness"], p["subsurface"], L, V),
        dm.sheen_lobe(c, p["sheen"], p["sheen_tint"], L, V),
        dm.specular_lobe(c, p["metallic"], p["specular"], p["specular_tint"], p["roughness"], p["anisotropic"], L, V),
        dm.clearcoat_lobe(p["clearcoat"], p["clearcoat_gloss"], L, V),
        MODEL.fn(p, L, V),
    )


# ---- the model against the oracle ---------------------------------------------------------------


@pytest.mark.parametrize("k", range(len(PARAM_SETS)))
def test_each_lobe_and_the_whole_match_the_reference_shader(k):
    p = PARAM_SETS[k]
    L, V = _pairs(300, 10 + k)
    names = ("diffuse", "sheen", "specular", "clearcoat", "whole")
    for name, got, want in zip(names, _lobes(_p(p), jnp.asarray(L), jnp.asarray(V)), oracle(p, L, V)):
        assert got.shape == (300, 3), name
        np.testing.assert_allclose(np.asarray(got), want, rtol=1e-10, atol=1e-14, err_msg=name)


def test_lobes_switch_off_as_documented():
    L, V = (jnp.asarray(a) for a in _pairs(300, 5))
    p = _p({**_random_params(5), "metallic": 1.0, "clearcoat": 0.0})
    spec = _lobes(p, L, V)[2]
    np.testing.assert_allclose(FN(p, L, V), spec, rtol=1e-14)  # metal: no diffuse, no sheen
    # A metal's F0 is its base color; a dielectric's is 0.08·specular (0.04 at the default 0.5).
    c = jnp.asarray([0.9, 0.6, 0.3])
    np.testing.assert_allclose(dm.specular_f0(c, 1.0, 0.5, 0.7), c, rtol=1e-14)
    np.testing.assert_allclose(dm.specular_f0(c, 0.0, 0.5, 0.0), [0.04] * 3, rtol=1e-14)
    np.testing.assert_allclose(dm.tint_color(c) @ jnp.asarray(dm.LUMINANCE), 1.0, rtol=1e-14)
    np.testing.assert_array_equal(np.asarray(dm.tint_color(jnp.zeros(3))), 1.0)


def test_anisotropic_alphas_follow_the_addenda():
    ax, ay = dm.anisotropic_alphas(0.5, 1.0)
    assert float(ax / ay) == pytest.approx(10.0)  # the 0.9 factor limits the aspect ratio to 10:1
    assert float(ax * ay) == pytest.approx(0.5**4)
    ax, ay = dm.anisotropic_alphas(0.3, 0.0)
    assert float(ax) == float(ay) == pytest.approx(0.09)


def test_registry_entry():
    assert MODEL.names == (
        "base_color", "subsurface", "metallic", "specular", "specular_tint", "roughness",
        "anisotropic", "sheen", "sheen_tint", "clearcoat", "clearcoat_gloss",
    )
    assert MODEL.size == 13 and MODEL.isotropic is False and MODEL.description
    lower = {"roughness": 0.02, "base_color": dm.BASE_COLOR_MIN}  # see dm.tint_color
    for q in MODEL.params:
        assert (q.lower, q.upper) == (lower.get(q.name, 0.0), 1.0), q.name
    d = MODEL.defaults()  # Burley's defaults in BRDF Explorer's disney.brdf
    np.testing.assert_allclose(d["base_color"], [0.82, 0.67, 0.16])
    assert (d["specular"], d["roughness"], d["sheen_tint"], d["clearcoat_gloss"]) == (0.5, 0.5, 0.5, 1.0)
    assert all(d[n] == 0.0 for n in ("subsurface", "metallic", "specular_tint", "anisotropic", "sheen", "clearcoat"))


# ---- invariants ----------------------------------------------------------------------------------


def test_reciprocity_and_zero_below_horizon():
    L, V = (jnp.asarray(a) for a in _pairs(300, 6))
    for p in PARAM_SETS[1:]:
        p = _p(p)
        np.testing.assert_allclose(FN(p, L, V), FN(p, V, L), rtol=1e-10, atol=1e-14)
        np.testing.assert_array_equal(np.asarray(FN(p, L * jnp.asarray([1, 1, -1.0]), V)), 0.0)


def _rot_z(v, angle):
    c, s = np.cos(angle), np.sin(angle)
    return v @ jnp.asarray([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T


def test_azimuth_matters_only_with_anisotropy():
    L, V = (jnp.asarray(a) for a in _pairs(300, 7))
    iso = {**_random_params(7), "anisotropic": 0.0}
    np.testing.assert_allclose(FN(_p(iso), _rot_z(L, 1.1), _rot_z(V, 1.1)), FN(_p(iso), L, V), rtol=1e-10)
    aniso = _p({**iso, "anisotropic": 0.8, "roughness": 0.3})
    diff = FN(aniso, _rot_z(L, 1.1), _rot_z(V, 1.1)) - FN(aniso, L, V)
    assert float(jnp.max(jnp.abs(diff))) > 1e-2


def _albedo_fn(theta_i, n_th=200, n_ph=96):
    """Directional albedo over half vectors (:mod:`half_vector_rule`): ``(wi, wo, weight)``."""
    return tuple(jnp.asarray(a) for a in half_vector_rule(theta_i, n_th, n_ph))


_ALBEDO = jax.jit(lambda f, p, wi, wo, w: jnp.sum(f(p, wi, wo) * w[..., None], axis=(0, 1)), static_argnums=0)


def test_energy_white_metal_albedo_at_most_one():
    """base_color = 1, metallic = 1: F0 = 1 so F = 1, and only the specular lobe remains. With
    F = 1 a Smith microfacet lobe can only lose energy. Measured: 0.9999 at roughness 0.1 (normal
    incidence), 0.31 at roughness 1; the quadrature is checked by the roughness-0.1 value."""
    grids = [_albedo_fn(t) for t in np.radians([0.0, 30.0, 60.0, 80.0])]
    for r in (0.1, 0.5, 1.0):
        for an in (0.0, 0.8):
            p = _p({"base_color": 1.0, "metallic": 1.0, "roughness": r, "anisotropic": an})
            a = np.array([np.asarray(_ALBEDO(MODEL.fn, p, *g)) for g in grids])
            assert np.all(a <= 1.0 + 2e-3), (r, an, a)
            assert np.all(a > 0.2), (r, an, a)
            if r == 0.1:
                np.testing.assert_allclose(a[:3], 1.0, atol=3e-3)


def test_clearcoat_albedo_scale():
    """At normal incidence the clearcoat lobe reflects about 0.25 · F0 = 0.25 · 0.04 (its D is
    normalised; G with α = 0.25 and F's growth off-peak move it by a few %): measured 0.0082
    (gloss 0) to 0.0094 (gloss 1)."""
    g = _albedo_fn(0.0, n_th=400)
    for gloss in (0.0, 1.0):
        p = {"cc": jnp.asarray(1.0), "gloss": jnp.asarray(gloss)}
        a = np.asarray(_ALBEDO(lambda p, l, v: dm.clearcoat_lobe(p["cc"], p["gloss"], l, v), p, *g))
        assert 0.25 * 0.04 * 0.75 < a[0] < 0.25 * 0.04 * 1.05, (gloss, a)


# ---- differentiability ---------------------------------------------------------------------------


def test_gradients_match_finite_differences_for_every_parameter():
    L, V = (jnp.asarray(a) for a in _pairs(64, 8))
    p0 = {**_random_params(8), "anisotropic": 0.6, "sheen": 0.5, "clearcoat": 0.7, "roughness": 0.35}
    x0 = MODEL.flatten(p0)
    scalar = jax.jit(lambda x: jnp.sum(jnp.log1p(MODEL.fn(MODEL.unflatten(x), L, V))))
    g = np.asarray(jax.jit(jax.grad(scalar))(jnp.asarray(x0)))
    for i, label in enumerate(MODEL.flat_names()):
        e = np.zeros_like(x0)
        e[i] = 1e-6
        fd = (float(scalar(jnp.asarray(x0 + e))) - float(scalar(jnp.asarray(x0 - e)))) / 2e-6
        assert g[i] == pytest.approx(fd, rel=1e-5, abs=1e-8), label
        assert abs(g[i]) > 1e-6, label  # every parameter reaches the output


def test_jit_matches_eager_and_float32_is_finite():
    L, V = (jnp.asarray(a) for a in _pairs(128, 9, min_cos=0.0))
    p = _p(PARAM_SETS[5])
    eager = MODEL.fn(p, L, V)
    np.testing.assert_allclose(FN(p, L, V), eager, rtol=1e-12, atol=1e-14)
    for q in (p, _p(PARAM_SETS[3])):
        q32 = {k: v.astype(jnp.float32) for k, v in q.items()}
        f32 = FN(q32, L.astype(jnp.float32), V.astype(jnp.float32))
        assert f32.dtype == jnp.float32 and bool(jnp.all(jnp.isfinite(f32)))
        np.testing.assert_allclose(f32, FN(q, L, V), rtol=2e-3, atol=1e-4)


def test_no_nan_gradients_at_grazing_normal_black_and_bounds():
    L = jnp.asarray([[1.0, 0, 0], [0, 0, 1.0], [0, 0, 1.0], [0.6, 0, -0.8], [0.8, 0, 0.6], [0.0, 1.0, 0]])
    V = jnp.asarray([[-1.0, 0, 0], [0, 0, 1.0], [0.6, 0, 0.8], [0.0, 0.6, 0.8], [-0.8, 0, 0.6], [0.0, 1.0, 0]])
    value_and_grad = jax.jit(jax.value_and_grad(lambda x, l: jnp.sum(MODEL.fn(MODEL.unflatten(x), l, V)), (0, 1)))
    lo, hi = MODEL.flat_bounds()
    for x in (lo, hi, MODEL.flatten(PARAM_SETS[4])):  # all-lower includes a black base color
        val, (gx, gl) = value_and_grad(jnp.asarray(x), L)
        assert np.isfinite(float(val)), x
        assert np.all(np.isfinite(np.asarray(gx))) and np.all(np.isfinite(np.asarray(gl))), x
