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
from .statistics import cell_metric_sums
from .transforms import to_physical, to_physical_host


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
        energy: the energy constraint's penalty (:class:`.constraints.EnergyLimit`), attached
            by :func:`.constraints.limited` where a fit broke the constraint; ``None``
            otherwise.
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
    energy: object = None

    @classmethod
    def build(cls, scalars, loss: Loss, x, dtype: str, chunks: int) -> Problem:
        """The problem of fitting ``scalars.model``'s free :class:`~.parameters.Scalars` under
        ``loss``, the other scalars held at their values in the flat vector ``x``; the one place
        a problem is built (the fit, and the posterior from a fit's result)."""
        free = list(scalars.free)
        slo, shi = scalars.bounds_in_s()
        return cls(
            scalars.model, loss, tuple(free), tuple(bool(b) for b in scalars.log[free]), dtype,
            chunks, jnp.asarray(x), jnp.asarray(slo), jnp.asarray(shi),
        )

    def physical(self, u):
        """Free scalars in physical units, ``x(u)``."""
        return to_physical(u, self.slo, self.shi, np.asarray(self.log, bool))

    def full_vector(self, x_free):
        return self.x_fixed.at[np.asarray(self.free, int)].set(x_free.astype(self.x_fixed.dtype))

    def flat_host(self, u) -> np.ndarray:
        """The whole flat parameter vector at box coordinates ``u``, in NumPy (physical units;
        the fixed scalars at their values): :meth:`physical` and :meth:`full_vector` on the
        host, without compiling anything."""
        x = np.array(self.x_fixed, float)
        x[list(self.free)] = to_physical_host(u, self.slo, self.shi, np.asarray(self.log, bool))
        return x

    def predict(self, x_free, data: FitData, tables=None):
        """Model ``f_r`` ``(n, 3)`` on the selected cells, in the compute dtype; with
        ``tables`` (from :meth:`pass_tables`) the model is ``per_pass.apply`` with them."""
        dt = jnp.dtype(self.compute_dtype)
        params = self.model.unflatten(self.full_vector(x_free).astype(dt))
        wi, wo = data.wi.astype(dt), data.wo.astype(dt)
        if tables is None:
            return self.model.fn(params, wi, wo)
        return self.model.per_pass.apply(params, tables[0], wi, wo)

    def residual_x(self, x_free, data: FitData, tables=None):
        """Flat residual as a function of the free scalars in physical units."""
        pred = self.predict(x_free, data, tables)
        return self._residual_of_pred(pred, data)

    def residual(self, u, data: FitData, tables=None):
        """Flat residual as a function of the unconstrained ``u`` (what the solver sees);
        ``tables`` as in :meth:`predict`, from :meth:`pass_tables` at ``u``."""
        return self.residual_x(self.physical(u), data, tables)

    def cost_floor(self, data: FitData, noise: float):
        r"""A constant for the solver's cost: the compute dtype's rounding and the data's own,

        .. math:: F = \tfrac12 \sum \big(\kappa\,\varepsilon\,(|g(\rho)| + 1)\,w\big)^2
                      / \text{noise} + \tfrac12 \sum \big(w\,(g(\rho(1 + \varepsilon_d))
                      - g(\rho))\big)^2.

        ``κ ε (|g(ρ)| + 1) w`` (``κ = 10``, ``ε`` the compute dtype's epsilon) bounds the rounding
        error of one residual, so ``noise × F`` is the rounding noise of a cost near zero. Adding
        ``F`` to the cost (constant: no step changes) lets the trust region's relative noise test
        (:class:`brdffit.fitting.bounded.NoiseTolerantTrustRegion`) recognise an exact fit (cost at
        its rounding floor) as converged instead of rejecting noise-sized steps forever.

        The second sum is the cost of a relative error ``ε_d`` in every measured value
        (``FitData.value_epsilon``: the epsilon of the type the values were stored in; 0 for
        values stored to the compute precision, which adds nothing): no model is known to be
        closer to the data than their storage, so the optimality test
        (:func:`brdffit.fitting.bounded.optimality`, a fraction of ``cost + F``) measures what
        a step could still remove against at least that. It matters only for an exact fit to
        float32 values: on small RGL files written from a model's defaults, ``F_d`` is 8e-14 to
        4e-12 where the fits end at costs of 1e-15 to 2e-13; a measured material's cost is many
        orders above it.
        """
        eps = float(jnp.finfo(jnp.dtype(self.compute_dtype)).eps)
        w = (jnp.abs(data.target) + 1.0) * data.sqrt_weight
        acc = jnp.promote_types(data.target.dtype, jnp.float32)
        floor = 0.5 * jnp.sum(jnp.square(10.0 * eps * w.astype(acc))) / noise
        if not data.value_epsilon:
            return floor
        ci, co = data.wi[:, 2:3].astype(acc), data.wo[:, 2:3].astype(acc)
        rgb, used = data.rgb.astype(acc), data.sqrt_weight > 0
        moved = self.loss.transform(rgb * (1.0 + data.value_epsilon), ci, co)
        r = jnp.where(used, data.sqrt_weight * (moved - self.loss.transform(rgb, ci, co)), 0.0)
        return floor + 0.5 * jnp.sum(jnp.square(r))

    def penalty_sums(self, u):
        """``(Σ r², JᵀJ, Jᵀr)`` of the energy penalty's residuals at ``u``
        (:class:`.constraints.EnergyLimit`, ``J`` by forward mode), or ``None`` without one."""
        if self.energy is None:
            return None
        dt = jnp.dtype(self.compute_dtype)
        acc = jnp.promote_types(u.dtype, jnp.float32)

        def res(v):
            params = self.model.unflatten(self.full_vector(self.physical(v)).astype(dt))
            return self.energy.residual(self.model, params, dt).astype(acc)

        def res_twice(v):  # the residual, and again as the primal jacfwd hands back
            r = res(v)
            return r, r

        jac, r = jax.jacfwd(res_twice, has_aux=True)(u)
        return jnp.sum(r * r), jac.T @ jac, jac.T @ r

    def _residual_of_pred(self, pred, data: FitData):
        dt = pred.dtype
        ci, co = data.wi[:, 2:3].astype(dt), data.wo[:, 2:3].astype(dt)
        r = self.loss.residual(pred, data.target.astype(dt), data.sqrt_weight.astype(dt), ci, co)
        return r.reshape(-1)

    def block_second_order(self, u, data: FitData):
        r"""``Σ_i r_i ∇²r_i`` over one block of cells (derivatives with respect to ``u``): the
        term of the Hessian of ``½Σr²`` that Gauss–Newton drops, exactly.

        On a table the model fits exactly it vanishes; on real materials (large residuals) it
        is what makes Gauss–Newton converge only linearly. It is the Hessian at ``u`` of
        ``g(v) = Σ_i r̄_i r_i(v)`` with the residuals ``r̄ = r(u)`` held fixed
        (``∇²g = Σ_i r̄_i ∇²r_i``), built with ``jax.hessian`` (forward over reverse). The fit
        itself uses forward differences of :meth:`block_gradient_held` instead
        (:func:`brdffit.fitting.solve.second_order`, much cheaper to compile); this exact form
        is their reference (tests, ``benchmarks/bench_second_order.py``).
        """
        acc = jnp.promote_types(u.dtype, jnp.float32)
        res = lambda v: self.residual(v, data).astype(acc)
        held = jax.lax.stop_gradient(res(u))
        return jax.hessian(lambda v: jnp.sum(held * res(v)))(u)

    def block_gradient_held(self, u, data: FitData, r_bar, tables=None):
        r"""``Σ_i r̄_i ∇r_i(u) = J(u)ᵀ r̄`` over one block of cells: the gradient at ``u`` of
        ``g(v) = Σ_i r̄_i r_i(v)`` with the residuals ``r̄`` (``(n, 3)``, e.g. ``r`` at another
        point) held fixed, in ``r̄``'s dtype. Its forward differences in ``u`` with
        ``r̄ = r(u₀)`` give ``Σ_i r_i(u₀) ∇²r_i(u₀)`` (:func:`brdffit.fitting.solve.second_order`).

        Exact first derivatives: by reverse mode (one evaluation of the model and its
        adjoint), or, for a model with ``per_pass`` tables given ``tables`` (from
        :meth:`pass_tables` at ``u``), by forward mode from the tangent fields of
        :meth:`tangents_x`, through which the tables' tangents enter (reverse mode would
        rebuild the tables for every block, several times slower for ``gtr``).
        """
        acc = r_bar.dtype
        if tables is None:
            g = lambda v: jnp.sum(r_bar * self.residual(v, data).reshape(-1, 3).astype(acc))
            return jax.grad(g)(u)
        x, dxdu = jax.jvp(self.physical, (u,), (jnp.ones_like(u),))  # the map is elementwise
        _, _, fields, where = self.tangents_x(x, data, tables)
        tr = jnp.stack([jnp.sum(t.astype(acc) * r_bar, axis=0) for t in fields])
        return jnp.einsum("ikc,kc->i", _placement_r(where, len(fields)), tr) * dxdu.astype(acc)

    def tangent_layout(self) -> tuple[tuple[str, tuple[int, ...], bool], ...]:
        """Per model parameter with free components: ``(name, free components, per_channel)``.

        Static (it depends on the model, the loss and which scalars are free only), in
        declaration order, so the columns come out in the order of the free flat indices.
        """
        layout, offset, free = [], 0, set(self.free)
        for p in self.model.params:
            comps = tuple(j for j in range(p.size) if offset + j in free)
            offset += p.size
            if comps:
                layout.append((p.name, comps, p.per_channel))
        return tuple(layout)

    def _tangent_directions(self, shapes):
        """``(name, on, local, t)`` per tangent field (see :meth:`tangents_x`): the parameter,
        the flat components the tangent is one on, whether the parameter is channel-local, and
        the tangent itself (NumPy, of shape ``shapes[name]``)."""
        for name, comps, local in self.tangent_layout():
            shape = shapes[name]
            for on in [comps] if local else [(c,) for c in comps]:
                t = np.zeros(int(np.prod(shape, dtype=int)))
                t[list(on)] = 1.0
                yield name, on, local, t.reshape(shape)

    def pass_tables(self, u):
        """``(tables, tangents)`` of a model with ``per_pass`` (:class:`~brdffit.models.registry.PerPass`)
        at ``u``, or ``None``: the parameter-only tables and, per tangent field of
        :meth:`tangents_x` whose parameter they use, their ``jvp``. Computed once per pass, before
        the loop over blocks (:func:`~brdffit.fitting.normal_form.gram`)."""
        split = self.model.per_pass
        if split is None:
            return None
        dt = jnp.dtype(self.compute_dtype)
        params = self.model.unflatten(self.full_vector(self.physical(u)).astype(dt))
        tangents = []
        for name, _on, _local, t in self._tangent_directions({k: v.shape for k, v in params.items()}):
            if name not in split.uses:
                tangents.append(None)
                continue
            f = lambda v, name=name: split.build({**params, name: v})
            tangents.append(jax.jvp(f, (params[name],), (jnp.asarray(t, dt),))[1])
        return split.build(params), tuple(tangents)

    def tangents_x(self, x_free, data: FitData, tables=None):
        r"""``(pred, r, fields, where)``: the model ``(n, 3)``, the residual ``(n, 3)`` and the
        forward-mode tangents the Jacobian is made of.

        Each field ``T_k`` is one ``jvp`` of the residual ``(n, 3)`` with respect to one model
        parameter, the others closed over (the tangent flows only through the terms that
        parameter touches: a diffuse albedo's skips the specular lobe). ``where[i] = (k, c)``
        gives Jacobian column ``i`` (free scalar ``i``): ``∂r/∂x_i = T_k`` restricted to channel
        ``c``, or all channels for ``c = None``.

        A channel-local RGB parameter (``Param.per_channel``: component ``c`` changes channel
        ``c`` only; every loss acts channel by channel) needs one ``jvp`` for all its
        components: with the tangent set to one on every free component, channel ``c`` of
        ``T_k`` is exactly ``∂r_{·c}/∂x_c``. Any other parameter takes one ``jvp`` per free
        component: 3 products instead of 7 for ``ggx``. XLA's common-subexpression elimination
        shares the primal between them; inside the loop over blocks only when while-loop
        invariant code motion is off (:data:`~brdffit.fitting.solve.CPU_COMPILER_OPTIONS`).

        ``tables`` (from :meth:`pass_tables`, for a model with ``per_pass``): the model is
        ``per_pass.apply`` with those tables, whose tangent enters the fields of the
        parameters they use.
        """
        dt = jnp.dtype(self.compute_dtype)
        params = self.model.unflatten(self.full_vector(x_free).astype(dt))
        wi, wo = data.wi.astype(dt), data.wo.astype(dt)
        if tables is None:
            model = lambda p, _tab: self.model.fn(p, wi, wo)
            tab, dtabs = None, None
        else:
            model = lambda p, tab: self.model.per_pass.apply(p, tab, wi, wo)
            tab, dtabs = tables
        pred = model(params, tab)
        r = self._residual_of_pred(pred, data).reshape(-1, 3)
        fields, where = [], []
        directions = self._tangent_directions({k: v.shape for k, v in params.items()})
        for i, (name, on, local, t) in enumerate(directions):
            t = jnp.asarray(t, dt)
            res = lambda v, tb, name=name: self._residual_of_pred(model({**params, name: v}, tb), data)
            if dtabs is not None and dtabs[i] is not None:
                field = jax.jvp(res, (params[name], tab), (t, dtabs[i]))[1]
            else:
                field = jax.jvp(lambda v, res=res: res(v, tab), (params[name],), (t,))[1]
            fields.append(field.reshape(-1, 3))
            k = len(fields) - 1
            where += [(k, c) for c in on] if (local and params[name].shape) else [(k, None)]
        return pred, r, fields, tuple(where)

    def block_sums(self, u, data: FitData, tables=None):
        """``(Σ r², JᵀJ, Jᵀr, Jᵀdiag(r²)J, extra)`` of one block of cells, ``J = ∂r/∂u``;
        ``extra`` holds the error-figure sums (:func:`~brdffit.fitting.statistics.cell_metric_sums`,
        the number of weighted residuals first).

        Built from the tangent fields of :meth:`tangents_x`: per channel ``c``, the sums
        ``Σ_n T_k T_l``, ``Σ_n T_k r`` and ``Σ_n T_k T_l r²`` over the cells (``k ≤ l``), then
        placed into the ``p × p`` matrices by the columns' channel masks. The Jacobian is never
        formed: for a channel-local parameter its columns would be two-thirds zeros. Products are
        accumulated in float64 when x64 is enabled, whatever the compute dtype.
        """
        x, dxdu = jax.jvp(self.physical, (u,), (jnp.ones_like(u),))  # the map is elementwise
        pred, r, fields, where = self.tangents_x(x, data, tables)
        acc = jnp.promote_types(u.dtype, jnp.float32)
        r = r.astype(acc)
        fields = [t.astype(acc) for t in fields]
        r2 = r * r
        pairs = [(k, l) for k in range(len(fields)) for l in range(k, len(fields))]
        tt, ttr2, tr = _field_sums(fields, r, pairs, batched=self.loss.linear_residual)
        place, place_r = _placement(where, len(fields), pairs)
        scale = dxdu.astype(acc)
        outer = scale[:, None] * scale[None, :]
        jtj = jnp.einsum("ijqc,qc->ij", place, tt) * outer
        meat = jnp.einsum("ijqc,qc->ij", place, ttr2) * outer
        jtr = jnp.einsum("ikc,kc->i", place_r, tr) * scale
        return jnp.sum(r2), jtj, jtr, meat, cell_metric_sums(pred, data).astype(acc)


def _field_sums(fields, r, pairs, batched: bool):
    r"""Per channel ``c``, over the cells ``n``: ``Σ T_k T_l``, ``Σ T_k T_l r²`` for the ``pairs``
    ``(k, l)`` (each ``(len(pairs), 3)``) and ``Σ T_k r`` (``(F, 3)``), from the fields ``T_k``
    and the residual ``r`` (each ``(n, 3)``).

    Two programs for the same sums, chosen by what XLA's CPU compiler makes of them:

    * one reduction per pair (``batched=False``), which XLA fuses with the fields' computation:
      the faster of the two where the residual is nonlinear in the model (the ``log`` loss);
    * the Gram matrices of the stacked fields and of ``T_k r``, one batched matrix product per
      channel (``batched=True``), for a residual linear in the model
      (:attr:`~brdffit.fitting.losses.Loss.linear_residual`: ``linear``, ``cosine``,
      ``cosine-in``, ``relative``). There the per-pair reductions are fused otherwise and a
      pass over the cells takes longer.
    """
    if not batched:
        r2 = r * r
        tt = jnp.stack([jnp.sum(fields[k] * fields[l], axis=0) for k, l in pairs])
        ttr2 = jnp.stack([jnp.sum(fields[k] * fields[l] * r2, axis=0) for k, l in pairs])
        return tt, ttr2, jnp.stack([jnp.sum(t * r, axis=0) for t in fields])
    first, second = (np.array(ix, dtype=int) for ix in zip(*pairs))
    t = jnp.moveaxis(jnp.stack(fields), -1, 0)  # (3, F, n)
    t_r = t * jnp.moveaxis(r, -1, 0)[:, None, :]
    tt = jnp.einsum("ckn,cln->klc", t, t)[first, second]
    ttr2 = jnp.einsum("ckn,cln->klc", t_r, t_r)[first, second]
    return tt, ttr2, jnp.sum(t_r, axis=-1).T


def _placement(where, n_fields: int, pairs):
    """Constant 0/1 arrays that place per-channel field sums into ``p × p`` (and ``p``) arrays.

    ``place[i, j, q, c] = 1`` when columns ``i`` and ``j`` are fields ``pairs[q]`` (either order)
    and both include channel ``c``; ``place_r[i, k, c] = 1`` when column ``i`` is field ``k`` on
    channel ``c``.
    """
    p = len(where)
    mask = _channel_mask(where)
    index = {pair: q for q, pair in enumerate(pairs)}
    place = np.zeros((p, p, len(pairs), 3))
    for i, (ki, _) in enumerate(where):
        for j, (kj, _) in enumerate(where):
            place[i, j, index[(min(ki, kj), max(ki, kj))]] = mask[i] * mask[j]
    return place, _placement_r(where, n_fields)


def _channel_mask(where) -> np.ndarray:
    """``mask[i, c] = 1`` when column ``i`` includes channel ``c``."""
    mask = np.zeros((len(where), 3))
    for i, (_k, c) in enumerate(where):
        mask[i] = 1.0 if c is None else np.eye(3)[c]
    return mask


def _placement_r(where, n_fields: int) -> np.ndarray:
    """``place_r[i, k, c] = 1`` when column ``i`` is field ``k`` on channel ``c``."""
    mask = _channel_mask(where)
    place_r = np.zeros((len(where), n_fields, 3))
    for i, (ki, _) in enumerate(where):
        place_r[i, ki] = mask[i]
    return place_r
