"""The sample-list format: round trips, the documented layouts, and every error with its message."""

import numpy as np
import pytest

from data_formats import SampleSet
from data_formats.samplelist import SampleListFormatError, read_samples, write_samples


def _dirs(rng, n):
    cos_t = rng.uniform(0.05, 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    sin_t = np.sqrt(1 - cos_t**2)
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


@pytest.fixture
def samples():
    rng = np.random.default_rng(1)
    n = 257
    return SampleSet(_dirs(rng, n), _dirs(rng, n), rng.uniform(0, 50, (n, 3)), np.ones(n, bool))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("angles", [True, False])
def test_round_trip(tmp_path, samples, suffix, angles):
    path = write_samples(tmp_path / f"s{suffix}", samples, angles=angles)
    back = read_samples(path)
    np.testing.assert_allclose(back.wi, samples.wi, rtol=0, atol=1e-14)
    np.testing.assert_allclose(back.wo, samples.wo, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(back.rgb, samples.rgb)  # colours are bit exact
    assert back.valid.all() and back.name == "s" and back.path == str(path)
    assert not list(tmp_path.glob(".*.tmp")), "the temporary file was left behind"


def test_only_valid_rows_are_written(tmp_path, samples):
    samples.valid[::2] = False
    samples.rgb[::2] = np.nan  # undefined where invalid: must not reach the file
    back = read_samples(write_samples(tmp_path / "s.csv", samples))
    assert len(back) == samples.n_valid
    np.testing.assert_array_equal(back.rgb, samples.rgb[samples.valid])


def test_documented_angle_convention(tmp_path):
    """θ from the normal, φ from x towards y, degrees; a hand-written file, header in any order."""
    text = "# goniometer run 7\nR,theta_i,phi_i,theta_o,phi_o,g,b\n0.5,90,0,60,90,0.25,0.125\n"
    text += "1,30,180,0,0,2,3\n"
    (tmp_path / "h.csv").write_text(text)
    s = read_samples(tmp_path / "h.csv")
    s60 = np.sqrt(3) / 2
    np.testing.assert_allclose(s.wi, [[1, 0, 0], [-0.5, 0, s60]], atol=1e-15)
    np.testing.assert_allclose(s.wo, [[0, s60, 0.5], [0, 0, 1]], atol=1e-15)
    np.testing.assert_array_equal(s.rgb, [[0.5, 0.25, 0.125], [1, 2, 3]])
    assert s.valid.tolist() == [False, True]  # on the horizon: kept, marked not usable


def test_vectors_are_renormalized(tmp_path):
    (tmp_path / "v.csv").write_text("wix,wiy,wiz,wox,woy,woz,r,g,b\n0,0,1.0005,0.6,0,0.8,1,1,1\n")
    s = read_samples(tmp_path / "v.csv")
    np.testing.assert_allclose(np.linalg.norm(s.wi, axis=-1), 1.0, rtol=1e-15)


HEADER = "theta_i,phi_i,theta_o,phi_o,r,g,b\n"
GOOD = "10,0,20,180,0.1,0.2,0.3\n"


@pytest.mark.parametrize(
    "body, message",
    [
        ("", "no header row"),
        ("10,0,20,180,0.1,0.2,0.3\n", "line 1 looks like data, not a header"),
        ("theta_i,phi_i,theta_o,phi_o,r,g\n" + GOOD, "missing column(s) b"),
        (HEADER.replace("\n", ",extra\n") + GOOD, "unknown column(s) extra"),
        ("theta_i,phi_i,wox,woy,woz,r,g,b\n", "missing column(s) theta_o, phi_o"),
        ("theta_i,theta_i,theta_o,phi_o,r,g,b\n", "duplicate column(s) theta_i"),
        (HEADER, "no samples"),
        (HEADER + GOOD + "10,0,20,x,0.1,0.2,0.3\n", "line 3, column 'phi_o': 'x' is not a number"),
        (HEADER + GOOD + "10,0,20,5,0.1,0.2\n", "line 3 has 6 fields, expected 7"),
        (HEADER + GOOD + GOOD + "10,0,20,5,nan,0.2,0.3\n", "line 4, column 'r': value nan is not finite"),
        (HEADER + "10,0,95,5,0.1,0.2,0.3\n", "line 2, column 'theta_o': 95° is below the horizon"),
        (HEADER + "-1,0,5,5,0.1,0.2,0.3\n", "line 2, column 'theta_i': -1° is negative"),
        (HEADER + "1,0,5,5,0.1,-0.2,0.3\n", "line 2, column 'g': -0.2 is negative"),
        (
            "wix,wiy,wiz,wox,woy,woz,r,g,b\n0,0,1,0,0,1,1,1,1\n0,0.6,-0.8,0,0,1,1,1,1\n",
            "line 3, column 'wiz': -0.8 < 0, the direction is below the horizon",
        ),
        (
            "wix,wiy,wiz,wox,woy,woz,r,g,b\n0,0,1,0,0.5,0.5,1,1,1\n",
            "line 2, columns wox,woy,woz: length 0.707107 is not 1",
        ),
    ],
)
def test_csv_errors_name_line_and_column(tmp_path, body, message):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(SampleListFormatError) as err:
        read_samples(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_npz_errors(tmp_path):
    n = 4
    cols = dict(theta_i=np.full(n, 10.0), phi_i=np.zeros(n), theta_o=np.full(n, 20.0),
                phi_o=np.zeros(n), r=np.ones(n), g=np.ones(n), b=np.ones(n))
    np.savez(tmp_path / "ok.npz", **cols)
    assert len(read_samples(tmp_path / "ok.npz")) == n
    cols["g"] = cols["g"].copy()
    cols["g"][2] = np.inf
    np.savez(tmp_path / "inf.npz", **cols)
    with pytest.raises(SampleListFormatError, match=r"row 2, column 'g': value inf is not finite"):
        read_samples(tmp_path / "inf.npz")
    np.savez(tmp_path / "len.npz", **{**cols, "b": np.ones(n + 1)})
    with pytest.raises(SampleListFormatError, match="arrays differ in length"):
        read_samples(tmp_path / "len.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(SampleListFormatError, match="not a readable NPZ archive"):
        read_samples(tmp_path / "junk.npz")


def test_path_errors(tmp_path):
    with pytest.raises(SampleListFormatError, match=r"unknown sample-list suffix '\.txt'"):
        read_samples(tmp_path / "s.txt")
    with pytest.raises(SampleListFormatError, match="no such file"):
        read_samples(tmp_path / "missing.csv")
    (tmp_path / "d.csv").mkdir()
    with pytest.raises(SampleListFormatError, match="is a directory"):
        read_samples(tmp_path / "d.csv")


def test_sigma_and_monochrome_columns_round_trip(tmp_path):
    from data_formats.samplelist import read_samples, write_samples
    from data_formats.samples import SampleSet

    w = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    sigma = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    rgb = SampleSet(w, w, np.array([[1.0, 2, 3], [4, 5, 6]]), np.ones(2, bool), sigma=sigma)
    back = read_samples(write_samples(tmp_path / "rgb.npz", rgb))
    np.testing.assert_array_equal(back.sigma, sigma)
    mono = SampleSet(w, w, np.array([[1.0, 1, 1], [2, 2, 2]]), np.ones(2, bool), channels=1,
                     sigma=np.full((2, 3), 0.1))
    path = write_samples(tmp_path / "mono.csv", mono)
    assert path.read_text().splitlines()[0] == "theta_i,phi_i,theta_o,phi_o,value,sigma"
    back = read_samples(path)
    assert back.channels == 1 and np.all(back.rgb == [[1, 1, 1], [2, 2, 2]])
    np.testing.assert_array_equal(back.sigma, 0.1)
    bad = tmp_path / "bad.csv"
    bad.write_text("theta_i,phi_i,theta_o,phi_o,value,sigma\n10,0,10,180,1,0\n")
    with pytest.raises(SampleListFormatError, match="line 2, column 'sigma': 0 is not a positive"):
        read_samples(bad)
