r"""Cloth NDFs: the generalized velvet NDF (RTR eq. 9.73) and the Imageworks sheen NDF (RTR eq. 9.75).

Both are "inverted" distributions, with their mass towards the horizon, and have no closed-form
Smith ``Λ``; ``Lambda`` is the numerical one of :mod:`brdffit.terms.ndf.numerical` (weak white
furnace, APS 2000 eqs. 18 and 25), tabulated from the current parameters when the NDF is built.
The Disney sheen (RTR eq. 9.72), a Schlick-shaped lobe rather than an NDF, is
:func:`brdffit.models.disney.sheen_lobe`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._math import chi_plus, safe_div
from .base import NDF
from .numerical import ProjectedAreaTable

#: Numerical-Λ table sizes used by the cloth NDFs (see :mod:`brdffit.terms.ndf.numerical`).
N_THETA, N_QUAD = 64, 32


def _velvet_D(alpha, k_amp, wm):
    c2 = wm[..., 2] ** 2
    s2 = jnp.maximum(1.0 - c2, 0.0)
    cot2 = safe_div(c2, s2, fill=1e12)
    bump = safe_div(jnp.exp(-cot2 / alpha**2), s2**2)
    return chi_plus(wm[..., 2]) * (1.0 + k_amp * bump) / (jnp.pi * (1.0 + k_amp * alpha**2))


def charlie_D(alpha, wm):
    """The Imageworks ("Charlie") sheen NDF of :class:`ImageworksSheen` as a function:
    ``(2 + 1/α) sin^{1/α}θm / 2π`` (Estevez & Kulla 2017; RTR eq. 9.75)."""
    s2 = jnp.maximum(1.0 - wm[..., 2] ** 2, 0.0)
    ok = s2 > 1e-30
    pw = jnp.where(ok, jnp.exp(jnp.log(jnp.where(ok, s2, 1.0)) / (2.0 * alpha)), 0.0)
    return chi_plus(wm[..., 2]) * (2.0 + 1.0 / alpha) * pw / (2.0 * jnp.pi)


#: The coefficients of Estevez & Kulla's fit of the sheen's ``Λ`` (their §3, as
#: ``KHR_materials_sheen`` transcribes them): ``(at α = 1, at α = 0)`` for ``a, b, c, d, e``,
#: mixed by ``(1 − α)²``.
CHARLIE_FIT = ((21.5473, 25.3245), (3.82987, 3.32435), (0.19823, 0.16801),
               (-1.97760, -1.27393), (-4.32054, -4.85967))


def _charlie_l(x, alpha):
    t = (1.0 - alpha) ** 2
    a, b, c, d, e = (lo + (hi - lo) * t for lo, hi in CHARLIE_FIT)
    xs = jnp.maximum(x, 1e-12)  # x^c: finite derivatives at 0
    return a / (1.0 + b * jnp.exp(c * jnp.log(xs))) + d * x + e


def charlie_lambda(cos_theta, alpha):
    r"""Estevez & Kulla's fitted Smith ``Λ`` of the Charlie sheen NDF (their eqs. 3-4, the
    "Charlie" visibility of ``KHR_materials_sheen``): ``exp(l(|cos θ|))`` for ``|cos θ| < 1/2``,
    ``exp(2 l(1/2) − l(1 − |cos θ|))`` above, with
    ``l(x) = a/(1 + b x^c) + d x + e`` and the coefficients of :data:`CHARLIE_FIT`. The fit,
    not the exact ``Λ`` (:class:`ImageworksSheen` tabulates that); a renderer following the
    extension uses this one."""
    c = jnp.abs(cos_theta)
    low = jnp.exp(_charlie_l(c, alpha))
    high = jnp.exp(2.0 * _charlie_l(0.5, alpha) - _charlie_l(1.0 - c, alpha))
    return jnp.where(c < 0.5, low, high)


def _table(D, alpha):
    return ProjectedAreaTable.build(D, 1.0, n_theta=N_THETA, n_quad=N_QUAD, dtype=alpha.dtype)


# Compiled once per dtype: eager model calls would otherwise dispatch the quadrature op by op.
_velvet_table = jax.jit(lambda a, k: _table(lambda m: _velvet_D(a, k, m), a))
_sheen_table = jax.jit(lambda a: _table(lambda m: charlie_D(a, m), a))


class GeneralizedVelvet(NDF):
    r"""Generalized velvet NDF (Ashikhmin & Premože 2007, as used in *The Order: 1886*), RTR eq. 9.73.

    .. math::

        D(\mathbf m) = \frac{\chi^+(\mathbf n\cdot\mathbf m)}{\pi(1 + k_\text{amp}\alpha^2)}
          \left(1 + \frac{k_\text{amp}\exp(-\cot^2\theta_m/\alpha^2)}{\sin^4\theta_m}\right)

    .. warning::
       RTR prints the exponent as ``−(n·m)²/(α²((n·m)² − 1))``, which equals ``+cot²θ/α²`` and
       diverges at the normal. The code uses ``−cot²θ/α²`` (Ashikhmin & Premože 2007; Neubelt &
       Pettineo 2013), for which ``D`` is normalized: ``∫ D (n·m) dm = 1`` exactly (the second
       term integrates to ``k α²/(1 + k α²)``), checked in ``tests/test_cloth.py``.
    """

    alpha: jax.Array
    k_amp: jax.Array
    table: ProjectedAreaTable

    def __init__(self, alpha, k_amp=4.0):
        self.alpha = jnp.maximum(jnp.asarray(alpha), 1e-3)
        self.k_amp = jnp.asarray(k_amp, self.alpha.dtype)
        self.table = _velvet_table(self.alpha, self.k_amp)

    def D(self, wm):
        return _velvet_D(self.alpha, self.k_amp, wm)

    def Lambda(self, w):
        return self.table.Lambda(w)


class ImageworksSheen(NDF):
    r"""Imageworks sheen NDF (Estevez & Kulla 2017), RTR eq. 9.75.

    .. math:: D(\mathbf m) = \frac{\chi^+(\mathbf n\cdot\mathbf m)\,(2 + 1/\alpha)\,
              (1 - (\mathbf n\cdot\mathbf m)^2)^{1/(2\alpha)}}{2\pi}

    Normalized (``∫ D (n·m) dm = 1``). Estevez & Kulla fit an analytic ``Λ``; here ``Λ`` is the
    numerical one (exact up to the quadrature, no fit).
    """

    alpha: jax.Array
    table: ProjectedAreaTable

    def __init__(self, alpha):
        self.alpha = jnp.maximum(jnp.asarray(alpha), 1e-3)
        self.table = _sheen_table(self.alpha)

    def D(self, wm):
        return charlie_D(self.alpha, wm)

    def Lambda(self, w):
        return self.table.Lambda(w)
