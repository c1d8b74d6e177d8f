r"""The error figure printed in every diagnostic title: RMS log ratio of fitted to measured.

.. math::

    E = \sqrt{\frac{1}{3N}\sum_{n,c}
        \left(\ln\frac{f_\text{fit}(n,c) + \varepsilon}{f_\text{meas}(n,c) + \varepsilon}\right)^2}

over valid measurements with both directions above the horizon, ``ε = 1e-3`` BRDF units (about
one quantum of the MERL encoding, 1/1500), so that near-black cells do not dominate. ``E`` is a
typical multiplicative error: ``E = 0.1`` means about 10 %. It is the same quantity the image
slice's ratio panel shows per cell (there in log10). It is a display figure, independent of the
loss a fit minimised; a caller may pass its own text instead (``error=`` in every figure).
"""

from __future__ import annotations

import numpy as np

from ._eval import evaluate_model, is_table, sample_view

#: Floor added to both sides of the ratio (BRDF units).
EPS = 1e-3


def _table_pairs(table, idx):
    from data_formats.merl import cell_angles
    from data_formats.rusinkiewicz import dirs_from_half_diff

    i, j, k = np.unravel_index(idx, np.shape(table.valid))
    wi, wo = dirs_from_half_diff(*cell_angles(i, j, k, np.shape(table.valid)))
    rgb = np.asarray(table.rgb, float)[i, j, k]
    return np.asarray(wi, float), np.asarray(wo, float), rgb


def error_pairs(data, *, max_samples: int = 100_000, seed: int = 0):
    """``(wi, wo, rgb)``: at most ``max_samples`` valid measurements above the horizon (seeded)."""
    rng = np.random.default_rng(seed)
    if is_table(data):
        idx = np.flatnonzero(np.asarray(data.valid, bool))
        if idx.size > max_samples:
            idx = np.sort(rng.choice(idx, max_samples, replace=False))
        wi, wo, rgb = _table_pairs(data, idx)
    else:
        data = sample_view(data)
        ok = np.flatnonzero(np.asarray(data.valid, bool))
        if ok.size > max_samples:
            ok = np.sort(rng.choice(ok, max_samples, replace=False))
        wi, wo, rgb = data.wi[ok], data.wo[ok], np.asarray(data.rgb, float)[ok]
    keep = (wi[:, 2] > 0) & (wo[:, 2] > 0) & np.all(np.isfinite(rgb), axis=-1)
    return wi[keep], wo[keep], rgb[keep]


def log_ratio(fitted, measured, eps: float = EPS):
    """``ln((fitted + ε) / (measured + ε))`` elementwise, negative values clipped to zero first."""
    f = np.clip(np.asarray(fitted, float), 0.0, None)
    m = np.clip(np.asarray(measured, float), 0.0, None)
    return np.log((f + eps) / (m + eps))


def rms_log_error(data, model, params, *, max_samples: int = 100_000, seed: int = 0) -> float:
    """``E`` of the module docstring for ``model(params)`` against ``data`` (NaN if no data)."""
    wi, wo, rgb = error_pairs(data, max_samples=max_samples, seed=seed)
    if len(rgb) == 0:
        return float("nan")
    fitted = evaluate_model(model, params, wi, wo)
    return float(np.sqrt(np.mean(log_ratio(fitted, rgb) ** 2)))


def format_error(value: float) -> str:
    """The title text for an error value."""
    return f"RMS ln-ratio {value:.3g}"
