r"""Directional albedo tables of a Schlick microfacet lobe over ``(cos θ, α)``, precomputed once.

For the lobe ``f = F D G2/(4 |n·l| |n·v|)`` (RTR eq. 9.34) with Schlick's
``F = m⁵ + f0 (1 − m⁵)``, ``m = 1 − (h·l)`` (RTR eq. 9.16), the directional albedo is linear in
``f0`` (Karis's split, RTR §9.9.3):

.. math::

    R_\text{spec}(\mu; \alpha, F_0) = E_0(\mu, \alpha) + F_0\,(E_1(\mu, \alpha) - E_0(\mu, \alpha)),

with ``E₁ = R_sF1`` the albedo at ``F = 1`` (RTR eq. 9.56) and ``E₀`` the albedo at ``F₀ = 0``.
Both are stored with their cosine-weighted averages ``Ē = 2∫E μ dμ`` (RTR eq. 9.57), which
depend on ``α`` only.

Layout and accuracy (defaults; a convention of this module): ``n_mu = 33`` nodes uniform in
``u = √μ`` (dense towards grazing) by ``n_alpha = 32`` nodes uniform in ``log α`` over
``[10⁻³, 1]`` — the Imageworks 32 × 32 of RTR p. 346 — read by bilinear interpolation in
``(u, log α)`` (continuous and piecewise-differentiable in ``α``). Each entry is the integral
over half vectors ``∫ D G2 F (h·l)/(n·l) dω_h`` with ``tan θ_h = α sinh y`` (Gauss–Legendre in
``y``, 64 nodes) and the trapezoid rule in ``φ_h`` (64 nodes). Measured for GGX with
height-correlated G2: node entries agree with a 4× finer quadrature (256 × 256) to 1.6e-3
absolute at worst (11 roughness rows × 33 elevations), and lookups at 200 random off-node
``(α, μ)`` with a direct 128 × 128 quadrature to 3.3e-3 absolute at worst (at ``α ≈ 0.008``,
``μ ≈ 0.03``, near grazing); ``tests/test_multiscatter.py`` asserts 5e-3 against an
independent quadrature over outgoing directions.

Tables are computed eagerly (float64 when JAX has x64 enabled, else float32) the first time a combination
``(ndf_factory, g2, sizes)`` is asked for (a few seconds), cached for the session, and cast to
the caller's dtype at lookup; they carry no parameters, so nothing is rebuilt inside a fit.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._math import safe_div
from ..masking import G2_height_correlated

ALPHA_RANGE = (1e-3, 1.0)


@dataclasses.dataclass(frozen=True, eq=False)
class AlbedoTable:
    """``E₀, E₁`` ``(n_alpha, n_mu)`` and their averages ``(n_alpha,)``, NumPy float64."""

    log_alpha: np.ndarray
    e0: np.ndarray
    e1: np.ndarray
    avg0: np.ndarray
    avg1: np.ndarray

    def _alpha_weights(self, alpha):
        lo, hi = float(self.log_alpha[0]), float(self.log_alpha[-1])  # Python floats: weak types
        la = jnp.log(jnp.clip(alpha, np.exp(lo).item(), np.exp(hi).item()))
        n = len(self.log_alpha)
        x = (la - lo) / (hi - lo) * (n - 1)
        i0 = jnp.clip(jnp.floor(x), 0, n - 2).astype(jnp.int32)
        return i0, x - i0

    def lookup(self, alpha, mu):
        """``(E₀, E₁)`` at roughness ``alpha`` (scalar) and ``mu = cos θ`` ``(...)``."""
        dt = jnp.result_type(alpha, mu)
        i, fa = self._alpha_weights(alpha)
        n_mu = self.e0.shape[1]
        x = jnp.sqrt(jnp.clip(mu, 0.0, 1.0)) * (n_mu - 1)
        j = jnp.clip(jnp.floor(x), 0, n_mu - 2).astype(jnp.int32)
        fm = x - j

        def bilinear(tab):
            t = jnp.asarray(tab, dt)
            row = (1 - fa) * t[i] + fa * t[i + 1]  # (n_mu,)
            return (1 - fm) * row[j] + fm * row[j + 1]

        return bilinear(self.e0), bilinear(self.e1)

    def average(self, alpha):
        """``(Ē₀, Ē₁)`` at roughness ``alpha`` (RTR eq. 9.57)."""
        dt = jnp.result_type(alpha)
        i, fa = self._alpha_weights(alpha)
        a0, a1 = jnp.asarray(self.avg0, dt), jnp.asarray(self.avg1, dt)
        return (1 - fa) * a0[i] + fa * a0[i + 1], (1 - fa) * a1[i] + fa * a1[i + 1]


def _albedo_at(ndf, alpha, mu, g2, n_y, n_phi):
    """``(E₀(μ), E₁(μ))`` of one NDF for an array of ``μ`` (eager, float64)."""
    x, w = np.polynomial.legendre.leggauss(n_y)
    y_max = np.arcsinh(1e4 / alpha)
    y, wy = 0.5 * y_max * (x + 1), 0.5 * y_max * w
    t = alpha * np.sinh(y)
    th = np.arctan(t)
    dth = alpha * np.cosh(y) / (1 + t * t)
    ph = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1)  # (Y, P, 3)
    wgt = (wy * dth * np.sin(th))[:, None] * (2 * np.pi / n_phi)
    mu = np.asarray(mu, float)
    l = np.stack([np.sqrt(1 - mu**2), np.zeros_like(mu), mu], -1)[:, None, None, :]  # (M,1,1,3)
    hl = np.sum(l * h, -1)
    v = 2 * hl[..., None] * h - l
    ok = (hl > 0) & (v[..., 2] > 0)
    hj, lj, vj = jnp.asarray(np.broadcast_to(h, v.shape)), jnp.asarray(np.broadcast_to(l, v.shape)), jnp.asarray(v)
    geo = np.asarray(g2(ndf, lj, vj, hj) * ndf.D(hj))
    base = np.where(ok, geo * np.asarray(safe_div(jnp.asarray(hl), jnp.asarray(l[..., 2]))), 0.0) * wgt
    m5 = np.clip(1 - hl, 0, 1) ** 5
    return np.sum(base * m5, axis=(1, 2)), np.sum(base, axis=(1, 2))


def _simpson_mu_average(e, n_mu):
    """``2∫E μ dμ`` with ``μ = u²``: ``4∫E u³ du``, Simpson in ``u``."""
    u = np.linspace(0, 1, n_mu)
    s = np.ones(n_mu)
    s[1:-1:2], s[2:-1:2] = 4, 2
    return (e * (s * 4 * u**3 / (3 * (n_mu - 1)))).sum(-1)


@functools.lru_cache(maxsize=16)
def albedo_table(ndf_factory, g2=G2_height_correlated, n_mu=33, n_alpha=32, n_y=64, n_phi=64) -> AlbedoTable:
    """The :class:`AlbedoTable` of the lobe ``ndf_factory(alpha)`` with masking ``g2`` (cached).

    ``ndf_factory`` maps a roughness to an isotropic NDF (e.g. :class:`brdffit.terms.ndf.GGX`).
    ``n_mu`` must be odd (Simpson's rule for the averages).
    """
    if n_mu % 2 == 0 or n_mu < 3:
        raise ValueError(f"albedo_table: n_mu must be odd and >= 3, got {n_mu}")
    la = np.linspace(np.log(ALPHA_RANGE[0]), np.log(ALPHA_RANGE[1]), n_alpha)
    mu = np.linspace(0, 1, n_mu) ** 2
    with jax.ensure_compile_time_eval():
        rows = [_albedo_at(ndf_factory(jnp.asarray(a)), a, mu, g2, n_y, n_phi) for a in np.exp(la)]
    e0, e1 = (np.array([r[i] for r in rows]) for i in (0, 1))
    return AlbedoTable(la, e0, e1, _simpson_mu_average(e0, n_mu), _simpson_mu_average(e1, n_mu))
