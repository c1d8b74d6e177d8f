"""Diffuse (subsurface) BRDF terms. Each returns ``f_r`` without the cosine factor."""

from __future__ import annotations

import jax.numpy as jnp

from ._math import chi_plus, cos_theta


def lambert(albedo, wi, wo):
    r"""Lambertian diffuse ``f = ρ_ss/π``, RTR eq. 9.61, zero unless both directions are above the horizon.

    ``albedo`` (RGB ``(3,)``) broadcasts to ``(..., 3)``.
    """
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    return (albedo / jnp.pi) * vis[..., None]
