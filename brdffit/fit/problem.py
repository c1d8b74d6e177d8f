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
        x_fixed: the full flat physical vector; free entries are overwritten from ``u``.
        slo, shi: bounds of the free scalars in the transform's ``s`` coordinate.
    """

    model: Model = eqx.field(static=True)
    loss: Loss = eqx.field(static=True)
    free: tuple[int, ...] = eqx.field(static=True)
    log: tuple[bool, ...] = eqx.field(static=True)
    compute_dtype: str = eqx.field(static=True)
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
        dt = jnp.dtype(self.compute_dtype)
        pred = self.predict(x_free, data)
        r = self.loss.residual(
            pred,
            data.target.astype(dt),
            data.sqrt_weight.astype(dt),
            data.cos_i.astype(dt),
            data.cos_o.astype(dt),
        )
        return r.reshape(-1)

    def residual(self, u, data: FitData):
        """Flat residual as a function of the unconstrained ``u`` (what the solver sees)."""
        return self.residual_x(self.physical(u), data)
