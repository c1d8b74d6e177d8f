r"""The APS 2000 specular term: eq. 26 (uncorrelated shadowing) and eq. 14 (correlated).

From eq. 10 with ``P(k₁,k₂,h)`` and eq. 25 for ``P(k)``:

.. math::

    \rho_s(\mathbf k_1,\mathbf k_2) = \frac{p(\mathbf h)\,F((\mathbf k\mathbf h))}{4}\,S,
    \qquad
    S_\text{uncorr} = \frac{\langle\langle\mathbf h\mathbf n\rangle\rangle}{g(\mathbf k_1)\,g(\mathbf k_2)}
    \quad\text{(eq. 26)},

    S_\text{corr} = (1-t(\phi))\,S_\text{uncorr} + t(\phi)\,
        \frac{\min(P(\mathbf k_1),P(\mathbf k_2))}{(\mathbf k_1\mathbf n)(\mathbf k_2\mathbf n)
        \langle\langle\mathbf h\mathbf n\rangle\rangle}
      = (1-t)\,S_\text{uncorr} + \frac{t}{\max(g(\mathbf k_1)(\mathbf k_2\mathbf n),\,
        g(\mathbf k_2)(\mathbf k_1\mathbf n))} \quad\text{(eq. 14)} .

The last form is the same quantity with the ``(k·n)`` factors cancelled, so it stays finite at
grazing angles. ``φ`` is the angle between the projections of ``k₁`` and ``k₂`` onto the
tangent plane (``φ = 0`` when either is the normal). The paper uses "a Gaussian in φ with the
width of 15 degrees"; this module reads *width* as the standard deviation:
``t(φ) = exp(−φ²/(2 w²))``, ``w = 15°`` (a convention; :class:`Correlated` takes ``width``).

Both forms are symmetric in ``k₁, k₂`` (reciprocal) and, with ``F = 1``, have directional albedo
``≤ 1`` for any ``p`` with mean normal along ``n`` (APS §5.3).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._math import chi_plus, cos_theta, dot, half_vector
from ..fresnel import schlick


def _uncorrelated(g1, g2, hn):
    d = g1 * g2
    return jnp.where(d > 0, hn / jnp.where(d > 0, d, 1.0), 0.0)


@dataclasses.dataclass(frozen=True)
class Uncorrelated:
    """Uncorrelated shadowing ``P(k₁)P(k₂)`` (APS eq. 13), giving eq. 26."""

    def factor(self, k1, k2, g1, g2, hn):
        return _uncorrelated(g1, g2, hn)


def tangent_azimuth_difference(k1, k2):
    """``|φ|``, the angle between the tangent-plane projections of ``k1`` and ``k2`` (0 at the pole)."""
    cross = k1[..., 0] * k2[..., 1] - k1[..., 1] * k2[..., 0]
    dotp = k1[..., 0] * k2[..., 0] + k1[..., 1] * k2[..., 1]
    ok = (cross**2 + dotp**2) > 1e-30
    return jnp.where(ok, jnp.arctan2(jnp.abs(cross), jnp.where(ok, dotp, 1.0)), 0.0)


@dataclasses.dataclass(frozen=True)
class Correlated:
    """APS eq. 14 with the Gaussian correlation ``t(φ) = exp(−φ²/(2 width²))`` (``width`` in radians)."""

    width: float = float(np.radians(15.0))

    def t(self, k1, k2):
        phi = tangent_azimuth_difference(k1, k2)
        return jnp.exp(-0.5 * (phi / self.width) ** 2)

    def factor(self, k1, k2, g1, g2, hn):
        t = self.t(k1, k2).astype(g1.dtype)
        m = jnp.maximum(g1 * cos_theta(k2), g2 * cos_theta(k1))
        corr = jnp.where(m > 0, 1.0 / jnp.where(m > 0, m, 1.0), 0.0)
        return (1.0 - t) * _uncorrelated(g1, g2, hn) + t * corr


UNCORRELATED = Uncorrelated()
CORRELATED = Correlated()


def specular_geometry(dist, table, wi, wo, shadowing=UNCORRELATED):
    """``p(h) S / 4`` with the visibility mask: ``ρ_s`` without its Fresnel factor, ``(...)``."""
    h = half_vector(wi, wo)
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    s = shadowing.factor(wi, wo, table.g(wi), table.g(wo), table.hn)
    return 0.25 * dist.p(h) * s * vis


def aps_specular(dist, table, f0, wi, wo, shadowing=UNCORRELATED):
    """APS specular BRDF (eq. 26, or eq. 14 with ``shadowing=CORRELATED``), Schlick F (eq. 31).

    Args:
        dist: a distribution from :mod:`brdffit.terms.aps.distributions`.
        table: its :class:`~brdffit.terms.aps.tables.GTable` (``build_g_table(dist, dtype)``).
        f0: normal-incidence reflectance, RGB ``(3,)`` (or scalar).
        wi, wo: unit directions ``(..., 3)``.

    Returns ``(..., 3)``. Schlick's argument is ``(k·h)`` (the same for ``k₁`` and ``k₂``): eq. 31
    prints ``(kn)``, but eqs. 4–6 and 26 evaluate ``F`` at the microfacet angle ``(kh)``.
    """
    h = half_vector(wi, wo)
    f = schlick(jnp.asarray(f0), dot(wi, h))
    return f * specular_geometry(dist, table, wi, wo, shadowing)[..., None]
