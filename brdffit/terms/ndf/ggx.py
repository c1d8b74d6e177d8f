"""GGX / Trowbridge–Reitz distribution, isotropic and anisotropic."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._math import chi_plus, cos2_sin2_phi, safe_div, tan2_theta
from .base import NDF, clamp_alpha


class GGX(NDF):
    r"""GGX (Trowbridge–Reitz) NDF with roughness ``alpha_x``, ``alpha_y``.

    .. math::

        D(\mathbf m) = \frac{\chi^+(\mathbf n\cdot\mathbf m)}
            {\pi\,\alpha_x\alpha_y\left(\frac{m_x^2}{\alpha_x^2} + \frac{m_y^2}{\alpha_y^2}
            + m_z^2\right)^2}

    RTR eq. 9.53 (anisotropic); with ``alpha_x = alpha_y = alpha_g`` it is RTR eq. 9.41.

    .. math::

        \Lambda(a) = \frac{-1 + \sqrt{1 + 1/a^2}}{2}, \qquad
        \frac{1}{a^2} = \alpha^2 \tan^2\theta_s, \qquad
        \alpha^2 = \alpha_x^2\cos^2\phi_s + \alpha_y^2\sin^2\phi_s

    RTR eq. 9.42 with eq. 9.37 and, for anisotropy, eq. 9.51. Only ``a^2`` appears, so no square
    root of ``a`` is needed (RTR p. 341).

    ``alpha_y`` defaults to ``alpha_x`` (isotropic). Both are clamped at
    :data:`~brdffit.terms.ndf.base.ALPHA_MIN`.
    """

    alpha_x: jax.Array
    alpha_y: jax.Array

    def __init__(self, alpha_x, alpha_y=None):
        self.alpha_x = clamp_alpha(alpha_x)
        self.alpha_y = self.alpha_x if alpha_y is None else clamp_alpha(alpha_y)

    def D(self, wm):  # noqa: N802
        ax, ay = self.alpha_x, self.alpha_y
        e = (wm[..., 0] / ax) ** 2 + (wm[..., 1] / ay) ** 2 + wm[..., 2] ** 2
        return chi_plus(wm[..., 2]) * safe_div(1.0, jnp.pi * ax * ay * e**2)

    def Lambda(self, w):  # noqa: N802
        c2, s2 = cos2_sin2_phi(w)
        alpha2 = self.alpha_x**2 * c2 + self.alpha_y**2 * s2
        inv_a2 = alpha2 * tan2_theta(w)
        return 0.5 * (jnp.sqrt(1.0 + inv_a2) - 1.0)


