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
  ``G2 ≈ 1``), so ``F0 ≈ 4π α² cos²θd H``. A peak above :data:`NO_PEAK` but lower than
  :data:`FLAT_PEAK` of the diffuse level has no width to read and reads as broad
  (``θ½ = 60°``).
* **anisotropy** ``α_x, α_y`` and the azimuth ``φ_t`` of the ``α_x`` axis: anisotropic GGX
  (RTR eq. 9.53) is ``D ∝ h_z⁻⁴ (1 + sᵀAs)⁻²`` in the half vector's slope
  ``s = (h_x, h_y)/h_z``, ``A = R diag(α_x⁻², α_y⁻²) Rᵀ`` with ``R`` the rotation by ``φ_t``. With
  the lobe's excess ``e`` (channel mean) times ``cos θi cos θo h_z⁴`` (which undoes the
  microfacet denominator and the ``h_z⁻⁴``), ``u = e'^{-1/2} = c₀ (1 + sᵀAs)`` is *linear* in
  ``c₀`` and ``c₀A``: a weighted least-squares fit on the cells of the lobe (``θd < 40°``,
  excess above 5 % of the peak; rows weighted by ``1/u``, i.e. relative error in ``e``) gives
  ``A``, whose eigenvalues are ``α⁻²`` and whose eigenvectors are the axes. The labelling with
  ``|φ_t| ≤ π/4`` is kept (:mod:`brdffit.models.frame`). Where the half vectors do not span
  the azimuths (a MERL table: every half vector in the x–z plane), the system is singular and
  the lobe reads as isotropic (``α_x = α_y = α``, ``φ_t = 0``).

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
    alpha_x: float | None = None  # the widths along the lobe's principal axes (None: alpha)
    alpha_y: float | None = None
    frame_angle: float = 0.0  # azimuth of the alpha_x axis from the data's x axis, |.| <= π/4
    #: whether the data determined the lobe's axes (:func:`anisotropy`): not on a table whose
    #: half vectors lie in one plane (a MERL table, isotropic by construction: ``φh = 0``), nor
    #: on too few cells of the lobe
    axes: bool = False

    def __post_init__(self):
        for name in ("alpha_x", "alpha_y"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, float(self.alpha))

    @property
    def isotropic(self) -> bool:
        """The lobe shows no anisotropy: its axes undetermined, or its widths equal."""
        return not self.axes or self.alpha_x == self.alpha_y

    def axis_widths(self) -> tuple[float, float]:
        r"""The lobe's widths along the data's own ``x`` and ``y`` axes, for a model whose
        tangent is the data's ``x`` (no ``frame_angle``): the square roots of the diagonal of
        the slope covariance :math:`R\,\mathrm{diag}(\alpha_x^2, \alpha_y^2)\,R^\top`
        (``R`` the turn by ``frame_angle``). An anisotropic GGX lobe's slope density is
        constant on the ellipses :math:`s^\top A^{-1} s = c` of that matrix ``A``; these widths
        are the ellipses' extent along each axis, so an axis-aligned lobe of these widths
        spreads as far along ``x`` and ``y`` as the turned one. Equal to ``(α_x, α_y)`` at
        ``frame_angle = 0``, and to ``(α, α)`` for an isotropic lobe."""
        c, s = np.cos(self.frame_angle), np.sin(self.frame_angle)
        ax2, ay2 = self.alpha_x ** 2, self.alpha_y ** 2
        return (float(np.sqrt(c * c * ax2 + s * s * ay2)),
                float(np.sqrt(s * s * ax2 + c * c * ay2)))


def _angles(wi, wo):
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1.0, 1.0))
    theta_d = np.arccos(np.clip(np.sum(wi * h, axis=1), -1.0, 1.0))
    return theta_h, theta_d


#: The half width of a peak whose excess never halves within the bins (and of a low peak,
#: :data:`FLAT_PEAK`): a broad lobe, ``α`` on the upper end of :data:`ALPHA_RANGE`.
BROAD_HALF_WIDTH = np.radians(60.0)


def _half_width(theta_h, excess, height):
    """``θh`` where the binned median of the (channel-mean) excess first drops below ``H/2``."""
    edges = np.concatenate([[0.0], np.geomspace(2e-4, np.radians(80.0), 64)])
    idx = np.digitize(theta_h, edges) - 1
    for b in range(len(edges) - 1):
        sel = idx == b
        if np.count_nonzero(sel) >= 3 and np.median(excess[sel]) < 0.5 * height:
            return 0.5 * (edges[b] + edges[b + 1])
    return BROAD_HALF_WIDTH


#: The least peak height :func:`measure` reports (where the cells nearest the mirror direction are
#: not above the diffuse level).
NO_PEAK = 1e-6
#: A peak lower than this fraction of the diffuse level ``ρ_d/π`` (channel means) has no width
#: that :func:`measure` can read: its excess is within the scatter of the cells, so the first
#: bin's median is already below half of it and the width would read as the narrowest one
#: (``α`` 0.002, on fabrics and foam). Such a lobe is read as broad instead (``θh`` 60°, the
#: width of a peak whose excess never halves). A table with no excess at all (every channel at
#: :data:`NO_PEAK`: a constant or Lambertian table) keeps the narrow reading: a narrow lobe
#: touches the fewest cells, so a lobe the data do not ask for vanishes (``F0 → 0``) without
#: moving the rest, and its width stays where it started, not identified. The realistic
#: corpus's peaks are either below 0.1 of the diffuse level (six fabrics and a foam,
#: 0.0001–0.09) or above 0.15.
FLAT_PEAK = 0.1

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
    height = np.maximum(np.median(excess[near][order], axis=0), NO_PEAK)
    if np.any(height > NO_PEAK) and height.mean() < FLAT_PEAK * diffuse.mean() / np.pi:
        theta_half = BROAD_HALF_WIDTH  # a low peak: no width to read
    else:
        theta_half = _half_width(theta_h[near], excess[near].mean(axis=1), height.mean())
    alpha = float(np.clip(np.tan(theta_half) / GGX_HALF_WIDTH, *ALPHA_RANGE))
    cos_d = np.cos(np.median(theta_d[near][order]))
    f0 = np.clip(4 * np.pi * alpha**2 * cos_d**2 * height, 0.01, 0.95)
    aniso = anisotropy(excess.mean(axis=1)[near], wi[near], wo[near], float(height.mean()))
    if aniso is None:
        return Features(diffuse, height, alpha, f0)
    return Features(diffuse, height, alpha, f0, *aniso, axes=True)


#: The widths :func:`anisotropy` reports are clipped to this range (as ``alpha``).
ALPHA_RANGE = (2e-3, 0.9)
#: Fewest lobe cells, and the smallest ratio of the least to the largest singular value of
#: the (column-normalized) system, for which :func:`anisotropy` trusts its solution.
ANISO_MIN_CELLS, ANISO_MIN_SINGULAR = 20, 1e-3


def anisotropy(excess, wi, wo, height: float):
    """``(α_x, α_y, φ_t)`` of the lobe (module docstring), or ``None`` where the cells do not
    determine it (too few cells, half vectors in one plane, no positive-definite fit).

    ``excess``: the channel-mean specular excess of each cell; ``height``: the peak's excess
    (sets which cells belong to the lobe)."""
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    hz = h[:, 2]
    lobe = (excess > 0.05 * height) & (hz > 0.2) & (wi[:, 2] > 0) & (wo[:, 2] > 0)
    if np.count_nonzero(lobe) < ANISO_MIN_CELLS:
        return None
    e = excess[lobe] * wi[lobe, 2] * wo[lobe, 2] * hz[lobe] ** 4
    sx, sy = h[lobe, 0] / hz[lobe], h[lobe, 1] / hz[lobe]
    u = 1.0 / np.sqrt(e)
    design = np.stack([np.ones_like(sx), sx * sx, 2.0 * sx * sy, sy * sy], axis=1) / u[:, None]
    scale = np.linalg.norm(design, axis=0)
    if np.any(scale == 0) or not np.all(np.isfinite(design)):
        return None
    sol, _, _, sing = np.linalg.lstsq(design / scale, np.ones_like(u), rcond=None)
    if sing[-1] < ANISO_MIN_SINGULAR * sing[0]:
        return None
    c0, axx, axy, ayy = sol / scale
    if not c0 > 0:
        return None
    lam, vec = np.linalg.eigh(np.array([[axx, axy], [axy, ayy]]) / c0)
    if not np.all(lam > 0):
        return None
    widths = np.clip(1.0 / np.sqrt(lam), *ALPHA_RANGE)  # eigh: ascending λ, so widest first
    angle = float(np.arctan2(vec[1, 0], vec[0, 0]))
    angle = (angle + np.pi / 2) % np.pi - np.pi / 2  # the axis, in [-π/2, π/2)
    ax, ay = float(widths[0]), float(widths[1])
    if abs(angle) > np.pi / 4:  # the other labelling: axes swapped, a quarter turn
        angle -= np.copysign(np.pi / 2, angle)
        ax, ay = ay, ax
    return ax, ay, angle


def by_name(feat: Features) -> dict:
    """The features by parameter name: the start of a model without a start hook."""
    return {
        "diffuse": feat.diffuse,
        "f0": feat.f0,
        "alpha": feat.alpha,
        "alpha_x": feat.alpha_x,
        "alpha_y": feat.alpha_y,
        "frame_angle": feat.frame_angle,
        "alpha_1": feat.alpha,
        "alpha_2": min(0.9, 4.0 * feat.alpha),
    }


def guess(model, feat: Features) -> dict:
    """A starting parameter dict for ``model`` from measured :class:`Features`: its start hook's
    values (``model.start``) or :func:`by_name`, each moved inside its bounds by a margin of
    1e-3 of the range in the coordinate the fit uses (``log`` for a log parameter: a margin of
    the linear range would put a start no lower than 1e-3 of the upper bound)."""
    values = model.start(feat) if model.start is not None else by_name(feat)
    out = {}
    for p in model.params:
        if p.name in values:
            v = np.broadcast_to(np.asarray(values[p.name], float), p.shape)
            if p.log:
                ratio = (p.upper / p.lower) ** 1e-3
                out[p.name] = np.clip(v, p.lower * ratio, p.upper / ratio)
            else:
                width = p.upper - p.lower
                out[p.name] = np.clip(v, p.lower + 1e-3 * width, p.upper - 1e-3 * width)
    return out


def start_point(model, features: Features, scalars, x0, init=None) -> np.ndarray:
    """The flat starting vector: ``x0`` (defaults and fixed values) with the free scalars at the
    data-driven :func:`guess` from ``features`` (:func:`measure` of the selected cells), then
    the user's ``init`` (name → value, or a previous ``FitResult``) on top; fixed scalars keep
    their values."""
    start = model.flatten(guess(model, features))
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
