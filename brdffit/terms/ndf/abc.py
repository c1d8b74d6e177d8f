r"""Löw et al. 2012's ABC distribution: a microfacet density with a K-correlation-like tail.

Löw, Kronander, Ynnerman & Unger 2012, "BRDF Models for Accurate and Efficient Rendering of
Glossy Surfaces" (ACM TOG 31(1)), eq. 15, after Church's ABC model of surface statistics:

.. math::  S(\mathbf m) = \left(1 + B\,(1 - \mathbf n\cdot\mathbf m)\right)^{-C}

``B`` sets the width of the peak (about ``√(2/B)`` radians for ``C ≈ 1``) and ``C`` the fall-off
of its tail. The paper scales ``S`` by a free ``A`` instead of normalising it; so does bbm's
``ndf::low`` (``include/ndf/low.h``), whose ``eval`` is this ``S``. :meth:`ABC.S` is that
unnormalised shape, what :mod:`brdffit.models.fitted_distributions` uses; :meth:`ABC.D` divides it
by ``g(n) = ∫ S(m)(n·m) dm`` so that ``D`` meets the contract of :mod:`.base` (RTR eq. 9.21).

``1 − n·m`` is evaluated as ``(m_x² + m_y²)/(1 + m_z)`` (equal for unit ``m``), free of the
cancellation that ``B`` up to 1e7 would magnify at the peak.

``g(n)`` and Smith's ``Λ`` have no closed form used here: both come from the weak white furnace
by quadrature (:mod:`.numerical`), with the peak scale of :meth:`ABC.scale`. Löw et al. use the
V-groove masking of Cook & Torrance 1982, not Smith's; their model does too.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .base import NDF, as_float
from .numerical import N_QUAD, N_QUAD_TABLE, N_THETA, ProjectedAreaTable, projected_area_normal


def one_minus_cos(wm):
    """``1 − m_z`` of a unit vector as ``(m_x² + m_y²)/(1 + m_z)`` (no cancellation at the pole)."""
    return (wm[..., 0] ** 2 + wm[..., 1] ** 2) / (1.0 + wm[..., 2])


class ABC(NDF):
    """Löw 2012's ABC NDF with width ``b`` (``B``) and tail exponent ``c`` (``C``), isotropic.

    ``b``, ``c`` are scalars or arrays broadcasting against the batch shape of ``wm``.
    """

    b: jax.Array
    c: jax.Array

    def __init__(self, b, c):
        self.b = as_float(b)
        self.c = as_float(c)

    def S(self, wm):  # noqa: N802 (the paper's symbol)
        """The unnormalised shape ``(1 + B(1 − m_z))^{−C}`` (Löw eq. 15), 0 for ``m_z ≤ 0``."""
        up = wm[..., 2] > 0
        base = 1.0 + self.b * jnp.where(up, one_minus_cos(wm), 1.0)
        return jnp.where(up, jnp.exp(-self.c * jnp.log(base)), 0.0)

    def scale(self):
        """``tan θm`` at which ``S`` has fallen to half (small-angle), the quadrature's peak scale."""
        half = jnp.expm1(jnp.log(2.0) / jnp.maximum(self.c, 1e-3))
        return jnp.clip(jnp.sqrt(2.0 * half / self.b), 1e-4, 1.0)

    def normalization(self, n_quad=N_QUAD):
        """``g(n) = ∫ S(m)(n·m) dm`` by quadrature (scalar ``b``, ``c``)."""
        return projected_area_normal(self.S, self.scale(), n_quad=n_quad, dtype=self.b.dtype)

    def D(self, wm):  # noqa: N802
        return self.S(wm) / self.normalization()

    def lambda_table(self, n_theta=N_THETA, n_quad=N_QUAD_TABLE) -> ProjectedAreaTable:
        return ProjectedAreaTable.build(self.S, self.scale(), n_theta=n_theta, n_quad=n_quad,
                                        dtype=self.b.dtype)

    def Lambda(self, w):  # noqa: N802
        """Smith ``Λ`` from the weak white furnace (:mod:`.numerical`; scalar ``b``, ``c``)."""
        return self.lambda_table().Lambda(w)
