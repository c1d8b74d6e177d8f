"""Named BRDF models: parameters as data, one registry for the CLI and configs.

A :class:`Model` is a pure function ``fn(params, wi, wo) -> f_r`` (RGB, shape ``(..., 3)``) plus
the declaration of its parameters (:class:`Param`: name, shape, physical bounds, default,
description). Fitting and sampling work from these declarations alone, so a new model is one
function and one :func:`register` call (see :mod:`brdffit.models.standard` for examples).

Names exist only at this boundary (CLI, configs); Python code may hold :class:`Model` objects.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import numpy as np

from ..errors import BrdffitError, UnknownNameError, canonical_name


@dataclasses.dataclass(frozen=True)
class Param:
    """One named model parameter.

    Attributes:
        name: identifier used in Python, configs and on the command line.
        shape: ``()`` for a scalar, ``(3,)`` for an RGB triple.
        lower, upper: physical bounds, applied to every component.
        default: starting value (scalar broadcasts over the shape).
        description: one line for humans.
        log: fitted in log space: the parameter spans decades (a roughness), or the model is
            far more curved in it near the lower bound than far from it (a colour that a
            tint divides by its luminance).
        scan: the start scan (:func:`brdffit.fitting.stages.candidates`) tries it ×8 and ÷8:
            a lobe width, whose optimum can lie in another basin. ``None`` (the default)
            means ``log``; ``False`` for a log-scaled parameter that is no width. Only a
            log-scaled parameter can be scanned.
        per_channel: an RGB parameter whose component ``c`` changes channel ``c`` of ``f_r``
            only (a Lambertian albedo, a Schlick ``F0``), for every value of every parameter.
            The fitter then differentiates all three components with one forward-mode product
            (:meth:`brdffit.fitting.problem.Problem.tangents_x`). Declare it only when true: a
            parameter that mixes channels (Disney's ``base_color``, through the tint's
            luminance) would get a wrong Jacobian. ``tests/test_models.py`` checks every
            registered model's declarations against forward-mode derivatives.
    """

    name: str
    shape: tuple[int, ...]
    lower: float
    upper: float
    default: float | tuple[float, ...]
    description: str
    log: bool = False
    per_channel: bool = False
    scan: bool | None = None

    def __post_init__(self):
        if self.scan and not self.log:
            raise ValueError(f"Param {self.name!r}: only a log-scaled parameter can be scanned")

    @property
    def scanned(self) -> bool:
        """Whether the start scan shifts this parameter (``scan``, by default ``log``)."""
        return self.log if self.scan is None else bool(self.scan)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape, dtype=int))

    def default_array(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.default, dtype=float), self.shape).copy()

    def coerce(self, value) -> np.ndarray:
        """``value`` as an array of this parameter's shape; a scalar fills an RGB triple."""
        arr = np.asarray(value, dtype=float)
        try:
            arr = np.broadcast_to(arr, self.shape).copy()
        except ValueError:
            raise BrdffitError(
                f"parameter {self.name!r} takes shape {self.shape or 'scalar'}, got {np.shape(value)}"
            ) from None
        if not np.all(np.isfinite(arr)):
            raise BrdffitError(f"parameter {self.name!r} must be finite, got {value!r}")
        return arr

    def check_bounds(self, value) -> np.ndarray:
        arr = self.coerce(value)
        if np.any(arr < self.lower) or np.any(arr > self.upper):
            raise BrdffitError(
                f"parameter {self.name!r}={value!r} is outside its bounds "
                f"[{self.lower:g}, {self.upper:g}]"
            )
        return arr


@dataclasses.dataclass(frozen=True)
class PerPass:
    """A model split for the fitter's passes over the cells, which are made block by block.

    ``build(params) -> tables`` computes what depends on the parameters alone (a numerical Λ
    table: many times the cost of evaluating one block of cells), ``apply(params, tables, wi,
    wo) -> f_r`` evaluates the model with them, so that ``fn(p, wi, wo) == apply(p, build(p),
    wi, wo)``. The fitter builds the tables, and their derivatives with respect to the
    parameters named in ``uses`` (the only ones they depend on), once per pass instead of once
    per block; a derivative with respect to any other parameter skips them.

    Unlike ``Model.stages`` (evaluation only), ``apply`` takes the parameters beside the
    tables, so the fitter's forward-mode tangent of a parameter outside ``uses`` closes over the
    tables instead of carrying a zero tangent through them.
    """

    build: Callable
    apply: Callable
    uses: tuple[str, ...]


@dataclasses.dataclass(frozen=True)
class Reading:
    """A parameter that says what a material *is*, held at one of two values instead of fitted.

    glTF's ``metallic`` is the example: 0 is a dielectric, 1 a metal, and the values between are
    a blend of two materials (a mask's transition, glTF 2.0 §3.9.2), not a material. Fitted
    freely it takes whatever blend lowers the cost: on the realistic corpus ``gltf-pbr`` left
    fabrics and black phenolics at ``metallic`` 0.1-0.9 and metals at 0.15-0.4. The fitter
    (:func:`brdffit.fitting.fitter.fit`) holds ``param`` at ``first``, fits, and asks
    ``decide(params, features)`` (the first fit's parameters, the data's
    :class:`~brdffit.fitting.start.Features`) whether the material is the other reading: a
    non-empty reason means yes, and the fit is made again, on the same cells, with ``param``
    held at ``other`` (and ``other_holds`` at theirs). The result's message gives the reading and its reason. A user who fixes
    or starts ``param`` fits it as any other parameter.
    """

    param: str
    first: float
    other: float
    decide: Callable[[Mapping, object], str] = dataclasses.field(repr=False, compare=False)
    #: The reading's names, for the message: ``(first, other)``.
    names: tuple[str, str] = ("first", "other")
    #: Parameters that do nothing in the other reading, held there at these values (a glTF
    #: metal's ``ior`` and ``specular``, which weigh the dielectric part only).
    other_holds: Mapping = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Model:
    """A named BRDF model: ``fn(params, wi, wo)`` with declared parameters.

    ``fn`` receives a mapping from every parameter name to an array of its shape and directions
    of shape ``(..., 3)``; it returns RGB ``f_r`` of shape ``(..., 3)`` (no cosine factor).

    ``stages`` (optional) splits ``fn`` for evaluation over large grids:
    ``(prepare, per_pair, combine)`` with ``prepare(params) -> state`` (e.g. tables built from
    the parameters), ``per_pair(state, wi, wo) -> quantities`` and
    ``combine(state, quantities) -> f_r``, such that ``fn(params, wi, wo)`` equals
    ``combine(s, per_pair(s, wi, wo))`` with ``s = prepare(params)``.
    :func:`brdffit.models.evaluate.evaluate_model` then prepares once per call and compiles the
    other two as separate programs (see :mod:`brdffit.models.aps` for why that is faster). The
    fitter uses ``fn``, or ``per_pass`` where a model declares it.

    ``start`` (optional) is the model's data-driven starting point for a fit:
    ``start(features) -> {name: value}``, from features the fitter reads off the data
    (:class:`brdffit.fitting.start.Features`: ``diffuse``, the diffuse albedo, RGB; ``height``,
    the specular peak's excess over it, RGB; ``alpha``, a GGX roughness from the peak's width;
    ``f0``, a Schlick ``F0`` from height and width, RGB; ``alpha_x``, ``alpha_y``,
    ``frame_angle``, the lobe's widths along its principal axes and the azimuth of the first,
    equal to ``alpha`` and 0 where the data do not show them). The fitter moves each value inside the
    parameter's bounds and keeps the declared default for a parameter the hook does not name.
    Without a hook the features go to parameters by name (``diffuse``, ``f0``, ``alpha``...);
    :mod:`brdffit.models.starts` has the hooks of the built-in models.

    ``per_pass`` (optional, a :class:`PerPass`) lets the fitter build parameter-only tables
    once per pass over the cells instead of once per block (``gtr``'s numerical Λ).

    ``refines`` (optional) names a simpler registered model that this one contains, with the
    map from that model's fitted parameters to starts of this one: ``(name, fn)``,
    ``fn(params) -> [{name: value}, ...]``. Unless the user gives ``init``, the fitter first
    fits the simpler model on the same cells and then starts this one from the dicts
    (parameters a dict does not name keep the data-driven start): from the one dict, or from
    the best of several after the start scan solves each on a sample of the cells
    (:mod:`brdffit.fitting.stages`); with a start that reproduces the simpler model exactly
    (``two-lobe-ggx`` with its blend at 0) the fit begins at the simpler model's cost.

    ``derived`` (optional) gives the quantities a result reports beside the parameters, which
    the model computes from them: ``derived(params) -> {name: value}`` (NumPy in, NumPy out;
    the standard models' grazing reflectance ``f90`` from ``f0`` and ``grazing``). A derived
    name is no parameter: it cannot be fixed, started or bounded, and :meth:`param` says so.

    ``reading`` (optional, a :class:`Reading`) names a parameter the fitter holds at one of two
    values (a dielectric or a metal) instead of fitting a blend of both.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    fn: Callable = dataclasses.field(repr=False, compare=False)
    isotropic: bool = True
    reference: str = ""
    stages: tuple[Callable, Callable, Callable] | None = dataclasses.field(
        default=None, repr=False, compare=False
    )
    start: Callable[[object], Mapping] | None = dataclasses.field(
        default=None, repr=False, compare=False
    )
    refines: tuple[str, Callable[[Mapping], list[Mapping]]] | None = dataclasses.field(
        default=None, repr=False, compare=False
    )
    per_pass: PerPass | None = dataclasses.field(default=None, repr=False, compare=False)
    derived: Callable[[Mapping], Mapping] | None = dataclasses.field(
        default=None, repr=False, compare=False
    )
    reading: Reading | None = dataclasses.field(default=None, repr=False, compare=False)

    # -- parameter bookkeeping ---------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def size(self) -> int:
        """Number of scalar parameters (an RGB parameter counts three)."""
        return sum(p.size for p in self.params)

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        note = ""
        if name in self.derived_values():
            note = (f"{name!r} is derived from the parameters, not one of them: "
                    f"{self.describe_derived(name)}")
        raise UnknownNameError("parameter", name, self.names, owner=f"model {self.name!r}",
                               note=note)

    def derived_values(self, params: Mapping | None = None) -> dict[str, np.ndarray]:
        """The :attr:`derived` quantities at ``params`` (defaults where missing), as NumPy
        arrays; ``{}`` for a model without any."""
        if self.derived is None:
            return {}
        full = {k: np.asarray(v, float) for k, v in self.complete(params).items()}
        return {k: np.asarray(v, float) for k, v in self.derived(full).items()}

    def describe_derived(self, name: str) -> str:
        """One sentence on derived quantity ``name``: the docstring's first line of
        :attr:`derived`, or a generic one."""
        doc = (getattr(self.derived, "__doc__", "") or "").strip()
        return " ".join(doc.split()) if doc else f"{name} is computed from the parameters."

    def defaults(self) -> dict[str, np.ndarray]:
        return {p.name: p.default_array() for p in self.params}

    def complete(self, params: Mapping | None = None) -> dict:
        """Defaults overridden by ``params``; unknown names raise :class:`UnknownNameError`."""
        out = dict(self.defaults())
        for k, v in (params or {}).items():
            self.param(k)  # raises on unknown names
            out[k] = v
        return out

    def flatten(self, params: Mapping) -> np.ndarray:
        """Concatenate parameters (in declaration order) into one float vector."""
        full = self.complete(params)
        return np.concatenate([np.ravel(self.param(n).coerce(full[n])) for n in self.names])

    def unflatten(self, x) -> dict:
        """Inverse of :meth:`flatten`; works on NumPy and JAX arrays (inside ``jit`` too)."""
        out, i = {}, 0
        for p in self.params:
            out[p.name] = x[i] if p.shape == () else x[i : i + p.size].reshape(p.shape)
            i += p.size
        return out

    def flat_names(self) -> list[str]:
        """Names of the flat vector's entries: ``alpha``, ``f0[0]``, ``f0[1]``, ..."""
        names = []
        for p in self.params:
            names += [p.name] if p.shape == () else [f"{p.name}[{i}]" for i in range(p.size)]
        return names

    def flat_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = np.concatenate([np.full(p.size, p.lower, float) for p in self.params])
        hi = np.concatenate([np.full(p.size, p.upper, float) for p in self.params])
        return lo, hi

    # -- evaluation ----------------------------------------------------------------------------
    def __call__(self, params: Mapping, wi, wo):
        """``f_r(wi, wo)`` as RGB ``(..., 3)``; missing parameters take their defaults."""
        return self.fn(self.complete(params), wi, wo)


_REGISTRY: dict[str, Model] = {}


def register(model: Model) -> Model:
    """Add ``model`` to the registry under ``model.name`` (names are unique)."""
    if model.name in _REGISTRY:
        raise ValueError(f"a model named {model.name!r} is already registered")
    _REGISTRY[model.name] = model
    return model


#: Functions ``name -> Model | None`` consulted by :func:`get_model` for a name not
#: registered: a family of variants (e.g. Mitsuba's ``roughconductor`` options) registers the
#: common ones at import and builds the others on first use by name, without registering them
#: (so :func:`available_models` does not depend on what was asked for before).
_FACTORIES: list[Callable] = []


def register_factory(factory: Callable) -> Callable:
    """Let ``factory(name)`` build models on demand (the same object for the same name; not
    registered); returns ``factory``."""
    _FACTORIES.append(factory)
    return factory


def get_model(model) -> Model:
    """A :class:`Model` from a registry name, in any case (or the model itself)."""
    if isinstance(model, Model):
        return model
    model = canonical_name(model, _REGISTRY) or model  # names ignore case: "GGX" is "ggx"
    if model not in _REGISTRY:
        for factory in _FACTORIES:
            built = factory(model.lower() if isinstance(model, str) else model)
            if built is not None:
                return built
    try:
        return _REGISTRY[model]
    except KeyError:
        raise UnknownNameError("model", model, _REGISTRY) from None


def available_models() -> list[str]:
    """Registered model names, sorted."""
    return sorted(_REGISTRY)
