r"""Data-driven starting points: diffuse level, specular peak height and width.

Measured features (NumPy, on the selected valid cells; ``θh`` the half angle, ``θd`` the
difference angle, Rusinkiewicz 1998):

* **diffuse level** ``ρ_d`` (RGB): ``π`` times the median of cells far from the peak
  (``40° ≤ θh ≤ 70°``, both directions within 60° of the normal);
* **peak height** ``H`` (RGB): the specular excess ``ρ - ρ_d/π`` of the cells nearest ``θh = 0``
  (``θd < 40°``, so Fresnel is still near ``F0``);
* **peak width** ``θ½``: the half angle where the excess falls to ``H/2``. For GGX
  (RTR eq. 9.41) ``D(θh)/D(0) = 1/2`` at ``tan²θh = α²(√2 − 1)``, so
  ``α ≈ tan θ½ / 0.6436``; at the peak ``f ≈ F0 D(0) / (4 cos²θd)`` (RTR eq. 9.34 with
  ``G2 ≈ 1``), so ``F0 ≈ 4π α² cos²θd H``.

A model maps these features onto its parameters itself when it declares a start hook
(``Model.start``, e.g. Disney's ``base_color``/``metallic``/``roughness``/``specular``);
otherwise they are mapped by parameter name (``diffuse``, ``f0*``, ``alpha*``). Any parameter
the map does not name keeps its declared default. The maps are conventions, not formulas of the
sources, and only a starting point for the solver; the user's ``init`` goes on top
(:func:`start_point`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .parameters import assign, check_within

GGX_HALF_WIDTH = np.sqrt(np.sqrt(2.0) - 1.0)


@dataclasses.dataclass(frozen=True)
class Features:
    """What :func:`measure` reads off the data (all positive, in physical units)."""

    diffuse: np.ndarray  # albedo ρ_d, RGB
    height: np.ndarray  # specular excess at the peak, RGB
    alpha: float  # GGX-equivalent roughness from the peak width
    f0: np.ndarray  # Schlick F0 from height and width, RGB


def _angles(wi, wo):
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1.0, 1.0))
    theta_d = np.arccos(np.clip(np.sum(wi * h, axis=1), -1.0, 1.0))
    return theta_h, theta_d


def _half_width(theta_h, excess, height):
    """``θh`` where the binned median of the (channel-mean) excess first drops below ``H/2``."""
    edges = np.concatenate([[0.0], np.geomspace(2e-4, np.radians(80.0), 64)])
    idx = np.digitize(theta_h, edges) - 1
    for b in range(len(edges) - 1):
        sel = idx == b
        if np.count_nonzero(sel) >= 3 and np.median(excess[sel]) < 0.5 * height:
            return 0.5 * (edges[b] + edges[b + 1])
    return np.radians(60.0)


#: ``measure`` reads at most this many cells (a fixed, evenly strided subset) plus the
#: cells nearest the peak, so that a full table costs milliseconds.
MEASURE_CELLS = 100_000


def _thin(wi, wo, good) -> np.ndarray:
    """Valid row indices: an even stride through the rows plus the 200 valid rows nearest the
    peak (all valid rows if there are few)."""
    n = len(wi)
    if np.count_nonzero(good) <= MEASURE_CELLS:
        return np.flatnonzero(good)
    # cos²θh = (wi_z + wo_z)² / |wi + wo|², |wi + wo|² = 2 (1 + wi·wo) for unit vectors
    hz = wi[:, 2] + wo[:, 2]
    hz2 = hz * hz / np.maximum(2.0 + 2.0 * np.einsum("ij,ij->i", wi, wo), 1e-300)
    hz2[~good] = -1.0
    peak = np.argpartition(hz2, n - 200)[n - 200 :]  # largest cos²θh
    mask = np.zeros(n, bool)
    mask[:: max(1, n // MEASURE_CELLS)] = True
    mask[peak] = True
    return np.flatnonzero(mask & good)


def measure(rgb, wi, wo, good) -> Features:
    """Read diffuse level, peak height and width off valid cells (see the module docstring)."""
    keep = _thin(wi, wo, good)
    rgb, wi, wo = rgb[keep], wi[keep], wo[keep]
    theta_h, theta_d = _angles(wi, wo)
    far = (theta_h > np.radians(40)) & (theta_h < np.radians(70))
    far &= (wi[:, 2] > 0.5) & (wo[:, 2] > 0.5)
    base = rgb[far] if np.count_nonzero(far) >= 10 else rgb
    diffuse = np.clip(np.pi * np.median(base, axis=0), 1e-3, 0.95)
    excess = rgb - diffuse / np.pi
    near = theta_d < np.radians(40)
    if np.count_nonzero(near) < 10:
        near = np.ones(len(rgb), bool)
    order = np.argsort(theta_h[near])[:5]
    height = np.maximum(np.median(excess[near][order], axis=0), 1e-6)
    theta_half = _half_width(theta_h[near], excess[near].mean(axis=1), height.mean())
    alpha = float(np.clip(np.tan(theta_half) / GGX_HALF_WIDTH, 2e-3, 0.9))
    cos_d = np.cos(np.median(theta_d[near][order]))
    f0 = np.clip(4 * np.pi * alpha**2 * cos_d**2 * height, 0.01, 0.95)
    return Features(diffuse, height, alpha, f0)


def by_name(feat: Features) -> dict:
    """The features by parameter name: the start of a model without a start hook."""
    return {
        "diffuse": feat.diffuse,
        "f0": feat.f0,
        "alpha": feat.alpha,
        "alpha_x": feat.alpha,
        "alpha_y": feat.alpha,
        "alpha_1": feat.alpha,
        "alpha_2": min(0.9, 4.0 * feat.alpha),
    }


def guess(model, feat: Features) -> dict:
    """A starting parameter dict for ``model`` from measured :class:`Features`: its start hook's
    values (``model.start``) or :func:`by_name`, each moved inside its bounds by a margin of
    1e-3 of the range."""
    values = model.start(feat) if model.start is not None else by_name(feat)
    out = {}
    for p in model.params:
        if p.name in values:
            v = np.broadcast_to(np.asarray(values[p.name], float), p.shape)
            width = p.upper - p.lower
            out[p.name] = np.clip(v, p.lower + 1e-3 * width, p.upper - 1e-3 * width)
    return out


def start_point(model, host, scalars, x0, init=None) -> np.ndarray:
    """The flat starting vector: ``x0`` (defaults and fixed values) with the free scalars at the
    data-driven :func:`guess` on the selected cells ``host`` (``(wi, wo, rgb, good)``), then the
    user's ``init`` (name → value, or a previous ``FitResult``) on top; fixed scalars keep their
    values."""
    wi, wo, rgb, good = host
    start = model.flatten(guess(model, measure(rgb, wi, wo, good)))
    free = list(scalars.free)
    x = x0.copy()
    x[free] = start[free]
    if init is not None:
        user = x.copy()
        idx = assign(model, getattr(init, "params", init), user, "init value of")
        check_within(model, user, scalars.lo, scalars.hi, idx, "init")
        held = set(scalars.fixed)
        keep = [i for i in idx if i not in held]
        x[keep] = user[keep]
    return x
