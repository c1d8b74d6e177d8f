r"""Directional albedo against incidence angle (Burley 2012 §4.4, Fig. 11), measured and fitted.

The directional-hemispherical reflectance

.. math::

    \rho(\omega_i) = \int_{H^2} f_r(\omega_i, \omega_o)\,\cos\theta_o\,d\omega_o

is integrated in **half-vector space**: ``wo = 2 (wi·h) h − wi`` with ``dωo = 4 (wi·h) dωh``
(RTR eq. 9.33's half vector; the Jacobian of reflection), over ``h`` in the upper hemisphere, with
the integrand masked to ``wo`` above the horizon and ``wi·h > 0``. Around the normal the specular
peak sits at ``θh = 0`` for *every* incidence angle, so a grid dense near ``θh = 0`` resolves
sharp lobes at all θi. The grid: ``θh = 90°·u²`` (MERL's warp), ``u`` by composite Gauss–Legendre
(half the nodes on ``[0, 0.3]``, half on ``[0.3, 1]``), ``φh`` by the midpoint rule (spectrally
accurate for a periodic integrand), weight ``sin θh · π u du dφh``. The integrand carries the
factors ``cos θo`` and ``wi·h``, which vanish on the masked boundaries, so it is continuous there.

Accuracy with the defaults (64 × 128 nodes per θi), as measured when this was written:
a synthesized Lambertian MERL table (trilinear lookup) gives ρ within 4e-4 at 45 angles from 0°
to 89°, the analytic Lambert model within 1.4e-4; the registry's ``ggx`` (α = 0.15, 0.5) agrees
with an independent Gauss–Legendre integral over ``ωo`` (400 × 400; 250 × 250 in the test)
within 1.6e-4 at θi = 0°, 40°, 70° (``tests/test_plots.py`` asserts 2e-3, 1e-3, 1e-3). Against
a 512 × 1024 grid of the same kind the default grid is within 5e-4 for α from 0.002 to 0.5 at
every θi up to 89°: a direct ``ωo`` grid needs thousands of nodes per axis for α = 0.02 near
grazing, this one does not.
The *measured* albedo of a table synthesized from ``ggx`` agrees with the model's within 1e-3 up
to θi = 70° for α ≥ 0.02; towards grazing the table's resolution shows (θi = 89°: +5e-4 at
α = 0.5, +8e-3 at α = 0.1, +8e-2 at α = 0.02): that is the data's limit, not the quadrature's.

The grid and the quadrature are :mod:`brdffit.models.albedo`'s (the plausibility check of
every fit uses them too). The azimuth of incidence is ``φi = 0`` (the x–z plane), which matters only for anisotropic models.
Measured albedo uses :func:`._eval.measured_lookup` (trilinear lookup in a table, nearest sample
in a sample set); a node without data contributes nothing, and an angle where the cosine-weighted
solid angle with data (the *coverage*) is below ``min_coverage`` is reported as NaN.
"""

from __future__ import annotations

import numpy as np

from ..models.albedo import half_vector_grid, quadrature as _quadrature
from . import _style
from ._eval import data_name, evaluate_model, measured_lookup

__all__ = ["THETA_I_DEG", "directional_albedo", "figure_size", "half_vector_grid",
           "measured_albedo", "model_albedo", "plot_albedo"]

#: Default incidence angles (degrees).
THETA_I_DEG = np.linspace(0.0, 89.0, 45)


def directional_albedo(f, theta_i_deg=THETA_I_DEG, *, n_u: int = 64, n_phi: int = 128):
    """``(albedo (T, 3), coverage (T,))`` of ``f(wi, wo) -> rgb`` at incidence ``theta_i_deg``.

    ``f`` takes NumPy ``(N, 3)`` arrays and returns ``(N, 3)``; NaN marks "no data" and counts
    as zero in the albedo and as missing in the coverage (the fraction of ``π``, the cosine-weighted
    hemisphere, that had data).
    """
    wi, wo, weight = _quadrature(theta_i_deg, n_u, n_phi)
    vals = np.asarray(f(wi.reshape(-1, 3), wo.reshape(-1, 3)), float).reshape(wo.shape)
    have = np.all(np.isfinite(vals), axis=-1)
    albedo = np.einsum("tm,tmc->tc", weight, np.where(have[..., None], vals, 0.0))
    coverage = np.sum(weight * have, axis=-1) / np.sum(weight, axis=-1)
    return albedo, coverage


def model_albedo(model, params, theta_i_deg=THETA_I_DEG, **grid):
    """Directional albedo ``(T, 3)`` of a model (see :func:`directional_albedo`)."""
    return directional_albedo(lambda wi, wo: evaluate_model(model, params, wi, wo),
                              theta_i_deg, **grid)[0]


def measured_albedo(data, theta_i_deg=THETA_I_DEG, *, min_coverage: float = 0.9, **grid):
    """Directional albedo ``(T, 3)`` of measured data; NaN where coverage < ``min_coverage``."""
    albedo, coverage = directional_albedo(measured_lookup(data), theta_i_deg, **grid)
    return np.where((coverage >= min_coverage)[:, None], albedo, np.nan)

def figure_size() -> tuple[float, float]:
    """``(width, height)`` in inches of the albedo figure."""
    return 7.0, 4.6


def plot_albedo(data, model=None, params=None, *, theta_i_deg=THETA_I_DEG, error: str | None = None,
                title: str | None = None, fig=None):
    """The albedo figure: ρ(θi) per RGB channel, measured (markers) and fitted (lines); drawn
    into ``fig`` (a figure or sub-figure) when given, else a new figure. Returns the figure."""
    theta_i_deg = np.asarray(theta_i_deg, float)
    meas = measured_albedo(data, theta_i_deg)
    fit = None if model is None else model_albedo(model, params, theta_i_deg)
    fig = _style.new_figure(*figure_size(), fig)
    ax = fig.subplots()
    for c, (color, ch) in enumerate(zip(_style.CHANNEL_COLORS, _style.CHANNEL_NAMES)):
        ax.plot(theta_i_deg, meas[:, c], "o" if fit is not None else "o-", ms=3.5, mfc="none",
                lw=0.6, color=color, label=f"{ch} measured")
        if fit is not None:
            ax.plot(theta_i_deg, fit[:, c], "-", lw=1.5, color=color, label=f"{ch} fitted")
    ax.set_xlim(0, 90)
    ax.set_xticks(range(0, 91, 15), [f"{t}°" for t in range(0, 91, 15)])
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("incidence angle θi")
    ax.set_ylabel("directional albedo  ∫ f_r cos θo dωo")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, ncol=3 if fit is not None else 1, loc="best")
    name = getattr(model, "name", model) if model is not None else None
    fig.suptitle(title or _style.figure_title(data_name(data), name, error, "Directional albedo"))
    return fig
