r"""The energy constraint of a fit: directional albedo at most 1 at every incidence.

A surface creates no light: its directional albedo

.. math:: \rho_c(\omega_i) = \int_{H^2} f_{r,c}(\omega_i, \omega_o)\cos\theta_o\,d\omega_o \le 1

per channel ``c`` at every incidence (RTR §9.3). Most models do not hold it by construction: a
Lambert term plus an independent specular lobe (the standard models), Disney's retro-reflective
diffuse and sheen at grazing incidence, an absolute loss that lets the diffuse term take up a
polished metal's peak (``--config ngan2005`` on chrome: albedo 1.06). So the fitter enforces
it as a constraint where the unconstrained optimum breaks it:

1. the fit is solved as usual; its largest albedo is computed on the plausibility check's
   quadrature (:func:`brdffit.models.albedo.max_albedo`: 16 incidences from 0° to 89°,
   densest near grazing, 64 × 64 half vectors each, the grid of the ``energy`` check);
2. only if it exceeds 1, the fit is solved again from that optimum with the penalty residuals

   .. math:: r_{tc} = \lambda\,\max\big(0,\ \rho_c(\theta_t) - 1\big), \qquad
             \lambda^2 = \Lambda\,(2\,\mathrm{cost} + 1)

   appended to the data's (an exterior penalty): their Gauss–Newton sums
   (``Σ r²``, ``JᵀJ``, ``Jᵀr``, with ``J`` by forward mode over the 65,536 quadrature
   directions) are added to the cells' in every pass
   (:func:`brdffit.fitting.normal_form.normal_form`). Where the constraint is active its
   residual balances the data's gradient, so the optimum exceeds 1 by about
   ``gradient / λ²``. ``Λ`` starts at 1e4 and grows a hundredfold (each solve starting where
   the last ended) until the largest albedo is within :data:`TOLERANCE` of 1
   (:data:`PENALTIES`): a weight large at once makes the problem stiff, and the solver crawls
   (a realistic metal: 50 steps at 1e6 against 13 at 1e4).

The metrics, the covariance and the reported cost stay those of the data; the optimality test
is that of the constrained problem. The message says the constraint was active and what the
albedo was without it. A fit that does not break the constraint runs no extra pass and
compiles nothing more.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..models.albedo import CHECK_ANGLES, CHECK_GRID, max_albedo, quadrature

#: ``Λ``: the penalty's weights relative to the cost, tried in turn (module docstring) ...
PENALTIES = (1e4, 1e6, 1e8)
#: ... until the largest albedo is at most ``LIMIT + TOLERANCE``.
LIMIT = 1.0
TOLERANCE = 1e-4


class EnergyLimit(eqx.Module):
    """The quadrature of the energy constraint (module docstring): directions ``wi``, ``wo``
    ``(T·M, 3)``, weights ``(T, M)`` (``cos θo`` and the half-vector Jacobian included), and the
    penalty's scale ``λ``."""

    wi: jax.Array
    wo: jax.Array
    weight: jax.Array
    scale: jax.Array

    @classmethod
    def of(cls, cost: float, penalty: float) -> EnergyLimit:
        wi, wo, weight = quadrature(CHECK_ANGLES, *CHECK_GRID)
        return cls(jnp.asarray(wi.reshape(-1, 3)), jnp.asarray(wo.reshape(-1, 3)),
                   jnp.asarray(weight), jnp.asarray(np.sqrt(penalty * (2.0 * cost + 1.0))))

    def residual(self, model, params, dtype):
        """``λ max(0, ρ − 1)`` per incidence and channel, flat ``(T·3,)``."""
        f = model.fn(params, self.wi.astype(dtype), self.wo.astype(dtype))
        f = jnp.where(jnp.isfinite(f), f, 0.0).reshape(self.weight.shape + (3,))
        rho = jnp.einsum("tm,tmc->tc", self.weight.astype(f.dtype), f)
        return (self.scale * jnp.maximum(rho - LIMIT, 0.0)).reshape(-1)


def energy_excess(model, x) -> tuple[float, float]:
    """``(ρ_max, θi)`` of ``model`` at the flat parameters ``x`` on the constraint's grid."""
    return max_albedo(model, model.unflatten(np.asarray(x, float)))


def limited(problem, cost: float, penalty: float = PENALTIES[0]):
    """``problem`` with the energy penalty of weight ``penalty`` (``Λ``) attached
    (:class:`EnergyLimit`)."""
    return eqx.tree_at(lambda p: p.energy, problem, EnergyLimit.of(cost, penalty),
                       is_leaf=lambda v: v is None)
