"""The tensor file container and the RGL ``.bsdf`` format, without Mitsuba.

Tensor files are built here with plain ``struct`` from the format facts (magic, version, count,
per field name/ndim/dtype/offset/shape; ``data_formats.tensorfile``'s docstring), independently
of the writer under test. The RGL checks: the reader's field checks, the Marginal2D warp's own
consistency, virtual measurements of an analytic GGX read back and evaluated against the model
(the interpolation error, bounds below), and the measurement pattern with its weights.
(``tests/test_rgl_mitsuba.py`` checks all of it against Mitsuba 3 itself.)
"""

import struct
import tracemalloc

import numpy as np
import pytest

from data_formats import (
    RGLFormatError,
    RGLMaterial,
    SampleSet,
    TensorFileError,
    read_rgl,
    read_tensor_file,
    synthesize_rgl,
    write_rgl,
    write_tensor_file,
)
from data_formats.rgl import Marginal2D
from data_formats.rusinkiewicz import dirs_from_half_diff
from numpy_ggx import ggx_numpy

CODES = {"uint8": 1, "int8": 2, "uint16": 3, "int16": 4, "uint32": 5, "int32": 6, "uint64": 7,
         "int64": 8, "float16": 9, "float32": 10, "float64": 11}


def raw_tensor_file(fields, *, count=None, version=(1, 0), magic=b"tensor_file\0", offsets=None,
                    shapes=None, codes=None, align=8):
    """Bytes of a tensor file from ``{name: array}``, from the format facts alone; the keyword
    arguments falsify single header entries."""
    header = magic + struct.pack("<BBI", *version, len(fields) if count is None else count)
    entries = []
    for name, arr in fields.items():
        shape = (shapes or {}).get(name, arr.shape)
        label = name.encode()
        code = (codes or {}).get(name, CODES[arr.dtype.name])
        entries.append((label, len(shape), code, shape))
    size = len(header) + sum(2 + len(lb) + 2 + 1 + 8 + 8 * nd for lb, nd, _, _ in entries)
    pos, body, offs = size, b"", []
    for arr in fields.values():
        pad = -pos % align
        body += b"\0" * pad
        pos += pad
        offs.append(pos)
        body += arr.astype(arr.dtype.newbyteorder("<")).tobytes()
        pos += arr.nbytes
    for (label, nd, code, shape), off, name in zip(entries, offs, fields):
        off = (offsets or {}).get(name, off)
        header += struct.pack("<H", len(label)) + label + struct.pack("<HBQ", nd, code, off)
        header += struct.pack(f"<{nd}Q", *shape)
    return header + body


FIELDS = {"a": np.arange(12, dtype=np.float32).reshape(3, 4),
          "b": np.array([1, 2, 3], dtype=np.uint8),
          "c": np.linspace(0, 1, 5).reshape(5, 1, 1)}


# -- the tensor file -------------------------------------------------------------------------------

def test_tensor_file_reads_the_format_facts_and_round_trips(tmp_path):
    path = tmp_path / "t.tensor"
    path.write_bytes(raw_tensor_file(FIELDS))
    got = read_tensor_file(path)
    assert list(got) == list(FIELDS)
    for k, v in FIELDS.items():
        assert got[k].dtype == v.dtype and got[k].shape == v.shape
        np.testing.assert_array_equal(got[k], v)
    every = {name: (np.arange(6) % 5).astype(name).reshape(2, 3) for name in CODES}
    every["text"] = "héllo"
    write_tensor_file(tmp_path / "w.tensor", every)
    back = read_tensor_file(tmp_path / "w.tensor")
    assert bytes(back.pop("text")).decode() == "héllo"
    for k, v in back.items():
        assert v.dtype == np.dtype(k) and np.array_equal(v, every[k])
    # The writer's bytes are the format's: same as the hand-built file for the same fields.
    write_tensor_file(tmp_path / "same.tensor", FIELDS)
    assert (tmp_path / "same.tensor").read_bytes() == raw_tensor_file(FIELDS)


def _one_line(exc, path, *needles):
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg, msg
    for needle in needles:
        assert needle in msg, msg
    return msg


def test_every_truncation_is_one_clear_error(tmp_path):
    data = raw_tensor_file(FIELDS)
    path = tmp_path / "cut.tensor"
    for n in range(len(data)):
        path.write_bytes(data[:n])
        with pytest.raises(TensorFileError) as exc:
            read_tensor_file(path)
        _one_line(exc, path)
        if n == 0:
            assert "empty" in str(exc.value)
        elif n < 18:
            assert "truncated" in str(exc.value)


@pytest.mark.parametrize("kw, needle", [
    (dict(shapes={"a": (2**30, 2**30)}), "asks for"),
    (dict(shapes={"c": (2**62, 4, 4)}), "asks for"),
    (dict(count=2**31), "fields"),
    (dict(version=(2, 0)), "version 2.0"),
    (dict(magic=b"tensor_filX\0"), "not a tensor file"),
    (dict(codes={"a": 12}), "unknown dtype code 12"),
    (dict(codes={"b": 0}), "unknown dtype code 0"),
    (dict(offsets={"a": 2**63}), "byte offset"),
    (dict(offsets={"b": 3}), "overlaps the header"),
])
def test_hostile_headers_fail_before_allocating(tmp_path, kw, needle):
    path = tmp_path / "bad.tensor"
    path.write_bytes(raw_tensor_file(FIELDS, **kw))
    tracemalloc.start()
    try:
        with pytest.raises(TensorFileError) as exc:
            read_tensor_file(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    _one_line(exc, path, needle)
    assert peak < 2 << 20, f"peaked at {peak:,} bytes"


def test_fields_may_not_share_bytes_to_multiply_the_file(tmp_path):
    big = {f"f{i}": np.zeros(1000) for i in range(3)}
    data = raw_tensor_file(big)
    first = len(data) - 3 * 8000  # all three fields' data point at the first one's
    path = tmp_path / "alias.tensor"
    path.write_bytes(raw_tensor_file(big, offsets={k: first for k in big})[:first + 8000])
    with pytest.raises(TensorFileError) as exc:
        read_tensor_file(path)
    _one_line(exc, path, "together")


def test_absurd_ndim_duplicate_names_and_foreign_files(tmp_path):
    path = tmp_path / "x.tensor"
    head = b"tensor_file\0" + struct.pack("<BBI", 1, 0, 1) + struct.pack("<H", 1) + b"a"
    path.write_bytes(head + struct.pack("<HBQ", 60000, 10, 0) + b"\0" * 64)
    with pytest.raises(TensorFileError) as exc:
        read_tensor_file(path)
    _one_line(exc, path, "60000 dimensions")
    dup = raw_tensor_file({"a": np.zeros(2, np.float32), "b": np.zeros(2, np.float32)})
    path.write_bytes(dup.replace(b"\x01\x00b", b"\x01\x00a"))
    with pytest.raises(TensorFileError) as exc:
        read_tensor_file(path)
    _one_line(exc, path, "declared twice")
    for content in (b"P6\n2 2\n255\n" + bytes(12), b"\x89PNG\r\n\x1a\n" + bytes(40)):
        path.write_bytes(content)
        with pytest.raises(TensorFileError) as exc:
            read_tensor_file(path)
        _one_line(exc, path, "not a tensor file")
    with pytest.raises(TensorFileError) as exc:
        read_tensor_file(tmp_path / "missing.bsdf")
    _one_line(exc, tmp_path / "missing.bsdf", "no such file")
    with pytest.raises(TensorFileError) as exc:
        read_tensor_file(tmp_path)
    _one_line(exc, tmp_path, "directory")


def test_writer_refuses_what_the_format_cannot_hold_and_leaves_nothing(tmp_path):
    with pytest.raises(TypeError, match="complex128"):
        write_tensor_file(tmp_path / "c.tensor", {"z": np.zeros(3, complex)})
    with pytest.raises(TypeError, match="object"):
        write_tensor_file(tmp_path / "o.tensor", {"z": np.array([None])})
    assert list(tmp_path.iterdir()) == []


# -- the Marginal2D warp ---------------------------------------------------------------------------

@pytest.mark.parametrize("normalize", [True, False])
def test_marginal_invert_undoes_sample_and_its_density_integrates_to_one(normalize):
    rng = np.random.default_rng(3)
    data = rng.random((3, 4, 6, 9)) ** 2 + 0.01
    params = [np.array([-1.0, 0.0, 2.0]), np.array([0.0, 0.3, 0.6, 0.9])]
    warp = Marginal2D(data, params, normalize=normalize)
    u = rng.random((4000, 2))
    p = [rng.uniform(-1.5, 2.5, 4000), rng.uniform(-0.2, 1.1, 4000)]
    pos, pdf = warp.sample(u, p)
    back, pdf2 = warp.invert(pos, p)
    np.testing.assert_allclose(back, u, atol=2e-5)
    np.testing.assert_allclose(pdf2, pdf, rtol=1e-5)
    np.testing.assert_allclose(warp.eval(pos, p), pdf, rtol=1e-5)
    if normalize:  # the bilinear density of every parameter value integrates to 1
        g = (np.arange(400) + 0.5) / 400
        gx, gy = np.meshgrid(g, g)
        pts = np.stack([gx.ravel(), gy.ravel()], 1)
        for pv in ([-0.5, 0.45], [2.0, 0.9]):
            dens = warp.eval(pts, [np.full(len(pts), pv[0]), np.full(len(pts), pv[1])])
            assert abs(dens.mean() - 1) < 1e-3


# -- the RGL reader --------------------------------------------------------------------------------

def lambert(wi, wo):
    return np.broadcast_to(np.array([0.2, 0.5, 0.8]) / np.pi, (len(wi), 3))


@pytest.fixture(scope="module")
def small_file(tmp_path_factory):
    mat = synthesize_rgl(lambert, name="lambert", n_theta_i=4, resolution=8, vndf_shape=(8, 8),
                         ndf_shape=(2, 16), sigma_shape=(2, 8))
    path = tmp_path_factory.mktemp("rgl") / "lambert.bsdf"
    write_rgl(path, mat)
    return path


def test_a_written_file_reads_back_field_for_field(small_file):
    mat = read_rgl(small_file)
    fields = read_tensor_file(small_file)
    assert set(fields) == {"description", "jacobian", "theta_i", "phi_i", "ndf", "sigma",
                           "vndf", "luminance", "rgb", "valid"}
    for k in ("theta_i", "phi_i", "ndf", "sigma", "vndf", "luminance", "rgb"):
        assert fields[k].dtype == np.float32
        np.testing.assert_array_equal(getattr(mat, k), fields[k])
    assert mat.isotropic and mat.jacobian and mat.name == "lambert"
    assert fields["jacobian"].tolist() == [1]
    # At the file's own nodes the constant is reproduced (to the file's float32).
    s = mat.to_samples()
    np.testing.assert_allclose(mat.eval(s.wi[s.valid], s.wo[s.valid]),
                               lambert(s.wi[s.valid], s.wo[s.valid]), rtol=1e-4)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(2, 3000, 3))
    d[..., 2] = np.abs(d[..., 2]) + 0.05
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    below = d[1] * np.array([1, 1, -1])
    assert np.all(mat.eval(d[0], below) == 0)


def _rewrite(path, dst, **change):
    fields = read_tensor_file(path)
    for k, v in change.items():
        if v is None:
            del fields[k]
        else:
            fields[k] = v
    write_tensor_file(dst, fields)
    return dst


@pytest.mark.parametrize("change, needle", [
    (dict(vndf=None), "missing field 'vndf'"),
    (dict(jacobian=None), "missing field 'jacobian'"),
    (dict(rgb=None), "missing field 'rgb'"),
    (dict(theta_i=np.zeros(4, np.float64)), "'theta_i' is float64"),
    (dict(ndf=np.ones(16, np.float32)), "'ndf' is float32 with shape (16,)"),
    (dict(vndf=np.ones((1, 3, 8, 8), np.float32)), "'vndf' has shape (1, 3, 8, 8)"),
    (dict(rgb=np.ones((1, 4, 3, 8, 7), np.float32)), "'rgb' has shape"),
    (dict(luminance=np.ones((1, 4, 8, 7), np.float32)), "'luminance' has shape"),
    (dict(jacobian=np.ones(2, np.uint8)), "'jacobian' has shape (2,)"),
    (dict(theta_i=np.array([0, 1, 1, 2], np.float32)), "not strictly increasing"),
    (dict(sigma=np.zeros((2, 8), np.float32)), "values <= 0"),
    (dict(ndf=np.full((2, 16), np.nan, np.float32)), "NaN"),
    (dict(wavelengths=np.array([400, 500], np.float32)), "missing field 'spectra'"),
])
def test_malformed_rgl_fields_are_one_clear_error(small_file, tmp_path, change, needle):
    path = _rewrite(small_file, tmp_path / "bad.bsdf", **change)
    with pytest.raises(RGLFormatError) as exc:
        read_rgl(path)
    assert isinstance(exc.value, TensorFileError)
    _one_line(exc, path, needle)


def test_rgl_reader_refuses_hostile_containers(small_file, tmp_path):
    data = small_file.read_bytes()
    path = tmp_path / "cut.bsdf"
    for n in sorted({0, 5, 17, 18, 40, 200, len(data) // 2, len(data) - 1}):
        path.write_bytes(data[:n])
        with pytest.raises(RGLFormatError) as exc:
            read_rgl(path)
        _one_line(exc, path)


# -- virtual measurements of an analytic model -----------------------------------------------------

GGX = np.array([0.1, 0.2, 0.3, 0.04, 0.04, 0.04, 0.3, 1.0])


def ggx_iso(wi, wo):
    return ggx_numpy(GGX, wi, wo)


def ggx_aniso(wi, wo, ax=0.2, ay=0.45, kd=(0.1, 0.2, 0.3), f0=0.04):
    """Anisotropic GGX (Heitz 2014 eqs. 85-86), Schlick Fresnel, height-correlated Smith G."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    d = 1 / (np.pi * ax * ay * ((h[:, 0] / ax) ** 2 + (h[:, 1] / ay) ** 2 + h[:, 2] ** 2) ** 2)

    def lam(w):
        return 0.5 * (np.sqrt(1 + ((ax * w[:, 0]) ** 2 + (ay * w[:, 1]) ** 2) / w[:, 2] ** 2) - 1)

    fres = f0 + (1 - f0) * (1 - np.clip(np.sum(wi * h, 1), 0, 1)) ** 5
    spec = fres * d / (1 + lam(wi) + lam(wo)) / (4 * wi[:, 2] * wo[:, 2])
    return np.asarray(kd) / np.pi + spec[:, None]


def random_pairs(n, seed, max_deg=90.0):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(2, n, 3))
    d[..., 2] = np.abs(d[..., 2])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    keep = np.all(d[..., 2] > np.cos(np.radians(max_deg)), axis=0)
    return d[0][keep], d[1][keep]


SYNTH = {"iso": (ggx_iso, dict(isotropic=True)),
         "aniso": (ggx_aniso, dict(isotropic=False, n_phi_i=13, n_theta_i=8, reduction=1,
                                   ndf_shape=(24, 24), sigma_shape=(16, 16),
                                   vndf_shape=(24, 24), resolution=24))}
#: (median, 99th percentile) of |f_file - f_model| / (f_model + 1e-3) for θi, θo < 70°, measured
#: at these resolutions (iso: 10 θi x 32 x 32; aniso: 8 θi x 13 φi x 24 x 24): 0.005, 0.054 and
#: 0.012, 0.25. The largest errors are in and near the specular peak (θh < 15°), where the table
#: on the warped square changes fastest, between θi slices, and (aniso) between the φi slices,
#: 30° apart (``data_formats.rgl._synthesize`` has the figures at the default resolutions).
BOUNDS = {"iso": (0.008, 0.07), "aniso": (0.02, 0.35)}


@pytest.fixture(scope="module", params=sorted(SYNTH))
def synthesized(request, tmp_path_factory):
    brdf, kw = SYNTH[request.param]
    path = tmp_path_factory.mktemp("synth") / f"ggx_{request.param}.bsdf"
    write_rgl(path, synthesize_rgl(brdf, name=request.param, **kw))
    return request.param, brdf, read_rgl(path)


def test_written_model_is_reproduced_within_the_interpolation_error(synthesized):
    kind, brdf, mat = synthesized
    assert mat.isotropic == (kind == "iso")
    wi, wo = random_pairs(20000, 1, max_deg=70)
    f, ref = mat.eval(wi, wo), brdf(wi, wo)
    rel = (np.abs(f - ref) / (ref + 1e-3)).max(axis=1)
    median, p99 = BOUNDS[kind]
    assert np.median(rel) < median and np.quantile(rel, 0.99) < p99, \
        (np.median(rel), np.quantile(rel, 0.99))
    # ...and exactly (to the file's float32) at the file's own nodes.
    s = mat.to_samples()
    v = s.valid
    np.testing.assert_allclose(s.rgb[v], brdf(s.wi[v], s.wo[v]), rtol=2e-6, atol=1e-9)
    np.testing.assert_allclose(mat.eval(s.wi[v], s.wo[v]), s.rgb[v], rtol=2e-3)


def test_samples_are_the_pattern_with_angle_measure_weights(synthesized):
    kind, brdf, mat = synthesized
    s = mat.to_samples()
    assert isinstance(s, SampleSet) and s.name == f"ggx_{kind}"
    n = mat.resolution
    assert len(s) == len(mat.phi_i) * len(mat.theta_i) * n * n
    assert np.all(s.wo[s.valid, 2] > 0) and np.all(s.wo[~s.valid, 2] <= 0)
    assert np.all(s.weight[~s.valid] == 0) and abs(s.weight[s.valid].mean() - 1) < 1e-12
    # The weights turn the adaptive pattern into a quadrature of the Rusinkiewicz angle
    # measure: the weighted share of pairs with θh < 15° approximates that share of the angles
    # (Monte Carlo over uniform θh, φh, θd, φd, both directions above the horizon: 0.255).
    # Measured: iso 0.261, aniso 0.252; counting each pair once gives 0.17.
    rng = np.random.default_rng(5)
    th, td = rng.uniform(0, np.pi / 2, (2, 400000))
    ph, pd = rng.uniform(0, 2 * np.pi, (2, 400000))
    wi, wo = dirs_from_half_diff(th, td, pd, ph)
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    share = np.mean(th[ok] < np.radians(15))
    h = s.wi + s.wo
    th_s = np.arccos(np.clip(h[:, 2] / np.linalg.norm(h, axis=1), -1, 1))
    v = s.valid
    weighted = np.sum(s.weight[v] * (th_s[v] < np.radians(15))) / np.sum(s.weight[v])
    counted = np.mean(th_s[v] < np.radians(15))
    assert abs(weighted - share) < 0.12 * share, (weighted, share, counted)
    assert abs(weighted - share) < abs(counted - share) / 3, (weighted, share, counted)


def test_material_requires_its_fields_and_reports_its_layout(synthesized):
    kind, _, mat = synthesized
    assert isinstance(mat, RGLMaterial)
    assert ("isotropic" if kind == "iso" else "anisotropic") in repr(mat)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        mat.eval(np.zeros((3, 3)), np.zeros((4, 3)))


def test_synthesize_refuses_a_model_that_is_not_finite():
    def bad(wi, wo):
        return np.full((len(wi), 3), np.nan)

    with pytest.raises(ValueError, match="non-finite"):
        synthesize_rgl(bad, n_theta_i=3, resolution=4, vndf_shape=(4, 4))


# -- spectral files --------------------------------------------------------------------------------

def spectral_version(mat, n_wl=12, seed=4):
    """``mat`` with its green table times a random positive spectrum per wavelength."""
    rng = np.random.default_rng(seed)
    wl = np.linspace(360, 1000, n_wl).astype(np.float32)
    curve = rng.uniform(0.2, 1.0, n_wl).astype(np.float32)
    spectra = mat.rgb[:, :, 1:2] * curve[None, None, :, None, None]
    return RGLMaterial(theta_i=mat.theta_i, phi_i=mat.phi_i, ndf=mat.ndf, sigma=mat.sigma,
                       vndf=mat.vndf, luminance=mat.luminance, spectra=spectra, wavelengths=wl,
                       jacobian=mat.jacobian, description="spectral", name="spectral"), curve


def test_spectral_files_round_trip_and_evaluate_as_their_rgb(small_file, tmp_path):
    from data_formats.rgl import spectra_to_rgb

    np.testing.assert_allclose(spectra_to_rgb([360.0, 830.0], [1.0, 1.0]), 1.0, atol=2e-4)
    assert np.allclose(spectra_to_rgb([500.0, 600.0], [1.0, 1.0]), 1.0, atol=2e-4)  # held flat
    mat, curve = spectral_version(read_rgl(small_file))
    write_rgl(tmp_path / "s.bsdf", mat)
    back = read_rgl(tmp_path / "s.bsdf")
    assert back.rgb is None and back.wavelengths.shape == (12,)
    np.testing.assert_array_equal(back.spectra, mat.spectra)
    wi, wo = random_pairs(3000, 2)
    rgb = spectra_to_rgb(back.wavelengths, curve)
    green = read_rgl(small_file).eval(wi, wo)[:, 1:2]
    np.testing.assert_allclose(back.eval(wi, wo), green * rgb, rtol=1e-5, atol=1e-9)
    at = back.eval_spectrum(wi, wo, back.wavelengths[[0, 5]])
    np.testing.assert_allclose(at, green * curve[[0, 5]], rtol=1e-5, atol=1e-9)


def test_a_file_beyond_the_size_limit_is_refused_before_reading(tmp_path, monkeypatch):
    import data_formats.tensorfile as tf

    path = tmp_path / "big.tensor"
    path.write_bytes(raw_tensor_file(FIELDS))
    monkeypatch.setattr(tf, "MAX_FILE_BYTES", 64)
    with pytest.raises(TensorFileError) as exc:
        read_tensor_file(path)
    _one_line(exc, path, "exceeds the reader's limit")


def test_writer_refuses_a_material_the_reader_would_refuse(small_file, tmp_path):
    import dataclasses

    mat = read_rgl(small_file)
    bad = dataclasses.replace(mat, sigma=np.zeros_like(mat.sigma))
    with pytest.raises(ValueError, match="sigma"):
        write_rgl(tmp_path / "bad.bsdf", bad)
    bad = dataclasses.replace(mat, vndf=mat.vndf[:, :2])
    with pytest.raises(ValueError, match="vndf"):
        write_rgl(tmp_path / "bad.bsdf", bad)
    assert list(tmp_path.iterdir()) == []
