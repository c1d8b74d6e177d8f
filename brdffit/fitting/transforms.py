r"""The box coordinates the solvers see: each free scalar as a position in ``[0, 1]``.

Each free scalar ``x ∈ [lo, hi]`` is fitted through its position ``z`` in the box

.. math::

    s = \mathrm{lo}_s + (\mathrm{hi}_s - \mathrm{lo}_s)\,z, \quad z \in [0, 1],
    \qquad x = \begin{cases} e^{s} & \text{log parameter (a roughness)} \\
                              s & \text{otherwise}\end{cases}

with ``lo_s, hi_s`` the bounds in ``s`` (``log`` of the bounds for a log parameter). The map is
affine in ``s``, so a parameter on its bound has the same derivative as one inside: the bounded
Levenberg–Marquardt step (:func:`brdffit.fitting.bounded.box_step`) keeps every iterate in the
box, puts a parameter whose optimum lies at or beyond its bound exactly on it, and leaves it
there only when the gradient points back inside (an active set, as in MINPACK/Ceres's bounded LM
or scipy's ``trf``). A logistic map ``x − lo ∝ eᵘ`` would not do: its derivative vanishes on the
way to a bound, so an optimum on the bound is approached without end.

The albedo-like parameters (diffuse, ``F0``) are linear in ``z``: most models are linear in
them, so the Gauss–Newton model is nearly exact along those coordinates.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

#: A coordinate within this of 0 or 1 counts as on its bound (the bounded step puts a
#: parameter exactly on it; this only absorbs the rounding of ``1 - z``).
AT_BOUND_TOL = 1e-12


def bounds_in_s(lo, hi, log):
    """Bounds in the pre-exponential coordinate ``s`` (``log`` bounds for log parameters)."""
    lo, hi, log = (np.asarray(a) for a in (lo, hi, log))
    return np.where(log, np.log(np.where(log, lo, 1.0)), lo), np.where(
        log, np.log(np.where(log, hi, 1.0)), hi
    )


def _physical(xp, z, slo, shi, log):
    z = xp.where(z < 0.0, 0.0, xp.where(z > 1.0, 1.0, z))
    s = slo + (shi - slo) * z
    return xp.where(log, xp.exp(xp.where(log, s, 0.0)), s)


def to_physical(z, slo, shi, log):
    """``x(z)``: box position → physical value (``jnp``; differentiable; ``log`` a NumPy mask).

    ``z`` is clamped to ``[0, 1]`` with ``where`` (derivative 1 on the bounds themselves, where
    ``jnp.clip`` would halve it).
    """
    return _physical(jnp, z, slo, shi, log)


def to_physical_host(z, slo, shi, log) -> np.ndarray:
    """:func:`to_physical` in NumPy, for the host-side bookkeeping after a solve (a ``jnp``
    call there would compile a small program of its own in every fresh process)."""
    return _physical(np, np.asarray(z, float), np.asarray(slo, float), np.asarray(shi, float), log)


def to_box(x, slo, shi, log) -> np.ndarray:
    """``z(x)``: physical value → box position (NumPy), clamped to ``[0, 1]``."""
    x = np.asarray(x, float)
    s = np.where(log, np.log(np.where(log, np.maximum(x, 1e-300), 1.0)), x)
    return np.clip((s - slo) / (shi - slo), 0.0, 1.0)


def held_on_bounds(z, g):
    """``(held_lo, held_hi)``: the box coordinates on their lower (upper) bound whose gradient
    ``g`` of the cost points outward, so that a bounded step keeps them there (``jnp``)."""
    return (z <= 0.0) & (g > 0), (z >= 1.0) & (g < 0)


def at_bound(z) -> np.ndarray:
    """``-1`` (lower), ``+1`` (upper) or ``0`` (interior) for each box coordinate."""
    z = np.asarray(z, float)
    return np.where(z <= AT_BOUND_TOL, -1, np.where(z >= 1.0 - AT_BOUND_TOL, 1, 0))
