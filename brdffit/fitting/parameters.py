"""A model's flat parameter vector in one fit: the user's ``fixed``/``init``/``bounds`` options
written into it (with clear errors), and which scalars are free (:class:`Scalars`)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np

from ..errors import ConfigError, FitError, UnknownNameError
from .transforms import bounds_in_s, to_box

_FLAT = re.compile(r"^(?P<name>[^\[\]]+)\[(?P<i>\d+)\]$")


def flat_log(model) -> np.ndarray:
    return np.concatenate([np.full(p.size, bool(p.log)) for p in model.params])


def flat_scanned(model) -> np.ndarray:
    """Per flat scalar, whether the start scan shifts it (:attr:`Param.scanned`)."""
    return np.concatenate([np.full(p.size, p.scanned) for p in model.params])


def _slots(model, key: str) -> tuple[str, list[int]]:
    """Parameter name and flat indices named by ``key`` (``"f0"`` or ``"f0[1]"``)."""
    names = model.flat_names()
    m = _FLAT.match(key)
    base = m.group("name") if m else key
    try:
        model.param(base)
    except UnknownNameError:
        raise UnknownNameError("parameter", key, model.names, owner=f"model {model.name!r}") from None
    if m:
        if key not in names:
            raise ConfigError(f"{key!r}: parameter {base!r} has no component {m.group('i')}")
        return base, [names.index(key)]
    return base, [i for i, n in enumerate(names) if n == base or n.startswith(base + "[")]


def assign(model, values, into: np.ndarray, what: str) -> list[int]:
    """Write ``values`` (name → value) into the flat vector ``into``; returns the indices set."""
    touched = []
    for key, value in (values or {}).items():
        _base, idx = _slots(model, str(key))
        arr = np.asarray(value, float).ravel()
        if arr.size not in (1, len(idx)):
            raise ConfigError(
                f"{what} {key!r} takes {len(idx)} value(s), got {arr.size}: {value!r}"
            )
        if not np.all(np.isfinite(arr)):
            raise ConfigError(f"{what} {key!r} must be finite, got {value!r}")
        into[idx] = arr if arr.size == len(idx) else arr[0]
        touched += idx
    return touched


def flat_bounds(model, bounds) -> tuple[np.ndarray, np.ndarray]:
    """Declared bounds overridden by ``bounds`` (name → ``(lo, hi)``)."""
    lo, hi = (b.astype(float) for b in model.flat_bounds())
    log = flat_log(model)
    for key, pair in (bounds or {}).items():
        _, idx = _slots(model, str(key))
        try:
            a, b = (float(v) for v in pair)
        except (TypeError, ValueError):
            raise ConfigError(f"bounds for {key!r} must be a pair (lo, hi), got {pair!r}") from None
        if not (np.isfinite(a) and np.isfinite(b) and a < b):
            raise ConfigError(f"bounds for {key!r} must be finite with lo < hi, got {pair!r}")
        if np.any(log[idx]) and a <= 0:
            raise ConfigError(
                f"{key!r} is fitted in log space, so its lower bound must be > 0, got {a!r}"
            )
        lo[idx], hi[idx] = a, b
    bad = ~(np.isfinite(lo) & np.isfinite(hi)) | (log & (lo <= 0))
    if np.any(bad):
        names = [n for n, b in zip(model.flat_names(), bad) if b]
        raise ConfigError(
            f"model {model.name!r} declares unusable bounds for {names} (need finite bounds, "
            f"and lo > 0 for log parameters); pass `bounds={{name: (lo, hi)}}`"
        )
    return lo, hi


def check_within(model, x, lo, hi, idx, what: str) -> None:
    names = model.flat_names()
    for i in idx:
        if not lo[i] <= x[i] <= hi[i]:
            raise ConfigError(
                f"{what} {names[i]}={x[i]:g} is outside its bounds [{lo[i]:g}, {hi[i]:g}]; "
                f"pick a value inside or widen `bounds`"
            )


@dataclasses.dataclass(frozen=True)
class Scalars:
    """The flat scalars of ``model`` in one fit: their bounds ``lo``, ``hi`` (the declared ones
    overridden by the fit's ``bounds``), which are fitted in log space, and which are ``free``
    (flat indices, ascending); the others are held at their values."""

    model: object
    lo: np.ndarray
    hi: np.ndarray
    free: tuple[int, ...]

    @classmethod
    def of(cls, model, free, bounds=None) -> Scalars:
        """The ``free`` scalars (flat indices) of ``model`` within ``bounds`` (name → pair)."""
        lo, hi = flat_bounds(model, bounds)
        return cls(model, lo, hi, tuple(int(i) for i in free))

    @property
    def log(self) -> np.ndarray:
        return flat_log(self.model)

    @property
    def fixed(self) -> list[int]:
        free = set(self.free)
        return [i for i in range(len(self.lo)) if i not in free]

    def bounds_in_s(self) -> tuple[np.ndarray, np.ndarray]:
        """The free scalars' bounds in the box map's ``s`` coordinate (:mod:`.transforms`)."""
        slo, shi = bounds_in_s(self.lo, self.hi, self.log)
        free = list(self.free)
        return slo[free], shi[free]

    def to_box(self, x) -> np.ndarray:
        """The box coordinates ``z`` of the free entries of the flat vector ``x``."""
        free = list(self.free)
        slo, shi = self.bounds_in_s()
        return to_box(np.asarray(x, float)[free], slo, shi, self.log[free])


def free_scalars(model, fixed=None, bounds=None) -> tuple[Scalars, np.ndarray]:
    """The :class:`Scalars` of a fit with ``fixed`` (name → value) and ``bounds`` (name →
    pair), and the flat vector of the declared defaults with the fixed values written in.
    Raises :class:`~brdffit.errors.FitError` when every scalar is fixed."""
    lo, hi = flat_bounds(model, bounds)
    x0 = model.flatten({})
    held = set(assign(model, fixed, x0, "fixed value of"))
    check_within(model, x0, lo, hi, sorted(held), "fixed")
    free = [i for i in range(len(x0)) if i not in held]
    if not free:
        raise FitError(f"every parameter of {model.name!r} is fixed: nothing to fit")
    return Scalars(model, lo, hi, tuple(free)), x0
