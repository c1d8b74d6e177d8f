"""The RGL material in memory: its fields, evaluation exactly as Mitsuba 3 renders it, and samples.

Model (Dupuy & Jakob 2018, "An Adaptive Parameterization for Efficient Material Acquisition and
Rendering", ACM TOG 37(6); Mitsuba 3 ``src/bsdfs/measured.cpp``). Angles map to the unit
square by ``u_θ = sqrt(2θ/π)``, ``u_φ = (φ + π) / 2π`` (``theta2u``, ``phi2u``). For incidence
``ωi = (θi, φi)`` and half vector ``ωm = normalize(ωi + ωo)`` (``elevation`` is the stable
``2 asin(|ω - z| / 2)``):

* ``u_m = (u_θ(θm), u_φ(φm - φi))`` for an isotropic file (relative azimuth; ``φi`` has at most
  two nodes), ``u_φ(φm)`` for an anisotropic one, wrapped to ``[0, 1)``;
* ``s = VNDF⁻¹(u_m; φi, θi)``: the inverse of the :class:`~data_formats.rgl._marginal.Marginal2D`
  warp built on ``vndf`` (the visible-normal density ``D(ωm)⟨ωi, ωm⟩ / σ(ωi)`` times the
  Jacobian ``2π² u_θ sin θm`` of the square), interpolated in the parameters ``(φi, θi)``;
* ``f_r cos θo = R(s; φi, θi) · D(u_m) / (4 σ(u_wi))`` where ``R`` is the bilinear interpolant of
  the ``rgb`` table on the warped square (``s``), ``D`` of ``ndf`` and ``σ`` (projected area) of
  ``sigma``; the factor ``D/(4σ)`` only when ``jacobian`` is set (the paper's parameterization: the tables store
  ``f_r cos θo`` divided by the VNDF-to-``ωo`` density, which is smooth).

Anisotropic files may store a reduced range of ``φi``: ``reduction = rint(2π / (φi[-1] - φi[0]))``
(1, 2 or 4); with 2 the pair is rotated by π so that ``ωi.y ≤ 0``, with 4 mirrored in x and y
so that ``ωi.x, ωi.y ≤ 0`` (``mulsign_neg``). For an isotropic file Mitsuba 3.9 leaves
``m_reduction`` uninitialized, so it may apply either fold; both keep the relative azimuth's
magnitude, and the tables :func:`~data_formats.rgl.synthesize_rgl` writes are symmetric in it, so
Mitsuba's value does not depend on the fold; here no fold is applied. Below the horizon
(``cos θi ≤ 0`` or ``cos θo ≤ 0``) the value is 0. Mitsuba's ``eval`` returns ``f_r cos θo``; :meth:`RGLMaterial.eval`
returns ``f_r`` (divided by ``cos θo``). Arithmetic is float64 on the file's float32 tables.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..rusinkiewicz import dirs_from_half_diff
from ..samples import SampleSet
from ._marginal import Marginal2D

__all__ = ["RGLMaterial", "theta2u", "phi2u", "u2theta", "u2phi", "elevation", "LUMINANCE"]

#: Rec. 709 luminance weights (the ``luminance`` table is the luminance of ``rgb``).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
_CHUNK = 1 << 16


def theta2u(theta):
    """``sqrt(2θ/π)`` (``measured.cpp``)."""
    return np.sqrt(np.maximum(theta, 0.0) * (2.0 / np.pi))


def phi2u(phi):
    """``(φ + π) / 2π`` (``measured.cpp``)."""
    return (phi + np.pi) * (0.5 / np.pi)


def u2theta(u):
    return np.square(u) * (np.pi / 2)


def u2phi(u):
    return (2.0 * u - 1.0) * np.pi


def elevation(d):
    """``2 asin(|d - z| / 2)``: ``acos(d.z)`` without its loss of precision near the pole."""
    dist = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + (d[..., 2] - 1.0) ** 2)
    return 2.0 * np.arcsin(np.clip(0.5 * dist, -1.0, 1.0))


def _mulsign_neg(x, s):
    """``dr::mulsign_neg``: ``x`` times the negated sign of ``s`` (sign bit, so ``+0`` flips)."""
    return np.where(np.signbit(s), x, -x)


def spherical(theta, phi):
    st = np.sin(theta)
    return np.stack([np.cos(phi) * st, np.sin(phi) * st, np.cos(theta)], axis=-1)


@dataclasses.dataclass(eq=False, repr=False)
class RGLMaterial:
    """An RGL ``.bsdf`` material (Dupuy & Jakob 2018) in memory; the file's fields, float32.

    Attributes:
        theta_i: ``(n_θ,)`` incidence elevations of the tables' slices, radians, increasing.
        phi_i: ``(n_φ,)`` incidence azimuths, radians, increasing; ``n_φ <= 2`` marks an
            isotropic material.
        ndf: ``(H_D, W_D)`` the microfacet normal distribution on the ``u_m`` square.
        sigma: ``(H_σ, W_σ)`` the projected area ``σ(ωi)`` on the ``u_wi`` square.
        vndf: ``(n_φ, n_θ, H_V, W_V)`` the visible-normal density per slice (a warp).
        luminance: ``(n_φ, n_θ, n, n)`` the luminance of the reflectance table (used for
            sampling only).
        rgb: ``(n_φ, n_θ, 3, n, n)`` the tabulated reflectance on the warped square, or ``None``
            for a spectral file, which has ``spectra`` ``(n_φ, n_θ, n_λ, n, n)`` and
            ``wavelengths`` ``(n_λ,)`` nm instead (:meth:`eval` then reduces spectra to RGB,
            :func:`data_formats.rgl.spectra_to_rgb`).
        jacobian: whether the tables are divided by ``D / (4σ)`` (module docstring).
        description: the file's free-text description.
        valid: the file's ``valid`` field if any (uint8, ``(n_φ, n_θ, n, n)`` when it marks the
            table's nodes; any other shape is kept but not used).
        name, path: a short label (the file stem) and the file read, if any.
    """

    theta_i: np.ndarray
    phi_i: np.ndarray
    ndf: np.ndarray
    sigma: np.ndarray
    vndf: np.ndarray
    luminance: np.ndarray
    rgb: np.ndarray | None = None
    spectra: np.ndarray | None = None
    wavelengths: np.ndarray | None = None
    jacobian: bool = True
    description: str = ""
    valid: np.ndarray | None = None
    name: str = ""
    path: str | None = None

    @property
    def isotropic(self) -> bool:
        """Mitsuba's rule: at most two ``φi`` slices."""
        return len(self.phi_i) <= 2

    @property
    def reduction(self) -> int:
        """1, 2 or 4: the symmetry folding ``φi`` of an anisotropic file (1 when isotropic)."""
        if self.isotropic:
            return 1
        span = float(self.phi_i[-1]) - float(self.phi_i[0])
        return int(np.rint(np.float32(2 * np.pi) / np.float32(span)))

    @property
    def resolution(self) -> int:
        """``n``: the side of the reflectance table on the warped square."""
        return int(self.luminance.shape[-1])

    def __repr__(self) -> str:
        kind = "isotropic" if self.isotropic else f"anisotropic (reduction {self.reduction})"
        table = "rgb" if self.rgb is not None else f"{len(self.wavelengths)} wavelengths"
        return (f"RGLMaterial({self.name!r}, {kind}, {len(self.theta_i)} θi x {len(self.phi_i)}"
                f" φi slices, {self.resolution}x{self.resolution} {table})")

    # -- interpolants (built once, as Mitsuba's constructor does) --------------------------------

    @functools.cached_property
    def _warps_geometry(self):
        """``ndf``, ``sigma`` (plain interpolants) and the ``vndf`` warp, as ``measured.cpp``."""
        return {
            "ndf": Marginal2D(self.ndf, (), normalize=False, enable_sampling=False),
            "sigma": Marginal2D(self.sigma, (), normalize=False, enable_sampling=False),
            "vndf": Marginal2D(self.vndf, [self.phi_i, self.theta_i]),
        }

    @functools.cached_property
    def _warps(self):
        """The geometry and the reflectance interpolants, one per channel (Mitsuba's ``Warp2D3``
        with the channel as its third parameter, whose nodes 0, 1, 2 pick one channel)."""
        rgb = self.rgb_table
        params = [self.phi_i, self.theta_i]
        return {**self._warps_geometry,
                "rgb": [Marginal2D(rgb[:, :, c], params, normalize=False, enable_sampling=False)
                        for c in range(3)]}

    @functools.cached_property
    def rgb_table(self) -> np.ndarray:
        """``(n_φ, n_θ, 3, n, n)`` float32: ``rgb``, or ``spectra`` reduced to linear sRGB."""
        if self.rgb is not None:
            return np.asarray(self.rgb, dtype=np.float32)
        from ._spectral import spectra_to_rgb_matrix
        m = spectra_to_rgb_matrix(self.wavelengths)
        return np.einsum("cl,ptlyx->ptcyx", m, self.spectra.astype(np.float64)).astype(np.float32)

    # -- evaluation ------------------------------------------------------------------------------

    def eval(self, wi, wo) -> np.ndarray:
        """``f_r(ωi, ωo)`` ``(N, 3)`` float64 in 1/sr (no cosine), exactly as Mitsuba 3's
        ``measured`` plugin evaluates it (module docstring) divided by ``cos θo``; 0 below the
        horizon. ``wi``, ``wo``: ``(N, 3)`` unit vectors in the shading frame (z the normal).
        A spectral file gives the linear sRGB of its spectra (:mod:`._spectral`)."""
        return self._evaluate(wi, wo, None)

    def eval_spectrum(self, wi, wo, wavelengths) -> np.ndarray:
        """``f_r`` ``(N, k)`` of a spectral file at the wavelengths ``(k,)`` nm (or ``(N, k)``),
        as Mitsuba's spectral variants evaluate it (the ``spectra`` table interpolated in the
        wavelength, weights clamped at the ends)."""
        if self.spectra is None:
            raise ValueError("RGLMaterial.eval_spectrum: an RGB file has no spectra; use eval")
        return self._evaluate(wi, wo, np.asarray(wavelengths, dtype=np.float64))

    def _evaluate(self, wi, wo, wavelengths):
        wi = np.asarray(wi, dtype=np.float64)
        wo = np.asarray(wo, dtype=np.float64)
        if wi.shape != wo.shape or wi.ndim != 2 or wi.shape[1] != 3:
            raise ValueError(f"RGLMaterial.eval: wi and wo must both be (N, 3), got {wi.shape} "
                             f"and {wo.shape}")
        k = 3 if wavelengths is None else wavelengths.shape[-1]
        if wavelengths is not None:
            wavelengths = np.broadcast_to(wavelengths, (len(wi), k))
        out = np.zeros((len(wi), k))
        for start in range(0, len(wi), _CHUNK):
            sl = slice(start, start + _CHUNK)
            out[sl] = self._eval_chunk(wi[sl], wo[sl],
                                       None if wavelengths is None else wavelengths[sl])
        return out

    def _eval_chunk(self, wi, wo, wavelengths):
        active = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        wi, wo = self._reduce(wi, wo)
        m = wi + wo
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        theta_i, phi_i = elevation(wi), np.arctan2(wi[:, 1], wi[:, 0])
        theta_m, phi_m = elevation(m), np.arctan2(m[:, 1], m[:, 0])
        u_wi = np.stack([theta2u(theta_i), phi2u(phi_i)], axis=1)
        u_m = np.stack([theta2u(theta_m), phi2u(phi_m - phi_i if self.isotropic else phi_m)],
                       axis=1)
        u_m[:, 1] -= np.floor(u_m[:, 1])
        u_m = np.nan_to_num(u_m)  # inactive pairs (wo = -wi) only
        params = [phi_i, theta_i]
        geometry = self._warps_geometry
        sample, _ = geometry["vndf"].invert(u_m, params)
        if wavelengths is None:
            spec = np.stack([w.eval(sample, params) for w in self._warps["rgb"]], axis=1)
        else:
            spec = np.stack([self._warp_spectra.eval(sample, params + [wavelengths[:, c]])
                             for c in range(wavelengths.shape[1])], axis=1)
        if self.jacobian:
            spec *= (geometry["ndf"].eval(u_m) / (4.0 * geometry["sigma"].eval(u_wi)))[:, None]
        cos_o = np.where(active, wo[:, 2], 1.0)
        return np.where(active[:, None], spec / cos_o[:, None], 0.0)

    @functools.cached_property
    def _warp_spectra(self):
        """Mitsuba's ``Warp2D3`` on ``spectra``: parameters ``(φi, θi, λ)``."""
        return Marginal2D(self.spectra, [self.phi_i, self.theta_i, self.wavelengths],
                          normalize=False, enable_sampling=False)

    # -- the measurement pattern -----------------------------------------------------------------

    def incidence_nodes(self):
        """``(φi, θi)`` of every slice, ``(n_φ, n_θ)`` each (the file's own nodes)."""
        return np.meshgrid(self.phi_i.astype(np.float64), self.theta_i.astype(np.float64),
                           indexing="ij")

    def node_half_vectors(self, nodes, phi, theta):
        """``(u_m, ωm)`` of nodes of the warped square for incidences ``(φi, θi)`` (N each).

        ``u_m`` is the VNDF warp of the node (Mitsuba's ``sample``) without the warp's clamp
        of its input to ``[ε, 1-ε]``: the square's edges map exactly onto the edges, so the
        two edges ``u_φ = 0`` and ``u_φ = 1`` (both the azimuth ``±π``) give the same pairs and
        table rows, as they must (with the clamp they differed by 1e-3 where the table is
        steep), and the edge ``u_θ = 0`` is the normal itself.
        """
        seam = nodes[:, 1] == 1.0  # sampled as u_φ = 0 (the CDF's rounding would overshoot 1)
        u_m, _ = self._warps_geometry["vndf"].sample(
            np.where(seam[:, None], nodes * [1.0, 0.0], nodes), [phi, theta], guard=False)
        u_m[:, 1] = np.where(seam, 1.0, u_m[:, 1])
        phi_m = u2phi(u_m[:, 1]) + (phi if self.isotropic else 0.0)
        return u_m, spherical(u2theta(u_m[:, 0]), phi_m)

    def pattern(self):
        """The file's own measurement pattern: ``(wi, wo, wm, u_m, value, valid, node)``.

        For every ``(φi, θi)`` slice and every node ``(x_k, y_j) = (k, j) / (n-1)`` of the
        reflectance table, ``u_m`` is the VNDF warp of the node (``Marginal2D.sample`` with the
        slice's parameters, as Mitsuba's ``sample`` maps it; :meth:`node_half_vectors`), ``ωm``
        its direction (azimuth relative to ``φi`` when isotropic) and ``ωo = 2(ωi·ωm)ωm - ωi``.
        ``value`` is the node's ``f_r`` (the table value times ``D/(4σ)`` when ``jacobian``, divided by ``cos θo``);
        ``valid`` is false below the horizon and where the file's ``valid`` marks the node.
        Arrays are flat over ``(n_φ, n_θ, n, n)``.
        """
        n, warps = self.resolution, self._warps_geometry
        phi, theta = (a.ravel() for a in self.incidence_nodes())
        grid = np.linspace(0.0, 1.0, n)
        gx, gy = np.meshgrid(grid, grid)  # [j, k] = (x_k, y_j)
        nodes = np.stack([gx.ravel(), gy.ravel()], axis=1)
        n_slice = len(phi)
        phi_r = np.repeat(phi, n * n)
        theta_r = np.repeat(theta, n * n)
        pts = np.tile(nodes, (n_slice, 1))
        u_m, wm = self.node_half_vectors(pts, phi_r, theta_r)
        wi = spherical(theta_r, phi_r)
        wo = 2.0 * np.sum(wi * wm, axis=1, keepdims=True) * wm - wi
        table = self.rgb_table.reshape(n_slice, 3, n * n).transpose(0, 2, 1).reshape(-1, 3)
        value = table.astype(np.float64)
        if self.jacobian:
            u_wi = np.stack([theta2u(theta_r), phi2u(phi_r)], axis=1)
            value = value * (warps["ndf"].eval(u_m) / (4.0 * warps["sigma"].eval(u_wi)))[:, None]
        valid = (wo[:, 2] > 0) & (wi[:, 2] > 0)
        if self.valid is not None and self.valid.size == n_slice * n * n:
            valid &= self.valid.ravel().astype(bool)
        value = np.where(valid[:, None], value / np.where(valid, wo[:, 2], 1.0)[:, None], 0.0)
        return wi, wo, wm, u_m, value, valid, pts

    def _reduce(self, wi, wo):
        """Mitsuba's fold of an anisotropic pair into the stored ``φi`` range (module doc)."""
        red = self.reduction
        if red >= 2:
            wi, wo = wi.copy(), wo.copy()
            sy = wi[:, 1].copy()
            sx = wi[:, 0].copy() if red == 4 else sy
            for v in (wi, wo):
                v[:, 0] = _mulsign_neg(v[:, 0], sx)
                v[:, 1] = _mulsign_neg(v[:, 1], sy)
        return wi, wo

    def _owners(self, wi, wo):
        """The pattern pair (flat index over ``(n_φ, n_θ, n, n)``) nearest each pair: the
        nearest ``(φi, θi)`` slice and the nearest node of the warped square, where
        :meth:`eval` would look the pair up (the VNDF inverse)."""
        n = self.resolution
        wi, wo = self._reduce(wi, wo)
        m = wi + wo
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        theta_i, phi_i = elevation(wi), np.arctan2(wi[:, 1], wi[:, 0])
        u_m = np.stack([theta2u(elevation(m)), phi2u(np.arctan2(m[:, 1], m[:, 0])
                                                     - (phi_i if self.isotropic else 0.0))], 1)
        u_m[:, 1] -= np.floor(u_m[:, 1])
        sample, _ = self._warps_geometry["vndf"].invert(u_m, [phi_i, theta_i])
        t = _nearest(self.theta_i.astype(np.float64), theta_i)
        p = (np.zeros(len(wi), np.int64) if self.isotropic else
             _nearest(self.phi_i.astype(np.float64), phi_i))
        k, j = (np.rint(np.clip(sample, 0, 1) * (n - 1)).astype(np.int64).T)
        return ((p * len(self.theta_i) + t) * n + j) * n + k

    def _monte_carlo_shares(self, count: int):
        """Angle-domain volume owned by each pair (:meth:`_owners`), from ``count`` points of a
        Kronecker (R4) sequence uniform in ``(θh, φh, θd, φd)``, and the hits per pair."""
        alpha = 1.0 / 1.1673039782614187 ** np.arange(1, 5)  # Roberts: g^5 = g + 1
        total = self.resolution**2 * len(self.theta_i) * len(self.phi_i)
        hits = np.zeros(total)
        for start in range(0, count, _CHUNK):
            k = np.arange(start, min(start + _CHUNK, count), dtype=np.float64)[:, None] + 1
            q = (0.5 + k * alpha) % 1.0
            wi, wo = dirs_from_half_diff(q[:, 0] * np.pi / 2, q[:, 2] * np.pi / 2,
                                         q[:, 3] * 2 * np.pi, q[:, 1] * 2 * np.pi)
            ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
            hits += np.bincount(self._owners(wi[ok], wo[ok]), minlength=total)
        return hits * (np.pi**4 / count), hits

    def _pointwise_shares(self, wi, wm, pts):
        """Angle-domain volume of each pair's cell from the Jacobians at the node: the product
        of the incidence and outgoing solid angles over ``4 cos θd sin θh sin θd``."""
        n = self.resolution
        phi, theta = (a.ravel() for a in self.incidence_nodes())
        cell_i = np.repeat(_incidence_cells(self.theta_i, self.phi_i, self.isotropic)[0].ravel(),
                           n * n)
        side = np.full(n, 1.0 / (n - 1))
        side[[0, -1]] *= 0.5
        area = np.tile(np.outer(side, side).ravel(), len(phi))
        params = [np.repeat(phi, n * n), np.repeat(theta, n * n)]
        u_m = self.node_half_vectors(pts, *params)[0]
        pdf = self._warps_geometry["vndf"].eval(u_m, params)
        cos_im = np.clip(np.sum(wi * wm, axis=1), 1e-12, None)
        sin_h = np.sqrt(np.clip(1 - wm[:, 2]**2, 1e-24, 1))
        sin_d = np.sqrt(np.clip(1 - cos_im**2, 1e-24, 1))
        cell_o = area * 2 * np.pi**2 * u_m[:, 0] * sin_h * 4 * cos_im / np.maximum(pdf, 1e-300)
        return cell_i * cell_o / (4 * cos_im * sin_h * sin_d)

    def pair_weights(self, wi, wm, pts, valid, *, count: int | None = None, min_hits: int = 6):
        """Each pair's share of the Rusinkiewicz angle domain, mean 1 over valid pairs
        (:meth:`to_samples` says which measure and why). ``count``: Monte Carlo points,
        default 16 per pair within ``[2^20, 2^22]``."""
        if count is None:
            count = int(np.clip(16 * len(wi), 1 << 20, 1 << 22))
        volume, hits = self._monte_carlo_shares(count)
        small = hits < min_hits
        if small.any():
            # A cell hit fewer than min_hits times is almost surely smaller than this many
            # hits' volume: the cap removes the pointwise estimate's excursions near its poles.
            cap = (min_hits + 3 * np.sqrt(min_hits)) * np.pi**4 / count
            point = np.minimum(self._pointwise_shares(wi, wm, pts), cap)
            volume = np.where(small & np.isfinite(point), point, volume)
        w = np.where(valid, volume, 0.0)
        mean = w[valid].mean() if valid.any() else 1.0
        return w / mean if mean > 0 else np.where(valid, 1.0, 0.0)

    def to_samples(self, *, weights: bool = True, count: int | None = None) -> SampleSet:
        """The file's measurement pattern as a :class:`SampleSet` (the pairs the fitter reads).

        Pairs: every ``(φi, θi)`` slice of the file (for an isotropic file ``φi`` is the file's
        own node, ``phi_i[0]``, usually 0: only the azimuth relative to it matters) times every
        node of the ``n x n`` reflectance table, mapped through the slice's VNDF warp to ``ωm``
        and reflected to ``ωo`` (:meth:`pattern`); the value is the node's tabulated ``f_r``,
        which :meth:`eval` reproduces there. Pairs with ``ωo`` below the horizon or marked
        invalid by the file stay in the arrays with ``valid == False`` (static shapes). The
        values come from float32 tables: ``value_epsilon`` is float32's epsilon.

        Weights (``SampleSet.weight``, ``weights=True``): the share of the Rusinkiewicz angle
        domain ``(θh, φh, θd, φd)`` each pair stands for, relative to the average pair — the
        measure MERL tables carry (``SampleSet.weight``), so a fit weighs a material the same
        way from either format. The pattern is adaptive: the VNDF warp puts equal visible-normal
        mass in each cell, so most nodes sit in the specular peak, and counting each pair once
        would fit the peak and neglect the rest of the lobe (and the grazing slices).

        The share is measured, not modelled: a deterministic low-discrepancy sequence (Roberts'
        R4, ``count`` points, 16 per pair by default) uniform in the four angles is mapped to
        direction pairs, each is assigned to the pair that :meth:`eval` would read it from
        (nearest ``θi``/``φi`` slice, nearest node of the warped square after the VNDF
        inverse), and a pair's share is its count. Cells hit fewer than ``min_hits`` times
        (the small cells of the peak) take the share of their own Jacobians instead (capped at
        the volume of ``min_hits + 3 sqrt(min_hits)`` hits): incidence
        solid angle times outgoing solid angle (node area on the square over the density of
        ``ωo``, ``vndf_pdf / (2π² u_θ sin θm · 4 ωi·ωm)``, Mitsuba's ``pdf`` without the
        luminance), over ``4 cos θd sin θh sin θd`` (solid angles to angles); for cells with
        many hits that estimate agrees with the count (median ratio 0.92-0.97 in the tests),
        but it is singular on the poles of the change of variables, where the cells are large.
        ``weights=False`` gives ``None``.

        The default call (``weights=True``, ``count=None``: what a fit and the figures read) is
        made once per material and kept by it (:attr:`_samples`; the material does not change
        after it is read), so the several figures of one material share it.
        """
        if weights and count is None:
            return self._samples
        return self._make_samples(weights, count)

    @functools.cached_property
    def _samples(self) -> SampleSet:
        """:meth:`to_samples` with its defaults, made at its first call."""
        return self._make_samples(True, None)

    def _make_samples(self, weights: bool, count: int | None) -> SampleSet:
        wi, wo, wm, u_m, value, valid, pts = self.pattern()
        weight = self.pair_weights(wi, wm, pts, valid, count=count) if weights else None
        return SampleSet(wi=wi, wo=wo, rgb=value, valid=valid, name=self.name, path=self.path,
                         weight=weight, value_epsilon=float(np.finfo(self.rgb_table.dtype).eps))


def _nearest(nodes, x):
    """Index of the node nearest each ``x`` (``nodes`` increasing; the lower one on a tie), by
    binary search: memory ``O(len(x))``, whatever the number of nodes."""
    i = np.clip(np.searchsorted(nodes, x, side="left"), 1, max(len(nodes) - 1, 1))
    if len(nodes) == 1:
        return np.zeros(len(x), np.int64)
    lower = np.abs(x - nodes[i - 1]) <= np.abs(nodes[i] - x)
    return np.where(lower, i - 1, i).astype(np.int64)


def _incidence_cells(theta_i, phi_i, isotropic):
    """``(n_φ, n_θ)`` solid angle of each incidence slice: θ from midpoint to midpoint (the
    first from 0 when ``θ0 = 0``), φ over the slice's share of its range (2π when isotropic);
    and ``(n_θ,)`` the width in θ of each band."""
    t = theta_i.astype(np.float64)
    mids = 0.5 * (t[1:] + t[:-1])
    lo = np.concatenate([[max(0.0, t[0] - (mids[0] - t[0]) if len(t) > 1 else 0.0)], mids])
    hi = np.concatenate([mids, [min(np.pi / 2, t[-1] + (t[-1] - mids[-1]) if len(t) > 1
                                    else np.pi / 2)]])
    band = np.cos(lo) - np.cos(hi)
    if isotropic:
        dphi = np.full(len(phi_i), 2 * np.pi / len(phi_i))
    else:
        p = phi_i.astype(np.float64)
        edges = np.concatenate([[p[0]], 0.5 * (p[1:] + p[:-1]), [p[-1]]])
        dphi = np.diff(edges)
    return np.outer(dphi, band), hi - lo

