"""Lit spheres (Burley 2012 §3.2, the BRDF Explorer's lit-sphere view), measured beside fitted.

A unit sphere seen orthographically along ``−z`` (viewer at ``+z``, image ``x`` to the right,
``y`` up) under one directional light of unit irradiance at normal incidence. Each pixel inside the
disc has the normal ``n = (x, y, sqrt(1 − x² − y²))``; the shading frame is Duff et al. 2017's
branchless orthonormal basis around ``n`` (only anisotropic models see its tangent). The linear
radiance is

    ``L = f_r(wi, wo) · max(0, cos θi)``,  ``wi`` the light and ``wo = (0, 0, 1)`` in that frame,

so a Lambertian surface of albedo ρ gives ``ρ/π · max(0, n·l)``. Pixels where the light or the
viewer is below the local horizon, the background and lookups without data are black (the
measured panel's dark silhouette, like Burley 2012 Fig. 4's black region); a thin grey circle
marks the sphere's outline. Display: one logarithmic tone mapping of the luminance for both
panels (:func:`._style.log_tonemap`; the median of the measured lit pixels at 0.4, their
99.9th percentile at white), so a shiny material's diffuse body is visible beside its
highlight (an exposure set by the highlight left a gold paint black apart from it).
"""

from __future__ import annotations

import numpy as np
from matplotlib.patches import Circle

from . import _style
from ._eval import data_name, evaluate_model, is_table, measured_lookup

#: Default light: 45° from the view direction, towards the top of the image.
DEFAULT_LIGHT = (0.0, np.sin(np.pi / 4), np.cos(np.pi / 4))


def _onb(n):
    """Tangent and bitangent of unit normals ``n`` ``(..., 3)`` (Duff et al. 2017, Listing 3)."""
    sign = np.where(n[..., 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], -1)
    s = np.stack([b, sign + n[..., 1] ** 2 * a, -n[..., 1]], -1)
    return t, s


def sphere_directions(size: int = 256, light_dir=DEFAULT_LIGHT):
    """``(inside (S, S) bool, n, wi, wo)`` for the pixels of the image (row 0 at the top).

    ``n`` is the world normal, ``wi``/``wo`` the light/view directions in each pixel's shading
    frame, all ``(S, S, 3)`` (arbitrary where not ``inside``).
    """
    light = np.asarray(light_dir, float)
    light = light / np.linalg.norm(light)
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    r2 = x**2 + y**2
    inside = r2 < 1.0
    n = np.stack([x, y, np.sqrt(np.clip(1.0 - r2, 0.0, None))], -1)
    n = np.where(inside[..., None], n, np.array([0.0, 0.0, 1.0]))
    t, s = _onb(n)
    to_local = lambda v: np.stack([t @ v, s @ v, n @ v], -1)  # noqa: E731
    return inside, n, to_local(light), to_local(np.array([0.0, 0.0, 1.0]))


#: The sides of the image, counter-clockwise from the right, in 45° sectors.
SIDES = ("right", "top right", "top", "top left", "left", "bottom left", "bottom", "bottom right")


def light_side(light) -> str:
    """Where a light direction ``(x, y, z)`` (unit, image ``x`` right, ``y`` up) comes from, in
    words: ``"from the top of the image"``, or ``"on the view axis"``."""
    x, y = float(light[0]), float(light[1])
    if np.hypot(x, y) < 1e-6:
        return "on the view axis"
    return f"from the {SIDES[int(np.round(np.degrees(np.arctan2(y, x)) / 45.0)) % 8]} of the image"


def render_sphere(f, size: int = 256, light_dir=DEFAULT_LIGHT) -> np.ndarray:
    """Linear radiance ``(S, S, 3)`` of the sphere shaded with ``f(wi, wo) -> rgb`` (NumPy, N×3).

    ``f`` is called only for pixels where light and viewer are both above the local horizon;
    NaN results (no data) become 0.
    """
    inside, _, wi, wo = sphere_directions(size, light_dir)
    lit = inside & (wi[..., 2] > 0) & (wo[..., 2] > 0)
    out = np.zeros((size, size, 3))
    if lit.any():
        vals = np.asarray(f(wi[lit], wo[lit]), float) * wi[lit][:, 2:3]
        out[lit] = np.nan_to_num(vals, nan=0.0)
    return out

def figure_size(fitted: bool) -> tuple[float, float]:
    """``(width, height)`` in inches of the sphere figure, one or two spheres."""
    return 4.1 * (2 if fitted else 1), 4.6


def plot_spheres(data, model=None, params=None, *, size: int = 256, light_dir=DEFAULT_LIGHT,
                 error: str | None = None, title: str | None = None, fig=None):
    """The lit-sphere figure: measured (table lookup / nearest sample) beside the fit, if any;
    drawn into ``fig`` (a figure or sub-figure) when given, else a new figure."""
    meas = render_sphere(measured_lookup(data), size, light_dir)
    how = ("trilinear table lookup" if is_table(data)
           else "evaluated" if callable(getattr(data, "eval", None)) else "nearest sample")
    images = [(f"measured ({how})", meas)]
    if model is not None:
        fitted = render_sphere(lambda wi, wo: evaluate_model(model, params, wi, wo), size,
                               light_dir)
        images.append(("fitted (same tone mapping)", fitted))
    inside, _, wi, wo = sphere_directions(size, light_dir)
    lit = inside & (wi[..., 2] > 0) & (wo[..., 2] > 0)
    levels = _style.log_levels(meas[lit])
    fig = _style.new_figure(*figure_size(len(images) > 1), fig)
    axes = np.atleast_1d(fig.subplots(1, len(images)))
    for ax, (label, img) in zip(axes, images):
        ax.imshow(_style.log_tonemap(img, *levels), interpolation="antialiased",
                  extent=(-1, 1, -1, 1))
        ax.add_patch(Circle((0, 0), 1.0, fill=False, lw=0.6, ec=(0.35, 0.35, 0.35)))
        ax.set_title(label, fontsize=10)
        ax.set_axis_off()
    light = np.asarray(light_dir, float) / np.linalg.norm(light_dir)
    elev = np.degrees(np.arccos(np.clip(light[2], -1, 1)))
    fig.supxlabel(f"directional light {elev:.0f}° off the view axis, {light_side(light)}; "
                  f"{_style.tonemap_label(*levels)}", fontsize=8)
    name = getattr(model, "name", model) if model is not None else None
    fig.suptitle(title or _style.figure_title(data_name(data), name, error, "Lit sphere"))
    return fig
