"""The fitted-distribution models (``low-smooth``, ``low-microfacet``, ``sgd``, ``student-t``).

The registry-wide invariants (reciprocity, isotropy, energy in a white setting, gradients
against finite differences, per-channel declarations, jit, float32, grazing NaN safety) run in
``tests/test_models.py`` and the bbm reference values of every published line in
``tests/test_published_models.py``. Here: every published parameter inside the declared bounds,
the Student-t lobe's limits as models (``ggx``, ``beckmann``), the data-driven starts, and
parameter recovery from synthetic MERL tables written to disk and read back.
"""

from __future__ import annotations

import jax
import numpy as np
import published
import pytest

import brdffit
from brdffit.fitting import Subsample
from brdffit.fitting.start import Features, guess
from brdffit.models import get_model, published_params
from data_formats.merl import read_merl, synthesize, write_merl

STEMS = {"low_lowsmooth_E2": "low-smooth", "low_lowmicrofacet_E2": "low-microfacet",
         "bagher_sgd": "sgd"}


@pytest.mark.parametrize("stem", sorted(STEMS))
def test_every_published_value_lies_inside_the_declared_bounds(stem):
    fits, _ = published.load(stem)
    for fit in fits:
        model, params = published_params(fit)
        assert model.name == STEMS[stem]
        for name, value in params.items():
            p = model.param(name)
            assert np.all((p.lower <= value) & (value <= p.upper)), (fit.material, name, value)


def _pairs(n, seed):
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.05, 1.0, (2, n))
    phi = rng.uniform(0, 2 * np.pi, (2, n))
    r = np.sqrt(1 - z**2)
    w = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
    return w[0], w[1]


def test_student_t_model_contains_ggx_and_tends_to_beckmann():
    wi, wo = _pairs(300, 1)
    p = dict(diffuse=np.array([0.1, 0.2, 0.3]), f0=np.array([0.9, 0.5, 0.04]), alpha=0.17, grazing=0.4)
    st = get_model("student-t")
    np.testing.assert_allclose(st(dict(p, gamma=2.0), wi, wo), get_model("ggx")(p, wi, wo), rtol=2e-6)
    np.testing.assert_allclose(st(dict(p, gamma=1e7), wi, wo), get_model("beckmann")(p, wi, wo),
                               rtol=1e-4)


def test_log_parameter_starts_keep_their_decades():
    """The start hook's values are moved inside the bounds by 1e-3 of the range in log space:
    ``low-smooth``'s ``b = 1/(4α²) = 1e4`` stays 1e4 (a margin of the linear range [1, 1e8] would
    lift every start to at least 1e5), and so do ``A`` and ``k_s`` of dim materials."""
    feat = Features(diffuse=np.full(3, 0.1), height=np.full(3, 0.5), alpha=0.005,
                    f0=np.full(3, 0.04))
    start = guess(get_model("low-smooth"), feat)
    assert start["b"] == pytest.approx(1e4)
    eta = (1 + np.sqrt(0.04)) / (1 - np.sqrt(0.04))
    assert np.allclose(start["a"], 0.5 / ((eta - 1) / (eta + 1)) ** 2)  # 12.5, not 100
    sgd = guess(get_model("sgd"), feat)
    assert np.all(sgd["ks"] < 1.0) and np.all(sgd["alpha"] < 1e-2)


#: model -> (truth, fixed). ``sgd``: one material per channel (its parameters are), the masking
#: term held at its published kind of value, which a table within 80° cannot identify.
CASES = {
    "low-smooth": ({"diffuse": [0.3, 0.2, 0.1], "a": [40.0, 30.0, 20.0], "b": 2e3, "c": 1.2,
                    "eta": 1.6}, None),
    "low-microfacet": ({"diffuse": [0.05, 0.1, 0.2], "a": [300.0, 200.0, 100.0], "b": 5e4, "c": 0.8,
                        "eta": 2.5}, None),
    "student-t": ({"diffuse": [0.2, 0.1, 0.05], "f0": [0.6, 0.4, 0.3], "alpha": 0.08, "gamma": 1.8,
                   "grazing": 0.5}, None),
    "sgd": ({"diffuse": [0.2, 0.1, 0.05], "ks": [2.0, 1.0, 3.0], "alpha": [0.004, 0.02, 0.05],
             "p": [0.4, 0.8, 1.1], "f0": [0.9, 0.5, 0.3], "f1": [0.2, 0.1, -0.1],
             "g_lambda": [3.0, 3.0, 3.0], "g_theta0": [0.5, 0.5, 0.5],
             "g_width": [1.05, 1.05, 1.05], "g_k": [30.0, 30.0, 30.0]},
            ("g_lambda", "g_theta0", "g_width", "g_k")),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_noise_free_recovery_from_default_start(tmp_path, name):
    truth, held = CASES[name]
    model = get_model(name)
    p = model.unflatten(model.flatten(truth))
    f = jax.jit(lambda wi, wo: model.fn(p, wi, wo))
    path = tmp_path / f"{name}.binary"
    write_merl(path, synthesize(lambda wi, wo: np.concatenate(
        [np.asarray(f(a, b))[None] for a, b in zip(wi, wo)]), name=name))
    table = read_merl(path)
    fixed = {k: truth[k] for k in held} if held else None
    res = brdffit.fit(table, name, subsample=Subsample(20000), fixed=fixed)
    x, want = res.x, model.flatten(truth)
    idx = [model.flat_names().index(n) for n in res.free]
    err = np.abs(x[idx] - want[idx]) / np.maximum(np.abs(want[idx]), 1e-2)
    assert res.success, res.message
    assert err.max() <= 1e-3, (res.summary(), dict(zip(res.free, err)))
