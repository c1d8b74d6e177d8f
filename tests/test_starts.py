"""Data-driven starting points: a model declares its own (``Model.start``), the fitter uses it.

Every hook of the registry names parameters of its model, with values inside their bounds, for
features at the edges of what :func:`brdffit.fitting.measure` returns; the conductor's start
reproduces the measured ``F0``; a model without a hook gets the features by parameter name.
Fits from the hooks are exercised by ``tests/test_models.py`` (recovery) and
``tests/test_export*.py`` (renderer-native models)."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import brdffit
from brdffit.fitting.start import Features, guess
from test_fit_units import hemisphere

#: Features at the edges of what ``measure`` returns: dielectric and metal, narrow and wide.
FEATURES = [
    Features(np.array([1e-3, 1e-3, 1e-3]), np.array([1e-6] * 3), 2e-3, np.array([0.01] * 3)),
    Features(np.array([0.95, 0.5, 0.1]), np.array([50.0, 20.0, 5.0]), 0.9, np.array([0.95, 0.6, 0.3])),
    Features(np.array([0.2, 0.2, 0.2]), np.array([3.0] * 3), 0.1, np.array([0.04, 0.04, 0.04])),
]
NATIVE = ("disney", "mitsuba-principled", "gltf-pbr", "mitsuba-roughconductor",
          "mitsuba-roughconductor-aniso", "mitsuba-roughconductor-beckmann",
          "mitsuba-roughconductor-tint")
HOOKED = sorted({*NATIVE, *(n for n in brdffit.available_models()
                            if brdffit.get_model(n).start is not None)})


def test_disney_and_the_renderer_native_models_declare_a_start():
    assert all(brdffit.get_model(name).start is not None for name in NATIVE)


@pytest.mark.parametrize("feat", FEATURES, ids=["dark-narrow", "metal-wide", "dielectric"])
@pytest.mark.parametrize("name", HOOKED)
def test_a_start_hook_names_its_models_parameters_inside_their_bounds(name, feat):
    model = brdffit.get_model(name)
    values = model.start(feat)
    assert values and set(values) <= set(model.names)
    for key, value in values.items():
        p = model.param(key)
        v = p.coerce(value)  # the parameter's shape
        assert np.all((p.lower <= v) & (v <= p.upper)), (key, v, p.lower, p.upper)
    start = guess(model, feat)  # what the fitter starts from: inside, off the bounds
    for key, v in start.items():
        p = model.param(key)
        assert np.all((p.lower < v) & (v < p.upper))


def test_metallic_roughness_models_read_metal_and_dielectric():
    metal, dielectric = FEATURES[1], FEATURES[2]
    for name in ("disney", "mitsuba-principled", "gltf-pbr"):
        model = brdffit.get_model(name)
        m, d = model.start(metal), model.start(dielectric)
        assert m["metallic"] > 0.5 > d["metallic"]
        np.testing.assert_allclose(m["base_color"], metal.f0)
        np.testing.assert_allclose(d["base_color"], dielectric.diffuse)
        assert d["roughness"] == pytest.approx(np.sqrt(dielectric.alpha))  # α = roughness²
    assert brdffit.get_model("disney").start(dielectric)["specular"] == pytest.approx(0.5)


@pytest.mark.parametrize("feat", FEATURES[1:], ids=["metal-wide", "dielectric"])
def test_the_conductor_start_reproduces_the_measured_f0(feat):
    """At normal incidence the complex-IOR model's Fresnel is the start's reflectance: the
    ratio to the tint form with ``specular_reflectance = 1`` (whose Fresnel is 1)."""
    ior = brdffit.get_model("mitsuba-roughconductor")
    tint = brdffit.get_model("mitsuba-roughconductor-tint")
    start = ior.start(feat)
    n = jnp.array([[0.0, 0.0, 1.0]])
    ratio = ior(start, n, n) / tint({"alpha": start["alpha"], "specular_reflectance": 1.0}, n, n)
    np.testing.assert_allclose(np.asarray(ratio)[0], feat.f0, rtol=1e-9)
    assert start["alpha"] == feat.alpha
    np.testing.assert_allclose(tint.start(feat)["specular_reflectance"], feat.f0)


def test_the_fitter_uses_a_models_hook_and_keeps_the_rest_at_defaults():
    ggx = brdffit.get_model("ggx")
    hooked = dataclasses.replace(ggx, name="ggx-hooked", start=lambda features: {"alpha": 0.5})
    assert guess(hooked, FEATURES[2]) == {"alpha": 0.5}
    by_name = guess(ggx, FEATURES[2])  # no hook: the features by parameter name
    assert set(by_name) == {"diffuse", "f0", "alpha"} and by_name["alpha"] == 0.1


def _lambert_with_a_peak(share: float, alpha: float = 0.1, n: int = 40_000, seed: int = 5):
    """Cells of a Lambertian ``ρ_d = 0.4`` plus a GGX lobe whose height at the mirror direction
    is ``share`` of ``ρ_d/π``, with 2 % multiplicative scatter (a measurement's)."""
    from brdffit.terms.ndf import GGX

    rng = np.random.default_rng(seed)
    wi, wo = hemisphere(n, rng), hemisphere(n, rng)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    lobe = np.asarray(GGX(alpha).D(jnp.asarray(h))) / float(GGX(alpha).D(jnp.array([0.0, 0, 1])))
    rho = 0.4 / np.pi * (1.0 + share * lobe)
    rgb = np.repeat(rho[:, None], 3, axis=1) * (1.0 + 0.02 * rng.standard_normal((n, 3)))
    return rgb, wi, wo


def test_a_peak_within_the_scatter_of_a_matte_table_reads_as_broad():
    """A lobe above the floor but lower than ``FLAT_PEAK`` of the diffuse level has no width to
    read: it reads as the broadest start (``α`` 0.9), not as whatever width the scatter of the
    bins nearest the peak suggests (narrow: the realistic fabrics and foam read 0.002, started a
    sharp lobe and walked it broad for tens of steps). A peak well above the diffuse level keeps
    its measured width."""
    from brdffit.fitting.start import ALPHA_RANGE, FLAT_PEAK, NO_PEAK, measure

    rgb, wi, wo = _lambert_with_a_peak(share=0.2 * FLAT_PEAK)
    flat = measure(rgb, wi, wo, np.ones(len(rgb), bool))
    assert flat.alpha == ALPHA_RANGE[1]
    rgb, wi, wo = _lambert_with_a_peak(share=5.0, alpha=0.1)
    peak = measure(rgb, wi, wo, np.ones(len(rgb), bool))
    assert 0.05 < peak.alpha < 0.2
    # no excess at all (an exact Lambertian table): the narrow reading, a lobe that can vanish
    lambert = np.full_like(rgb, 0.4 / np.pi)
    none = measure(lambert, wi, wo, np.ones(len(rgb), bool))
    assert np.all(none.height == NO_PEAK) and none.alpha < 0.1
