"""MERL coordinates: Rusinkiewicz angles, the theta_h-warped cell index, lower corners, directions.

The oracle is written here from the formulas (``../shared/reference/merl-format.md``, the
database's ``BRDFRead.cpp``): explicit rotation matrices, ``acos``/``atan2``, the reader's index
arithmetic with C truncation. It shares no code with ``data_formats``.
"""

import numpy as np
import pytest

from data_formats.merl import (
    HORIZON_EPS,
    MERL_SHAPE,
    above_horizon,
    cell_angles,
    cell_directions,
    merl_index,
)
from data_formats.rusinkiewicz import dirs_from_half_diff, fold_phi_d, half_diff_from_dirs

DEG = np.pi / 180.0


# -- the independent oracle -------------------------------------------------------------------

def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                     np.stack([zero, zero, one], -1)], -2)


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1),
                     np.stack([-s, zero, c], -1)], -2)


def oracle_angles(wi, wo):
    """``std_coords_to_half_diff_coords``: h, acos/atan2, d = R_y(-theta_h) R_z(-phi_h) wi."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1, 1))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    d = np.einsum("nij,njk,nk->ni", _rot_y(-theta_h), _rot_z(-phi_h), wi)
    return theta_h, np.arccos(np.clip(d[:, 2], -1, 1)), np.arctan2(d[:, 1], d[:, 0])


def oracle_index(theta_h, theta_d, phi_d):
    """``theta_half_index``, ``theta_diff_index``, ``phi_diff_index`` of ``BRDFRead.cpp``."""
    i = np.where(theta_h <= 0, 0, np.trunc(np.sqrt(theta_h / (np.pi / 2) * 90 * 90)))
    j = np.trunc(theta_d / (np.pi * 0.5) * 90)
    phi = np.where(phi_d < 0, phi_d + np.pi, phi_d)
    k = np.trunc(phi / np.pi * 360 / 2)
    return (np.clip(i, 0, 89).astype(int), np.clip(j, 0, 89).astype(int),
            np.clip(k, 0, 179).astype(int))


def random_pairs(n, seed):
    """Direction pairs, each uniform on the upper hemisphere."""
    rng = np.random.default_rng(seed)

    def hemi():
        z, phi = rng.uniform(0, 1, n), rng.uniform(0, 2 * np.pi, n)
        r = np.sqrt(1 - z * z)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)

    return hemi(), hemi()


def index_of_dirs(wi, wo):
    return np.stack(merl_index(*half_diff_from_dirs(wi, wo)), -1)


# -- indexing ---------------------------------------------------------------------------------

@pytest.mark.parametrize("deg, cell", [(0.0, 0), (1.0, 9), (45.0, 63), (90.0, 89), (-3.0, 0),
                                       (120.0, 89)])
def test_theta_h_is_warped(deg, cell):
    assert merl_index(deg * DEG, 0.0, 0.0)[0] == cell


@pytest.mark.parametrize("deg, cell", [(0.0, 0), (0.99, 0), (1.0, 1), (45.5, 45), (89.999, 89),
                                       (90.0, 89), (135.0, 89), (-1.0, 0)])
def test_theta_d_is_linear_and_clamped(deg, cell):
    assert merl_index(0.0, deg * DEG, 0.0)[1] == cell


@pytest.mark.parametrize("deg, cell", [(0.0, 0), (1.0, 1), (90.5, 90), (179.5, 179), (180.0, 0),
                                       (-10.0, 170), (-180.0, 0), (190.0, 10)])
def test_phi_d_is_folded_by_reciprocity(deg, cell):
    assert merl_index(0.0, 0.0, deg * DEG)[2] == cell


def test_nan_angles_give_an_in_range_index():
    i, j, k = merl_index(np.nan, np.nan, np.nan)
    assert (i, j, k) == (0, 0, 0)


def test_every_lower_corner_maps_back_to_its_own_cell():
    I, J, K = np.meshgrid(*(np.arange(n) for n in MERL_SHAPE), indexing="ij", sparse=True)
    th, td, pd = cell_angles(I, J, K)
    i, j, k = merl_index(th, td, pd)
    assert i.shape == MERL_SHAPE
    assert np.array_equal(i, np.broadcast_to(I, MERL_SHAPE))
    assert np.array_equal(j, np.broadcast_to(J, MERL_SHAPE))
    assert np.array_equal(k, np.broadcast_to(K, MERL_SHAPE))


def test_lower_corners_are_the_closed_form_and_the_smallest_angle_of_their_cell():
    n_th, n_td, n_pd = MERL_SHAPE
    ii, jj, kk = np.arange(n_th), np.arange(n_td), np.arange(n_pd)
    th = cell_angles(ii, 0, 0)[0]
    td = cell_angles(0, jj, 0)[1]
    pd = cell_angles(0, 0, kk)[2]
    for got, closed in ((th, (ii / 90) ** 2 * 90 * DEG), (td, jj * DEG), (pd, kk * DEG)):
        assert np.all(np.abs(got - closed) <= 4 * np.spacing(np.maximum(closed, 1e-300)))
    # one ulp lower is in the previous cell: these are the cells' true lower boundaries
    below = (np.nextafter(th[1:], -1), np.nextafter(td[1:], -1), np.nextafter(pd[1:], -1))
    assert np.array_equal(merl_index(below[0], 0, 0)[0], ii[:-1])
    assert np.array_equal(merl_index(0, below[1], 0)[1], jj[:-1])
    assert np.array_equal(merl_index(0, 0, below[2])[2], kk[:-1])


# -- angles of direction pairs ----------------------------------------------------------------

def test_random_pairs_agree_with_the_database_oracle():
    wi, wo = random_pairs(200_000, seed=1)
    ref = oracle_angles(wi, wo)
    got = half_diff_from_dirs(wi, wo, fold=False)
    for a, b in zip(got, ref):
        assert np.allclose(a, b, rtol=0, atol=1e-7)  # acos loses digits near 0
    assert np.array_equal(index_of_dirs(wi, wo), np.stack(oracle_index(*ref), -1))


def test_reciprocity_swapping_wi_and_wo_gives_the_same_cell():
    wi, wo = random_pairs(200_000, seed=2)
    a, b = half_diff_from_dirs(wi, wo, fold=False), half_diff_from_dirs(wo, wi, fold=False)
    assert np.allclose(a[0], b[0], atol=1e-12) and np.allclose(a[1], b[1], atol=1e-12)
    shift = np.mod(b[2] - a[2], 2 * np.pi)  # phi_d -> phi_d + pi
    assert np.allclose(shift, np.pi, atol=1e-9)
    assert np.array_equal(index_of_dirs(wi, wo), index_of_dirs(wo, wi))


def test_isotropy_rotating_both_about_the_normal_gives_the_same_cell():
    wi, wo = random_pairs(200_000, seed=3)
    rot = _rot_z(np.random.default_rng(4).uniform(0, 2 * np.pi, len(wi)))
    wi_r, wo_r = np.einsum("nij,nj->ni", rot, wi), np.einsum("nij,nj->ni", rot, wo)
    assert np.array_equal(index_of_dirs(wi, wo), index_of_dirs(wi_r, wo_r))


def test_dirs_from_half_diff_inverts_half_diff_from_dirs():
    rng = np.random.default_rng(5)
    n = 50_000
    th, td = rng.uniform(0.01, 1.55, n), rng.uniform(0.01, 1.55, n)
    pd, ph = rng.uniform(-3.1, 3.1, n), rng.uniform(-3.1, 3.1, n)
    wi, wo = dirs_from_half_diff(th, td, pd, ph)
    assert np.allclose(np.linalg.norm(wi, axis=-1), 1)
    assert np.allclose(np.linalg.norm(wo, axis=-1), 1)
    h = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    assert np.allclose((wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True), h, atol=1e-12)
    # wo is the mirror of wi about h (RTR eq. 9.33 reversed)
    assert np.allclose(wo, 2 * np.sum(wi * h, -1, keepdims=True) * h - wi, atol=1e-12)
    for a, b in zip(half_diff_from_dirs(wi, wo, fold=False), (th, td, pd)):
        assert np.allclose(a, b, atol=1e-9)
    # and against the oracle's rotation matrices
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
    assert np.allclose(wi, np.einsum("nij,njk,nk->ni", _rot_z(ph), _rot_y(th), d), atol=1e-12)


def test_dirs_from_half_diff_of_separable_axes_is_that_of_the_flat_angles():
    """A grid given as separable axes (each sine and cosine taken on its axis, the azimuthal
    rotation skipped for the default ``phi_h = 0``) gives exactly the directions of the same
    angles given flat with an array of zero ``phi_h`` (the general path), and those agree with
    the oracle's rotation matrices."""
    rng = np.random.default_rng(6)
    th = rng.uniform(0.0, 1.55, 7)[:, None, None]
    td = rng.uniform(0.0, 1.55, 5)[None, :, None]
    pd = rng.uniform(0.0, 3.1, 9)[None, None, :]
    wi, wo = dirs_from_half_diff(th, td, pd)
    assert wi.shape == wo.shape == (7, 5, 9, 3)
    flat = [a.ravel() for a in np.broadcast_arrays(th, td, pd)]
    ref_i, ref_o = dirs_from_half_diff(*flat, np.zeros(flat[0].size))
    assert np.array_equal(wi.reshape(-1, 3), ref_i) and np.array_equal(wo.reshape(-1, 3), ref_o)
    t, d_, p = flat
    d = np.stack([np.sin(d_) * np.cos(p), np.sin(d_) * np.sin(p), np.cos(d_)], -1)
    assert np.allclose(ref_i, np.einsum("nij,njk,nk->ni", _rot_z(0 * t), _rot_y(t), d), atol=1e-12)


def test_degenerate_pairs_are_finite():
    z = np.array([0.0, 0.0, 1.0])
    x = np.array([1.0, 0.0, 0.0])
    th, td, pd = half_diff_from_dirs(np.stack([z, x, x]), np.stack([z, -x, x]))
    assert np.all(np.isfinite(th)) and np.all(np.isfinite(td)) and np.all(np.isfinite(pd))
    assert np.allclose(th, [0.0, 0.0, np.pi / 2]) and np.allclose(td, [0.0, np.pi / 2, 0.0])


def test_fold_phi_d():
    eps = 1e-20
    got = fold_phi_d(np.array([-eps, 0.0, np.pi, -np.pi, -np.pi / 2, 3 * np.pi / 2, np.nan]))
    assert np.array_equal(got[:6], [0.0, 0.0, 0.0, 0.0, np.pi / 2, np.pi / 2])
    assert np.isnan(got[6])


# -- the grid of sample directions ------------------------------------------------------------

def test_cell_centres_map_back_to_their_cell_through_directions():
    n_th, n_td, n_pd = MERL_SHAPE
    I, J, K = np.meshgrid(*(np.arange(n) for n in MERL_SHAPE), indexing="ij", sparse=True)
    wi, wo = dirs_from_half_diff(((I + 0.5) / n_th) ** 2 * (np.pi / 2),
                                 (J + 0.5) / n_td * (np.pi / 2), (K + 0.5) / n_pd * np.pi)
    i, j, k = merl_index(*half_diff_from_dirs(wi, wo))
    assert np.array_equal(i, np.broadcast_to(I, MERL_SHAPE))
    assert np.array_equal(j, np.broadcast_to(J, MERL_SHAPE))
    assert np.array_equal(k, np.broadcast_to(K, MERL_SHAPE))


def test_cell_directions_are_the_corners_cached_and_read_only():
    wi, wo = cell_directions()
    assert wi.shape == wo.shape == MERL_SHAPE + (3,)
    assert cell_directions()[0] is wi
    with pytest.raises(ValueError):
        wi[0, 0, 0, 0] = 1.0
    ijk = (np.array([0, 17, 63, 89]), np.array([0, 30, 1, 89]), np.array([0, 45, 179, 90 - 1]))
    ref_i, ref_o = dirs_from_half_diff(*cell_angles(*ijk))
    assert np.array_equal(wi[ijk], ref_i) and np.array_equal(wo[ijk], ref_o)


def test_above_horizon_matches_the_closed_form_and_the_reference_fraction():
    I, J, K = np.meshgrid(*(np.arange(n) for n in MERL_SHAPE), indexing="ij", sparse=True)
    th, td, pd = (I / 90) ** 2 * (np.pi / 2), J * DEG, K * DEG
    # z components of R_y(theta_h) applied to d and to d mirrored about the normal
    zi = np.cos(td) * np.cos(th) - np.sin(td) * np.cos(pd) * np.sin(th)
    zo = np.cos(td) * np.cos(th) + np.sin(td) * np.cos(pd) * np.sin(th)
    mask = above_horizon()
    assert np.array_equal(mask, (zi > HORIZON_EPS) & (zo > HORIZON_EPS))
    assert 0.75 < mask.mean() < 0.77  # "about 76%" (merl-format.md)
    assert not mask[30, 80, 0] and not mask[60, 50, 0]  # theta_h + theta_d = 90 deg exactly


def test_grid_caches_accept_any_spelling_of_the_shape():
    assert cell_directions([90, 90, 180])[0] is cell_directions()[0]
    assert above_horizon(np.array(MERL_SHAPE)) is above_horizon()
