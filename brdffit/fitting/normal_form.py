r"""The Gauss–Newton normal form of a tall least-squares problem, for optimistix's solvers.

A MERL table gives ``m ≈ 3.3 million`` residuals for ``p ≈ 7`` parameters. Optimistix's
Gauss–Newton family (Levenberg–Marquardt, Gauss–Newton, Dogleg) uses the residual ``r`` and the
Jacobian ``J`` only through

* the cost :math:`\tfrac12\|r\|^2`,
* the gradient :math:`J^\top r` and
* the quadratic model :math:`\tfrac12\|J\delta + r\|^2`, i.e. :math:`J^\top J`.

Factor :math:`J^\top J = R^\top R` (``R`` is ``p × p``; from an eigendecomposition, so a
rank-deficient ``J`` is fine) and define the compressed residual of length ``p + 1``

.. math::

    \tilde r = \begin{pmatrix} R^{-\top} J^\top r \\ c \end{pmatrix}, \qquad
    c = \sqrt{\|r\|^2 - \|R^{-\top}J^\top r\|^2}, \qquad
    \tilde J = \begin{pmatrix} R \\ 0 \end{pmatrix}

(``R^{-⊤}`` a pseudo-inverse). Then :math:`\|\tilde r\|^2 = \|r\|^2`,
:math:`\tilde J^\top\tilde J = J^\top J`, :math:`\tilde J^\top \tilde r = J^\top r` and
:math:`\|\tilde J\delta + \tilde r\|^2 = \|J\delta + r\|^2` for every step ``δ``: the solver takes
exactly the steps, trust-region ratios and damping it would take on the full residual. ``J̃`` is
attached to ``r̃`` with a ``jax.custom_jvp``, so optimistix's ``jax.linearize`` sees a ``p × p``
Jacobian and its QR/Cholesky work is on tiny matrices.

:math:`J^\top J` and :math:`J^\top r` come from forward mode: one ``jvp`` per model parameter
(per free scalar for parameters that couple the colour channels), each with respect to that
parameter only, so unrelated parts of the model carry no tangent; see
:meth:`brdffit.fitting.problem.Problem.block_sums`. They are accumulated in float64 even when the
model runs in float32. The Jacobian is never materialised as a whole, and no reverse-mode tape is
stored.

The one difference from running optimistix on the full residual: its Cauchy termination test
compares successive residual vectors element by element; here it compares successive ``r̃``
(``R^{-⊤}J^⊤r`` tends to zero at the optimum, ``c`` to the residual norm), together with the
usual test on the step in ``u``. That test only catches a stall; convergence is the
optimality test of :class:`brdffit.fitting.bounded.Optimality`, computed from ``J̃`` and ``r̃``.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .transforms import held_on_bounds

#: Eigenvalues of ``JᵀJ`` below this fraction of the largest are treated as zero.
RANK_RTOL = 1e-13


def chunked(data, chunks: int):
    """Every leaf of ``data`` reshaped ``(n, ...) -> (chunks, n // chunks, ...)``."""
    return jax.tree.map(lambda a: a.reshape((chunks, a.shape[0] // chunks) + a.shape[1:]), data)


def gram(sums: Callable, u, data, chunks: int = 1, active=None, prepare: Callable | None = None,
         n_extra: int | None = None):
    """``(Σ r², JᵀJ, Jᵀr, Jᵀdiag(r²)J, extra)`` summed over the blocks of cells.

    ``sums(u, data_block)`` returns the five for one block (``extra``: a vector of further sums
    whose first entry is ``m``, the number of residuals with non-zero weight), e.g.
    :meth:`Problem.block_sums <brdffit.fitting.problem.Problem.block_sums>`. The cells are processed in ``chunks`` equal blocks (a loop), so the
    per-block derivatives stay in cache and the whole Jacobian is never in memory. ``active`` (a
    traced integer, default all) sums over the first ``active`` blocks only: the same compiled
    program then serves a fit on a leading subset of the blocks (the warm start of
    :mod:`brdffit.fitting.stages`). ``prepare(u)`` (optional) computes, once before the loop,
    what every block shares (:meth:`Problem.pass_tables
    <brdffit.fitting.problem.Problem.pass_tables>`); it is passed to ``sums(u, data_block,
    prepared)``. ``n_extra``: the length of ``extra`` if known (else ``sums`` is traced once
    more to find it: a quarter of a cold ``ggx`` solve's tracing).
    """
    acc = jnp.promote_types(u.dtype, jnp.float32)
    p = u.shape[0]
    prepared = None if prepare is None else prepare(u)
    block_sums = lambda v, d: sums(v, d) if prepare is None else sums(v, d, prepared)
    if n_extra is None:
        first = jax.tree.map(lambda a: a[: a.shape[0] // chunks], data)
        n_extra = jax.eval_shape(block_sums, u, first)[4].shape[0]
    init = (jnp.zeros((), acc), jnp.zeros((p, p), acc), jnp.zeros((p,), acc),
            jnp.zeros((p, p), acc), jnp.zeros((n_extra,), acc))

    def block(carry, chunk):
        return tuple(c + s.astype(acc) for c, s in zip(carry, block_sums(u, chunk)))

    return over_blocks(block, init, data, chunks, active)


def over_blocks(block: Callable, init, data, chunks: int, active=None):
    """``carry = block(carry, data_block)`` over the first ``active`` of ``chunks`` blocks."""
    if chunks == 1:
        return block(init, data)
    blocks = chunked(data, chunks)
    if active is None:
        return jax.lax.scan(lambda c, b: (block(c, b), None), init, blocks)[0]
    take = lambda i: jax.tree.map(lambda a: jax.lax.dynamic_index_in_dim(a, i, keepdims=False), blocks)
    return jax.lax.fori_loop(0, active, lambda i, c: block(c, take(i)), init)


def compress(sum_r2, jtj, jtr):
    """``(r̃, R)`` with ``RᵀR = JᵀJ``, ``Rᵀ r̃[:p] = Jᵀr`` and ``‖r̃‖² = Σ r²`` (module docstring)."""
    lam, vec = jnp.linalg.eigh(jtj)
    keep = lam > RANK_RTOL * jnp.max(jnp.abs(lam))
    sq = jnp.sqrt(jnp.where(keep, lam, 1.0))
    rmat = jnp.where(keep[:, None], sq[:, None] * vec.T, 0.0)  # R = Λ^½ Vᵀ
    head = jnp.where(keep, (vec.T @ jtr) / sq, 0.0)  # R^{-ᵀ} Jᵀ r
    tail = jnp.sqrt(jnp.maximum(sum_r2 - jnp.sum(head**2), 0.0))
    return jnp.concatenate([head, tail[None]]), rmat


def compress_newton(sum_r2, jtj, second, jtr, u):
    r""":func:`compress` of a Newton model ``JᵀJ + S`` (``S`` an estimate of the second-order
    term :math:`\sum_i r_i \nabla^2 r_i` that Gauss–Newton drops), so that the solver's
    quadratic model is Newton's; ``J̃ᵀr̃ = Jᵀr`` and ``‖r̃‖² = Σ r²`` still hold.

    * With the box coordinates ``u``, the rows and columns of ``S`` of the coordinates *held*
      on a bound (on it, the gradient ``Jᵀr`` pointing outward: the bounded step keeps them
      there, :func:`brdffit.fitting.transforms.held_on_bounds`, as in
      :func:`brdffit.fitting.bounded.box_step`) are left out: the curvature that
      matters is the one of the free coordinates. A parameter whose optimum lies beyond its
      bound can have strong negative curvature along its own coordinate (``F90`` pressed on 0
      by the grazing cells: an eigenvalue of −1.5e8 against ``JᵀJ``'s 3e4…2e8 on aluminium,
      ``beckmann``).
    * Along an eigenvector ``v`` of ``JᵀJ + S`` with non-positive curvature the model takes
      Gauss–Newton's, ``vᵀJᵀJv ≥ 0`` (a modified Newton model, in the spirit of Gill and
      Murray's modified factorizations): Newton's model where it is convex, Gauss–Newton's
      along the rest. Falling back to ``JᵀJ`` as a whole there gave up the second-order term
      everywhere and left a solve with Gauss–Newton's linear convergence (``gtr`` on fabrics,
      with ``γ`` on its way to its bound: 3–4 full-table steps instead of 2).
    * Where the Newton decrement ``(Jᵀr)ᵀH⁻¹Jᵀr`` of that model exceeds ``Σ r²`` (far from the
      optimum, or a wrong ``S``) it falls back to ``JᵀJ``, so the cost is always represented
      exactly (``c ≥ 0``, :func:`compress`)."""
    held_lo, held_hi = held_on_bounds(u, jtr)
    out = held_lo | held_hi
    second = jnp.where(out[:, None] | out[None, :], 0.0, second)
    h = jtj + second
    lam, vec = jnp.linalg.eigh(h)
    # Along eigenvectors of non-positive curvature, Gauss–Newton's curvature vᵀJᵀJv (≥ 0).
    gn = jnp.einsum("ik,ij,jk->k", vec, jtj, vec)
    lam = jnp.where(lam > RANK_RTOL * jnp.max(jnp.abs(lam)), lam, gn)
    h = (vec * lam) @ vec.T
    rt, rmat = compress(sum_r2, h, jtr)
    ok = jnp.sum(rt[:-1] ** 2) < sum_r2
    rt_gn, rmat_gn = compress(sum_r2, jtj, jtr)
    return jnp.where(ok, rt, rt_gn), jnp.where(ok, rmat, rmat_gn)


def normal_form(sums: Callable, chunks: int = 1, prepare: Callable | None = None,
                n_extra: int | None = None, penalty: Callable | None = None) -> Callable:
    """``fn(u, args) -> r̃`` for optimistix, whose derivative is the Gauss–Newton ``J̃``.

    ``sums(u, data)`` returns ``(Σ r², JᵀJ, Jᵀr, Jᵀdiag(r²)J, m)`` for a block of cells
    (``data`` is split into ``chunks`` blocks, see :func:`gram`, which also says what
    ``prepare`` and ``n_extra`` do). ``args = (data, floor)``
    or ``(data, floor, active)``: ``floor`` is a constant added to the cost ``½‖r̃‖²`` (through
    ``c``), see :meth:`brdffit.fitting.problem.Problem.cost_floor`; it changes no step, gradient
    or ratio. ``active`` restricts the sums to the first blocks (:func:`gram`).

    ``fn`` returns ``(r̃, aux)`` (use ``has_aux=True``) with ``aux = {"jtj", "meat", "sum_r2",
    "extra", "m"}``: ``JᵀJ`` and ``Jᵀdiag(r²)J`` at ``u``, accumulated in the same pass, for the
    covariance at the optimum; ``Σ r²`` (without the floor) and the further sums of ``sums``
    (the error figures); ``m = extra[0]``, the number of weighted residuals (for the covariance).
    ``fn`` is only meant to be differentiated once, to first order, by the solver (its ``jvp`` is
    ``J̃ δ``; ``aux`` has zero tangent).

    ``penalty(u)`` (optional) returns ``(Σ r², JᵀJ, Jᵀr)`` of further residuals that are no
    cells (the energy constraint, :mod:`brdffit.fitting.constraints`): added to the solver's
    sums, left out of ``aux`` (the data's figures and covariance).
    """

    def _both(u, args):
        data, floor, *rest = args
        active = rest[0] if rest else None
        sum_r2, jtj, jtr, meat, extra = gram(sums, u, data, chunks, active, prepare, n_extra)
        total, gjtj, gjtr = sum_r2, jtj, jtr
        if penalty is not None:
            total, gjtj, gjtr = (a + b.astype(a.dtype) for a, b in zip((total, gjtj, gjtr),
                                                                        penalty(u)))
        if len(rest) > 1:  # a second-order term: Newton's quadratic model
            rt, rmat = compress_newton(total + 2.0 * floor, gjtj, rest[1].astype(jtj.dtype),
                                       gjtr, u.astype(jtj.dtype))
        else:
            rt, rmat = compress(total + 2.0 * floor, gjtj, gjtr)
        aux = {"jtj": jtj, "meat": meat, "sum_r2": sum_r2, "extra": extra, "m": extra[0]}
        return rt, rmat, aux

    @jax.custom_jvp
    def fn(u, args):
        rt, _, aux = _both(u, args)
        return rt, aux

    @fn.defjvp
    def _fn_jvp(primals, tangents):
        u, args = primals
        du = tangents[0]
        rt, rmat, aux = _both(u, args)
        dr = rmat @ du.astype(rmat.dtype)
        drt = jnp.concatenate([dr, jnp.zeros((1,), dr.dtype)]).astype(rt.dtype)
        return (rt, aux), (drt, jax.tree.map(jnp.zeros_like, aux))

    return fn
