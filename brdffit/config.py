"""The fit options (:class:`FitOptions`, one field each) and TOML presets that load into them.

A preset (``configs/<name>.toml``) names some of the options of :func:`brdffit.fit`; what it does
not name keeps the default that lives in code. Layers merge left to right (preset, then
command-line flags), a later layer winning key by key. Layout (every key optional)::

    description = "free text, shown by `brdffit fit`"
    model = "ggx"                 # a registered model name
    loss = "cosine"               # a registered loss name
    cutoff = 80.0                 # degrees: drop samples with θi or θo beyond it (0 < cutoff ≤ 90;
                                  # default 80, 90 keeps every sample above the horizon)
    subsample = 200000            # fit on at most this many valid samples
    seed = 0                      # for subsampling and multi-start
    multistart = 0                # extra random starts, best kept

    covariance = "sandwich"       # or "gn"
    weighting = "angles"          # or "samples", "solid-angle": how samples count

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

from data_formats.files import NotRegularFileError, open_regular

from .errors import ConfigError, UnknownNameError, canonical_name
from .fitting import DEFAULT_LOSS, DEFAULT_SOLVER, LOSSES, SOLVERS  # JAX-free registries

#: The most samples a subsample may ask for (the readers' limit, ``MAX_SAMPLES`` = 2^24).
MAX_SUBSAMPLE = 2**24


@dataclasses.dataclass(frozen=True)
class Option:
    """What :class:`FitOptions` knows about one option (its field's ``metadata["option"]``).

    Attributes:
        default: the code's default (``None``: decided at fit time from the data or the
            precision, or not used); :data:`brdffit.fitting.FIT_DEFAULTS` is these.
        want: what a value must be, in error messages ("degrees in (0, 90]").
        kind: ``int``, ``float`` or ``str`` for a preset's type check and the flag's parser;
            ``None`` for the tables and ``subsample`` (a count or a fraction).
        low, high, low_in: the range of a number (``high`` included, ``low`` when ``low_in``).
        choices: the valid names of a named option (any case on input).
        table: where a preset sets it: ``""`` at the top level, ``"solver"`` in ``[solver]``
            (``key`` names it there), ``None`` not at all.
        flag, metavar, help: the ``brdffit fit`` flag (``None``: none).
    """

    default: object = None
    want: str = ""
    kind: type | None = None
    low: float | None = None
    high: float | None = None
    low_in: bool = True
    choices: tuple = ()
    table: str | None = ""
    key: str | None = None
    flag: str | None = None
    metavar: str | None = None
    help: str = ""


def _option(**spec):
    """A :class:`FitOptions` field: unset (``None``) unless given, described by ``spec``."""
    return dataclasses.field(default=None, metadata={"option": Option(**spec)})


def _table_option(flag, help, metavar="NAME=VALUE"):
    return dataclasses.field(default_factory=dict, metadata={"option": Option(
        want="a table", table="", flag=flag, metavar=metavar, help=help)})


def _one_of(names, default) -> str:
    """``"lm (default), gauss-newton or dogleg"``."""
    words = [f"{n} (default)" if n == default else n for n in names]
    return f"{', '.join(words[:-1])} or {words[-1]}" if len(words) > 1 else words[0]


_UNIT = dict(kind=float, low=0.0, high=1.0, low_in=False, want="a number in (0, 1]")
_TOL = "step tolerance of the stall test (default 1e-14 in float64, 1e-6 in float32)"

#: The default angle cutoff (degrees): a fit uses the samples with θi and θo at most this.
#: Where renderers spend their samples and measurements are trustworthy (MERL's values past
#: about 75–80° are extrapolated, Burley 2012 §3.1/§4.7); on 12 realistic materials a fit on
#: these cells is better in every metric over θ ≤ 80° than one on every cell (``ggx``: median
#: ratio 0.69 of the log metric, 0.65 of Ngan's, 0.59 of the peak's relative error; 12, 8 and
#: 10 of 12 materials), and worse on all cells only through the grazing ones
#: (``benchmarks/bench_compare.py``, ``docs/compare.md``). ``cutoff=90`` (or ``None`` given to
#: :func:`brdffit.fit`) fits every sample above the horizon.
DEFAULT_CUTOFF = 80.0

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
    return OPTIONS["subsample"].want


def check_fit_options(options: Mapping, label=None, ranges=None) -> Mapping:
    """Refuse, before any work, numeric options of :func:`brdffit.fit` outside their ranges.

    ``options`` maps option names (``rtol``, ``multistart``, ...) to values; ``None`` and names
    without a range are ignored. The ranges are :data:`FIT_OPTION_RANGES` plus ``subsample``
    (a count in ``[1, 2^24]`` or a fraction in ``(0, 1]``), or ``ranges`` (the ``--mcmc``
    flags': :data:`brdffit.posterior.options.FLAG_RANGES`) in their place: every value must be
    finite and of the right kind (an integer where a count is meant; ``bool`` is not a number).
    ``label(key)`` says how the message names an option (``"--multistart"`` on the command
    line). Raises
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


@dataclasses.dataclass(frozen=True)
class FitOptions:
    """Options for :func:`brdffit.fit`; ``None`` (or an empty mapping) means "the code's default".

    The one owner of the options: each field's :class:`Option` (``metadata["option"]``) holds
    its default, range, choices, preset key and flag, from which come :data:`OPTIONS`,
    :data:`FIT_OPTION_RANGES`, the preset schema (:func:`parse_config`), the code's defaults
    (:data:`CODE_DEFAULTS`), the ``brdffit fit`` flags and the words of the advice. A new
    option is a new field.

    ``solver`` holds the solver name; ``rtol``, ``atol``, ``ftol``, ``max_steps`` its
    tolerances, ``precision`` the model evaluation's dtype; ``covariance`` how standard errors
    are estimated; ``weighting`` how samples count against each other; ``energy`` whether the
    directional albedo is held at most 1; ``scan`` whether the start scan runs (Python only:
    presets do not set it).
    ``brdffit.fit(table, model, options)`` takes it as it is.
    ``init`` and ``fixed`` map parameter names to a number or an RGB triple; ``bounds`` maps
    parameter names to ``(lower, upper)``. ``sources`` lists the presets merged in.
    """

    model: str | None = _option(kind=str, want="a model name", default=None)
    loss: str | None = _option(
        kind=str, want="a loss name", default=DEFAULT_LOSS, flag="--loss",
        help=f"residual weighting: {_one_of(LOSSES, DEFAULT_LOSS)} (+huber)")
    solver: str | None = _option(
        kind=str, want="a solver name", default=DEFAULT_SOLVER, table="solver", key="name",
        flag="--solver", help=_one_of(SOLVERS, DEFAULT_SOLVER))
    init: Mapping = _table_option("--init", "start a parameter at a value; repeatable")
    fixed: Mapping = _table_option(
        "--fix", "hold a parameter at a value (f0=0.04 or f0=0.9,0.6,0.3); repeatable")
    bounds: Mapping = _table_option(
        "--bound", "narrow a parameter's bounds (alpha=0.01,0.5); repeatable", "NAME=LO,HI")
    cutoff: float | None = _option(
        kind=float, low=0.0, high=90.0, low_in=False, want="degrees in (0, 90]",
        default=DEFAULT_CUTOFF, flag="--cutoff", metavar="DEG",
        help=f"drop samples with θi or θo above DEG degrees (default {DEFAULT_CUTOFF:g}; 90 "
        f"keeps every sample above the horizon)")
    subsample: int | None = _option(
        want=f"a sample count in [1, {MAX_SUBSAMPLE}] or a fraction in (0, 1]",
        flag="--subsample", metavar="N",
        help="fit on N randomly chosen valid samples (or a fraction like 0.1)")
    seed: int | None = _option(
        kind=int, low=0, high=2**32 - 1, want="an integer in [0, 2^32 - 1]", default=0,
        flag="--seed", help="seed for subsampling and multi-start")
    multistart: int | None = _option(
        kind=int, low=0, high=1000, want="an integer in [0, 1000]", default=0,
        flag="--multistart", metavar="K", help="K extra random starts, best kept")
    max_steps: int | None = _option(
        kind=int, low=1, high=100_000, want="an integer in [1, 100000]", default=200,
        table="solver", flag="--max-steps", metavar="N",
        help="solver steps per start before giving up (default 200)")
    rtol: float | None = _option(**_UNIT, table="solver", flag="--rtol", metavar="X",
                                 help=f"relative {_TOL}")
    atol: float | None = _option(**_UNIT, table="solver", flag="--atol", metavar="X",
                                 help=f"absolute {_TOL}")
    ftol: float | None = _option(
        **_UNIT, table="solver", flag="--ftol", metavar="X",
        help="the optimality test: converged when the best bounded Gauss-Newton step would "
        "lower the cost by less than X times the cost (default 1e-9 in float64, 1e-6 in "
        "float32)")
    scan: bool | None = _option(default=True, table=None)
    precision: str | None = _option(
        kind=str, choices=("float64", "float32"), want='"float64" or "float32"',
        table="solver", flag="--precision", help="model evaluation dtype (default float64)")
    covariance: str | None = _option(
        kind=str, choices=("sandwich", "gn"), want='"sandwich" or "gn"', default="sandwich",
        flag="--covariance", help="standard errors: sandwich (robust, default) or gn (classical)")
    weighting: str | None = _option(
        kind=str, choices=("angles", "samples", "solid-angle"),
        want='"angles", "samples" or "solid-angle"', default="angles", flag="--weighting",
        help="how samples count: by the share of the angles each stands for (default; undoes "
        "the MERL θh warp), once each, or by the solid angle dωi dωo each stands for (the "
        "literature's measure)")
    energy: str | None = _option(
        kind=str, choices=("limit", "free"), want='"limit" or "free"', default="limit",
        flag="--energy",
        help="directional albedo: at most 1 at every incidence (limit, default: a fit that "
        "breaks it is solved again under the constraint) or unconstrained (free)")
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
            if f.name in _TABLES:
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
        kwargs = {}
        for key in FIT_KEYS:
            value = getattr(self, key)
            if key in _TABLES:
                if value:
                    kwargs[key] = dict(value)
            elif value is not None:
                kwargs[key] = value
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


#: Every option, name -> :class:`Option`, in the order of :class:`FitOptions`.
OPTIONS = {f.name: f.metadata["option"] for f in dataclasses.fields(FitOptions)
           if "option" in f.metadata}
#: The options of :func:`brdffit.fit` (all but the model).
FIT_KEYS = tuple(key for key in OPTIONS if key != "model")
#: Each option of :func:`brdffit.fit` with the code's default (``None``: see :class:`Option`).
CODE_DEFAULTS = {key: OPTIONS[key].default for key in FIT_KEYS}
#: Ranges of the numeric options: ``key -> (integer?, low, high, low included?, what to say)``,
#: from :data:`OPTIONS`; :func:`check_fit_options` is the one place that enforces them.
FIT_OPTION_RANGES = {key: (o.kind is int, o.low, o.high, o.low_in, o.want)
                     for key, o in OPTIONS.items() if o.high is not None}
_TABLES = ("init", "fixed", "bounds")
#: A preset's keys: top-level ones, and those of its ``[solver]`` table (-> the option).
_PRESET_KEYS = {key: key for key, o in OPTIONS.items() if o.table == "" and key not in _TABLES}
_SOLVER_KEYS = {o.key or key: key for key, o in OPTIONS.items() if o.table == "solver"}
VALID_KEYS = tuple(_PRESET_KEYS) + _TABLES + ("solver", "description")


def canonical_choices(options: dict) -> dict:
    """``options`` with each named option (``covariance``, ``precision``, ``weighting``) spelled
    as its choice (names ignore case: ``"GN"`` is ``"gn"``); raises
    :class:`~brdffit.errors.UnknownNameError` for a name that is no choice."""
    for key, option in OPTIONS.items():
        value = options.get(key)
        if option.choices and value is not None:
            name = canonical_name(value, option.choices)
            if name is None:
                raise UnknownNameError(key, str(value), list(option.choices))
            options[key] = name
    return options


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


def _check_scalar(where: str, key: str, value, option: Option):
    """A preset's value for ``option``: of its type and among its choices (ranges:
    :func:`check_fit_options`)."""
    types = {str: str, int: int, float: (int, float), None: (int, float)}[option.kind]
    if isinstance(value, bool) or not isinstance(value, types):
        raise ConfigError(
            f"{where}{key!r} must be {option.want}, got {type(value).__name__} {value!r}"
        )
    if option.choices and value not in option.choices:
        raise ConfigError(f"{where}{key!r} must be {option.want}, got {value!r}")
    return float(value) if option.kind is float else value


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
        if key in _PRESET_KEYS:
            opts[key] = _check_scalar(where, key, value, OPTIONS[key])
        elif key == "description":
            opts[key] = _check_scalar(where, key, value, Option(kind=str, want="a string"))
        elif key == "solver":
            for sub, v in _table(where, key, value).items():
                if sub not in _SOLVER_KEYS:
                    raise _unknown_key(f"{where}[solver] ", sub, _SOLVER_KEYS)
                opts[_SOLVER_KEYS[sub]] = _check_scalar(
                    f"{where}[solver] ", sub, v, OPTIONS[_SOLVER_KEYS[sub]]
                )
        elif key in _TABLES:
            conv = _bounds_value if key == "bounds" else _param_value
            opts[key] = {k: conv(f"{where}[{key}] ", k, v) for k, v in _table(where, key, value).items()}
        else:
            raise _unknown_key(where, key, VALID_KEYS)
    both = sorted(set(opts.get("init", {})) & set(opts.get("fixed", {})))
    if both:
        raise ConfigError(f"{where}{', '.join(both)} is both in [init] and in [fixed]; a "
                          f"parameter is either fitted from a start value or held fixed: keep one")
    solver = {name for name, o in OPTIONS.items() if o.table == "solver"}
    check_fit_options(opts, lambda key: f"{where}{'[solver] ' if key in solver else ''}{key!r}")
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
