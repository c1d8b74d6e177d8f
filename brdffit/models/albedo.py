r"""The directional albedo of a model: how much of the light arriving from one direction it
reflects, by quadrature in half-vector space.

.. math::

    \rho(\omega_i) = \int_{H^2} f_r(\omega_i, \omega_o)\,\cos\theta_o\,d\omega_o

A surface that creates no light has :math:`\rho(\omega_i) \le 1` at every incidence, per
channel (RTR §9.3: "energy conservation"). The integral runs over half vectors ``h``:
``wo = 2 (wi·h) h − wi`` with ``dωo = 4 (wi·h) dωh`` (the Jacobian of reflection, RTR eq. 9.33's
half vector), the integrand masked to ``wo`` above the horizon and ``wi·h > 0``. Around the
normal the specular peak sits at ``θh = 0`` for every incidence, so a grid dense near
``θh = 0`` resolves sharp lobes at all ``θi``: ``θh = 90°·u²`` (MERL's warp), ``u`` by composite
Gauss–Legendre (half the nodes on ``[0, 0.3]``, half on ``[0.3, 1]``), ``φh`` by the midpoint
rule, weight ``sin θh · π u du dφh``. The integrand carries ``cos θo`` and ``wi·h``, which vanish
on the masked boundaries. :mod:`brdffit.plots.albedo` (the albedo figure) states the accuracy
of its default grid (64 × 128 nodes per ``θi``); :func:`max_albedo` uses a coarser one.

The incidence azimuth is ``φi = 0`` (the x–z plane), which matters only for anisotropic models.
"""

from __future__ import annotations

import numpy as np

from .evaluate import evaluate_model


def half_vector_grid(n_u: int = 64, n_phi: int = 128, split: float = 0.3):
    """Half vectors ``(n_u·n_phi, 3)`` and their solid-angle weights (module docstring)."""
    x, w = np.polynomial.legendre.leggauss(n_u // 2)
    u = np.concatenate([split * (x + 1) / 2, split + (1 - split) * (x + 1) / 2])
    wu = np.concatenate([w * split / 2, w * (1 - split) / 2])
    theta = 0.5 * np.pi * u**2
    phi = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    st = np.sin(theta)
    h = np.stack(np.broadcast_arrays(
        (st[:, None] * np.cos(phi)), (st[:, None] * np.sin(phi)), np.cos(theta)[:, None]), -1)
    weight = (st * np.pi * u * wu)[:, None] * np.full(n_phi, 2 * np.pi / n_phi)
    return h.reshape(-1, 3), weight.ravel()


def quadrature(theta_i_deg, n_u: int = 64, n_phi: int = 128):
    """Per ``θi``: ``wi``, ``wo`` ``(T, M, 3)`` and weights ``(T, M)`` that include
    ``cos θo · 4 (wi·h)``, so ``ρ(θi) = Σ_m weight · f_r(wi, wo)``."""
    h, w = half_vector_grid(n_u, n_phi)
    t = np.radians(np.asarray(theta_i_deg, float))
    wi = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1)[:, None, :]
    wi_h = np.sum(wi * h, axis=-1)
    wo = 2 * wi_h[..., None] * h - wi
    ok = (wi_h > 0) & (wo[..., 2] > 0)
    weight = np.where(ok, w * wo[..., 2] * 4 * wi_h, 0.0)
    wo = np.where(ok[..., None], wo, np.array([0.0, 0.0, 1.0]))
    return np.broadcast_to(wi, wo.shape), wo, weight


#: The incidence angles :func:`max_albedo` looks at (degrees): 16 from 0° to 89°, densest
#: near grazing incidence, where Disney's retro-reflective diffuse and sheen and a Lambert term
#: beside a Schlick lobe reach their largest albedo (a realistic ``disney`` fit: 0.89 at 85°,
#: 1.03 at 88°, 1.006 at 89.5°). "Every incidence" a renderer evaluates: a measurement says
#: little beyond 85°, a renderer shows it at silhouettes.
CHECK_ANGLES = np.array([0.0, 15.0, 30.0, 45.0, 55.0, 65.0, 70.0, 75.0, 80.0, 83.0, 85.0, 86.0,
                         87.0, 88.0, 88.5, 89.0])
#: The grid of :func:`max_albedo`: 64 × 64 half vectors (``θh`` × ``φh``) per angle, 16 angles:
#: 65,536 model evaluations, one compiled chunk of
#: :func:`~brdffit.models.evaluate.evaluate_model`. Against a 128 × 256 grid it agrees within
#: 8e-4 for a ``ggx`` metal with α from 0.002 to 1 at every angle up to 89°, as measured when
#: this was written (``tests/test_plausible.py`` asserts 1e-3 against the figure's 64 × 128);
#: 64 × 32 was off by 1.7e-3 at 88.5°-89° for broad lobes (the ``φh`` nodes matter at
#: grazing incidence), 32 × 32 by 4e-3 at 85°.
CHECK_GRID = (64, 64)


def albedo(model, params, theta_i_deg, *, n_u: int = 64, n_phi: int = 128) -> np.ndarray:
    """The directional albedo ``(T, 3)`` of ``model`` with ``params`` at ``theta_i_deg``."""
    wi, wo, weight = quadrature(theta_i_deg, n_u, n_phi)
    vals = evaluate_model(model, params, wi.reshape(-1, 3), wo.reshape(-1, 3)).reshape(wo.shape)
    return np.einsum("tm,tmc->tc", weight, np.where(np.isfinite(vals), vals, 0.0))


def max_albedo(model, params) -> tuple[float, float]:
    """``(ρ_max, θi)``: the largest directional albedo of any channel over :data:`CHECK_ANGLES`
    and the incidence angle (degrees) where it occurs, on :data:`CHECK_GRID`."""
    rho = albedo(model, params, CHECK_ANGLES, n_u=CHECK_GRID[0], n_phi=CHECK_GRID[1])
    per_angle = np.max(rho, axis=1)
    k = int(np.argmax(per_angle))
    return float(per_angle[k]), float(CHECK_ANGLES[k])
