r"""Bijections between bounded physical parameters and the unconstrained space the solvers see.

Levenberg–Marquardt, Gauss–Newton and Dogleg have no bounds of their own, so each free scalar
``x ∈ [lo, hi]`` is fitted through an unconstrained ``u``:

.. math::

    s = \mathrm{lo}_s + (\mathrm{hi}_s - \mathrm{lo}_s)\,\sigma(\mathrm{clip}(u, -U, U)),
    \qquad x = \begin{cases} e^{s} & \text{log parameter} \\ s & \text{otherwise}\end{cases}

with ``σ`` the logistic function and ``lo_s, hi_s`` the bounds in ``s`` (``log`` of the bounds
for a log parameter such as a roughness). Near a bound ``x - lo ∝ e^u``: the map behaves like a
log transform there, so a diffuse albedo of 0.005 and one of 0.5 are equally easy to fit.

Convention: ``u`` is clipped at ``±U`` (``U = 700``) only to keep ``e^{±u}`` finite. A parameter
whose optimum lies at or beyond its bound runs towards ``|u| → ∞`` until its derivative is
negligible next to the other columns and the (scaled) damping holds it
(:class:`brdffit.fitting.solvers.ScaledDampedNewtonDescent`). Such parameters are reported in
``FitResult.at_bound``. A tight clip (an exactly zero derivative at, say, ``|u| = 30``) would
trap parameters that overshoot towards a bound during the first steps.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

#: Clip of the unconstrained coordinate (keeps ``exp(±u)`` finite).
U_CLIP = 700.0
#: A parameter is "at its bound" when ``σ(u)`` is within this of 0 or 1.
AT_BOUND_TOL = 1e-6
#: Starting values are moved at least this far inside their bounds (a fraction of the range in
#: the ``s`` coordinate). A start at ``σ(u) = 1e-6`` would have ``∂x/∂u ≈ 1e-6``: the solver could
#: hardly move it, so a default of 0 (Disney's ``sheen``) would never leave its bound.
START_MARGIN = 0.01


def bounds_in_s(lo, hi, log):
    """Bounds in the pre-exponential coordinate ``s`` (``log`` bounds for log parameters)."""
    lo, hi, log = (np.asarray(a) for a in (lo, hi, log))
    return np.where(log, np.log(np.where(log, lo, 1.0)), lo), np.where(
        log, np.log(np.where(log, hi, 1.0)), hi
    )


def to_physical(u, slo, shi, log):
    """``x(u)``: unconstrained → physical (``jnp``; differentiable; ``log`` is a NumPy bool mask)."""
    u = jnp.clip(u, -U_CLIP, U_CLIP)
    w = shi - slo
    # measured from the nearer bound, so that 1 - σ(u) keeps its precision for large u
    s = jnp.where(u < 0, slo + w * jax.nn.sigmoid(u), shi - w * jax.nn.sigmoid(-u))
    return jnp.where(log, jnp.exp(jnp.where(log, s, 0.0)), s)


def to_unconstrained(x, slo, shi, log, margin: float = 0.0):
    """``u(x)``: physical → unconstrained (NumPy). Values within ``margin`` (a fraction of the
    range, at least 1e-12) of a bound are moved to that distance first."""
    x = np.asarray(x, float)
    s = np.where(log, np.log(np.where(log, np.maximum(x, 1e-300), 1.0)), x)
    m = max(float(margin), 1e-12)
    p = np.clip((s - slo) / (shi - slo), m, 1.0 - m)
    return np.log(p) - np.log1p(-p)


def sigmoid_position(u):
    """``σ(clip(u))`` in NumPy: 0 at the lower bound, 1 at the upper."""
    u = np.clip(np.asarray(u, float), -U_CLIP, U_CLIP)
    return 1.0 / (1.0 + np.exp(-u))


def at_bound(u) -> np.ndarray:
    """``-1`` (lower), ``+1`` (upper) or ``0`` (interior) for each unconstrained coordinate."""
    p = sigmoid_position(u)
    return np.where(p <= AT_BOUND_TOL, -1, np.where(p >= 1.0 - AT_BOUND_TOL, 1, 0))
