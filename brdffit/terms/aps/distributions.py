r"""Microfacet normal distributions ``p(h)`` for the APS 2000 BRDF generator.

A distribution is an :class:`equinox.Module` with a method ``p(h)`` (``(..., 3) -> (...)``) and
two static flags:

* ``heightfield``: ``p`` lives on the upper hemisphere only (APS §2: then ``P(n) = 1``). The
  integrals of :mod:`brdffit.terms.aps.tables` then run over ``h·n > 0`` only, so ``p`` need not be
  zero below the horizon itself.
* ``isotropic``: ``p`` depends on ``h_z`` only, so ``g(k)`` is tabulated over ``θ_k`` alone.

``p`` need not be normalized: APS eq. 26 is invariant under ``p → c p`` (``⟨⟨hn⟩⟩`` and both
``g`` scale alike), which is why eqs. 34 and 35 leave their constants ``c`` unspecified; here
``c = 1``. Mixtures (satin, V-grooves) normalize each component by its integral ``∫ p dω`` so
the mixture weights are the area fractions the paper means (§6.3).

Every ``p`` is written with gradient-safe divisions: ``tan²θ = (h_x² + h_y²)/h_z²`` is finite
(large) at the horizon, and ``exp(−large) = 0`` with a zero gradient.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._math import azimuth, safe_div
from .quadrature import polar_rule

#: ``tan²``/``cot²`` values standing in for infinity (``exp(-BIG/σ²)`` underflows to 0).
BIG = 1e12


class Distribution(eqx.Module):
    """Abstract ``p(h)``; subclasses set ``heightfield`` and ``isotropic`` and implement ``p``."""

    def p(self, h):
        raise NotImplementedError

    @property
    def heightfield(self) -> bool:
        return True

    @property
    def isotropic(self) -> bool:
        return False


def _quad_weights(n_theta, n_phi, dtype):
    h, w = polar_rule(n_theta, n_phi)
    return jnp.asarray(h, dtype), jnp.asarray(w, dtype)


def hemisphere_integral(fn, dtype, n_theta=64, n_phi=64):
    """``∫_{h_z > 0} fn(h) dω`` by :func:`~brdffit.terms.aps.quadrature.polar_rule`."""
    h, w = _quad_weights(n_theta, n_phi, dtype)
    return jnp.sum(w * fn(h))


class FunctionDistribution(Distribution):
    """A user-supplied ``p(h, params)``: any JAX function of the half vector and a parameter pytree.

    Example (an isotropic Gaussian heightfield of width ``s``)::

        FunctionDistribution(lambda h, s: jnp.exp(-(h[..., 0]**2 + h[..., 1]**2) / (s * h[..., 2])**2),
                             jnp.asarray(0.2), isotropic=True)

    ``isotropic=True`` promises that ``fn`` depends on ``h_z`` only (the tables become 1-D).
    ``fn`` is a static (hashed) field: define it once, not as a fresh lambda per call, or every
    call compiles the table builders anew.
    """

    fn: Callable = eqx.field(static=True)
    params: Any
    is_heightfield: bool = eqx.field(static=True, default=True)
    is_isotropic: bool = eqx.field(static=True, default=False)

    def __init__(self, fn, params, *, heightfield=True, isotropic=False):
        self.fn, self.params = fn, params
        self.is_heightfield, self.is_isotropic = heightfield, isotropic

    def p(self, h):
        return self.fn(h, self.params)

    @property
    def heightfield(self):
        return self.is_heightfield

    @property
    def isotropic(self):
        return self.is_isotropic


class NDFDistribution(Distribution):
    """``p(h) = D(h)`` of an NDF from :mod:`brdffit.terms.ndf` (e.g. GGX): the consistency check.

    For a normalized NDF ``⟨⟨hn⟩⟩ = 1`` (RTR eq. 9.21) and ``P(k)`` (APS eq. 25) is Smith's G1
    (RTR eq. 9.24), so APS eq. 26 is the microfacet lobe (RTR eq. 9.34) with the separable G2
    (RTR eq. 9.27). Pass ``is_isotropic=False`` for an anisotropic NDF.
    """

    ndf: Any
    is_isotropic: bool = eqx.field(static=True, default=True)

    def p(self, h):
        return self.ndf.D(h)

    @property
    def isotropic(self):
        return self.is_isotropic


class AnisotropicGaussian(Distribution):
    r"""APS 2000 eq. 34, with ``c = 1``:

    .. math:: p(\mathbf h) = \exp\!\left(-\tan^2\theta\left(\frac{\cos^2\phi}{\sigma_x^2}
              + \frac{\sin^2\phi}{\sigma_y^2}\right)\right)
              = \exp\!\left(-\frac{h_x^2/\sigma_x^2 + h_y^2/\sigma_y^2}{h_z^2}\right)

    A heightfield (``p = 0`` for ``h·n < 0``). ``sigma_y = inf`` (``1/σ_y = 0``) is the
    "cylindrical" Gaussian of §6.3; pass ``inv_sigma_y=0`` for it.
    """

    inv_sx2: jax.Array
    inv_sy2: jax.Array

    def __init__(self, sigma_x, sigma_y=None, *, inv_sigma_y=None):
        self.inv_sx2 = 1.0 / jnp.asarray(sigma_x) ** 2
        if inv_sigma_y is not None:
            self.inv_sy2 = jnp.asarray(inv_sigma_y) ** 2
        else:
            self.inv_sy2 = 1.0 / jnp.asarray(sigma_x if sigma_y is None else sigma_y) ** 2

    def p(self, h):
        q = h[..., 0] ** 2 * self.inv_sx2 + h[..., 1] ** 2 * self.inv_sy2
        return jnp.exp(-safe_div(q, h[..., 2] ** 2, fill=BIG))


class Velvet(Distribution):
    r"""The velvet "inverse Gaussian" heightfield, APS 2000 eq. 35, with ``c = 1``:

    .. math:: p(\mathbf h) = \exp(-\cot^2\theta/\sigma^2), \qquad
              \cot^2\theta = h_z^2/(h_x^2 + h_y^2)

    Largest (1) at the horizon, zero at the normal. Isotropic.
    """

    inv_s2: jax.Array

    def __init__(self, sigma):
        self.inv_s2 = 1.0 / jnp.asarray(sigma) ** 2

    def p(self, h):
        cot2 = safe_div(h[..., 2] ** 2, h[..., 0] ** 2 + h[..., 1] ** 2, fill=BIG)
        return jnp.exp(-cot2 * self.inv_s2)

    @property
    def isotropic(self):
        return True


class TiltedGaussian(Distribution):
    r"""A narrow Gaussian around a tilted facet normal ``m`` (one side of a V-groove, APS §6.2).

    ``p(h) = χ⁺(h·m) exp(−tan²∠(h, m)/σ²)``, ``tan²∠ = (1 − (h·m)²)/(h·m)²``, with
    ``m = (sin τ cos φ_g, sin τ sin φ_g, cos τ)``.
    """

    m: jax.Array
    inv_s2: jax.Array

    def __init__(self, tilt, sigma, azimuth=0.0):
        tilt, az = jnp.asarray(tilt), jnp.asarray(azimuth)
        self.m = jnp.stack([jnp.sin(tilt) * jnp.cos(az), jnp.sin(tilt) * jnp.sin(az), jnp.cos(tilt)])
        self.inv_s2 = 1.0 / jnp.asarray(sigma) ** 2

    def p(self, h):
        c = jnp.sum(h * self.m.astype(h.dtype), axis=-1)
        tan2 = safe_div(1.0 - c**2, c**2, fill=BIG)
        return jnp.where(c > 0, jnp.exp(-jnp.maximum(tan2, 0.0) * self.inv_s2), 0.0)


class Mixture(Distribution):
    """``p = Σ w_i p_i / ∫ p_i dω``: components normalized to unit area, then mixed (APS §6.3).

    The normalizations are computed numerically (:func:`hemisphere_integral`) from the current
    parameters, so gradients flow through them. All components must be heightfields.
    """

    components: tuple
    weights: jax.Array
    norms: jax.Array

    def __init__(self, components, weights, *, n_theta=96, n_phi=96, dtype=None):
        self.components = tuple(components)
        self.weights = jnp.asarray(weights)
        dt = dtype or self.weights.dtype
        self.norms = jnp.stack(
            [hemisphere_integral(c.p, dt, n_theta, n_phi) for c in self.components]
        )

    def p(self, h):
        return sum(
            (w / n).astype(h.dtype) * c.p(h) for c, w, n in zip(self.components, self.weights, self.norms, strict=True)
        )

    @property
    def isotropic(self):
        return all(c.isotropic for c in self.components)


def satin(sigma_flats=0.1, sigma_ends=0.3, w_flats=0.7, **kw):
    """APS 2000 §6.3: ``0.7 p_flats + 0.3 p_ends``, both "cylindrical" Gaussians (``σ_y = ∞``)."""
    return Mixture(
        [AnisotropicGaussian(sigma_flats, inv_sigma_y=0.0), AnisotropicGaussian(sigma_ends, inv_sigma_y=0.0)],
        jnp.stack([jnp.asarray(w_flats), 1.0 - jnp.asarray(w_flats)]),
        **kw,
    )


def v_groove(tilt=0.3490658503988659, sigma=0.1, **kw):  # 20°
    """APS 2000 §6.2: two narrow Gaussians (σ = 0.1) around the facet normals of symmetric
    V-grooves running along ``y``, tilted by ``±tilt`` about ``y`` (the paper's grooves "with the
    angle of 40 degrees" read as facet normals 40° apart: ``tilt = 20°``, the default)."""
    tilt = jnp.asarray(tilt)
    return Mixture([TiltedGaussian(tilt, sigma), TiltedGaussian(-tilt, sigma)], jnp.asarray([0.5, 0.5]), **kw)


class TabulatedDistribution(Distribution):
    """``p(h)`` tabulated on the hemisphere: ``values[i, j]`` at ``θ_i = i·(π/2)/(n_θ−1)``,
    ``φ_j = 2π j/n_φ``; bilinear in ``(θ, φ)``, periodic in ``φ``. ``n_φ = 1`` is isotropic.

    The values are a (differentiable) array: a fit can adjust them. A heightfield.
    """

    values: jax.Array

    def p(self, h):
        v = jnp.asarray(self.values)
        n_t, n_p = v.shape
        theta = jnp.arccos(jnp.clip(h[..., 2], -1.0, 1.0))
        x = jnp.clip(theta / (np.pi / 2) * (n_t - 1), 0.0, n_t - 1.0)
        i0 = jnp.clip(jnp.floor(x), 0, n_t - 2).astype(jnp.int32)
        fx = x - i0
        if n_p == 1:
            return (1 - fx) * v[i0, 0] + fx * v[i0 + 1, 0]
        y = azimuth(h[..., 0], h[..., 1]) / (2 * np.pi) * n_p
        j0 = jnp.clip(jnp.floor(y), 0, n_p - 1).astype(jnp.int32)
        fy, j1 = y - j0, (j0 + 1) % n_p
        return (1 - fx) * ((1 - fy) * v[i0, j0] + fy * v[i0, j1]) + fx * (
            (1 - fy) * v[i0 + 1, j0] + fy * v[i0 + 1, j1]
        )

    @property
    def isotropic(self):
        return np.shape(self.values)[1] == 1
