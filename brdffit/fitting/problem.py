"""The fitting problem as a pytree: which scalars are free, their bounds, the residual.

A :class:`Problem` maps the unconstrained vector ``u`` of the free scalars to the model's
parameter dict and to the flat residual of the selected cells. Its static part (model, loss,
which scalars are free, which are fitted in log space, the compute dtype) selects the compiled
program; everything else (fixed values, bounds, the data) is a runtime argument, so refitting
another table of the same layout, or with other fixed values, reuses the compilation.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..models.registry import Model
from .data import FitData
from .losses import Loss
from .transforms import to_physical


class Problem(eqx.Module):
    """Free scalars, bounds and fixed values of one fit.

    Attributes:
        model, loss: what is fitted, and how residuals are weighted.
        free: flat indices (into ``model.flatten``) of the free scalars.
        log: per free scalar, whether it is fitted in log space (``Param.log``).
        compute_dtype: dtype of the model evaluation (``"float32"`` or ``"float64"``).
        chunks: blocks the cells are split into for the Jacobian accumulation.
        x_fixed: the full flat physical vector; free entries are overwritten from ``u``.
        slo, shi: bounds of the free scalars in the transform's ``s`` coordinate.
    """

    model: Model = eqx.field(static=True)
    loss: Loss = eqx.field(static=True)
    free: tuple[int, ...] = eqx.field(static=True)
    log: tuple[bool, ...] = eqx.field(static=True)
    compute_dtype: str = eqx.field(static=True)
    chunks: int = eqx.field(static=True)
    x_fixed: jax.Array
    slo: jax.Array
    shi: jax.Array

    def physical(self, u):
        """Free scalars in physical units, ``x(u)``."""
        return to_physical(u, self.slo, self.shi, np.asarray(self.log, bool))

    def full_vector(self, x_free):
        return self.x_fixed.at[np.asarray(self.free, int)].set(x_free.astype(self.x_fixed.dtype))

    def predict(self, x_free, data: FitData):
        """Model ``f_r`` ``(n, 3)`` on the selected cells, in the compute dtype."""
        dt = jnp.dtype(self.compute_dtype)
        params = self.model.unflatten(self.full_vector(x_free).astype(dt))
        return self.model.fn(params, data.wi.astype(dt), data.wo.astype(dt))

    def residual_x(self, x_free, data: FitData):
        """Flat residual as a function of the free scalars in physical units."""
        pred = self.predict(x_free, data)
        return self._residual_of_pred(pred, data)

    def residual(self, u, data: FitData):
        """Flat residual as a function of the unconstrained ``u`` (what the solver sees)."""
        return self.residual_x(self.physical(u), data)

    def cost_floor(self, data: FitData, noise: float):
        """A constant for the solver's cost, ``F = ½ Σ (κ ε (|g(ρ)| + 1) w)² / noise``.

        ``κ ε (|g(ρ)| + 1) w`` (``κ = 10``, ``ε`` the compute dtype's epsilon) bounds the rounding
        error of one residual, so ``noise × F`` is the rounding noise of a cost near zero. Adding
        ``F`` to the cost (constant: no step changes) lets the trust region's relative noise test
        (:class:`brdffit.fitting.solvers.NoiseTolerantTrustRegion`) recognise an exact fit (cost at
        its rounding floor) as converged instead of rejecting noise-sized steps forever.
        """
        eps = float(jnp.finfo(jnp.dtype(self.compute_dtype)).eps)
        w = (jnp.abs(data.target) + 1.0) * data.sqrt_weight
        acc = jnp.promote_types(data.target.dtype, jnp.float32)
        return 0.5 * jnp.sum(jnp.square(10.0 * eps * w.astype(acc))) / noise

    def _residual_of_params(self, params, data: FitData):
        dt = jnp.dtype(self.compute_dtype)
        return self._residual_of_pred(self.model.fn(params, data.wi.astype(dt), data.wo.astype(dt)), data)

    def _residual_of_pred(self, pred, data: FitData):
        dt = pred.dtype
        ci, co = data.wi[:, 2:3].astype(dt), data.wo[:, 2:3].astype(dt)
        r = self.loss.residual(pred, data.target.astype(dt), data.sqrt_weight.astype(dt), ci, co)
        return r.reshape(-1)

    def columns_x(self, x_free, data: FitData):
        """``(r, J)``: the flat residual and its Jacobian rows ``J[k] = ∂r/∂x_k`` (free scalars).

        One forward-mode ``jvp`` per free scalar, each with respect to one parameter of the
        model's dict while the others are closed over: the tangent then flows only through
        the terms that parameter touches (a diffuse albedo's tangent skips the specular lobe).
        XLA's common-subexpression elimination shares the primal between the ``jvp`` calls.
        """
        dt = jnp.dtype(self.compute_dtype)
        params = self.model.unflatten(self.full_vector(x_free).astype(dt))
        r = self._residual_of_params(params, data)
        cols, offset, free = [], 0, set(self.free)
        for p in self.model.params:
            comps = [j for j in range(p.size) if offset + j in free]
            offset += p.size
            if not comps:
                continue

            def f(v, name=p.name):
                return self._residual_of_params({**params, name: v}, data)

            basis = jnp.eye(p.size, dtype=dt)[np.asarray(comps)].reshape((len(comps),) + p.shape)
            cols.append(jax.vmap(lambda t, f=f, v=params[p.name]: jax.jvp(f, (v,), (t,))[1])(basis))
        return r, jnp.concatenate(cols, axis=0)

    def columns(self, u, data: FitData):
        """``(r, J)`` with respect to the unconstrained ``u`` (chain rule through ``x(u)``)."""
        x, dxdu = jax.jvp(self.physical, (u,), (jnp.ones_like(u),))  # the map is elementwise
        r, cols = self.columns_x(x, data)
        return r, cols * dxdu.astype(cols.dtype)[:, None]
