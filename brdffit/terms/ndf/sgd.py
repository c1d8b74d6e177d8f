r"""Bagher et al. 2012's shifted gamma distribution (SGD) of microfacet slopes, and its fitted G1.

Bagher, Soler & Holzschuch 2012, "Accurate Fitting of Measured Reflectances Using a Shifted
Gamma Micro-facet Distribution" (CGF 31(4)), eqs. 7–8, as bbm implements it
(``include/ndf/sgd.h``): with ``t² = tan²θm``,

.. math::

    P_{22}(t^2) = \frac{e^{-(\alpha + t^2/\alpha)}}{(\alpha + t^2/\alpha)^{p}}, \qquad
    D(\mathbf m) = \frac{K\,P_{22}}{\pi\cos^4\theta_m}

``p = 0`` is Beckmann with ``α_b² = α`` (up to the constant ``e^{−α}``); ``p > 0`` lengthens the
tail. :meth:`SGD.shape` is ``P22/(π cos⁴θm)`` (bbm's ``sgd_base``); :meth:`SGD.D` divides it by
``g(n) = ∫ shape (n·m) dm`` (:mod:`.numerical`), the ``K`` that normalises it
(``1/(α Γ(1 − p, α))`` in closed form). ``P22`` is evaluated in log space: bbm zeroes it where
``(α + t²/α)^p`` is below its epsilon, which ``α ≥ 1e-5``, ``p ≤ 2`` never reach.
``α`` and ``p`` broadcast against the batch shape (RGB triples give one lobe per channel).

Bagher et al. do not use Smith's ``Λ`` of this ``D``: they fit a masking term
(:func:`bagher_g1`). :meth:`SGD.Lambda` is the Smith ``Λ`` by the weak white furnace
(:mod:`.numerical`), for scalar ``α``, ``p``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._math import safe_sqrt, tan2_theta
from .base import NDF, as_float
from .numerical import N_QUAD, N_QUAD_TABLE, N_THETA, ProjectedAreaTable, projected_area_normal

#: :func:`bagher_g1` caps the exponent ``((θ − θ0)/w)^k`` here: past it ``G1`` is 0 already
#: (``1 + Λ(1 − e^{50}) < 0`` for every ``Λ > 2e-22``), and ``e^{50}`` is finite in float32.
_MAX_EXPONENT = 50.0


class SGD(NDF):
    """The shifted gamma distribution with ``alpha`` (``α``) and ``p`` (module docstring)."""

    alpha: jax.Array
    p: jax.Array

    def __init__(self, alpha, p):
        self.alpha = as_float(alpha)
        self.p = as_float(p)

    def shape(self, wm):
        """``P22(tan²θm)/(π cos⁴θm)`` (bbm's ``sgd_base::eval``), 0 for ``m_z ≤ 0``."""
        up = wm[..., 2] > 0
        x = self.alpha + tan2_theta(wm) / self.alpha
        mz2 = jnp.where(up, wm[..., 2] ** 2, 1.0)
        log_p22 = -x - self.p * jnp.log(x)
        return jnp.where(up, jnp.exp(log_p22) / (jnp.pi * mz2 * mz2), 0.0)

    def scale(self):
        """``tan θm`` width of the peak for the quadrature, ``√α`` (Beckmann's ``α_b`` at ``p = 0``)."""
        return jnp.clip(jnp.sqrt(self.alpha), 1e-4, 1.0)

    def normalization(self, n_quad=N_QUAD):
        """``g(n) = ∫ shape(m)(n·m) dm = 1/K`` by quadrature (scalar ``α``, ``p``): within 3e-6 of
        ``α Γ(1 − p, α)`` for ``α`` from 2e-4 to 0.6 and ``p`` from 0 to 1.4 (the Gauss–Legendre
        panels resolve a power-law tail better than the cut-off ``e^{−t²/α}``)."""
        return projected_area_normal(self.shape, self.scale(), n_quad=n_quad, dtype=self.alpha.dtype)

    def D(self, wm):  # noqa: N802
        return self.shape(wm) / self.normalization()

    def lambda_table(self, n_theta=N_THETA, n_quad=N_QUAD_TABLE) -> ProjectedAreaTable:
        return ProjectedAreaTable.build(self.shape, self.scale(), n_theta=n_theta, n_quad=n_quad,
                                        dtype=self.alpha.dtype)

    def Lambda(self, w):  # noqa: N802
        return self.lambda_table().Lambda(w)


def theta_of(w):
    """The polar angle ``θ = atan2(√(x² + y²), z)``: finite gradients at the pole (unlike ``acos``)."""
    return jnp.arctan2(safe_sqrt(w[..., 0] ** 2 + w[..., 1] ** 2), w[..., 2])


def bagher_g1(theta, lam, theta0, width, k):
    r"""Bagher et al.'s fitted masking term (Bagher 2012 §5; bbm ``ndf::sgd::G1``), clamped at 0.

    .. math::

        G_1(\theta) = 1 + \Lambda\left(1 - e^{\,c\,(\theta - \theta_0)^k}\right)\ (\theta > \theta_0),
        \qquad 1 \text{ otherwise}

    written with ``c (θ − θ0)^k = ((θ − θ0)/w)^k``, ``w = c^{−1/k}``: the angle past ``θ0`` at
    which the exponent reaches 1, where bbm's ``c`` spans 1e-8 to 1e109 over the published fits
    and ``w`` spans 0.3 to 2. The published ``(Λ, c, k)`` make ``G1`` negative far enough past
    ``θ0``; it is clamped at 0 (no bbm reference value is negative). ``θ`` broadcasts against the
    parameters (RGB triples: one ``G1`` per channel).
    """
    above = theta > theta0
    u = jnp.where(above, (theta - theta0) / width, 1.0)
    e = jnp.minimum(k * jnp.log(u), jnp.log(_MAX_EXPONENT))
    g = 1.0 + lam * (1.0 - jnp.exp(jnp.exp(e)))
    return jnp.where(above, jnp.maximum(g, 0.0), 1.0)
