"""The interface every normal distribution function (NDF) implements.

An NDF is a small immutable pytree (an :class:`equinox.Module`) holding its parameters, with two
methods, after pbrt-v4's ``TrowbridgeReitzDistribution``:

* ``D(wm)``: the microfacet normal density, normalised so that ``∫ D(m) (n·m) dm = 1``
  (RTR eq. 9.21), zero for back-facing ``wm``.
* ``Lambda(w)``: Smith's auxiliary function, from which ``G1 = 1/(1 + Λ)`` (RTR eq. 9.24) and
  every G2 form in :mod:`brdffit.terms.masking` are built.

Parameters are stored as JAX arrays so an NDF can be built inside a jitted, differentiated
function (``GGX(params["alpha"])``). New families go in their own module in this package and are
re-exported from :mod:`brdffit.terms.ndf`.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

#: Roughness values are clamped to at least this, keeping ``D`` finite as ``alpha -> 0``
#: (a peak of height ``1/(pi alpha^2) ~ 3e7``). Fits report a parameter sitting at it.
ALPHA_MIN = 1e-4


def clamp_alpha(alpha):
    """``max(alpha, ALPHA_MIN)`` as an array (gradient zero below the clamp)."""
    return jnp.maximum(jnp.asarray(alpha), ALPHA_MIN)


def as_float(x):
    """``x`` as a JAX array of a floating dtype: its own, or the default float for integers."""
    x = jnp.asarray(x)
    return x if jnp.issubdtype(x.dtype, jnp.floating) else x.astype(jnp.result_type(float))


class NDF(eqx.Module):
    """Abstract base: ``D(wm)`` and ``Lambda(w)`` over batches of unit vectors ``(..., 3)``."""

    def D(self, wm):  # noqa: N802 (the book's symbol)
        raise NotImplementedError

    def Lambda(self, w):  # noqa: N802
        raise NotImplementedError
