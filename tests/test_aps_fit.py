"""Parameter recovery through ``brdffit.fit``: an APS velvet table in the MERL layout (written to
disk and read back) and anisotropic-Gaussian direction-pair samples, fitted back to the
parameters that made them. Small grids and subsamples keep the fits quick.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from test_aps import hemi

import brdffit
from data_formats.merl import read_merl, synthesize, write_merl
from data_formats.samples import SampleSet

VELVET = {"diffuse": [0.3, 0.15, 0.08], "f0": [0.12, 0.1, 0.08], "sigma": 0.8}
GAUSSIAN = {"diffuse": [0.2, 0.25, 0.3], "f0": [0.6, 0.5, 0.4], "sigma_x": 0.15, "sigma_y": 0.4}


def _truth_fn(name, truth):
    m = brdffit.get_model(name)
    p = {k: jnp.asarray(v) for k, v in truth.items()}
    return jax.jit(lambda wi, wo: m(p, wi, wo))


def _check(result, truth, rtol):
    assert result.success, result.message
    for k, v in truth.items():
        np.testing.assert_allclose(result.params[k], v, rtol=rtol, err_msg=k)


def test_velvet_recovered_from_a_merl_layout_table(tmp_path):
    f = _truth_fn("aps-velvet", VELVET)
    table = synthesize(lambda wi, wo: np.asarray(f(jnp.asarray(wi), jnp.asarray(wo))), shape=(16, 16, 32))
    path = tmp_path / "velvet.binary"
    write_merl(path, table)
    result = brdffit.fit(read_merl(path), "aps-velvet", cutoff=80.0, subsample=300, seed=1)
    _check(result, VELVET, rtol=1e-3)  # noise-free: exact up to the solver tolerance


def test_anisotropic_gaussian_recovered_from_direction_pairs():
    wi, wo = hemi(300, 21, min_cos=0.15), hemi(300, 22, min_cos=0.15)
    # Half the pairs near the specular configuration, so the lobe's two widths are seen.
    h = np.asarray(hemi(150, 23, min_cos=0.9))
    wi2 = np.asarray(hemi(150, 24, min_cos=0.4))
    wo2 = 2 * np.sum(wi2 * h, -1, keepdims=True) * h - wi2
    keep = wo2[:, 2] > 0.15
    wi_all = np.concatenate([np.asarray(wi), wi2[keep]])
    wo_all = np.concatenate([np.asarray(wo), wo2[keep]])
    rgb = np.asarray(_truth_fn("aps-gaussian", GAUSSIAN)(jnp.asarray(wi_all), jnp.asarray(wo_all)))
    samples = SampleSet(wi_all, wo_all, rgb, np.ones(len(rgb), bool), name="gaussian")
    result = brdffit.fit(samples, "aps-gaussian", init={"sigma_x": 0.3, "sigma_y": 0.3})
    _check(result, GAUSSIAN, rtol=1e-3)
