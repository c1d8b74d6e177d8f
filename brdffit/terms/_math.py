"""Shading-frame conventions and gradient-safe primitives shared by every model term.

Conventions (stated once, used everywhere):

* The shading frame has the surface normal ``n = (0, 0, 1)``; tangent ``x``, bitangent ``y``.
* Directions are unit vectors pointing *away* from the surface: ``wi`` (towards the light),
  ``wo`` (towards the viewer), ``wm`` the microfacet normal / half vector (RTR eq. 9.33).
* Every direction argument has shape ``(..., 3)``; every scalar result has the batch shape
  ``(...)``; RGB results have shape ``(..., 3)``. Parameters broadcast against the batch.
* BRDFs return ``f_r`` without the cosine factor: the quantity a MERL table stores.

Inside jitted code nothing branches on data: invalid configurations (a direction below the
horizon, a back-facing half vector, ``alpha -> 0``) are handled with masks and the
"double ``where``" trick, so that neither values nor gradients become NaN.
"""

from __future__ import annotations

import jax.numpy as jnp

#: Smallest denominator or radicand treated as non-zero in the safe primitives.
EPS = 1e-12


def dot(a, b):
    """Dot product over the last axis, keeping the batch shape.

    Written out term by term for 3-vectors: elementwise work that XLA fuses into the caller's
    loop, where ``jnp.sum(a * b, axis=-1)`` is a reduction over a length-3 axis, which XLA's CPU
    backend (jaxlib 0.10) turns into a separate, slow library fusion (``benchmarks/bench_aps.py``
    times models over a MERL grid).
    """
    if a.shape[-1:] == (3,) or b.shape[-1:] == (3,):
        return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]
    return jnp.sum(a * b, axis=-1)


def safe_sqrt(x, eps: float = EPS):
    """``sqrt(max(x, 0))`` whose gradient is finite (zero) at and below ``eps``."""
    ok = x > eps
    return jnp.where(ok, jnp.sqrt(jnp.where(ok, x, 1.0)), 0.0)


def safe_div(num, den, fill: float = 0.0, eps: float = EPS):
    """``num / den`` where ``|den| > eps``, else ``fill``; gradients stay finite."""
    ok = jnp.abs(den) > eps
    return jnp.where(ok, num / jnp.where(ok, den, 1.0), fill)


def normalize(v, eps: float = EPS):
    """Unit vector along ``v``; the zero vector maps to ``(0, 0, 1)`` with finite gradients."""
    n2 = dot(v, v)
    ok = n2 > eps
    inv = jnp.where(ok, 1.0 / jnp.sqrt(jnp.where(ok, n2, 1.0)), 0.0)
    return jnp.where(ok[..., None], v * inv[..., None], jnp.array([0.0, 0.0, 1.0], v.dtype))


def half_vector(wi, wo):
    """The (unnormalised sum, then normalised) half vector ``h = (wi + wo)/|wi + wo|``, RTR eq. 9.33."""
    return normalize(wi + wo)


def azimuth(x, y):
    """The azimuth ``φ ∈ [0, 2π)`` of ``(x, y)``: ``atan2(y, x)`` wrapped to be non-negative.

    Computed as ``arctan`` of the octant ratio ``min/max ∈ [0, 1]`` and reflected: the same value
    to rounding, at about 60 % of the cost of ``jnp.mod(jnp.arctan2(y, x), 2π)`` on XLA's CPU
    backend (which the APS table lookups pay for every direction). ``(0, 0)`` gives 0.
    """
    ax, ay = jnp.abs(x), jnp.abs(y)
    steep = ay > ax
    num, den = jnp.where(steep, ax, ay), jnp.where(steep, ay, ax)
    a = jnp.arctan(num / jnp.where(den > 0, den, 1.0))
    a = jnp.where(steep, 0.5 * jnp.pi - a, a)  # first quadrant
    a = jnp.where(x < 0, jnp.pi - a, a)  # upper half
    return jnp.where(y < 0, 2.0 * jnp.pi - a, a)


def cos_theta(w):
    """``n . w`` with ``n = z``."""
    return w[..., 2]


def cos2_theta(w):
    return w[..., 2] ** 2


def sin2_theta(w):
    """``1 - cos^2 theta``, clamped at zero against rounding."""
    return jnp.maximum(0.0, 1.0 - w[..., 2] ** 2)


#: ``cos^2 theta`` at or below which :func:`tan2_theta` stops following its closed form. The
#: readers keep directions down to ``cos theta > 1e-9`` (``data_formats.merl.HORIZON_EPS``), so
#: the closed form must hold to ``cos^2 = 1e-18``; this threshold is 100x below it
#: (``cos theta = 1e-10``), and ``1 / TAN2_COS2_MIN = 1e20`` is still finite in float32.
TAN2_COS2_MIN = 1e-20


def tan2_theta(w):
    r"""``tan^2 theta = sin^2 theta / cos^2 theta``, exact for every ``cos^2 theta > 1e-20``.

    Masking functions grow like ``tan theta`` towards the horizon (GGX ``Lambda ~ alpha tan/2``,
    RTR eq. 9.42), so this must not saturate above the readers' horizon ``cos theta > 1e-9``:
    closer to the horizon than :data:`TAN2_COS2_MIN` (and below it) the value is the finite
    ``1 / TAN2_COS2_MIN``, with a zero gradient (gradient-safe ``where``).
    """
    return safe_div(sin2_theta(w), cos2_theta(w), fill=1.0 / TAN2_COS2_MIN, eps=TAN2_COS2_MIN)


def cos2_sin2_phi(w):
    """``(cos^2 phi, sin^2 phi)`` of the azimuth of ``w``; ``(1, 0)`` at the pole.

    Anisotropic NDFs need the azimuth only through these squares (RTR eqs. 9.51-9.53).
    """
    s2 = w[..., 0] ** 2 + w[..., 1] ** 2
    c2 = safe_div(w[..., 0] ** 2, s2, fill=1.0)
    return c2, 1.0 - c2


def chi_plus(x):
    """Heaviside ``chi^+(x)``: 1 for ``x > 0``, else 0 (RTR eq. 9.21)."""
    return (x > 0).astype(jnp.result_type(x, jnp.float32))
