r"""Quadrature rules on the sphere of microfacet normals, for the APS 2000 integrals.

Two rules, both returned as NumPy node/weight arrays (cached; cast to the caller's dtype):

* :func:`polar_rule`: the hemisphere around ``±n`` in polar coordinates: Gauss–Legendre in
  ``θ ∈ [0, π/2]`` (nodes cluster at the pole, where most distributions peak, and at the
  horizon, where a heightfield's ``p(h)`` may jump) and the periodic trapezoid rule in ``φ``
  (spectrally accurate for smooth periodic integrands). Used for the moments
  ``∫ p dω``, ``∫ h p dω`` (the mean normal, APS eq. 22) and the hemispherical reflectance R(k)
  (APS eq. 29).
* :func:`lune_rule`: the domain ``{h : h·k > 0}`` (intersected with ``h·n > 0`` for a heightfield)
  parametrized so that *both* boundaries are coordinate lines. Every great circle through the
  axis ``a = n × k/|n × k|`` is a line of constant ``ψ``; with ``h = cos β (cos ψ k + sin ψ e₂)
  + sin β a`` and ``e₂ = a × k``, ``h·k = cos β cos ψ`` and ``h·n = cos β cos(ψ + θ_k)``, so the
  domain is ``ψ ∈ (−π/2, π/2 − θ_k)`` (heightfield) or ``(−π/2, π/2)``, ``β ∈ (−π/2, π/2)``,
  ``dω = cos β dβ dψ``. The integrand ``(h·k)⁺ p(h)`` of APS eq. 18 is then smooth on the whole
  domain: no kink of ``(·)⁺`` and no heightfield cut inside it, so Gauss–Legendre converges
  spectrally instead of at second order. ``β`` is split at 0 (where ``n`` lies) so that nodes
  cluster there.
"""

from __future__ import annotations

import functools

import numpy as np


@functools.cache
def gauss_legendre(n: int, lo: float = -1.0, hi: float = 1.0):
    """Gauss–Legendre nodes and weights on ``[lo, hi]`` (NumPy, float64)."""
    x, w = np.polynomial.legendre.leggauss(n)
    half = 0.5 * (hi - lo)
    return lo + half * (x + 1.0), half * w


@functools.cache
def polar_rule(n_theta: int, n_phi: int, lower: bool = False):
    """Nodes ``h`` ``(n_theta*n_phi, 3)`` and weights (solid angle) on the hemisphere ``±h_z > 0``.

    ``∫_{h_z>0} f(h) dω ≈ Σ w_i f(h_i)``; exact for polynomials of degree ``2 n_theta − 1`` in
    ``θ`` times trigonometric polynomials of degree ``< n_phi`` in ``φ``.
    """
    th, wt = gauss_legendre(n_theta, 0.0, np.pi / 2)
    ph = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    z = np.cos(TH) * (-1.0 if lower else 1.0)
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), z], -1).reshape(-1, 3)
    w = (wt[:, None] * np.sin(th)[:, None] * np.full(n_phi, 2 * np.pi / n_phi)).reshape(-1)
    h.setflags(write=False)
    w.setflags(write=False)
    return h, w


def lune_frames(theta_k, phi_k):
    """``(k, e₂, a)``, each ``(..., 3)``, for directions at polar angle ``theta_k``, azimuth ``phi_k``.

    ``a = (−sin φ_k, cos φ_k, 0)`` (along ``n × k``, defined at the pole too), ``e₂ = a × k``, so
    that ``n = cos θ_k k − sin θ_k e₂``.
    """
    st, ct, sp, cp = np.sin(theta_k), np.cos(theta_k), np.sin(phi_k), np.cos(phi_k)
    k = np.stack([st * cp, st * sp, ct], -1)
    a = np.stack([-sp, cp, np.zeros_like(sp)], -1)
    e2 = np.stack([cp * ct, sp * ct, -st], -1)
    return k, e2, a


@functools.cache
def lune_rule(theta_k: tuple, phi_k: tuple, n_psi: int, n_beta: int, heightfield: bool):
    """Nodes and weights for ``g(k) = ∫_{Ω+(k)} (h·k) p(h) dω`` (APS eq. 18) for many ``k``.

    Returns ``h`` of shape ``(K, n_psi, 2 n_beta, 3)`` and weights ``(K, n_psi, 2 n_beta)`` that
    already include the factor ``(h·k) = cos β cos ψ`` and the measure ``cos β``, so that
    ``g(k_j) ≈ Σ w_j p(h_j)``. ``theta_k`` may exceed π/2 (directions below the horizon).
    """
    tk, pk = np.asarray(theta_k, float), np.asarray(phi_k, float)
    k, e2, a = lune_frames(tk, pk)
    x, wx = gauss_legendre(n_psi)  # on [-1, 1]
    lo = -np.pi / 2
    hi = np.pi / 2 - tk if heightfield else np.full_like(tk, np.pi / 2)
    hi = np.maximum(hi, lo)  # an empty domain (k = -n on a heightfield) gets zero weights
    psi = lo + (hi - lo)[:, None] * 0.5 * (x + 1.0)
    wpsi = (hi - lo)[:, None] * 0.5 * wx
    bl, wbl = gauss_legendre(n_beta, -np.pi / 2, 0.0)
    beta = np.concatenate([bl, -bl[::-1]])
    wbeta = np.concatenate([wbl, wbl[::-1]])
    cb, sb = np.cos(beta), np.sin(beta)
    cps, sps = np.cos(psi)[..., None, None], np.sin(psi)[..., None, None]
    h = cb[:, None] * (cps * k[:, None, None, :] + sps * e2[:, None, None, :]) + (
        sb[:, None] * a[:, None, None, :]
    )
    w = wpsi[..., None] * wbeta * cb**2 * np.cos(psi)[..., None]
    h.setflags(write=False)
    w.setflags(write=False)
    return h, w
