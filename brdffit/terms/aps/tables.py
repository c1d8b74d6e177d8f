r"""``g(k)`` (APS 2000 eq. 18) and ``⟨⟨hn⟩⟩``, tabulated over directions and interpolated.

The paper's ``g(k) = ∫_{Ω+(k)} (h·k) p(h) dω_h`` is split exactly, for *any* ``p`` (APS eq. 23
generalized: ``Ω+(k)`` and ``Ω−(k)`` partition the sphere), into

.. math::

    g(\mathbf k) = \mathbf k\cdot\bar{\mathbf m} + \Delta(\mathbf k), \qquad
    \bar{\mathbf m} = \int_\Omega \mathbf h\,p(\mathbf h)\,d\omega_h, \qquad
    \Delta(\mathbf k) = \int_{\Omega_-(\mathbf k)} (\mathbf h\cdot\mathbf k)^-\,p\,d\omega_h
    = g(-\mathbf k) \ge 0 ,

with ``⟨⟨hn⟩⟩ = n·m̄`` (APS eq. 22; the full-sphere average of eqs. 10 and 25). The mean
normal ``m̄`` is one smooth moment (polar rule); only the small, smooth, non-negative ``Δ`` is
tabulated (lune rule, which puts the kink of ``(h·k)⁺`` and the heightfield cut on the domain
boundary). For a distribution with ``m̄ ∥ n`` the visibility ``P(k) = (k·n)⟨⟨hn⟩⟩/g(k)``
(APS eq. 25) is then ``≤ 1`` exactly, whatever the interpolation error of ``Δ``; for a
heightfield Smith NDF ``Δ(k)/((k·n)⟨⟨hn⟩⟩) = Λ(k)`` (RTR eq. 9.24).

Table layout (a convention of this module): nodes uniform in ``u = √(cos θ_k)``, which puts half
of them within 30° of the horizon where ``Δ`` varies fastest, and (anisotropic ``p`` only) in
``φ_k`` over ``[0, 2π)``, periodic. The number of ``u`` nodes is odd so that cosine-weighted
averages over the table (:func:`hemisphere_average`) can use Simpson's rule. Interpolation is
(bi)linear. Tables are rebuilt from the current parameters inside the traced function.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._math import azimuth, dot
from .quadrature import lune_rule, polar_rule


@dataclasses.dataclass(frozen=True)
class Resolution:
    """Table and quadrature sizes (static; each distinct value compiles once).

    Attributes:
        n_u: table nodes in ``u = √(cos θ_k)`` (odd, ≥ 3).
        n_phi: table nodes in ``φ_k`` (anisotropic distributions only).
        n_psi, n_beta: lune rule: Gauss–Legendre nodes in ``ψ`` and per half-range of ``β``.
        n_theta, n_phi_q: polar rule of the mean normal (which uses twice these per axis).
        r_grid: ``(n_u, n_phi)`` of the reflectance table ``R(k)`` (only the diffuse term reads
            it; ``R`` is smoother than ``g``); ``n_phi`` is 1 for isotropic distributions.
        r_quad: ``(n_theta, n_phi)`` of the polar rule over half vectors for ``R(k)``.
    """

    n_u: int = 33
    n_phi: int = 32
    n_psi: int = 24
    n_beta: int = 12
    n_theta: int = 48
    n_phi_q: int = 96
    r_grid: tuple = (17, 24)
    r_quad: tuple = (48, 64)

    def __post_init__(self):
        for name, n in (("n_u", self.n_u), ("r_grid[0]", self.r_grid[0])):
            if n < 3 or n % 2 == 0:
                raise ValueError(f"Resolution.{name} must be odd and >= 3 (Simpson's rule); got {n}")


#: The default sizes.
DEFAULT_RESOLUTION = Resolution()

#: Coarse settings for tests and quick looks (isotropic tables ~1e-3 relative accuracy).
COARSE = Resolution(n_u=17, n_phi=16, n_psi=16, n_beta=8, n_theta=32, n_phi_q=48, r_grid=(9, 8), r_quad=(32, 48))


def table_angles(n_u: int, n_phi: int):
    """``(θ_k, φ_k)`` of the table nodes, each ``(n_u, n_phi)`` (NumPy)."""
    u = np.linspace(0.0, 1.0, n_u)
    theta = np.arccos(np.clip(u**2, 0.0, 1.0))
    phi = np.arange(n_phi) * (2 * np.pi / n_phi)
    return np.meshgrid(theta, phi, indexing="ij")


def table_directions(n_u: int, n_phi: int):
    """Unit vectors of the table nodes, ``(n_u, n_phi, 3)`` (NumPy)."""
    th, ph = table_angles(n_u, n_phi)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)


def interp_table(values, k):
    """(Bi)linear interpolation of a table ``(n_u, n_phi, ...)`` at directions ``k`` ``(..., 3)``.

    ``n_phi == 1`` means isotropic (only ``k_z`` is read). Directions below the horizon read the
    horizon row. The table's values may be traced; the node positions are not.
    """
    n_u, n_phi = values.shape[:2]
    extra = (None,) * (values.ndim - 2)  # trailing table axes (several tables on one grid)
    u = jnp.sqrt(jnp.clip(k[..., 2], 0.0, 1.0))
    x = u * (n_u - 1)
    i0 = jnp.clip(jnp.floor(x), 0, n_u - 2).astype(jnp.int32)
    fx = (x - i0)[(...,) + extra]
    if n_phi == 1:
        col = values[:, 0]
        return (1 - fx) * col[i0] + fx * col[i0 + 1]
    y = azimuth(k[..., 0], k[..., 1]) * (n_phi / (2 * np.pi))
    j0 = jnp.clip(jnp.floor(y), 0, n_phi - 1).astype(jnp.int32)
    fy, j1 = (y - j0)[(...,) + extra], (j0 + 1) % n_phi
    lo = (1 - fy) * values[i0, j0] + fy * values[i0, j1]
    hi = (1 - fy) * values[i0 + 1, j0] + fy * values[i0 + 1, j1]
    return (1 - fx) * lo + fx * hi


def hemisphere_average(values):
    r"""Cosine-weighted hemispherical average of a table, ``(1/π)∫ v(k) (k·n) dω_k``.

    With ``μ = u²``: ``(1/π)∫₀^{2π}∫₀¹ v · 2u³ du dφ``; Simpson in ``u``, periodic trapezoid in
    ``φ``. Trailing axes of ``values`` beyond ``(n_u, n_phi)`` (e.g. RGB) are kept.
    """
    n_u, n_phi = values.shape[:2]
    u = np.linspace(0.0, 1.0, n_u)
    simpson = np.ones(n_u)
    simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
    wu = simpson * (1.0 / (n_u - 1)) / 3.0 * 2.0 * u**3
    w = jnp.asarray(np.outer(wu, np.full(n_phi, 2.0 / n_phi)), values.dtype)  # (1/π)(2π/n_phi)
    return jnp.tensordot(w, values, axes=((0, 1), (0, 1)))


class GTable(eqx.Module):
    """``m̄`` and the tabulated ``Δ``; gives ``g(k)``, ``⟨⟨hn⟩⟩`` and ``P(k)`` (APS eqs. 18, 22, 25)."""

    mean_normal: jax.Array  # (3,)
    delta: jax.Array  # (n_u, n_phi)

    @property
    def hn(self):
        """``⟨⟨hn⟩⟩ = ∫_Ω (h·n) p dω`` over the whole sphere (APS eqs. 22, 25)."""
        return self.mean_normal[2]

    def g(self, k):
        """``g(k) = k·m̄ + Δ(k)`` (APS eq. 18), ``(..., 3) -> (...)``."""
        return dot(k, self.mean_normal.astype(k.dtype)) + interp_table(self.delta, k)

    def P(self, k):
        """Visibility ``P(k) = (k·n)⟨⟨hn⟩⟩/g(k)`` (APS eq. 25)."""
        g = self.g(k)
        return jnp.where(g > 0, k[..., 2] * self.hn / jnp.where(g > 0, g, 1.0), 0.0)


def mean_normal(dist, dtype, res: Resolution = DEFAULT_RESOLUTION):
    """``m̄ = ∫ h p(h) dω`` over the support (upper hemisphere, and the lower one unless a heightfield)."""
    total = 0.0
    for lower in (False,) if dist.heightfield else (False, True):
        # One integral, so it affords twice the nodes per axis of the per-direction rules.
        h, w = polar_rule(2 * res.n_theta, 2 * res.n_phi_q, lower)
        h = jnp.asarray(h, dtype)
        total = total + jnp.sum((jnp.asarray(w, dtype) * dist.p(h))[:, None] * h, axis=0)
    return total


@eqx.filter_jit
def build_g_table(dist, dtype, res: Resolution = DEFAULT_RESOLUTION) -> GTable:
    """Build :class:`GTable` for ``dist`` from its current parameters (traceable, differentiable).

    Compiled once per distribution type, dtype and resolution (``equinox.filter_jit``), so that
    eager calls (outside any ``jit``) do not dispatch hundreds of small operations.
    """
    n_phi = 1 if dist.isotropic else res.n_phi
    th, ph = table_angles(res.n_u, n_phi)
    # Δ(k) = g(−k): the lune rule about −k (polar angle π − θ_k, azimuth φ_k + π).
    h, w = lune_rule(
        tuple((np.pi - th).ravel()), tuple((ph + np.pi).ravel()), res.n_psi, res.n_beta, dist.heightfield
    )
    delta = jnp.sum(jnp.asarray(w, dtype) * dist.p(jnp.asarray(h, dtype)), axis=(1, 2))
    return GTable(mean_normal(dist, dtype, res), delta.reshape(res.n_u, n_phi))
