"""Grey fits of monochrome measurements: one channel of data, every colour parameter grey.

A monochrome sample list (``SampleSet.channels == 1``) holds its one value in all three
columns of ``rgb`` and the fit gives channels 1 and 2 zero weight
(:func:`brdffit.fitting.data.select`), so the residuals, the cost, the number of observations
and the Jacobian are those of the single channel. The model's RGB parameters are made grey by
holding their components 1 and 2 during the solve (they act on channels 1 and 2 only, which
carry no weight) and then setting them to component 0, with component 0's standard error and
covariance: the result is the grey model ``f0 = (v, v, v)``.

That is exact only for colour parameters declared ``per_channel`` (component ``c`` changes
channel ``c`` alone): a parameter that mixes channels (Disney's ``base_color``) would see its
held components in channel 0, so such models are refused for monochrome data.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .errors import ConfigError


def is_monochrome(data) -> bool:
    """True for a sample set that says it holds one channel (``channels == 1``)."""
    return getattr(data, "channels", 3) == 1


def _rgb_params(model):
    return [p for p in model.params if p.shape == (3,)]


def tie_options(model, options: dict) -> tuple[dict, dict]:
    """``(options, tied)``: ``options`` with components 1 and 2 of each RGB parameter held
    (at the parameter's default) during the solve, and ``tied`` mapping each held flat name to
    the component-0 name it copies afterwards. A parameter the user fixed whole is left alone.
    Raises :class:`ConfigError` for a model with a channel-mixing RGB parameter."""
    mixing = [p.name for p in _rgb_params(model) if not p.per_channel]
    if mixing:
        raise ConfigError(
            f"monochrome data (one value column) fit a grey model, which needs colour "
            f"parameters that act per channel; {model.name!r} has {', '.join(mixing)} mixing "
            f"the channels. Choose a model such as ggx, beckmann or blinn-phong, or give the "
            f"data as r, g, b columns"
        )
    fixed = dict(options.get("fixed") or {})
    tied = {}
    for p in _rgb_params(model):
        if p.name in fixed:
            continue
        default = p.default_array()
        for c in (1, 2):
            fixed.setdefault(f"{p.name}[{c}]", float(default[c]))
            tied[f"{p.name}[{c}]"] = f"{p.name}[0]"
    return {**options, "fixed": fixed}, tied


def untie(result, model, tied: dict):
    """The grey :class:`~brdffit.fitting.FitResult`: each tied component set to its
    component 0 (value, standard error, covariance row and column, start value) and dropped
    from ``fixed``."""
    if not tied:
        return result
    idx = {n: i for i, n in enumerate(result.names)}
    x, cov = np.array(result.x, float), np.array(result.cov, float)
    for name, source in tied.items():
        i, j = idx[name], idx[source]
        x[i] = x[j]
        cov[i, :], cov[:, i] = cov[j, :], cov[:, j]
        cov[i, i] = cov[j, j]
    tied_params = {n.split("[")[0] for n in tied}
    params = {k: ([v[0]] * 3 if k in tied_params else v) for k, v in result.params.items()}
    stderr = {k: ([v[0]] * 3 if k in tied_params else v) for k, v in result.stderr.items()}
    init = {k: ([v[0]] * 3 if k in tied_params else v) for k, v in result.init.items()}
    return dataclasses.replace(
        result, x=x, cov=cov, params=params, stderr=stderr, init=init,
        fixed=[f for f in result.fixed if f not in tied],
    )
