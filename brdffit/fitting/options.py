"""The options of a fit: one path that checks them, whether given as keywords or as a
:class:`~brdffit.config.FitOptions`, and the defaults that live in code.

:func:`fit_options` merges a ``FitOptions`` (or a mapping of option names) with keyword
arguments, the keywords winning option by option, and refuses unknown names, out-of-range
numbers (:func:`brdffit.config.check_fit_options`) and unknown ``covariance``/``precision``/
``weighting`` names (:func:`brdffit.config.canonical_choices`) before any work: every option's
default, range and choices live in one place, :class:`brdffit.config.FitOptions`.
:meth:`Settings.of` then resolves what is left: the loss by name, the precision and the
tolerances that depend on it; :func:`brdffit.fitting.fit` takes a ``Settings`` as it is.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import jax

from ..config import CODE_DEFAULTS, FitOptions, canonical_choices, check_fit_options
from .losses import Loss, get_loss
from .bounded import FTOL

#: Every option of :func:`brdffit.fitting.fit` with its default (``None``: decided from the
#: data, the precision or not at all; see :class:`Settings`); they live with the options
#: themselves, in :class:`brdffit.config.FitOptions`.
FIT_DEFAULTS = CODE_DEFAULTS


def default_precision() -> str:
    """The dtype of the model evaluation when none is asked for: ``"float64"`` when the caller
    enabled ``jax_enable_x64``, else ``"float32"``."""
    return "float64" if jax.config.jax_enable_x64 else "float32"


def tolerances(precision: str, rtol=None, atol=None, ftol=None) -> tuple[float, float, float]:
    """``(rtol, atol, ftol)`` with the defaults of ``precision`` filled in: the Cauchy test's
    ``1e-14`` in float64 (``1e-6`` in float32), near rounding so that it catches only a true
    stall, and the optimality test's :data:`~brdffit.fitting.bounded.FTOL`."""
    base = 1e-14 if precision == "float64" else 1e-6
    return (
        base if rtol is None else float(rtol),
        base if atol is None else float(atol),
        FTOL[precision] if ftol is None else float(ftol),
    )


def fit_options(options=None, **kwargs) -> dict:
    """The options of one fit, checked: ``options`` (a :class:`~brdffit.config.FitOptions` or a
    mapping of option names) overridden by ``kwargs``; only what was given, defaults not filled
    in.

    Raises ``TypeError`` for a name that is no option (listing the valid ones),
    :class:`~brdffit.errors.ConfigError` for a number out of its range and
    :class:`~brdffit.errors.UnknownNameError` for an unknown ``covariance``, ``precision`` or
    ``weighting`` (names in any case; returned as the canonical name).
    """
    if options is None:
        given = {}
    elif isinstance(options, FitOptions):
        given = options.fit_kwargs()
    elif isinstance(options, Mapping):
        given = dict(options)
    else:
        raise TypeError(f"options must be a FitOptions or a mapping of option names, got "
                        f"{type(options).__name__}")
    given.update(kwargs)
    unknown = sorted(set(given) - set(FIT_DEFAULTS))
    if unknown:
        raise TypeError(
            f"brdffit.fit() got unknown option(s) {', '.join(unknown)}; valid options: "
            f"{', '.join(sorted(FIT_DEFAULTS))}, progress, throw"
        )
    return canonical_choices(check_fit_options(given))


@dataclasses.dataclass(frozen=True)
class Settings:
    """The options of one fit, every default resolved (defaults: :data:`FIT_DEFAULTS`).

    Attributes:
        loss: the :class:`~brdffit.fitting.losses.Loss`, from a name of
            :data:`brdffit.fitting.LOSSES` (``"log"`` by default, ``"log+huber"``...) or given.
        solver: as given: ``"lm"`` (default), ``"gauss-newton"``, ``"dogleg"``, or an optimistix
            least-squares solver.
        init: name → starting value (overrides the data-driven guess), or a previous
            ``FitResult``.
        fixed: name → value of scalars held fixed (``"f0"`` or one component ``"f0[1]"``).
        bounds: name → ``(lo, hi)`` overriding the declared bounds.
        cutoff: drop cells with ``θi`` or ``θo`` above this many degrees (Burley 2012 §4.7;
            default :data:`brdffit.config.DEFAULT_CUTOFF`, 80°; ``None`` given explicitly or
            90 keeps every cell above the horizon).
        subsample: a cell count, a fraction, or a :class:`~brdffit.fitting.data.Subsample`.
        seed: for the subsample and the multi-start perturbations.
        multistart: number of extra perturbed starts; the lowest cost wins.
        max_steps: the step limit; reaching it is a failure (``success=False``), never the
            normal way out. It bounds every solve of the fit, so a whole fit takes at most
            ``(1 + multistart) × (3 scan candidates + warm + full) × max_steps`` steps (twice
            that for a model fitted from another model's optimum), each one pass over at most
            the selected cells: its time is bounded by the step limit and the cell count,
            whatever the values (values that are no measurement are masked before the fit,
            :func:`brdffit.fitting.data.screen`).
        rtol, atol: optimistix's Cauchy test on the accepted step (defaults 1e-14 in float64,
            1e-6 in float32: near rounding, so that it ends only a solve that no longer moves,
            reported as stalled unless the optimality test holds too).
        ftol: the optimality test: converged when the bounded Gauss–Newton step from the end
            point would lower the cost by less than ``ftol`` times the cost (default 1e-9 in
            float64, 1e-6 in float32); see :func:`brdffit.fitting.bounded.optimality`.
        scan: before the warm start, solve a few candidate starts with shifted lobe widths on a
            small evenly spread subset of the cells and keep the best
            (:mod:`brdffit.fitting.stages`); ``False`` starts from the data-driven (or given)
            start alone. A model that refines a simpler one scans the starts the simpler fit
            maps to; ``False`` fits each of them to the end and keeps the best.
        precision: ``"float64"`` or ``"float32"`` model evaluation (products are accumulated in
            float64 either way when x64 is enabled); default :func:`default_precision`.
        covariance: ``"sandwich"`` (default, robust to heteroscedastic residuals) or ``"gn"``
            (classical ``s² (JᵀJ)⁻¹``); see :mod:`brdffit.fitting.statistics`.
        weighting: ``"angles"`` (default): each squared residual counts by the share of the
            angle domain its sample stands for (``SampleSet.weight``; on a MERL table the
            ``θh`` width of its cell, which undoes the format's warp towards the peak);
            ``"samples"``: every sample counts once; ``"solid-angle"``: by the solid angle
            ``dωi dωo`` it stands for (the MERL-fitting studies' measure). See
            :mod:`brdffit.fitting.data`.
        energy: ``"limit"`` (default): a fit whose directional albedo exceeds 1 at some
            incidence is solved again with the albedo held at most 1
            (:mod:`brdffit.fitting.constraints`); ``"free"``: the optimum as it is (the verdict
            still flags it).
    """

    loss: Loss
    solver: object
    init: object
    fixed: Mapping | None
    bounds: Mapping | None
    cutoff: float | None
    subsample: object
    seed: int
    multistart: int
    max_steps: int
    rtol: float
    atol: float
    ftol: float
    scan: bool
    precision: str
    covariance: str
    weighting: str
    energy: str

    @classmethod
    def of(cls, given: Mapping) -> Settings:
        """From the output of :func:`fit_options`, over :data:`FIT_DEFAULTS`: every option
        passes through by its name, the ones resolved here replaced. A field of
        :class:`~brdffit.config.FitOptions` without a field here (or the reverse) is a
        ``TypeError`` at the first fit, never an option silently dropped."""
        o = {**FIT_DEFAULTS, **given}
        precision = o["precision"] or default_precision()
        rtol, atol, ftol = tolerances(precision, o["rtol"], o["atol"], o["ftol"])
        return cls(**{
            **o, "loss": get_loss(o["loss"]), "multistart": int(o["multistart"]),
            "max_steps": int(o["max_steps"]), "rtol": rtol, "atol": atol, "ftol": ftol,
            "scan": bool(o["scan"]), "precision": precision,
        })
