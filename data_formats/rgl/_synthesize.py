"""A virtual RGL measurement: the ``.bsdf`` tables of any BRDF given as a NumPy callable.

Follows the acquisition of Dupuy & Jakob 2018 with the model in place of the
goniophotometer, and Mitsuba 3's ``measured`` plugin (``src/bsdfs/measured.cpp``) for what
each table means:

1. **NDF from retro-reflection** (as the paper measures it): a microfacet BRDF seen back along ``ω`` is
   ``f_r(ω, ω) = F D(ω) G1(ω)² / (4 cos²θ)`` and Smith's ``G1(ω) = cos θ / σ(ω)`` with the
   projected area ``σ(ω) = ∫ D(ωm) ⟨ω, ωm⟩₊ dωm``, so ``D ∝ f_r(ω, ω) σ[D](ω)²``: a fixed point,
   found by iterating from ``D = f_r(ω, ω)`` and normalizing ``∫ D cos θm dωm = 1`` after each
   step (the paper's power iteration). ``f_r`` is reduced to its luminance. ``D`` is tabulated
   on the ``u_m`` square (``θ = u_θ² π/2``, ``φ = (2u_φ - 1)π``) and integrals use its bilinear
   interpolant (what Mitsuba evaluates) on a midpoint grid twice as fine, with the Jacobian
   ``dω = 2π² u_θ sin θ du_θ du_φ``.
2. **σ** (``sigma``): the projected area of that tabulated NDF at the nodes of its square.
3. **VNDF** (``vndf``): per incidence slice ``(φi, θi)`` the density on the ``u_m`` square
   ``D(u_m) ⟨ωi, ωm⟩₊ 2π² u_θ sin θm`` (Mitsuba normalizes it into a warp); azimuth relative to
   ``φi`` when isotropic.
4. **Reflectance** (``rgb``): each node ``s`` of the ``n x n`` warped square is mapped by the
   slice's VNDF warp to ``u_m``, ``ωm``, ``ωo = 2(ωi·ωm)ωm - ωi`` and the table stores
   ``f_r(ωi, ωo) cos θo · 4 σ(u_wi) / D(u_m)`` with ``D`` and ``σ`` the tables' interpolants, so
   that Mitsuba's product ``R · D / (4σ)`` returns ``f_r cos θo`` exactly at every node; 0 (and
   ``valid = 0``) where ``ωo`` is below the horizon. ``luminance`` is its luminance.

Between nodes the file interpolates (bilinearly on the warped square, linearly in ``θi``, ``φi``):
:meth:`RGLMaterial.eval` of the result reproduces ``brdf`` at the nodes to float32 (1e-5) and
elsewhere to within that interpolation error. Measured (``benchmarks/bench_rgl.py``, GGX with
diffuse, 1M random pairs, ``θi, θo < 70°``, error ``|f_file - f| / (f + 1e-3)``): isotropic
``α = 0.3`` at the defaults (10 ``θi`` slices, 32 x 32 tables): median 0.004, 99th percentile
0.056, max 0.55; anisotropic ``α = (0.15, 0.4)`` with 13 ``φi`` slices: median 0.012, p99 0.26,
max 3.7. The error is largest in and near the specular peak (isotropic, ``θh < 15°``: p99 0.27-0.29
against 0.01-0.04 elsewhere), where the table on the warped square changes fastest (towards its
``u_θ = 0`` edge), and grows between ``θi`` slices (median 0.002 on a slice, 0.005 midway) and,
anisotropic, between the ``φi`` slices (30° apart). Near the horizon the tables interpolate
towards the zeros stored below it: ``f_r cos θo`` is then off by up to a few 1e-3 absolute, which
``f_r`` magnifies by ``1 / cos θo``.
"""

from __future__ import annotations

import numpy as np

from ._marginal import Marginal2D
from ._material import LUMINANCE, RGLMaterial, phi2u, spherical, theta2u, u2phi, u2theta

__all__ = ["synthesize_rgl"]

#: Retro-reflection is evaluated at most this far from the normal (f_r is undefined at 90°).
_MAX_RETRO = np.deg2rad(89.5)


def _luminance(rgb):
    return np.asarray(rgb, dtype=np.float64) @ LUMINANCE


def _call(brdf, wi, wo, what):
    out = np.asarray(brdf(wi, wo), dtype=np.float64)
    if out.shape != (len(wi), 3):
        raise ValueError(f"synthesize_rgl: brdf(wi, wo) must return ({len(wi)}, 3), got "
                         f"{out.shape} ({what})")
    bad = ~np.isfinite(out)
    if bad.any():
        raise ValueError(f"synthesize_rgl: brdf returned {int(bad.any(axis=1).sum())} "
                         f"non-finite values ({what}); it must be finite above the horizon")
    return out


def _quadrature(h, w):
    """Midpoints of a ``2h x 2w`` grid on the square: points ``(Q, 2)``, ``dω`` weights."""
    ux = (np.arange(2 * w) + 0.5) / (2 * w)
    uy = (np.arange(2 * h) + 0.5) / (2 * h)
    gx, gy = np.meshgrid(ux, uy)
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    theta = u2theta(pts[:, 0])
    dw = 2 * np.pi**2 * pts[:, 0] * np.sin(theta) / (4 * h * w)
    return pts, spherical(theta, u2phi(pts[:, 1])), dw


def _projected_area(ndf_table, dirs):
    """``σ(ω) = ∫ D(ωm) ⟨ω, ωm⟩₊ dωm`` of the table's interpolant, for ``dirs`` ``(K, 3)``."""
    h, w = ndf_table.shape
    pts, m, dw = _quadrature(h, w)
    d = Marginal2D(ndf_table, (), normalize=False, enable_sampling=False).eval(pts) * dw
    return np.clip(dirs @ m.T, 0.0, None) @ d


def _ndf_from_retro(brdf, shape, isotropic, iterations):
    h, w = shape
    gx, gy = np.meshgrid(np.linspace(0, 1, w), np.linspace(0, 1, h))
    theta = np.minimum(u2theta(gx), _MAX_RETRO)
    phi = np.zeros_like(gy) if isotropic else u2phi(gy)
    dirs = spherical(theta, phi).reshape(-1, 3)
    retro = _luminance(_call(brdf, dirs, dirs, "retro-reflection")).reshape(h, w)
    retro = np.maximum(retro, 1e-12 * max(retro.max(), 1e-30))
    ndf = retro.copy()
    z = np.array([[0.0, 0.0, 1.0]])
    for _ in range(iterations):
        ndf = ndf / _projected_area(ndf.astype(np.float32), z)[0]
        sigma = _projected_area(ndf.astype(np.float32), dirs).reshape(h, w)
        ndf = retro * sigma**2
    ndf = ndf / _projected_area(ndf.astype(np.float32), z)[0]
    return ndf.astype(np.float32)


def _sigma_table(ndf, shape, isotropic):
    h, w = shape
    gx, gy = np.meshgrid(np.linspace(0, 1, w), np.linspace(0, 1, h))
    phi = np.zeros_like(gy) if isotropic else u2phi(gy)
    dirs = spherical(u2theta(gx), phi).reshape(-1, 3)
    return _projected_area(ndf, dirs).reshape(h, w).astype(np.float32)


def _vndf_table(ndf, phi_i, theta_i, shape, isotropic):
    h, w = shape
    gx, gy = np.meshgrid(np.linspace(0, 1, w), np.linspace(0, 1, h))
    u_m = np.stack([gx.ravel(), gy.ravel()], axis=1)
    d = Marginal2D(ndf, (), normalize=False, enable_sampling=False).eval(u_m)
    theta_m = u2theta(u_m[:, 0])
    jac = 2 * np.pi**2 * u_m[:, 0] * np.sin(theta_m)
    out = np.empty((len(phi_i), len(theta_i), h, w), np.float32)
    for p, phi in enumerate(phi_i):
        m = spherical(theta_m, u2phi(u_m[:, 1]) + (phi if isotropic else 0.0))
        for t, theta in enumerate(theta_i):
            wi = spherical(np.float64(theta), np.float64(phi))
            out[p, t] = (d * np.clip(m @ wi, 0.0, None) * jac).reshape(h, w)
    return out


def _reflectance(brdf, mat, n, jacobian):
    """The ``rgb``, ``luminance`` and ``valid`` tables on the warped square (module docstring)."""
    n_phi, n_theta = len(mat.phi_i), len(mat.theta_i)
    grid = np.linspace(0.0, 1.0, n)
    gx, gy = np.meshgrid(grid, grid)
    nodes = np.stack([gx.ravel(), gy.ravel()], axis=1)
    warps = mat._warps_geometry
    rgb = np.zeros((n_phi, n_theta, n * n, 3))
    valid = np.zeros((n_phi, n_theta, n * n), bool)
    for p, phi in enumerate(mat.phi_i.astype(np.float64)):
        for t, theta in enumerate(mat.theta_i.astype(np.float64)):
            params = [np.full(n * n, phi), np.full(n * n, theta)]
            u_m, wm = mat.node_half_vectors(nodes, *params)
            wi = np.broadcast_to(spherical(theta, phi), wm.shape)
            wo = 2.0 * np.sum(wi * wm, axis=1, keepdims=True) * wm - wi
            ok = (wo[:, 2] > 0) & (wi[:, 2] > 0)
            f = np.zeros((n * n, 3))
            if ok.any():
                f[ok] = _call(brdf, np.ascontiguousarray(wi[ok]), wo[ok], "the reflectance")
            value = f * np.where(ok, wo[:, 2], 0.0)[:, None]
            if jacobian:
                u_wi = np.array([[theta2u(theta), phi2u(phi)]])
                scale = 4.0 * warps["sigma"].eval(u_wi)[0] / warps["ndf"].eval(u_m)
                value = value * scale[:, None]
            rgb[p, t], valid[p, t] = value, ok
    rgb = rgb.reshape(n_phi, n_theta, n, n, 3).transpose(0, 1, 4, 2, 3)
    lum = np.clip(np.einsum("c,ptcyx->ptyx", LUMINANCE, rgb), 0.0, None)
    lum += 1e-9 * max(float(lum.max()), 1e-30)  # every slice keeps mass (a sampling table)
    return (rgb.astype(np.float32), lum.astype(np.float32),
            valid.reshape(n_phi, n_theta, n, n).astype(np.uint8))


def _phi_nodes(isotropic, n_phi_i, reduction):
    if isotropic:
        return np.zeros(1, np.float32)
    if reduction not in (1, 2, 4) or n_phi_i < 3:
        raise ValueError("synthesize_rgl: an anisotropic file needs n_phi_i >= 3 and "
                         f"reduction 1, 2 or 4, got n_phi_i={n_phi_i}, reduction={reduction}")
    return np.linspace(-np.pi, -np.pi + 2 * np.pi / reduction, n_phi_i).astype(np.float32)


def synthesize_rgl(brdf, *, isotropic: bool = True, name: str = "", description: str = "",
                   n_theta_i: int = 10, max_theta_i: float = np.deg2rad(87.5),
                   n_phi_i: int = 13, reduction: int = 1, ndf_shape=None, sigma_shape=None,
                   vndf_shape=(32, 32), resolution: int = 32, jacobian: bool = True,
                   iterations: int = 6) -> RGLMaterial:
    """The RGL tables of ``brdf`` (module docstring): a material :func:`write_rgl` can save.

    Args:
        brdf: ``brdf(wi, wo) -> (N, 3)`` ``f_r`` in 1/sr (no cosine) for unit ``(N, 3)``
            directions above the horizon, NumPy; finite there.
        isotropic: one ``φi`` slice (azimuths relative to it) instead of ``n_phi_i``.
        n_theta_i, max_theta_i: incidence slices ``θi = linspace(0, max_theta_i)`` (radians).
        n_phi_i, reduction: anisotropic slices ``φi = linspace(-π, -π + 2π/reduction)``; a
            reduction of 2 or 4 assumes the symmetry Mitsuba then applies (module
            ``_material``): use it only for a ``brdf`` that has it.
        ndf_shape, sigma_shape, vndf_shape: ``(H, W)`` (``φ`` rows, ``θ`` columns) of those
            tables; defaults ``(2, 64)`` and ``(2, 32)`` isotropic, ``(32, 32)`` anisotropic.
        resolution: ``n``, the side of the reflectance table on the warped square.
        jacobian: store ``f_r cos θo · 4σ/D`` (Mitsuba's ``jacobian`` flag) or ``f_r cos θo``.
        iterations: fixed-point steps of the retro-reflection NDF.
    """
    ndf_shape = tuple(ndf_shape or ((2, 64) if isotropic else (32, 32)))
    sigma_shape = tuple(sigma_shape or ((2, 32) if isotropic else (32, 32)))
    phi_i = _phi_nodes(isotropic, n_phi_i, reduction)
    theta_i = np.linspace(0.0, max_theta_i, n_theta_i).astype(np.float32)
    ndf = _ndf_from_retro(brdf, ndf_shape, isotropic, iterations)
    sigma = _sigma_table(ndf, sigma_shape, isotropic)
    vndf = _vndf_table(ndf, phi_i.astype(np.float64), theta_i.astype(np.float64),
                       tuple(vndf_shape), isotropic)
    n = int(resolution)
    mat = RGLMaterial(theta_i=theta_i, phi_i=phi_i, ndf=ndf, sigma=sigma, vndf=vndf,
                      luminance=np.ones((len(phi_i), len(theta_i), n, n), np.float32),
                      rgb=np.zeros((len(phi_i), len(theta_i), 3, n, n), np.float32),
                      jacobian=jacobian, name=name,
                      description=description or f"synthesized virtual measurement {name}".strip())
    rgb, lum, valid = _reflectance(brdf, mat, n, jacobian)
    return RGLMaterial(theta_i=theta_i, phi_i=phi_i, ndf=ndf, sigma=sigma, vndf=vndf,
                       luminance=lum, rgb=rgb, jacobian=jacobian, description=mat.description,
                       valid=valid, name=name)
