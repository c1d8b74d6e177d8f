"""Evaluate a registered model on many direction pairs (jitted once, in chunks) → NumPy."""

from __future__ import annotations

import numpy as np

CHUNK = 1 << 18


def evaluate(model, params: dict, wi, wo, chunk: int = CHUNK) -> np.ndarray:
    """``model(params, wi, wo)`` as a NumPy ``(N, 3)`` array; the last chunk is padded so that
    every chunk has the same shape and the function compiles once."""
    import jax
    import jax.numpy as jnp

    full = {k: jnp.asarray(v, dtype=float) for k, v in model.complete(params).items()}
    fn = jax.jit(lambda w1, w2: model.fn(full, w1, w2))
    wi, wo = np.asarray(wi, float).reshape(-1, 3), np.asarray(wo, float).reshape(-1, 3)
    n = len(wi)
    size = min(chunk, max(n, 1))
    out = np.empty((n, 3))
    for start in range(0, n, size):
        stop = min(start + size, n)
        pad = size - (stop - start)
        a = np.concatenate([wi[start:stop], np.tile([[0.0, 0.0, 1.0]], (pad, 1))])
        b = np.concatenate([wo[start:stop], np.tile([[0.0, 0.0, 1.0]], (pad, 1))])
        out[start:stop] = np.asarray(fn(a, b))[: stop - start]
    return out
