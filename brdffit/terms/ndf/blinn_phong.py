"""Blinn-Phong distribution, with Walter's Beckmann Λ through ``α_p = 2 α_b⁻² − 2``."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .base import NDF, clamp_alpha
from .beckmann import Beckmann

#: The largest exponent, the Beckmann-equivalent of ``ALPHA_MIN`` (``2/1e-8 − 2``).
ALPHA_P_MAX = 2.0 / 1e-4**2 - 2.0


def beckmann_alpha_to_phong(alpha_b):
    """``α_p = 2 α_b⁻² − 2`` (Walter et al. 2007, quoted in RTR p. 340)."""
    return 2.0 / clamp_alpha(alpha_b) ** 2 - 2.0


def phong_to_beckmann_alpha(alpha_p):
    """The inverse of :func:`beckmann_alpha_to_phong`: ``α_b = √(2 / (α_p + 2))``."""
    return jnp.sqrt(2.0 / (alpha_p + 2.0))


class BlinnPhong(NDF):
    r"""Blinn-Phong NDF with exponent ``alpha_p`` (RTR eq. 9.40).

    .. math::  D(\mathbf m) = \chi^+(\mathbf n\cdot\mathbf m)\,\frac{\alpha_p + 2}{2\pi}\,
        (\mathbf n\cdot\mathbf m)^{\alpha_p}

    normalised (RTR eq. 9.21) for every ``α_p > −2``; ``alpha_p`` is clamped to
    ``[0, ALPHA_P_MAX]`` (0 is the uniform NDF, RTR p. 340). The power is evaluated as
    ``exp(α_p · ½ log1p(−sin²θm))`` near the pole, accurate for the huge exponents of polished surfaces.

    Blinn-Phong is not shape-invariant and has no closed-form Λ; as Walter et al. suggest (RTR
    p. 340) ``Lambda`` is Beckmann's exact Λ (RTR eq. 9.38) at ``α_b = √(2/(α_p + 2))``.
    Build from a Beckmann-like roughness with :meth:`from_beckmann_alpha`.
    """

    alpha_p: jax.Array

    def __init__(self, alpha_p):
        self.alpha_p = jnp.clip(jnp.asarray(alpha_p), 0.0, ALPHA_P_MAX)

    @classmethod
    def from_beckmann_alpha(cls, alpha_b):
        """Blinn-Phong with ``α_p = 2 α_b⁻² − 2`` (``α_b`` clamped at ``ALPHA_MIN``)."""
        return cls(beckmann_alpha_to_phong(alpha_b))

    def D(self, wm):  # noqa: N802
        mz = wm[..., 2]
        up = mz > 0
        sin2 = wm[..., 0] ** 2 + wm[..., 1] ** 2
        near_pole = sin2 < 0.5  # log1p form near the pole, log(cos) elsewhere
        log_cos = jnp.where(
            near_pole,
            0.5 * jnp.log1p(-jnp.where(near_pole, sin2, 0.0)),
            jnp.log(jnp.where(up & ~near_pole, mz, 1.0)),
        )
        d = (self.alpha_p + 2.0) / (2.0 * jnp.pi) * jnp.exp(self.alpha_p * log_cos)
        return jnp.where(up, d, 0.0)

    def Lambda(self, w):  # noqa: N802
        return Beckmann(phong_to_beckmann_alpha(self.alpha_p)).Lambda(w)
