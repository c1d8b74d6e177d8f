"""Fresnel reflectance terms ``F(h, l)``.

Each function takes the cosine between the light (or view) direction and the microfacet normal,
``cos_d = wi · wm``, batched ``(...)``, and returns reflectance; RGB parameters give ``(..., 3)``.
"""

from __future__ import annotations

import jax.numpy as jnp


def schlick(f0, cos_d):
    r"""Schlick's approximation, RTR eq. 9.16, as used by Burley 2012 §5.5.

    .. math:: F(\mathbf h, \mathbf l) \approx F_0 + (1 - F_0)(1 - (\mathbf h\cdot\mathbf l)^+)^5

    ``f0`` broadcasts against ``cos_d[..., None]`` (RGB ``f0`` of shape ``(3,)`` gives
    ``(..., 3)``); a scalar ``f0`` with scalar output is obtained by passing ``f0[..., None]``.
    """
    m = jnp.clip(1.0 - cos_d, 0.0, 1.0)[..., None]
    return f0 + (1.0 - f0) * m**5
