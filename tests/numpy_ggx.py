"""The ``ggx`` model in plain NumPy, on its flat parameter vector: the independent reference
that the scipy comparisons of ``tests/test_fit_cross.py`` and ``tests/test_fit_realistic.py``
fit (``benchmarks/bench_fit.py`` keeps its own copy: benchmarks do not import the tests)."""

import numpy as np

#: Bounds of ``ggx``'s flat vector (diffuse ×3, f0 ×3, alpha, grazing) for ``least_squares``.
LOWER = np.array([0.0] * 6 + [1e-3, 0.0])
UPPER = np.ones(8)


def ggx_numpy(x, wi, wo):
    """RTR eqs. 9.34, 9.41, 9.42, 9.31, 9.18, 9.61; ``x`` is diffuse (3), f0 (3), alpha, the
    grazing rise ``t`` (``F90 = F0 + (1 − F0) t``)."""
    diffuse, f0, a2 = x[0:3], x[3:6], x[6] ** 2
    f90 = f0 + (1 - f0) * x[7]
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    ci, co, ch = wi[:, 2], wo[:, 2], h[:, 2]
    d = a2 / (np.pi * (1 + (a2 - 1) * ch**2) ** 2)

    def lam(c):
        return 0.5 * (np.sqrt(1 + a2 * (1 - c**2) / c**2) - 1)

    fres = f0 + (f90 - f0) * (1 - np.clip(np.sum(wi * h, axis=1), 0, 1))[:, None] ** 5
    return diffuse / np.pi + fres * (d / (1 + lam(ci) + lam(co)) / (4 * ci * co))[:, None]
