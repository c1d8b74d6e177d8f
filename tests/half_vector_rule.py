"""The tests' independent albedo quadrature over half vectors (not library code).

``∫ f(wi, wo) cosθo dωo`` is integrated over the half vector ``h`` with ``dωo = 4 (wo·h) dωh``,
``θh`` warped as ``(π/2)u²`` (the MERL warp, which resolves narrow peaks) and the midpoint rule
in ``u`` and ``φh``. Used by the energy tests of the models, the Disney lobes and APS.
"""

from __future__ import annotations

import numpy as np


def half_vector_rule(theta_i, n_th, n_ph, phi_i=0.0):
    """``(wi, wo, weight)``, each on the ``(n_th, n_ph)`` grid (``wi`` broadcast), such that the
    albedo at incidence ``(θi, φi)`` is ``Σ f(wi, wo) · weight``; ``weight`` is 0 where ``wo``
    falls below the horizon."""
    u = (np.arange(n_th) + 0.5) / n_th
    th, dth = 0.5 * np.pi * u**2, np.pi * u / n_th
    ph = (np.arange(n_ph) + 0.5) / n_ph * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1)
    wi = np.array([np.sin(theta_i) * np.cos(phi_i), np.sin(theta_i) * np.sin(phi_i), np.cos(theta_i)])
    hw = h @ wi
    wo = 2 * hw[..., None] * h - wi
    ok = (wo[..., 2] > 0) & (hw > 0)
    weight = np.where(ok, wo[..., 2] * 4 * hw, 0.0) * np.sin(TH) * dth[:, None] * (2 * np.pi / n_ph)
    return np.broadcast_to(wi, wo.shape), wo, weight
