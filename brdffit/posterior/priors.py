r"""Priors of the posterior: one independent prior per free scalar, as data.

The default is **uniform inside each parameter's physical bounds** and
``-inf`` outside: the model's declared bounds, narrowed by any ``bounds=`` of the fit. Override
any scalar from Python with ``prior={name: ...}``, where the value is

* a pair ``(lo, hi)`` — uniform on that interval,
* :class:`Uniform` ``(lo, hi)``, :class:`LogUniform` ``(lo, hi)`` (density ``∝ 1/x``, the
  scale-invariant choice for a roughness), or :class:`Normal` ``(mu, sigma, lo, hi)``
  (a Gaussian truncated to ``[lo, hi]``).

Names are those of :meth:`Model.flat_names` (``"alpha"``, ``"f0"`` for all three channels, or
``"f0[1]"`` for one). Every prior is truncated to its interval, so the support is always a box
and the walkers' start is clipped into it.

Convention: the prior is on the **physical** parameter (what the sampler moves), not on the
fitter's unconstrained coordinate ``u``; a uniform prior on ``x`` is not uniform on ``u``.
Normalising constants are dropped (they do not change the posterior).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ConfigError
from ..fitting import assign

#: Integer codes of the prior families inside the jitted log-density.
_UNIFORM, _LOG_UNIFORM, _NORMAL = 0, 1, 2


@dataclasses.dataclass(frozen=True)
class Uniform:
    """Uniform on ``[lo, hi]`` (``-inf`` outside)."""

    lo: float
    hi: float

    def coded(self):
        return _UNIFORM, 0.0, 1.0, self.lo, self.hi


@dataclasses.dataclass(frozen=True)
class LogUniform:
    """Density ``∝ 1/x`` on ``[lo, hi]`` (needs ``lo > 0``): uniform in ``log x``."""

    lo: float
    hi: float

    def coded(self):
        if not self.lo > 0:
            raise ConfigError(f"LogUniform prior needs lo > 0, got lo={self.lo!r}; use Uniform")
        return _LOG_UNIFORM, 0.0, 1.0, self.lo, self.hi


@dataclasses.dataclass(frozen=True)
class Normal:
    """Gaussian ``N(mu, sigma²)`` truncated to ``[lo, hi]``."""

    mu: float
    sigma: float
    lo: float
    hi: float

    def coded(self):
        if not self.sigma > 0:
            raise ConfigError(f"Normal prior needs sigma > 0, got {self.sigma!r}")
        return _NORMAL, self.mu, self.sigma, self.lo, self.hi


def _as_prior(key, value):
    if isinstance(value, (Uniform, LogUniform, Normal)):
        return value
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(
            f"prior for {key!r} must be (lo, hi), Uniform, LogUniform or Normal; got {value!r}"
        ) from None
    return Uniform(lo, hi)


class PriorBox(eqx.Module):
    """Per-scalar prior codes and parameters (arrays, traced under ``jit``), evaluated by
    :meth:`log_prior` in ``jnp``.

    Attributes:
        names: flat names of the sampled scalars. kind, a, b: family code and its two
        parameters (``mu, sigma`` for a Normal). lo, hi: the support.
    """

    names: tuple = eqx.field(static=True)
    kind: np.ndarray
    a: np.ndarray
    b: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def log_prior(self, theta):
        """``log p(θ)`` up to a constant for one ``θ`` (``(d,)``); ``-inf`` outside the box."""
        inside = jnp.all((theta >= self.lo) & (theta <= self.hi))
        safe = jnp.where((theta >= self.lo) & (theta <= self.hi), theta, self.hi)
        log_uni = -jnp.log(jnp.where(self.kind == _LOG_UNIFORM, safe, 1.0))
        normal = -0.5 * jnp.square((safe - self.a) / self.b)
        terms = jnp.where(self.kind == _LOG_UNIFORM, log_uni,
                          jnp.where(self.kind == _NORMAL, normal, 0.0))
        return jnp.where(inside, jnp.sum(terms), -jnp.inf)

    def describe(self) -> dict:
        """Name → a short human label (for summaries and JSON)."""
        fam = {_UNIFORM: "uniform", _LOG_UNIFORM: "log-uniform", _NORMAL: "normal"}
        kind, a, b, lo, hi = (np.asarray(v) for v in (self.kind, self.a, self.b, self.lo, self.hi))
        out = {}
        for i, n in enumerate(self.names):
            extra = f" N({a[i]:g}, {b[i]:g}²)" if kind[i] == _NORMAL else ""
            out[n] = f"{fam[int(kind[i])]}{extra} on [{lo[i]:g}, {hi[i]:g}]"
        return out


def build_prior(model, free, lo, hi, prior=None, extra=()) -> PriorBox:
    """The prior over the free scalars ``free`` (flat indices) of ``model``.

    ``lo, hi`` are the flat physical bounds (declared, or the fit's ``bounds``); ``prior``
    overrides single scalars (see the module docstring), intersected with the model's declared
    bounds so the model is never evaluated outside its domain; ``extra`` appends already-built
    ``(name, prior)`` pairs (the noise scale when it is sampled).
    """
    n = len(lo)
    declared_lo, declared_hi = model.flat_bounds()
    rows = np.array([[_UNIFORM, 0.0, 1.0, lo[i], hi[i]] for i in range(n)], float)
    for key, value in (prior or {}).items():
        p = _as_prior(key, value)
        idx = assign(model, {key: 0.0}, np.zeros(n), "prior of")
        if not set(idx) <= set(free):
            raise ConfigError(
                f"prior for {key!r}: that parameter is fixed in the fit, so it is not sampled; "
                f"drop it from `prior` or free it in the fit"
            )
        coded = np.array(p.coded(), float)
        if not (np.isfinite(coded[3:]).all() and coded[3] < coded[4]):
            raise ConfigError(f"prior for {key!r} needs finite lo < hi, got {p!r}")
        rows[idx] = coded
        rows[idx, 3] = np.maximum(rows[idx, 3], declared_lo[idx])
        rows[idx, 4] = np.minimum(rows[idx, 4], declared_hi[idx])
        if np.any(rows[idx, 3] >= rows[idx, 4]):
            raise ConfigError(
                f"prior for {key!r} ({p!r}) does not overlap the parameter's physical bounds "
                f"[{declared_lo[idx][0]:g}, {declared_hi[idx][0]:g}]"
            )
    names = [model.flat_names()[i] for i in free]
    rows = rows[list(free)]
    for name, p in extra:
        names.append(name)
        rows = np.vstack([rows, np.array(p.coded(), float)])
    return PriorBox(tuple(names), *(jnp.asarray(c) for c in rows.T))
