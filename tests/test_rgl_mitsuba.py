"""The RGL format against Mitsuba 3 itself (``scalar_rgb``): Mitsuba's code is the reference.

* The NumPy ``Marginal2D`` against ``mitsuba.MarginalContinuous2D0`` / ``...2D2`` (``sample``,
  ``invert``, ``eval`` on random data, with and without parameters and normalization).
* Files made by :func:`synthesize_rgl` / :func:`write_rgl` load in Mitsuba's ``measured`` BSDF,
  and its ``eval`` (divided by ``cos θo``: Mitsuba's includes the cosine) agrees with
  :meth:`RGLMaterial.eval` at 10,000+ random direction pairs, isotropic and anisotropic (each
  ``φi`` reduction), to float32 precision.
* A tensor file written by Mitsuba's own ``tensor_io.write`` reads back here.

The directions are rounded to float32 first, so that both sides evaluate the same pairs.
"""

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba", reason="mitsuba (scalar_rgb) not installed: "
                         "pip install -e '.[mitsuba]'")
mi.set_variant("scalar_rgb")

from data_formats import read_rgl, read_tensor_file, synthesize_rgl, write_rgl  # noqa: E402
from data_formats.rgl import Marginal2D  # noqa: E402
from test_rgl_format import ggx_aniso, ggx_iso, random_pairs  # noqa: E402


def f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


@pytest.mark.parametrize("dim", [0, 2])
@pytest.mark.parametrize("normalize", [True, False])
def test_marginal2d_matches_mitsuba(dim, normalize):
    rng = np.random.default_rng(10 + dim + normalize)
    shape = (3, 4, 5, 7) if dim else (6, 9)
    data = (rng.random(shape) ** 3).astype(np.float32)
    values = ([np.sort(rng.uniform(-1, 1, 3)).astype(np.float32),
               np.sort(rng.uniform(0, 1, 4)).astype(np.float32)] if dim else [])
    ours = Marginal2D(data, values, normalize=normalize)
    if dim:
        ref = mi.MarginalContinuous2D2(data, [v.tolist() for v in values], normalize=normalize)
    else:
        ref = mi.MarginalContinuous2D0(data, normalize=normalize)
    n = 3000
    u = f32(rng.random((n, 2)))
    params = [f32(rng.uniform(-1.3, 1.3, n)), f32(rng.uniform(-0.2, 1.2, n))] if dim else []
    for op in ("sample", "invert", "eval"):
        mine = getattr(ours, op)(u, params)
        theirs = []
        for k in range(n):
            args = [mi.Point2f(*u[k])] + ([mi.Vector2f(params[0][k], params[1][k])] if dim else [])
            r = getattr(ref, op)(*args)
            theirs.append([r] if op == "eval" else [r[0][0], r[0][1], r[1]])
        theirs = np.array(theirs)
        # Mitsuba's float32 arithmetic: absolute errors of a few ulps of the largest value,
        # and in sample() the cancellation of its quadratic inversion (sample_segment).
        scale = float(np.max(ours.data))
        if op == "eval":
            np.testing.assert_allclose(mine, theirs[:, 0], rtol=1e-5, atol=1e-6 * scale)
        else:
            atol = 5e-5 if op == "sample" else 1e-6
            np.testing.assert_allclose(mine[0], theirs[:, :2], atol=atol)
            np.testing.assert_allclose(mine[1], theirs[:, 2], rtol=5e-4 if op == "sample" else
                                       1e-5, atol=1e-6 * scale)


def mitsuba_eval(path, wi, wo):
    """Mitsuba's ``measured`` BSDF at each pair, divided by ``cos θo``."""
    bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    out = np.empty((len(wi), 3))
    for k in range(len(wi)):
        si.wi = mi.Vector3f(*wi[k])
        v = bsdf.eval(ctx, si, mi.Vector3f(*wo[k]))
        out[k] = (v[0], v[1], v[2])
    return out / wo[:, 2:3]


CASES = {
    "iso": (ggx_iso, dict(isotropic=True, n_theta_i=6, resolution=16, vndf_shape=(16, 16))),
    "aniso-1": (ggx_aniso, dict(isotropic=False, reduction=1, n_phi_i=9, n_theta_i=5,
                                resolution=12, vndf_shape=(12, 12), ndf_shape=(12, 12),
                                sigma_shape=(8, 8))),
    "aniso-2": (ggx_aniso, dict(isotropic=False, reduction=2, n_phi_i=5, n_theta_i=5,
                                resolution=12, vndf_shape=(12, 12), ndf_shape=(12, 12),
                                sigma_shape=(8, 8))),
    "aniso-4": (ggx_aniso, dict(isotropic=False, reduction=4, n_phi_i=4, n_theta_i=5,
                                resolution=12, vndf_shape=(12, 12), ndf_shape=(12, 12),
                                sigma_shape=(8, 8))),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_written_files_render_in_mitsuba_as_brdffit_evaluates_them(tmp_path, case):
    brdf, kw = CASES[case]
    path = tmp_path / f"{case}.bsdf"
    write_rgl(path, synthesize_rgl(brdf, name=case, **kw))
    mat = read_rgl(path)
    assert mat.isotropic == (case == "iso")
    assert mat.reduction == (1 if case == "iso" else int(case[-1]))
    wi, wo = random_pairs(12000, 7)
    wi, wo = f32(wi), f32(wo)
    assert len(wi) >= 10000
    theirs = mitsuba_eval(path, wi, wo)
    mine = mat.eval(wi, wo)
    assert np.all(mine >= 0) and np.any(mine > 0)
    # float32 precision: Mitsuba's single-precision arithmetic on the same float32 tables.
    np.testing.assert_allclose(mine, theirs, rtol=1e-4, atol=1e-6)
    # Below the horizon both give 0.
    flip = wo * np.array([1, 1, -1])
    assert np.all(mat.eval(wi[:200], flip[:200]) == 0)
    assert np.all(mitsuba_eval(path, wi[:200], flip[:200]) == 0)


def test_a_tensor_file_written_by_mitsuba_reads_here(tmp_path):
    from mitsuba.python import tensor_io

    a = np.arange(24, dtype=np.float32).reshape(2, 3, 4)
    b = np.array([7, 8], dtype=np.uint8)
    tensor_io.write(str(tmp_path / "m.tensor"), a=a, b=b, text="hi")
    got = read_tensor_file(tmp_path / "m.tensor")
    np.testing.assert_array_equal(got["a"], a)
    np.testing.assert_array_equal(got["b"], b)
    assert bytes(got["text"]) == b"hi"


def test_spectral_files_match_mitsubas_spectral_variant(tmp_path):
    """A spectral ``.bsdf`` (``spectra`` + ``wavelengths``) in ``scalar_spectral``: Mitsuba's
    value at four random wavelengths per pair against :meth:`RGLMaterial.eval_spectrum`."""
    from test_rgl_format import spectral_version

    brdf, kw = CASES["iso"]
    mat, _ = spectral_version(synthesize_rgl(brdf, **kw))
    path = tmp_path / "spectral.bsdf"
    write_rgl(path, mat)
    mine_mat = read_rgl(path)
    wi, wo = random_pairs(3000, 3)
    wi, wo = f32(wi), f32(wo)
    lam = f32(np.random.default_rng(0).uniform(350, 1010, (len(wi), 4)))
    mi.set_variant("scalar_spectral")
    try:
        bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
        ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        theirs = np.empty((len(wi), 4))
        for k in range(len(wi)):
            si.wi, si.wavelengths = mi.Vector3f(*wi[k]), mi.Spectrum(*lam[k])
            v = bsdf.eval(ctx, si, mi.Vector3f(*wo[k]))
            theirs[k] = [v[i] for i in range(4)]
    finally:
        mi.set_variant("scalar_rgb")
    np.testing.assert_allclose(mine_mat.eval_spectrum(wi, wo, lam), theirs / wo[:, 2:3],
                               rtol=1e-4, atol=1e-6)


def test_spectra_reduce_to_rgb_as_mitsubas_spectrum_list_to_srgb():
    from data_formats.rgl import spectra_to_rgb

    rng = np.random.default_rng(8)
    wl = np.linspace(360, 830, 48)
    for _ in range(5):
        v = rng.random(48)
        theirs = np.array(mi.spectrum_list_to_srgb(wl.tolist(), v.tolist(), False, True))
        # Mitsuba's 1000-step quadrature and its normalization constants: 1e-3 apart.
        np.testing.assert_allclose(spectra_to_rgb(wl, v), theirs, rtol=3e-3, atol=1e-4)
