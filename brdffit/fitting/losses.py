r"""Residual weightings: how a model's ``f_r`` is compared with a measured one, cell by cell.

Every loss turns a measured value ``ρ`` and a predicted value ``ρ̂`` (both ``f_r``, no cosine)
into a residual

.. math::

    r = w(\rho, \cos\theta_i, \cos\theta_o)\,\bigl(g(\hat\rho) - g(\rho)\bigr)

and the fitter minimises :math:`\tfrac12\sum r^2` over the cells and the three channels. ``g`` is
applied to the data once (the fitter stores ``g(ρ)``), so each loss is two tiny pure functions.

========== ==================================== ===============================================
name       ``g(ρ)`` / weight                     use
========== ==================================== ===============================================
linear     ``ρ``                                 plain least squares; dominated by the peak
cosine     ``ρ cosθi cosθo``                     radiance-like weighting, tames grazing cells
log        ``log(1 + ρ cosθi)``                  the default; Löw et al. 2012 style
relative   ``ρ``, weight ``1/max(ρ, floor)``     every cell counts by its relative error
cosine-in  ``ρ cosθi``                           Ngan et al. 2005's and Löw et al. 2012's E1
========== ==================================== ===============================================

``cosine-in`` is the residual of the cosine-weighted L2 errors of the MERL-fitting studies
(Ngan, Durand & Matusik 2005; Löw et al. 2012's E1), ``(ρ̂ - ρ) cosθi``, as the BSDF benchmark
project transcribes them (``bsdfbenchmark/bbm``, ``include/loss/cosine_weighted_l2.h``:
``nganL2_error`` and ``lowL2_error``); ``log`` is Löw et al. 2012's E2 residual
(``include/loss/cosine_weighted_log.h``, ``lowLog_error``). Those studies weight each sample by
its solid angle (bbm's ``sinθi sinθo`` sample weights): the option ``weighting="solid-angle"``
(:mod:`brdffit.fitting.data`), which the presets of their protocols set.

A new loss is one :class:`Loss` entry of :data:`LOSSES`. This module imports no JAX when it is
imported (the functions that run inside a fit import ``jax.numpy`` when first called), so the
command line lists the registry in its ``--loss`` help (:data:`brdffit.config.OPTIONS`) without
importing JAX.

A robust variant of any loss (``huber=δ``) replaces ``r`` beyond ``|r| > δ`` by
``sign(r) sqrt(2δ|r| - δ²)``, so that ``r²/2`` becomes Huber's ``δ|r| - δ²/2`` there.

``log`` is the default: ``log(1 + ρ cosθi)`` compresses the peak to a few units and is linear
(``≈ ρ cosθi``) on the diffuse floor, so both regions count, and the cosine down-weights the
grazing cells that Burley 2012 §4.7 calls extrapolated. It is the weighting of the MERL fitting
literature (Löw et al. 2012, "BRDF models for accurate and efficient rendering of glossy
surfaces"; a citation from outside the seed texts, which do not cover fitting losses). On a
real-like table (a sharp lobe over a weak broad one and a diffuse floor, noise, wild cells)
``log`` finds the sharp lobe from either start; under ``linear`` the peak cells decide and the
diffuse level collapses; ``cosine`` converges elsewhere from a second start; ``relative`` lets
wild and grazing cells pull ``F0`` to its bound. ``tests/test_fit_cross.py`` keeps the evidence.

The default stays ``log`` on the measured materials too, over the cells with ``θi, θo ≤ 80°``
(the default ``cutoff``, :data:`brdffit.config.DEFAULT_CUTOFF`: scored on identical cells in
the literature's metrics, that fit is better than one over every cell in each metric over
``θ ≤ 80°`` and in the peak, ``docs/compare.md``). Against the published Cook–Torrance roughness of 69 MERL materials,
two things moved the ``beckmann`` fits: the Fresnel term's grazing value (a free ``F90``,
:mod:`brdffit.models.standard`: 36% → 78% within a factor 1.5) and how the cells count
against each other (each MERL cell weighted by its width in ``θh``, which undoes the
format's warp towards the peak: 78% → 91%, the default ``weighting="angles"`` of
:mod:`brdffit.fitting.data`). The loss itself did not: with ``F90`` free, an 80° cutoff
lowers that figure (measured on every cell's weighting before it became the default: to 70%;
on 12 realistic materials with the default cells: 10 within the factor against 11 on every
cell, the broad lobes of paints and plastics end narrower, the sharp ones nearer the
published values), and the ``cosine`` loss and Ngan 2005's linear ``ρ cosθi`` residual make
sharp lobes 4–5× too narrow.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable

import numpy as np

from ..errors import ConfigError, UnknownNameError, canonical_name

#: Values below this are not used as the denominator of the relative loss.
RELATIVE_FLOOR = 1e-3


def _identity(f, cos_i, cos_o):
    return f


def _cosine(f, cos_i, cos_o):
    return f * cos_i * cos_o


def _cosine_in(f, cos_i, cos_o):
    return f * cos_i


def _log(f, cos_i, cos_o):
    import jax.numpy as jnp  # here, not above: the registry is read without JAX (module docstring)

    return jnp.log1p(f * cos_i)


def _unit_weight(rho, cos_i, cos_o):
    return np.ones_like(rho)


def _relative_weight(rho, cos_i, cos_o):
    return 1.0 / np.maximum(np.abs(rho), RELATIVE_FLOOR)


def huber_residual(r, delta):
    r"""The residual whose half square is Huber's loss: ``r`` if ``|r| ≤ δ``, else
    ``sign(r) sqrt(2δ|r| - δ²)`` (so that ``r_h²/2 = δ|r| - δ²/2``)."""
    import jax.numpy as jnp

    a = jnp.abs(r)
    big = a > delta
    safe = jnp.where(big, 2.0 * delta * a - delta**2, 1.0)
    return jnp.where(big, jnp.sign(r) * jnp.sqrt(safe), r)


@dataclasses.dataclass(frozen=True)
class Loss:
    """A residual weighting: ``r = weight(ρ) (transform(ρ̂) - transform(ρ))``, optionally Huber.

    ``transform`` and ``weight`` act value by value: channel ``c`` of the residual depends on
    channel ``c`` of the prediction only (the fitter differentiates per-channel parameters with
    one forward-mode product on that assumption, see ``Param.per_channel``).

    Attributes:
        name: registry name.
        transform: ``g(f, cos_i, cos_o)`` in ``jnp`` (applied to data and predictions).
        weight: ``w(ρ, cos_i, cos_o)`` in NumPy (data only, computed once); it multiplies the
            residual, so the cost weight is ``w²``.
        huber: ``None`` or the Huber threshold ``δ`` in residual units.
        description: one line for humans.
        linear: ``transform`` is linear in the prediction, ``g(f) = c(cosθi, cosθo) f``.
    """

    name: str
    transform: Callable = dataclasses.field(repr=False)
    weight: Callable = dataclasses.field(repr=False, default=_unit_weight)
    huber: float | None = None
    description: str = ""
    linear: bool = False

    @property
    def absolute(self) -> bool:
        """The residual is an absolute error of ``f_r`` (times a cosine at most): ``transform``
        linear, no weight from the data. Under such a loss the peak's cells outweigh the whole
        diffuse signal (:mod:`brdffit.fitting.plausibility` says so of a diffuse term at 1)."""
        return self.linear and self.weight is _unit_weight

    @property
    def linear_residual(self) -> bool:
        """The residual is linear in the prediction (a linear ``transform``, no Huber): its
        derivative is the model's times a constant per cell."""
        return self.linear and self.huber is None

    def robust(self, delta: float) -> Loss:
        """The Huber variant of this loss with threshold ``delta`` (residual units)."""
        if not (np.isfinite(delta) and delta > 0):
            raise ConfigError(f"Huber threshold must be a positive number, got {delta!r}")
        return dataclasses.replace(self, huber=float(delta))

    @property
    def label(self) -> str:
        return self.name if self.huber is None else f"{self.name}+huber({self.huber:g})"

    def residual(self, pred, target, sqrt_weight, cos_i, cos_o):
        """Residuals ``(..., 3)`` from predictions, the stored ``g(ρ)`` and the weights."""
        r = sqrt_weight * (self.transform(pred, cos_i, cos_o) - target)
        return r if self.huber is None else huber_residual(r, self.huber)


#: The losses by name.
LOSSES: dict[str, Loss] = {loss.name: loss for loss in (
    Loss("linear", _identity, description="ρ̂ - ρ (unweighted)", linear=True),
    Loss("cosine", _cosine, description="(ρ̂ - ρ) cosθi cosθo", linear=True),
    Loss("log", _log, description="log(1 + ρ̂ cosθi) - log(1 + ρ cosθi)"),
    Loss("relative", _identity, _relative_weight, description="(ρ̂ - ρ) / max(ρ, 1e-3)",
         linear=True),
    Loss("cosine-in", _cosine_in, description="(ρ̂ - ρ) cosθi (Ngan 2005, Löw 2012 E1)",
         linear=True),
)}

#: The loss :func:`brdffit.fit` uses unless told otherwise (see the module docstring for why):
#: the default of :class:`brdffit.config.FitOptions`.
DEFAULT_LOSS = "log"


_ROBUST = re.compile(r"^huber(?:\((?P<delta>[^()]+)\))?$")


def _huber_of(robust: str) -> float | None:
    """The threshold of ``huber(δ)`` (a :attr:`Loss.label`'s suffix), ``None`` for ``huber``;
    ``ValueError`` for anything else."""
    m = _ROBUST.match(robust)
    if m is None:
        raise ValueError(robust)
    return None if m.group("delta") is None else float(m.group("delta"))


def get_loss(loss, huber: float | None = None) -> Loss:
    """A :class:`Loss` from a registry name or a label (or a ``Loss``), optionally made robust.

    ``"log+huber"`` style names are accepted too (Huber threshold ``huber`` or 0.1), and so is
    every :attr:`Loss.label` (``"log+huber(0.05)"``, what a ``FitResult`` records). Names
    ignore case (``"LOG+Huber"``).
    """
    if isinstance(loss, Loss):
        return loss if huber is None else loss.robust(huber)
    name = str(loss)
    base, _, robust = name.partition("+")
    try:
        delta = _huber_of(robust.lower()) if robust else None
        out = LOSSES[canonical_name(base, LOSSES) or base]
    except (KeyError, ValueError):
        raise UnknownNameError("loss", name, list(LOSSES) + [f"{k}+huber" for k in LOSSES]) from None
    if robust and delta is None:
        out, huber = out.robust(0.1 if huber is None else huber), None
    elif robust:
        out = out.robust(delta)
    return out if huber is None else out.robust(huber)
