r"""The Student-t distribution of slopes (STD) of Ribardière et al. 2017.

Ribardière, Bringier, Meneveaux & Simonot 2017, "STD: Student's t-Distribution of Slopes for
Microfacet Based BSDFs" (CGF 36(2), Eurographics), eq. 10 (isotropic): with ``t² = tan²θm``,

.. math::

    D(\mathbf m) = \frac{\chi^+(\mathbf n\cdot\mathbf m)}
        {\pi\alpha^2\cos^4\theta_m\left(1 + \dfrac{t^2}{(\gamma - 1)\,\alpha^2}\right)^{\gamma}}

normalised for every ``γ > 1`` (the slope density ``P22 = (πα²)^{-1}(1 + r²/((γ−1)α²))^{-γ}``
integrates to 1 over the plane). ``γ = 2`` is GGX (RTR eq. 9.41) with the same ``α`` exactly;
``γ → ∞`` is Beckmann (RTR eq. 9.35) with the same ``α``, ``(1 + x/γ')^{-γ} → e^{-x}``. bbm
writes the same ``D`` (``include/ndf/studentt.h``).

Smith's ``Λ`` (``γ > 3/2``; the mean slope is infinite below) in closed form: the marginal slope
density is ``P2(q) ∝ (1 + q²/s)^{½−γ}`` with ``s = γ − 1`` and, with ``μ = cot θ/α`` and
``x = s/(s + μ²)``,

.. math::

    \Lambda(\mu) = \frac{\Gamma(\gamma - \tfrac12)}{\sqrt{\pi}\,\Gamma(\gamma)}\,\frac{\sqrt s}{\mu}
        \left[\frac{s}{2\gamma - 3}\Big(1 + \frac{\mu^2}{s}\Big)^{\frac32-\gamma}
        - \frac{\mu\sqrt s}{2}\,B\big(\gamma - 1, \tfrac12\big)\,I_x\big(\gamma - 1, \tfrac12\big)\right]

(the paper's eqs. 13–15: ``S1`` and ``S2``; it then approximates the incomplete beta ``S2`` by a
rational fit, eqs. 22–23, which bbm uses). JAX cannot differentiate ``I_x`` in its shape
parameter, so :meth:`StudentT.Lambda` is the numerical Smith ``Λ`` of the weak white furnace
(:mod:`.numerical`, as for GTR), with the derivative in ``γ`` that a fit needs, plus the slopes
beyond the quadrature's last node in closed form (:meth:`StudentT.tail`); the closed form above is
its check (``tests/test_ndf_literature.py``: ``G1`` within 1e-6 for γ from 1.7 to 10).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .base import NDF, as_float, clamp_alpha
from .._math import safe_sqrt, tan2_theta
from .numerical import N_QUAD_TABLE, N_THETA, TAN_THETA_M_MAX, ProjectedAreaTable

#: ``γ`` is clamped to at least this: ``Λ`` diverges as ``γ → 3/2``.
GAMMA_MIN = 1.5 + 1e-3


class StudentT(NDF):
    """STD NDF with roughness ``alpha`` and tail exponent ``gamma`` (module docstring), isotropic.

    ``alpha``, ``gamma`` are scalars (batch over parameter sets with ``jax.vmap``). ``table``
    (from :meth:`lambda_table` of the same ``α, γ``) skips building the θ table of ``Λ``.
    """

    alpha: jax.Array
    gamma: jax.Array
    table: ProjectedAreaTable | None

    def __init__(self, alpha, gamma, *, table=None):
        self.alpha = clamp_alpha(as_float(alpha))
        self.gamma = jnp.maximum(jnp.asarray(gamma, self.alpha.dtype), GAMMA_MIN)
        self.table = table

    def D(self, wm):  # noqa: N802
        """In log space, ``m_z^{2γ−4}/(πα² b^γ)`` with ``b = m_z² + (m_x² + m_y²)/((γ − 1)α²)``
        (the same for unit ``m``), finite for every ``m_z > 0``."""
        up = wm[..., 2] > 0
        a2 = self.alpha**2
        tiny = jnp.finfo(a2.dtype).tiny
        mz2 = jnp.maximum(jnp.where(up, wm[..., 2] ** 2, 1.0), tiny)
        b = mz2 + (wm[..., 0] ** 2 + wm[..., 1] ** 2) / ((self.gamma - 1.0) * a2)
        log_d = (self.gamma - 2.0) * jnp.log(mz2) - self.gamma * jnp.log(b) - jnp.log(jnp.pi * a2)
        return jnp.where(up, jnp.exp(log_d), 0.0)

    def lambda_table(self, n_theta=N_THETA, n_quad=N_QUAD_TABLE) -> ProjectedAreaTable:
        """The θ table of the numerical ``Λ`` of this ``α, γ``."""
        return ProjectedAreaTable.build(self.D, self.alpha, n_theta=n_theta, n_quad=n_quad,
                                        dtype=self.alpha.dtype)

    def tail(self):
        r"""The slopes beyond the quadrature's last node ``R`` (``tan θm = 1e8``): for ``r > R``,
        ``P22 ≈ (πα²)^{-1}(r²/(sα²))^{-γ}`` and ``(ω·m̃)⁺ ≈ r sin θ cos⁺φ``, so they add
        ``T tan θ`` to ``Λ`` with ``T = 2 (sα²)^γ R^{3−2γ} / (πα² (2γ − 3))`` (``R^{3−2γ}``
        decays slowly near ``γ = 3/2``: 6e-4 at ``γ = 1.7``)."""
        s, g = self.gamma - 1.0, self.gamma
        log_t = (g * jnp.log(s * self.alpha**2) + (3.0 - 2.0 * g) * jnp.log(TAN_THETA_M_MAX)
                 - jnp.log(jnp.pi * self.alpha**2 * (2.0 * g - 3.0)))
        return 2.0 * jnp.exp(log_t)

    def Lambda(self, w):  # noqa: N802
        table = self.lambda_table() if self.table is None else self.table
        return table.Lambda(w) + self.tail() * safe_sqrt(tan2_theta(w))
