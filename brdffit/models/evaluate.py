"""Evaluate a model on many NumPy direction pairs: compiled once per model, run in chunks.

The one place that turns ``model(params, wi, wo)`` into a NumPy array for whole grids (fitted
tables, synthetic tables, figures). Parameters are arguments of the compiled function, not
constants, and every chunk has the same padded shape, so any batch size and any parameter
values reuse one compilation per model; memory stays bounded by the chunk size.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import numpy as np

#: Directions evaluated per compiled call; the last chunk is padded to this size.
CHUNK = 32768


@functools.lru_cache(maxsize=None)
def _compiled(parts: tuple) -> tuple:
    """``jax.jit`` of each function of ``parts``: one compile per model function and shape.

    A pure function of the (hashable) model functions, memoised: a call gives what a fresh
    ``jax.jit`` would, the memo only keeps JAX's compilations for the next call. One entry per
    model function (the registered models, and those a caller builds)."""
    import jax

    return tuple(jax.jit(f) for f in parts)


def _jitted(model):
    """The compiled pieces of ``model``: ``(jit(fn),)``, or ``(jit(prepare), jit(per_pair),
    jit(combine))`` for a model with ``stages``."""
    return _compiled(tuple(model.stages or (model.fn,)))


def evaluate_model(model, params: Mapping | None, wi, wo, *, chunk: int = CHUNK) -> np.ndarray:
    """RGB ``f_r`` of ``model`` with ``params`` at directions ``wi, wo`` ``(..., 3)``: ``(..., 3)``.

    Missing parameters take the model's defaults. Evaluation runs in chunks of ``chunk``
    directions; padding uses the pair ``(z, z)`` so it never produces NaN. The dtype follows JAX's
    setting (float64 when the caller enabled ``jax_enable_x64``). A model with ``stages``
    (:class:`~brdffit.models.registry.Model`) is prepared once (its tables built once), then each
    chunk runs its two per-pair programs.
    """
    import jax.numpy as jnp

    from .registry import get_model

    model = get_model(model)
    full = {k: jnp.asarray(np.asarray(v, dtype=float)) for k, v in model.complete(params).items()}
    parts = _jitted(model)
    if len(parts) == 3:
        prepare, per_pair, combine = parts
        state = prepare(full)

        def fn(a, b):
            return combine(state, per_pair(state, a, b))
    else:
        (whole,) = parts

        def fn(a, b):
            return whole(full, a, b)

    wi, wo = np.asarray(wi, dtype=float), np.asarray(wo, dtype=float)
    batch = np.broadcast_shapes(wi.shape, wo.shape)[:-1]
    wi = np.broadcast_to(wi, batch + (3,)).reshape(-1, 3)
    wo = np.broadcast_to(wo, batch + (3,)).reshape(-1, 3)
    n = len(wi)
    out = np.empty((n, 3))
    pad = np.zeros((chunk, 3))
    pad[:, 2] = 1.0
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        a, b = pad.copy(), pad.copy()
        a[:m], b[:m] = wi[start : start + m], wo[start : start + m]
        out[start : start + m] = np.asarray(fn(jnp.asarray(a), jnp.asarray(b)))[:m]
    return out.reshape(batch + (3,))
