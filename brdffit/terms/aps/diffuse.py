r"""The APS 2000 energy-conserving diffuse term (eqs. 28–30) and its metal variant (§5.1).

.. math::

    \rho(\mathbf k_1,\mathbf k_2) = c\,(1 - R(\mathbf k_1))(1 - R(\mathbf k_2))\,\rho_d
        + \rho_s(\mathbf k_1,\mathbf k_2), \qquad
    R(\mathbf k) = \int \rho_s(\mathbf k,\mathbf k')(\mathbf k'\mathbf n)\,d\omega_{k'}
    \quad\text{(eqs. 29, 30)}

``c`` is fixed by "for ``ρ_d = 1`` the total incident and reflected energies are the same":
integrating over both hemispheres with uniform incident radiance,
``c π² (1 − R̄)² + π R̄ = π``, so ``c = 1/(π (1 − R̄))`` with ``R̄`` the cosine-weighted average
of ``R`` (RTR eq. 9.57); this is also RTR eq. 9.65. With it the total directional albedo is
``R(k) + (1 − R(k)) = 1`` for *every* ``k``, not only on average.

``R`` is linear in ``f0`` under Schlick (eq. 31): ``R(k; f0) = R₀(k) + f0 (R₁(k) − R₀(k))`` with
``R₀, R₁`` the reflectances at ``f0 = 0`` and ``f0 = 1``, the paper's two tables (§5.2). They
are computed in half-vector space: ``dω₂ = 4 (k₁h) dω_h`` (eq. 5), so
``R(k₁) = ∫ p F S (k₁h)(k₂n) dω_h`` over ``(k₂n) > 0`` with ``S`` from
:mod:`brdffit.terms.aps.specular` — the same shadowing form as the specular term it accompanies.

Metal variant (§5.1): "ones replaced by ``f0``", ``ρ_d = f0``, and the factors
``(f0 − R(k))`` clamped at zero. The paper does not restate ``c`` for it; here the same
normalization is applied to what is left: ``c = 1/(π · avg((f0 − R)⁺))``, so the diffuse albedo
is ``ρ_d (f0 − R(k))⁺`` and the total albedo ``R + f0 (f0 − R)⁺`` (a choice, documented).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._math import chi_plus, cos_theta
from .quadrature import polar_rule
from .specular import UNCORRELATED
from .tables import (
    DEFAULT_RESOLUTION,
    Resolution,
    hemisphere_average,
    interp_table,
    table_directions,
)


class RTable(eqx.Module):
    """Directional-hemispherical reflectance of the specular term at ``f0 = 0`` and ``f0 = 1``."""

    r0: jax.Array  # (n_u, n_phi)
    r1: jax.Array  # (n_u, n_phi)

    def nodes(self, f0):
        """``R(k_j; f0)`` at the table nodes, ``(n_u, n_phi, 3)`` for RGB ``f0``."""
        return self.r0[..., None] + jnp.asarray(f0) * (self.r1 - self.r0)[..., None]

    def both(self, k):
        """``(R₀(k), R₁(k))`` at directions ``(..., 3)``, stacked ``(..., 2)`` (one lookup)."""
        return interp_table(jnp.stack([self.r0, self.r1], axis=-1), k)

    @staticmethod
    def mix(both, f0):
        """``R(k; f0) = R₀ + f0 (R₁ - R₀)`` from :meth:`both`: ``(..., 3)`` for RGB ``f0``."""
        r0, r1 = both[..., 0:1], both[..., 1:2]
        return r0 + jnp.asarray(f0) * (r1 - r0)

    def __call__(self, k, f0):
        """``R(k; f0)`` at directions ``(..., 3)``: ``(..., 3)`` for RGB ``f0``."""
        return self.mix(self.both(k), f0)


@eqx.filter_jit
def build_r_table(dist, table, dtype, res: Resolution = DEFAULT_RESOLUTION, shadowing=UNCORRELATED):
    """``R₀, R₁`` (APS eq. 29) on the ``res.r_grid`` directions; ``p`` is evaluated once on the
    polar rule ``res.r_quad`` and shared by all directions."""
    n_u, n_phi = res.r_grid[0], (1 if table.delta.shape[1] == 1 else res.r_grid[1])
    k1 = jnp.asarray(table_directions(n_u, n_phi).reshape(-1, 1, 3), dtype)  # (K, 1, 3)
    h_np, w_np = polar_rule(*res.r_quad)
    h = jnp.asarray(h_np, dtype)  # (Q, 3)
    w = jnp.asarray(w_np, dtype) * dist.p(h)  # (Q,)
    c = jnp.sum(k1 * h, axis=-1)  # (K, Q)  (k1·h)
    k2 = 2.0 * c[..., None] * h - k1
    mask = chi_plus(c) * chi_plus(cos_theta(k2))
    s = shadowing.factor(
        jnp.broadcast_to(k1, k2.shape), k2, table.g(k1), table.g(k2), table.hn
    )
    base = w * s * c * jnp.maximum(cos_theta(k2), 0.0) * mask
    r1 = jnp.sum(base, axis=-1)
    r0 = jnp.sum(base * jnp.clip(1.0 - c, 0.0, 1.0) ** 5, axis=-1)
    return RTable(r0.reshape(n_u, n_phi), r1.reshape(n_u, n_phi))


def coupled_scale(rtable, f0, white):
    """``c`` of eq. 30 (RGB): ``1/(π · avg(white - R(·; f0))⁺)``, 0 where nothing is left."""
    avail = jnp.maximum(white - rtable.nodes(f0), 0.0)  # (n_u, n_phi, 3)
    norm = jnp.pi * hemisphere_average(avail)  # (3,)
    return jnp.where(norm > 0, 1.0 / jnp.where(norm > 0, norm, 1.0), 0.0)


def coupled_term(rho_d, c, white, r1, r2, vis):
    """``ρ_d c (white - R(k₁))⁺ (white - R(k₂))⁺`` times the visibility ``vis`` ``(...)``."""
    a1, a2 = jnp.maximum(white - r1, 0.0), jnp.maximum(white - r2, 0.0)
    return jnp.asarray(rho_d) * c * a1 * a2 * vis[..., None]


def _coupled(rtable, rho_d, f0, white, wi, wo):
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    return coupled_term(rho_d, coupled_scale(rtable, f0, white), white, rtable(wi, f0), rtable(wo, f0), vis)


def aps_diffuse(rtable, rho_d, f0, wi, wo):
    """Energy-conserving diffuse term ``c (1−R(k₁))(1−R(k₂)) ρ_d`` (APS eqs. 28–30), ``(..., 3)``."""
    return _coupled(rtable, rho_d, f0, 1.0, wi, wo)


def aps_diffuse_metal(rtable, f0, wi, wo):
    """Metal variant (APS §5.1): ``c (f0−R(k₁))⁺ (f0−R(k₂))⁺ f0``, ``(..., 3)``."""
    f0 = jnp.asarray(f0)
    return _coupled(rtable, f0, f0, f0, wi, wo)
