"""TOML presets → fit options: the one place where option *names* meet the library.

A preset (``configs/<name>.toml``) names some of the options of :func:`brdffit.fit`; what it does
not name keeps the default that lives in code. Layers merge left to right (preset, then
command-line flags), a later layer winning key by key. Layout (every key optional)::

    description = "free text, shown by `brdffit fit`"
    model = "ggx"                 # a registered model name
    loss = "cosine"               # a registered loss name
    cutoff = 80.0                 # degrees: drop samples with θi or θo beyond it (0 < cutoff ≤ 90)
    subsample = 200000            # fit on at most this many valid samples
    seed = 0                      # for subsampling and multi-start
    multistart = 0                # extra random starts, best kept

    covariance = "sandwich"       # or "gn"
    weighting = "angles"          # or "samples": how samples count against each other

    [solver]                      # solver and its tolerances
    name = "lm"
    rtol = 1e-14
    atol = 1e-14
    ftol = 1e-9                   # converged when the best step would lower the cost by < ftol × cost
    max_steps = 256
    precision = "float64"         # or "float32" model evaluation

    [init]                        # start values: a number, or [r, g, b] for an RGB parameter
    alpha = 0.1
    [fixed]                       # parameters held at the given value
    f0 = 0.04
    [bounds]                      # [lower, upper] narrowing a parameter's physical bounds
    alpha = [0.001, 0.5]

Unknown keys and wrong types raise :class:`~brdffit.errors.ConfigError` naming the key and the
valid choices; unknown model or parameter names raise :class:`~brdffit.errors.UnknownNameError`.
Presets are loaded by path or by a bare name such as ``ggx``, looked up as ``ggx.toml`` in
``./configs/`` (the working directory), then among the presets installed with the package
(the wheel carries the checkout's ``configs/`` as ``brdffit/configs/``), then in the checkout
this module was imported from (an editable install).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
import numbers
import tomllib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from data_formats._files import NotRegularFileError, open_regular

from .errors import ConfigError, canonical_name

#: The most samples a subsample may ask for (the readers' limit, ``MAX_SAMPLES`` = 2^24).
MAX_SUBSAMPLE = 2**24
#: Ranges of the numeric options of :func:`brdffit.fit`: ``key -> (integer?, low, high,
#: low included?, what to say)``. :func:`check_fit_options` is the one place that enforces them.
FIT_OPTION_RANGES = {
    "cutoff": (False, 0.0, 90.0, False, "degrees in (0, 90]"),
    "seed": (True, 0, 2**32 - 1, True, "an integer in [0, 2^32 - 1]"),
    "multistart": (True, 0, 1000, True, "an integer in [0, 1000]"),
    "max_steps": (True, 1, 100_000, True, "an integer in [1, 100000]"),
    "rtol": (False, 0.0, 1.0, False, "a number in (0, 1]"),
    "atol": (False, 0.0, 1.0, False, "a number in (0, 1]"),
    "ftol": (False, 0.0, 1.0, False, "a number in (0, 1]"),
}
_SCALARS = {  # key -> (types, check, what the check wants); numeric ranges: check_fit_options
    "model": (str, None, "a model name"),
    "loss": (str, None, "a loss name"),
    "cutoff": ((int, float), None, FIT_OPTION_RANGES["cutoff"][4]),
    "subsample": ((int, float), None, "a sample count or a fraction in (0, 1]"),
    "seed": (int, None, "a non-negative integer"),
    "multistart": (int, None, "a non-negative integer"),
    "covariance": (str, lambda v: v in ("sandwich", "gn"), '"sandwich" or "gn"'),
    "weighting": (str, lambda v: v in ("angles", "samples"), '"angles" or "samples"'),
}
_SOLVER = {
    "name": (str, None, "a solver name"),
    "rtol": ((int, float), None, "a positive number"),
    "atol": ((int, float), None, "a positive number"),
    "max_steps": (int, None, "a positive integer"),
    "ftol": ((int, float), None, "a number in (0, 1)"),
    "precision": (str, lambda v: v in ("float64", "float32"), '"float64" or "float32"'),
}

#: Ranges of the posterior-sampling options (``brdffit fit --mcmc``), checked the same way.
#: The chain holds ``walkers * steps * parameters`` doubles: 10^4 x 10^5 x 10 would be 80 GB,
#: so the product is bounded too (:data:`MAX_CHAIN_VALUES`).
POSTERIOR_OPTION_RANGES = {
    "walkers": (True, 2, 10_000, True, "an even integer in [2, 10000]"),
    "steps": (True, 1, 1_000_000, True, "an integer in [1, 1000000]"),
    "burn": (True, 0, 1_000_000, True, "an integer in [0, 1000000]"),
    "mcmc_subsample": (True, 1, 2**24, True, "an integer in [1, 16777216]"),
}
MAX_CHAIN_VALUES = 10**8

#: The narrowest ``[bounds]`` interval, relative to ``max(1, |bound|)``; narrower ones cannot
#: be fitted in float64 (the Jacobian degenerates): fix the parameter instead.
MIN_BOUNDS_WIDTH = 1e-6


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def _is_real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _range_error(value, integer, lo, hi, lo_in) -> bool:
    """True when ``value`` is not of the right kind or outside ``lo .. hi``."""
    if not (_is_int(value) if integer else _is_real(value)) or not math.isfinite(value):
        return True
    return not ((lo <= value if lo_in else lo < value) and value <= hi)


def _subsample_error(value) -> str | None:
    if not _is_real(value):
        return None  # a Subsample object: the fitter checks it
    if _is_int(value) and 1 <= value <= MAX_SUBSAMPLE:
        return None
    if not _is_int(value) and math.isfinite(value) and 0 < value <= 1:
        return None
    return f"a sample count in [1, {MAX_SUBSAMPLE}] or a fraction in (0, 1]"


def check_fit_options(options: Mapping, label=None, ranges=None) -> Mapping:
    """Refuse, before any work, numeric options of :func:`brdffit.fit` outside their ranges.

    ``options`` maps option names (``rtol``, ``multistart``, ...) to values; ``None`` and names
    without a range are ignored. The ranges are :data:`FIT_OPTION_RANGES` plus ``subsample``
    (a count in ``[1, 2^24]`` or a fraction in ``(0, 1]``), or ``ranges`` (e.g.
    :data:`POSTERIOR_OPTION_RANGES`) in their place: every value must be finite and of
    the right kind (an integer where a count is meant; ``bool`` is not a number). ``label(key)``
    says how the message names an option (``"--multistart"`` on the command line). Raises
    :class:`~brdffit.errors.ConfigError` ("'multistart' must be an integer in [0, 1000], got
    100000000"); returns ``options`` unchanged.
    """
    label = label or (lambda key: repr(key))
    ranges = FIT_OPTION_RANGES if ranges is None else ranges
    for key, value in options.items():
        if value is None:
            continue
        if key == "subsample":
            want = _subsample_error(value)
        elif key in ranges:
            integer, lo, hi, lo_in, want = ranges[key]
            want = want if _range_error(value, integer, lo, hi, lo_in) else None
        else:
            continue
        if want is not None:
            kind = "" if _is_real(value) else f"{type(value).__name__} "
            raise ConfigError(f"{label(key)} must be {want}, got {kind}{value!r}")
    return options
_TABLES = ("init", "fixed", "bounds", "solver")
_FREE_TEXT = ("description",)
VALID_KEYS = tuple(_SCALARS) + _TABLES + _FREE_TEXT


@dataclasses.dataclass(frozen=True)
class FitOptions:
    """Options for :func:`brdffit.fit`; ``None`` (or an empty mapping) means "the code's default".

    ``solver`` holds the solver name; ``rtol``, ``atol``, ``ftol``, ``max_steps`` its
    tolerances, ``precision`` the model evaluation's dtype; ``covariance`` how standard errors
    are estimated; ``weighting`` how samples count against each other; ``scan`` whether the
    start scan runs (Python only: presets do not set it).
    ``brdffit.fit(table, model, options)`` takes it as it is.
    ``init`` and ``fixed`` map parameter names to a number or an RGB triple; ``bounds`` maps
    parameter names to ``(lower, upper)``. ``sources`` lists the presets merged in.
    """

    model: str | None = None
    loss: str | None = None
    solver: str | None = None
    cutoff: float | None = None
    subsample: int | None = None
    seed: int | None = None
    multistart: int | None = None
    rtol: float | None = None
    atol: float | None = None
    max_steps: int | None = None
    ftol: float | None = None
    precision: str | None = None
    covariance: str | None = None
    weighting: str | None = None
    scan: bool | None = None
    init: Mapping = dataclasses.field(default_factory=dict)
    fixed: Mapping = dataclasses.field(default_factory=dict)
    bounds: Mapping = dataclasses.field(default_factory=dict)
    description: str = ""
    sources: tuple[str, ...] = ()

    def merged(self, later: "FitOptions") -> "FitOptions":
        """``self`` overridden by ``later``: set scalars win; parameter tables merge by name.

        A parameter given a start value in ``later`` is freed (dropped from ``fixed``), and one
        fixed in ``later`` loses its start value, so the later layer's intent wins.
        """
        out = {}
        for f in dataclasses.fields(self):
            mine, theirs = getattr(self, f.name), getattr(later, f.name)
            if f.name in ("init", "fixed", "bounds"):
                out[f.name] = {**mine, **theirs}
            elif f.name == "sources":
                out[f.name] = mine + theirs
            else:
                out[f.name] = theirs if theirs not in (None, "") else mine
        out["fixed"] = {k: v for k, v in out["fixed"].items() if k not in later.init}
        out["init"] = {k: v for k, v in out["init"].items() if k not in later.fixed}
        return FitOptions(**out)

    def fit_kwargs(self) -> dict:
        """Keyword arguments for :func:`brdffit.fit`: only what was set (the model excluded)."""
        keys = ("loss", "solver", "cutoff", "subsample", "seed", "multistart",
                "rtol", "atol", "ftol", "max_steps", "precision", "covariance", "weighting",
                "scan")
        kwargs = {k: getattr(self, k) for k in keys if getattr(self, k) is not None}
        for k in ("init", "fixed", "bounds"):
            if getattr(self, k):
                kwargs[k] = dict(getattr(self, k))
        return kwargs

    def check_params(self, model) -> "FitOptions":
        """Check parameter names, shapes and values against ``model`` (a :class:`Model`)."""
        for table in ("init", "fixed"):
            for name, value in getattr(self, table).items():
                param = model.param(name)  # UnknownNameError lists the valid names
                _with_context(f"[{table}] {name}", param.check_bounds, value)
        for name, (lo, hi) in self.bounds.items():
            param = model.param(name)
            if hi - lo < MIN_BOUNDS_WIDTH * max(1.0, abs(lo), abs(hi)):
                raise ConfigError(
                    f"[bounds] {name} = [{lo:g}, {hi:g}] is narrower than {MIN_BOUNDS_WIDTH:g}; "
                    f"such a range cannot be fitted: hold the parameter with [fixed] {name} = "
                    f"{hi:g} (or --fix {name}={hi:g}) instead"
                )
            if not param.lower <= lo < hi <= param.upper:
                raise ConfigError(
                    f"[bounds] {name} = [{lo:g}, {hi:g}] must satisfy {param.lower:g} ≤ lower < "
                    f"upper ≤ {param.upper:g} (the parameter's physical bounds)"
                )
        return self


def _with_context(where, fn, *args):
    try:
        return fn(*args)
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def _unknown_key(where: str, key: str, valid) -> ConfigError:
    close = difflib.get_close_matches(key, list(valid), n=1)
    hint = f" Did you mean {close[0]!r}?" if close else ""
    return ConfigError(
        f"{where}unknown key {key!r}; valid keys: {', '.join(valid)}.{hint}"
    )


def _check_scalar(where: str, key: str, value, spec):
    types, check, want = spec
    if isinstance(value, bool) or not isinstance(value, types):
        raise ConfigError(
            f"{where}{key!r} must be {want}, got {type(value).__name__} {value!r}"
        )
    if check is not None and not check(value):
        raise ConfigError(f"{where}{key!r} must be {want}, got {value!r}")
    return float(value) if key in ("cutoff", "rtol", "atol") else value


def _param_value(where: str, key: str, value):
    """A number or a list of three numbers (an RGB parameter)."""
    def finite(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    ok_number = finite(value)
    ok_rgb = isinstance(value, list) and len(value) == 3 and all(finite(v) for v in value)
    if not (ok_number or ok_rgb):
        raise ConfigError(
            f"{where}{key!r} must be a finite number or a list of 3 finite numbers [r, g, b], "
            f"got {value!r}"
        )
    return float(value) if ok_number else tuple(float(v) for v in value)


def _bounds_value(where: str, key: str, value):
    pair = isinstance(value, list) and len(value) == 2
    if not pair or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and math.isfinite(v) for v in value):
        raise ConfigError(f"{where}{key!r} must be [lower, upper] (finite numbers), got {value!r}")
    lo, hi = float(value[0]), float(value[1])
    if not lo < hi:
        raise ConfigError(f"{where}{key!r} = {value!r}: lower must be below upper")
    return (lo, hi)


def _table(where: str, key: str, value) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}{key!r} must be a table ([{key}]), got {value!r}")
    return value


def parse_config(data: Mapping, source: str = "<config>") -> FitOptions:
    """Validate a decoded TOML mapping into :class:`FitOptions` (names checked later)."""
    where = f"{source}: "
    opts: dict = {"sources": (source,)}
    for key, value in data.items():
        if key in _SCALARS:
            opts[key] = _check_scalar(where, key, value, _SCALARS[key])
        elif key == "description":
            opts[key] = _check_scalar(where, key, value, (str, None, "a string"))
        elif key == "solver":
            for sub, v in _table(where, key, value).items():
                if sub not in _SOLVER:
                    raise _unknown_key(f"{where}[solver] ", sub, _SOLVER)
                opts["solver" if sub == "name" else sub] = _check_scalar(
                    f"{where}[solver] ", sub, v, _SOLVER[sub]
                )
        elif key in ("init", "fixed", "bounds"):
            conv = _bounds_value if key == "bounds" else _param_value
            opts[key] = {k: conv(f"{where}[{key}] ", k, v) for k, v in _table(where, key, value).items()}
        else:
            raise _unknown_key(where, key, VALID_KEYS)
    both = sorted(set(opts.get("init", {})) & set(opts.get("fixed", {})))
    if both:
        raise ConfigError(f"{where}{', '.join(both)} is both in [init] and in [fixed]; a "
                          f"parameter is either fitted from a start value or held fixed: keep one")
    check_fit_options(opts, lambda key: f"{where}{'[solver] ' if key in _SOLVER else ''}{key!r}")
    return FitOptions(**opts)


#: Where a bare preset name is looked for, in order (see the module docstring).
def preset_folders() -> list[Path]:
    here = Path(__file__).resolve().parent
    return [Path("configs"), here / "configs", here.parent / "configs"]


def available_presets() -> list[str]:
    """Names of the presets found in :func:`preset_folders`, sorted."""
    return sorted({p.stem for f in preset_folders() if f.is_dir() for p in f.glob("*.toml")})


def find_config(name_or_path) -> Path:
    """The preset file for a path, or for a bare name (``ggx`` → ``configs/ggx.toml``; a bare
    name ignores case when no file has it exactly: ``GGX`` → ``configs/ggx.toml``)."""
    path = Path(name_or_path)
    if path.exists() and not path.is_dir():  # not a regular file: load_config says so
        return path
    bare = path.parent == Path(".") and path.suffix == ""
    if bare:
        found = available_presets()
        names = dict.fromkeys([path.name, canonical_name(path.name, found) or path.name])
        for name in names:  # the name as given, then the preset it names ignoring case
            for folder in preset_folders():
                candidate = folder / f"{name}.toml"
                if candidate.is_file():
                    return candidate
        close = difflib.get_close_matches(path.name, found, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        known = f"; known presets: {', '.join(found)}" if found else ""
        raise ConfigError(
            f"no preset named {path.name!r} (looked for {path.name}.toml in ./configs and among "
            f"the installed presets){known}.{hint} Or pass a path to a .toml file"
        )
    raise ConfigError(f"config file {str(path)!r} not found; pass a path to a .toml preset")


#: The largest preset file read (presets are a few hundred bytes).
MAX_PRESET_BYTES = 1 << 20


def load_config(name_or_path) -> FitOptions:
    """Read and validate a TOML preset (by path, or a bare name: see :func:`find_config`)."""
    path = find_config(name_or_path)
    try:
        with open_regular(path, "rb") as fh:
            if os.fstat(fh.fileno()).st_size > MAX_PRESET_BYTES:
                raise ConfigError(f"{path}: larger than {MAX_PRESET_BYTES:,} bytes; a preset is a "
                                  f"few lines of TOML")
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML (not UTF-8 text: {exc.reason} at byte "
                          f"{exc.start})") from None
    except RecursionError:
        raise ConfigError(f"{path}: not valid TOML (nested too deeply)") from None
    except NotRegularFileError as exc:
        raise ConfigError(str(exc)) from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the preset ({exc.strerror})") from None
    return parse_config(data, str(path))
