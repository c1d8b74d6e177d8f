"""The MERL binary format: byte layout, exact round trips, scales, missing cells, malformed files,
the table type, and the nearest / trilinear lookups.

Files are parsed and built here with plain ``struct``/``np.frombuffer`` from the format facts
(``../shared/reference/merl-format.md``), independently of the reader and writer under test.
"""

import os
import struct
import time
import tracemalloc

import numpy as np
import pytest

from data_formats import SampleSet
from data_formats.merl import (
    MAX_DIM,
    MERL_SHAPE,
    SCALE,
    MERLFormatError,
    MERLTable,
    above_horizon,
    cell_angles,
    cell_directions,
    lookup_linear,
    lookup_linear_angles,
    lookup_nearest,
    lookup_nearest_angles,
    read_merl,
    snap_to_file,
    synthesize,
    theta_h_weights,
    write_merl,
)
from data_formats.rusinkiewicz import dirs_from_half_diff

SMALL = (6, 5, 8)
SCALES = (1 / 1500, 1.15 / 1500, 1.66 / 1500)


def raw_file(path, dims, stored):
    """A MERL file from channel-last stored values, written from the format facts alone."""
    body = np.ascontiguousarray(np.moveaxis(np.asarray(stored, float), -1, 0)).astype("<f8")
    path.write_bytes(struct.pack("<3i", *dims) + body.tobytes())
    return path


def parse_file(path):
    """(dims, channel-last stored values) of a MERL file, from the format facts alone."""
    data = path.read_bytes()
    dims = struct.unpack("<3i", data[:12])
    assert len(data) == 12 + 8 * 3 * int(np.prod(dims))
    blocks = np.frombuffer(data[12:], dtype="<f8").reshape((3,) + dims)
    return dims, np.moveaxis(blocks, 0, -1)


def bits(a):
    return np.ascontiguousarray(a).view(np.uint64)


def random_table(shape=SMALL, seed=0, missing=0.2):
    rng = np.random.default_rng(seed)
    rgb = rng.lognormal(0.0, 3.0, shape + (3,))
    valid = rng.uniform(size=shape) > missing
    return MERLTable.from_rgb(rgb, valid, name="random")


# -- round trips and layout -------------------------------------------------------------------

def test_round_trip_is_exact_bit_for_bit(tmp_path):
    table = random_table(seed=1)
    write_merl(tmp_path / "t.binary", table)
    back = read_merl(tmp_path / "t.binary")
    assert np.array_equal(bits(back.rgb), bits(table.rgb))
    assert np.array_equal(back.valid, table.valid)
    assert back.path == str(tmp_path / "t.binary") and back.name == "t"
    assert back.shape == SMALL


def test_written_file_has_the_database_layout(tmp_path):
    table = random_table(seed=2)
    write_merl(tmp_path / "t.binary", table)
    dims, stored = parse_file(tmp_path / "t.binary")
    assert dims == SMALL
    v = table.valid
    assert np.all(stored[~v] == -1.0)  # missing: -1 in every channel
    for c, scale in enumerate(SCALES):
        assert np.array_equal(stored[..., c][v] * scale, table.rgb[..., c][v])
    # flat index (i * n_td + j) * n_pd + k within each channel block
    flat = np.frombuffer((tmp_path / "t.binary").read_bytes()[12:], dtype="<f8")
    i, j, k = 4, 3, 7
    n = int(np.prod(SMALL))
    for c in range(3):
        want = stored[i, j, k, c]
        assert flat[c * n + (i * SMALL[1] + j) * SMALL[2] + k] == want


def test_reader_applies_the_scales_per_channel_and_marks_negatives_missing(tmp_path):
    rng = np.random.default_rng(3)
    stored = rng.uniform(0, 3000, SMALL + (3,))
    stored[0, 0, 0] = 1500.0
    stored[1, 2, 3] = -1.0  # the database's missing marker
    stored[2, 2, 2, 1] = -0.5  # one negative channel makes the whole cell missing
    table = read_merl(raw_file(tmp_path / "raw.binary", SMALL, stored))
    assert np.array_equal(table.rgb[0, 0, 0], 1500.0 * SCALE)
    assert np.allclose(table.rgb[0, 0, 0], [1.0, 1.15, 1.66], rtol=1e-15, atol=0)
    valid = np.all(stored >= 0, axis=-1)
    assert np.array_equal(table.valid, valid) and valid.sum() == valid.size - 2
    for c, scale in enumerate(SCALES):
        assert np.array_equal(table.rgb[..., c][valid], stored[..., c][valid] * scale)
    assert np.all(table.rgb[~valid] == 0.0)


def test_tables_read_from_any_file_round_trip_exactly(tmp_path):
    # arbitrary stored doubles over 20 decades: what the reader returns, the writer reproduces
    rng = np.random.default_rng(4)
    stored = rng.uniform(0, 1, SMALL + (3,)) * 10.0 ** rng.integers(-10, 10, SMALL + (1,))
    first = read_merl(raw_file(tmp_path / "a.binary", SMALL, stored))
    write_merl(tmp_path / "b.binary", first)
    second = read_merl(tmp_path / "b.binary")
    assert np.array_equal(bits(second.rgb), bits(first.rgb))


def test_snapping_moves_at_most_one_ulp_and_exactly_the_unreachable_values():
    rng = np.random.default_rng(5)
    x = rng.uniform(0, 1, (200_000, 3)) * 10.0 ** rng.integers(-300, 300, (200_000, 1))
    snapped = snap_to_file(x)
    assert np.all(np.abs(snapped - x) <= np.spacing(x))
    assert np.array_equal(snap_to_file(snapped), snapped)
    # reachable = some stored double t near x / SCALE has t * SCALE == x (brute force, +-3 ulps)
    t = x / SCALE
    reachable = np.zeros(x.shape, bool)
    up, down = t.copy(), t.copy()
    for _ in range(4):
        reachable |= (up * SCALE == x) | (down * SCALE == x)
        up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
    assert np.array_equal(snapped == x, reachable)
    assert 0.8 < reachable.mean() < 0.95
    # every value a reader can produce (stored * SCALE) is reachable: subnormals to 1e300
    y = (rng.uniform(0, 1, (200_000, 3)) * 10.0 ** rng.integers(-320, 300, (200_000, 1))) * SCALE
    assert np.array_equal(snap_to_file(y), y)


def test_synthesized_full_table_round_trips_and_mmap_reads_the_same(tmp_path, shiny):
    path = tmp_path / "shiny.binary"
    write_merl(path, shiny)
    assert path.stat().st_size == 34_992_012
    peaks = {}
    for mmap in (False, True):
        tracemalloc.start()
        table = read_merl(path, mmap=mmap)
        peaks[mmap] = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
        assert np.array_equal(bits(table.rgb), bits(shiny.rgb))
        assert np.array_equal(table.valid, shiny.valid)
    # the documented memory cost (MB): one 35 MB body buffer fewer with mmap
    assert 70 < peaks[False] < 80 and 36 < peaks[True] < 45


def test_write_is_atomic_and_leaves_no_temporary_files(tmp_path, monkeypatch):
    path = tmp_path / "t.binary"
    write_merl(path, random_table(seed=6))
    before = path.read_bytes()
    write_merl(path, random_table(seed=7))  # overwrite in place
    assert path.read_bytes() != before and os.listdir(tmp_path) == ["t.binary"]
    after = path.read_bytes()

    def boom(src, dst):
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError, match="simulated"):
        write_merl(path, random_table(seed=8))
    assert path.read_bytes() == after and os.listdir(tmp_path) == ["t.binary"]


def test_write_refuses_values_the_format_cannot_carry(tmp_path):
    table = random_table(seed=9)
    rgb = np.array(table.rgb)
    cell = tuple(int(x) for x in np.argwhere(table.valid)[0])
    rgb[cell + (1,)] = -2.0
    bad = MERLTable(rgb, np.array(table.valid))  # bypasses from_rgb's checks
    with pytest.raises(ValueError, match=r"1 valid cells hold values a MERL file cannot store "
                                         r"\(first: cell \(\d+, \d+, \d+\)"):
        write_merl(tmp_path / "bad.binary", bad)
    assert os.listdir(tmp_path) == []
    with pytest.raises(TypeError, match="expected a MERLTable, got ndarray"):
        write_merl(tmp_path / "x.binary", rgb)


# -- malformed files --------------------------------------------------------------------------

def header(*dims):
    return struct.pack("<3i", *dims)


FULL_BODY = 8 * 3 * 90 * 90 * 180


@pytest.mark.parametrize("name, content, message", [
    ("empty", b"", r"empty file: expected a 12-byte header .* found 0 bytes"),
    ("short", b"\x5a\x00\x00\x00\x5a", r"file too short for the header: .* found 5 bytes"),
    ("truncated", header(90, 90, 180) + bytes(FULL_BODY - 8),
     r"truncated by 8 bytes\): expected 12 \+ 8\*3\*90\*90\*180 = 34,992,012 bytes, "
     r"found 34,992,004 bytes"),
    ("padded", header(90, 90, 180) + bytes(FULL_BODY + 8),
     r"padded by 8 bytes\): expected .* = 34,992,012 bytes, found 34,992,020 bytes"),
    ("zero_dim", header(90, 0, 180), r"bad header dims: expected three dims between 1 and 10000 "
                                     r".* found dims \(90, 0, 180\)"),
    ("negative_dim", header(-90, 90, 180), r"found dims \(-90, 90, 180\)"),
    ("huge_dim", header(90, 90, MAX_DIM + 1), r"found dims \(90, 90, 10001\)"),
    ("body_only", bytes(FULL_BODY), r"found dims \(0, 0, 0\)"),
])
def test_malformed_files_raise_merl_format_error(tmp_path, name, content, message):
    path = tmp_path / f"{name}.binary"
    path.write_bytes(content)
    with pytest.raises(MERLFormatError, match=message) as info:
        read_merl(path)
    assert str(info.value).startswith(f"{path}: ")
    assert info.value.path == str(path)
    assert isinstance(info.value, ValueError)
    if name not in ("empty", "short"):
        assert "re-download" in str(info.value)


def test_absurd_dims_fail_fast_without_allocating(tmp_path):
    path = tmp_path / "huge.binary"
    path.write_bytes(header(2048, 1024, 1024) + bytes(64))  # 2**31 cells asked for
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(MERLFormatError, match=r"expected 12 \+ 8\*3\*2048\*1024\*1024 = "
                                              r"51,539,607,564 bytes, found 76 bytes"):
        read_merl(path, mmap=True)
    with pytest.raises(MERLFormatError, match="51,539,607,564 bytes"):
        read_merl(path)
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1_000_000 and elapsed < 1.0


@pytest.mark.parametrize("value, shown", [(np.nan, "nan"), (np.inf, "inf"), (-np.inf, "-inf")])
def test_non_finite_values_raise(tmp_path, value, shown):
    stored = np.ones(SMALL + (3,))
    stored[2, 3, 4, 1] = value
    stored[5, 0, 0, 2] = value
    path = raw_file(tmp_path / "nan.binary", SMALL, stored)
    flat = (2 * SMALL[1] + 3) * SMALL[2] + 4
    offset = 12 + 8 * (int(np.prod(SMALL)) + flat)
    with pytest.raises(MERLFormatError, match=(
            rf"non-finite values in the body: expected finite float64 values .* found 2 NaN/inf "
            rf"values, the first {shown} in channel G at cell \(2, 3, 4\) \(byte offset "
            rf"{offset:,}\)\. Regenerate the file storing missing cells as -1")):
        read_merl(path)


def test_directory_and_missing_path(tmp_path):
    with pytest.raises(MERLFormatError, match=r"is a directory: expected a MERL \.binary file, "
                                              r"found a directory\. Pass the path of one"):
        read_merl(tmp_path)
    with pytest.raises(MERLFormatError, match=r"no such file: expected an existing MERL \.binary "
                                              r"file, found nothing at this path"):
        read_merl(tmp_path / "nope.binary")


# -- the table --------------------------------------------------------------------------------

def test_from_rgb_checks_its_input():
    rgb = np.ones(SMALL + (3,))
    with pytest.raises(ValueError, match=r"expected rgb of shape \(n_th, n_td, n_pd, 3\), "
                                         r"got \(6, 5, 8\)"):
        MERLTable.from_rgb(rgb[..., 0])
    with pytest.raises(ValueError, match=r"expected valid of shape \(6, 5, 8\) .* got \(6, 5\)"):
        MERLTable.from_rgb(rgb, np.ones((6, 5), bool))
    rgb[1, 1, 1, 2] = np.nan
    with pytest.raises(ValueError, match=r"1 valid cells hold values .* cell \(1, 1, 1\)"):
        MERLTable.from_rgb(rgb)
    valid = np.ones(SMALL, bool)
    valid[1, 1, 1] = False  # a missing cell may hold anything; it becomes 0
    table = MERLTable.from_rgb(rgb, valid)
    assert np.all(table.rgb[1, 1, 1] == 0) and not table.rgb.flags.writeable
    with pytest.raises(ValueError, match="float64 array of shape"):
        MERLTable(rgb.astype(np.float32), valid)


def test_info_figures():
    table = random_table(seed=10)
    info = table.info()
    v = table.rgb[table.valid]
    assert info["dims"] == list(SMALL) and info["n_cells"] == 240
    assert info["n_valid"] == table.valid.sum()
    assert info["valid_fraction"] == pytest.approx(table.valid.mean())
    for c, ch in enumerate("RGB"):
        got = info["channels"][ch]
        assert (got["min"], got["median"], got["max"]) == (
            v[:, c].min(), np.median(v[:, c]), v[:, c].max())
    peak = info["peak"]
    cell = tuple(peak["index"])
    assert peak["value"] == v.max() == table.rgb[cell]["RGB".index(peak["channel"])]
    assert table.valid[cell]
    angles = np.degrees(cell_angles(*cell, shape=SMALL))
    assert [peak["theta_h_deg"], peak["theta_d_deg"], peak["phi_d_deg"]] == list(angles)
    text = table.info_text()
    assert "6 x 5 x 8" in text and f"{peak['value']:.6g}" in text and str(cell) in text
    assert str(table) == text and repr(table).startswith("MERLTable(name='random', shape=(6, 5, 8)")
    empty = MERLTable.from_rgb(np.ones(SMALL + (3,)), np.zeros(SMALL, bool))
    assert empty.info()["peak"] is None and "no valid cells" in empty.info_text()


def test_to_samples_is_the_grid_in_file_order(shiny):
    samples = shiny.to_samples()
    assert isinstance(samples, SampleSet) and len(samples) == 1_458_000
    wi, wo = cell_directions()
    n = (17 * 90 + 44) * 180 + 100  # cell (17, 44, 100)
    assert np.array_equal(samples.wi[n], wi[17, 44, 100])
    assert np.array_equal(samples.wo[n], wo[17, 44, 100])
    assert np.array_equal(samples.rgb[n], shiny.rgb[17, 44, 100])
    assert np.array_equal(samples.valid, (shiny.valid & above_horizon()).reshape(-1))
    # stored valid everywhere: horizon cells still drop out of the samples
    full = MERLTable.from_rgb(np.ones(SMALL + (3,)))
    s = full.to_samples()
    corner_i, corner_o = cell_directions(SMALL)
    above = (corner_i[..., 2] > 1e-9) & (corner_o[..., 2] > 1e-9)
    assert np.array_equal(s.valid, above.reshape(-1)) and not above.all()


def test_theta_h_weights_are_the_cells_widths_against_the_mean():
    """Row ``i`` covers ``[(i/n)², ((i+1)/n)²)·90°``: the widths from the cell corners (an
    independent route: ``cell_angles``, then differences up to 90°) over the mean width 90°/n."""
    for shape in (MERL_SHAPE, SMALL):
        n = shape[0]
        corners = cell_angles(np.arange(n), 0, 0, shape=shape)[0]
        widths = np.diff(np.append(corners, np.pi / 2))
        w = theta_h_weights(shape)
        np.testing.assert_allclose(w, widths / (np.pi / 2 / n), rtol=1e-12)
        assert w.mean() == pytest.approx(1.0, rel=1e-14) and not w.flags.writeable
    assert theta_h_weights()[0] == 1 / 90 and theta_h_weights()[-1] == 179 / 90
    # every sample of a table carries its row's weight, in file order
    s = MERLTable.from_rgb(np.ones(SMALL + (3,))).to_samples()
    i = np.unravel_index(np.arange(len(s)), SMALL)[0]
    np.testing.assert_array_equal(s.weight, theta_h_weights(SMALL)[i])


def test_sample_set_weights_are_checked():
    wi = np.tile([[0.0, 0.6, 0.8]], (4, 1))
    args = (wi, wi.copy(), np.ones((4, 3)), np.ones(4, bool))
    assert SampleSet(*args, weight=np.array([0.0, 1.0, 2.0, 1.0])).weight is not None
    for bad, what in ((np.ones(3), "shape"), (np.array([1.0, -1.0, 1.0, 1.0]), ">= 0"),
                      (np.array([1.0, np.nan, 1.0, 1.0]), "finite")):
        with pytest.raises(ValueError, match=f"SampleSet.weight.*{what}"):
            SampleSet(*args, weight=bad)


def test_synthesize_marks_the_horizon_missing_and_checks_values(shiny):
    wi, wo = cell_directions()
    assert np.array_equal(shiny.valid, above_horizon())
    v = shiny.valid
    ref = shiny_brdf(wi[v][::97], wo[v][::97])
    assert np.all(np.abs(shiny.rgb[v][::97] - ref) <= np.spacing(ref))
    with pytest.raises(ValueError, match=r"synthesize: fn returned .* negative or non-finite"):
        synthesize(lambda a, b: a - 0.5, shape=SMALL)
    nan_below = synthesize(lambda a, b: np.where((a[..., 2:] > 0) & (b[..., 2:] > 0), 1.0, np.nan),
                           shape=SMALL)
    assert np.all(nan_below.rgb[nan_below.valid] == 1.0)


# -- lookups ----------------------------------------------------------------------------------

def shiny_brdf(wi, wo):
    """A smooth, positive, non-separable test BRDF."""
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    spec = 30.0 * h[..., 2:] ** 80
    return 0.05 + spec * np.array([1.0, 0.8, 0.6]) + 0.1 * (wi[..., :1] - wo[..., :1]) ** 2


@pytest.fixture(scope="module")
def shiny():
    return synthesize(shiny_brdf, name="shiny")


def test_nearest_returns_the_cell_value_and_nan_for_missing(shiny):
    I, J, K = np.meshgrid(*(np.arange(n) for n in MERL_SHAPE), indexing="ij", sparse=True)
    got = lookup_nearest_angles(shiny, *cell_angles(I, J, K))
    v = shiny.valid
    assert np.array_equal(got[v], shiny.rgb[v]) and np.all(np.isnan(got[~v]))
    # directions at cell centres land in their own cell (corners sit on a boundary)
    sl = (slice(None, None, 3), slice(None, None, 2), slice(None))
    th, td, pd = cell_angles(I, J, K)
    n_th = MERL_SHAPE[0]
    wi, wo = dirs_from_half_diff(((I + 0.5) / n_th) ** 2 * (np.pi / 2), td + 0.5 * np.pi / 180,
                                 pd + 0.5 * np.pi / 180)
    got = lookup_nearest(shiny, wi[sl], wo[sl])
    assert np.array_equal(got[v[sl]], shiny.rgb[sl][v[sl]])
    assert np.isnan(lookup_nearest(shiny, [np.nan, 0, 1], [0, 0, 1])).all()


def test_linear_is_exact_at_corners(shiny):
    I, J, K = np.meshgrid(*(np.arange(n) for n in MERL_SHAPE), indexing="ij", sparse=True)
    got = lookup_linear_angles(shiny, *cell_angles(I, J, K))
    v = shiny.valid
    assert np.allclose(got[v], shiny.rgb[v], rtol=1e-12, atol=0)
    # where the corner's coordinates compute to exact integers the value comes back bit for bit
    th, td, pd = (np.broadcast_to(a, MERL_SHAPE) for a in cell_angles(I, J, K))
    integral = ((np.sqrt(th / (np.pi / 2) * 90 * 90) == I) & (td / (np.pi / 2) * 90 == J)
                & (pd / np.pi * 180 == K) & v)
    assert integral.sum() > 100_000
    assert np.array_equal(got[integral], shiny.rgb[integral])
    # through directions (theta_d > 0, where phi_d is defined): exact up to rounding
    wi, wo = cell_directions()
    sub = (slice(None, None, 7), slice(1, None, 5), slice(None, None, 3))
    got = lookup_linear(shiny, wi[sub], wo[sub])
    assert np.allclose(got[v[sub]], shiny.rgb[sub][v[sub]], rtol=1e-10, atol=0)


def multilinear_table(shape=SMALL):
    I, J, K = np.meshgrid(*(np.arange(n, dtype=float) for n in shape), indexing="ij")
    f = np.stack([1 + I + 2 * J + 3 * K, 2 + I * J * K, 5 + 0.5 * I * K], -1)
    return MERLTable.from_rgb(f)


def test_linear_reproduces_multilinear_data_between_samples():
    table = multilinear_table()
    n_th, n_td, n_pd = SMALL
    rng = np.random.default_rng(11)
    u, v, w = (rng.uniform(0, n - 1, 5000) for n in SMALL)  # inside the sample lattice
    th, td, pd = (u / n_th) ** 2 * (np.pi / 2), v / n_td * (np.pi / 2), w / n_pd * np.pi
    got = lookup_linear_angles(table, th, td, pd)
    want = np.stack([1 + u + 2 * v + 3 * w, 2 + u * v * w, 5 + 0.5 * u * w], -1)
    assert np.allclose(got, want, rtol=1e-12)


def test_linear_is_continuous_across_the_phi_d_fold():
    table = multilinear_table()
    n_th, n_td, n_pd = SMALL
    th, td = (2.3 / n_th) ** 2 * (np.pi / 2), 1.6 / n_td * (np.pi / 2)
    at = lambda pd: lookup_linear_angles(table, th, td, pd)  # noqa: E731
    cell0 = at(0.0)
    # approaching pi from below blends the last cell into cell 0, reaching it at pi
    assert np.allclose(at(np.pi - 1e-12), cell0, rtol=1e-9)
    assert np.allclose(at(-1e-12), cell0, rtol=1e-9)  # unfolded side, same limit
    last = at((n_pd - 1) / n_pd * np.pi)
    assert np.allclose(at((n_pd - 0.5) / n_pd * np.pi), 0.5 * (last + cell0), rtol=1e-12)
    assert not np.allclose(last, cell0)  # so the test can see a jump if the wrap were missing
    wi, wo = random_dirs(20_000, seed=12)
    shiny_small = synthesize(shiny_brdf, shape=(30, 30, 60))
    a, b = lookup_linear(shiny_small, wi, wo), lookup_linear(shiny_small, wo, wi)
    ok = ~np.isnan(a[:, 0])
    assert np.allclose(a[ok], b[ok], rtol=1e-9) and np.array_equal(ok, ~np.isnan(b[:, 0]))


def test_linear_holds_past_the_last_sample_and_drops_missing_corners():
    table = multilinear_table()
    n_th, n_td, n_pd = SMALL
    last_j = lookup_linear_angles(table, 0.0, (n_td - 1) / n_td * (np.pi / 2), 0.0)
    assert np.array_equal(lookup_linear_angles(table, 0.0, np.pi / 2 - 1e-9, 0.0), last_j)
    rgb = np.array(table.rgb)
    valid = np.ones(SMALL, bool)
    valid[1, 1, 1] = False
    holey = MERLTable.from_rgb(rgb, valid)
    th, td = (1.0 / n_th) ** 2 * (np.pi / 2), 1.0 / n_td * (np.pi / 2)
    # halfway between the missing cell (1,1,1) and the valid (1,1,2): only the valid one counts
    got = lookup_linear_angles(holey, th, td, 1.5 / n_pd * np.pi)
    assert np.allclose(got, rgb[1, 1, 2], rtol=1e-12)
    # a quarter of the way: weights 3/4 (missing) and 1/4 (valid) -> renormalised to the valid
    assert np.allclose(lookup_linear_angles(holey, th, td, 1.75 / n_pd * np.pi), rgb[1, 1, 2])
    assert np.isnan(lookup_linear_angles(holey, *cell_angles(1, 1, 1, shape=SMALL))).all()
    assert np.isnan(lookup_linear_angles(holey, np.nan, td, 0.0)).all()


def test_lookup_method_dispatch(shiny):
    wi, wo = random_dirs(100, seed=13)
    assert np.array_equal(shiny.lookup(wi, wo), lookup_nearest(shiny, wi, wo))
    assert np.array_equal(shiny.lookup(wi, wo, method="linear"), lookup_linear(shiny, wi, wo))
    assert shiny.lookup(wi.reshape(10, 10, 3), wo.reshape(10, 10, 3)).shape == (10, 10, 3)
    with pytest.raises(ValueError, match=r"unknown method 'cubic'; expected one of "
                                         r"\['linear', 'nearest'\]"):
        shiny.lookup(wi, wo, method="cubic")
    with pytest.raises(ValueError,
                       match=r"expected directions of shape \(\.\.\., 3\), got \(100, 2\)"):
        lookup_nearest(shiny, wi[:, :2], wo[:, :2])


def test_nearest_agrees_with_the_database_oracle_on_random_pairs(shiny):
    from test_merl_coords import oracle_angles, oracle_index

    wi, wo = random_dirs(100_000, seed=14)
    i, j, k = oracle_index(*oracle_angles(wi, wo))
    want = np.where(shiny.valid[i, j, k][:, None], shiny.rgb[i, j, k], np.nan)
    assert np.array_equal(lookup_nearest(shiny, wi, wo), want, equal_nan=True)


def random_dirs(n, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(2):
        z, phi = rng.uniform(0, 1, n), rng.uniform(0, 2 * np.pi, n)
        r = np.sqrt(1 - z * z)
        out.append(np.stack([r * np.cos(phi), r * np.sin(phi), z], -1))
    return out
