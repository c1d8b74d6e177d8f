"""Turning the user's ``fixed``/``init``/``bounds`` options into flat vectors, with clear errors."""

from __future__ import annotations

import re

import numpy as np

from ..errors import ConfigError, UnknownNameError

_FLAT = re.compile(r"^(?P<name>[^\[\]]+)\[(?P<i>\d+)\]$")


def flat_log(model) -> np.ndarray:
    return np.concatenate([np.full(p.size, bool(p.log)) for p in model.params])


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
