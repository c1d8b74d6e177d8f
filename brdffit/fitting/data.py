"""From a :class:`~data_formats.SampleSet` to fixed-shape device arrays and residual weights.

Selection happens in two stages, so that every table of one layout compiles once:

* **static** (depends on the directions and the options only, never on the measured values):
  cells with both directions above the horizon, within the angle ``cutoff``, and, if asked, a
  seeded ``subsample`` of a fixed size. This sets the array shapes.
* **dynamic** (weights): the validity mask and the screening of the values (:func:`screen`:
  non-finite, negative, or above :data:`MAX_BRDF`, which no measurement gives) become zero
  weights and zero targets; cells that are marked valid but fail the screening are counted by
  reason and reported in one :class:`MaskedValuesWarning`; when most valid cells are above
  :data:`MAX_BRDF` the table is at the wrong scale, not corrupt in places, and
  :func:`check_scale` refuses it. Masked cells cost compute but never
  change the shapes. A sample list with measurement uncertainties (``SampleSet.sigma``)
  weights each residual by ``1/σ`` carried through the loss's transform
  (:func:`sigma_weight`); a monochrome one (``SampleSet.channels == 1``) gives channels 1 and
  2 zero weight.
* **the angle measure** (``weighting="angles"``, the default): each residual is multiplied by
  ``sqrt(w)``, ``w`` the share of the angle domain ``(θh, θd, φd)`` its sample stands for
  (``SampleSet.weight``, :func:`measure_weight`) scaled to mean 1 over the cells used, so that
  the cost ``½Σ w r²`` approximates an integral over the angles and does not depend on how
  densely a layout samples them, while staying in the units of an average cell. A MERL
  table's ``θh`` warp puts ``90/(2i+1)`` times the average density of cells in row ``i``: 90×
  at the peak, half at ``θh = 90°``. Counting every cell once (``weighting="samples"``) lets
  the rows near the peak decide the lobe's width; on 69 measured materials that made the
  ``beckmann`` roughness systematically narrower than the published Cook–Torrance fits
  Measurements with ``σ`` are χ² terms and are not reweighted.
  ``weighting="solid-angle"`` multiplies that share by the density of direction pairs
  ``sinθh sinθd cosθd`` (:func:`brdffit.metrics.solid_angle_weight`): each cell counts by the
  solid angle ``dωi dωo`` it stands for, the measure of the MERL-fitting studies' errors (Ngan
  et al. 2005, Löw et al. 2012); the peak's rows and the grazing ``θd`` then count little.

Burley 2012 §3.1/§4.7: data past about 75–80° is extrapolated in the MERL set; ``cutoff=80``
drops it. :func:`select` keeps everything unless given a ``cutoff``; a fit's default is
:data:`brdffit.config.DEFAULT_CUTOFF` (80°), the caller's options decide.

Memory: a fit holds about :data:`FIT_BYTES_PER_CELL` bytes per selected cell beyond its input
(host gathers, the device arrays, the solver's buffers) and :data:`FIT_FIXED_BYTES` for the
compiled programs. Before anything is gathered, :func:`check_memory` compares that estimate
with what the process may still map (its address-space limit, ``ulimit -v``) and with the
memory the system has available, and refuses with a :class:`~brdffit.errors.FitError` that
says so: XLA cannot always report an allocation that fails (it may abort the process).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..config import OPTIONS
from ..errors import ConfigError, FitError, UnknownNameError
from .losses import Loss

try:
    import resource
except ImportError:  # pragma: no cover - not on Windows: no address-space limit to check
    resource = None

#: Fewer usable cells than this (times the number of free parameters) is an error.
MIN_CELLS_PER_PARAM = 3
#: Cells per block of the Jacobian accumulation (:func:`brdffit.fitting.normal_form.gram`) on a
#: CPU; larger selections are padded with zero-weight cells to a whole number of blocks. A
#: block's tangent fields then stay in the core's cache (a ``ggx`` pass over a full MERL table
#: is faster than in blocks of 32768 cells), and the start scan and the warm start can use
#: fewer cells.
CHUNK_CELLS = 4096
#: Cells per block on an accelerator, which needs wide blocks to fill its cores.
ACCELERATOR_CHUNK_CELLS = 1 << 18


def chunk_cells(backend: str | None = None) -> int:
    """Cells per block for ``backend`` (JAX's default backend if ``None``)."""
    backend = jax.default_backend() if backend is None else backend
    return CHUNK_CELLS if backend == "cpu" else ACCELERATOR_CHUNK_CELLS


@dataclasses.dataclass(frozen=True)
class Subsample:
    """A fixed-size subset of the usable cells, chosen with the fit's ``seed``.

    Attributes:
        size: an ``int`` (number of cells) or a ``float`` in ``(0, 1]`` (fraction of usable cells).
        method: ``"random"`` (uniform without replacement) or ``"stratified"`` (equal-count strata
            along ``θh``, one random cell each, so the specular peak is always represented).
    """

    size: int | float
    method: str = "random"

    def count(self, n: int) -> int:
        if isinstance(self.size, float) and not isinstance(self.size, bool):
            if not 0.0 < self.size <= 1.0:
                raise ConfigError(f"subsample fraction must be in (0, 1], got {self.size!r}")
            return max(1, round(self.size * n))
        if int(self.size) < 1:
            raise ConfigError(f"subsample size must be a positive count, got {self.size!r}")
        return min(int(self.size), n)

    def choose(self, theta_h: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Indices (sorted) of the kept cells among ``len(theta_h)`` usable ones."""
        n = len(theta_h)
        k = self.count(n)
        if self.method == "random":
            return np.sort(rng.choice(n, size=k, replace=False))
        if self.method == "stratified":
            order = np.argsort(theta_h, kind="stable")
            edges = np.linspace(0, n, k + 1).astype(int)
            picks = edges[:-1] + (rng.random(k) * np.maximum(np.diff(edges), 1)).astype(int)
            return np.sort(order[np.minimum(picks, n - 1)])
        raise ConfigError(
            f"unknown subsample method {self.method!r}; valid methods: random, stratified"
        )


def as_subsample(subsample) -> Subsample | None:
    """``None``, a :class:`Subsample`, an ``int`` count or a ``float`` fraction."""
    if subsample is None or isinstance(subsample, Subsample):
        return subsample
    if isinstance(subsample, (int, float, np.integer, np.floating)):
        return Subsample(subsample.item() if hasattr(subsample, "item") else subsample)
    raise ConfigError(
        f"subsample must be None, a count, a fraction or a Subsample, got {subsample!r}"
    )


class FitData(eqx.Module):
    """Device arrays of the selected cells (``n`` rows); the residual of cell ``k`` channel ``c``
    is ``sqrt_weight[k, c] * (g(pred) - target[k, c])``. Cosines are ``wi[:, 2]``, ``wo[:, 2]``."""

    wi: jax.Array
    wo: jax.Array
    rgb: jax.Array  # measured f_r, zero where masked
    target: jax.Array  # g(rgb)
    sqrt_weight: jax.Array  # (n, 3); zero where masked
    #: the relative precision of the measured values as stored (``SampleSet.value_epsilon``):
    #: static, so one value per table layout (:meth:`.problem.Problem.cost_floor`)
    value_epsilon: float = eqx.field(static=True, default=0.0)


@dataclasses.dataclass(frozen=True)
class Selection:
    """What was selected: counts, host copies (for the initial guess) and the device data."""

    data: FitData
    index: np.ndarray  # rows of the SampleSet that were kept, ascending (interleaved in ``data``)
    n_total: int
    n_usable: int  # above the horizon and within the cutoff
    n_used: int  # of the selected rows, those with a valid value
    chunks: int  # number of equal blocks the (padded) rows split into
    host: tuple  # (wi, wo, rgb, good) of the selected rows, NumPy, ascending, unpadded
    screened: tuple = ()  # (reason, count) of the valid selected rows masked by :func:`screen`


def _static_rows(wi, wo, cutoff):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    if cutoff is not None:  # in range: checked with the other options (brdffit.config)
        cmin = np.cos(np.radians(float(cutoff)))
        ok &= (wi[:, 2] >= cmin) & (wo[:, 2] >= cmin)
    return np.flatnonzero(ok)


def _aligned_empty(shape, dtype, align: int = 64):
    """``np.empty(shape, dtype)`` whose data start on an ``align``-byte boundary.

    ``jax.device_put`` of such an array on the CPU aliases it instead of copying it (NumPy's
    own large allocations start 16 bytes past a page, and ``jnp.asarray`` copies even an
    aligned array): a full MERL table's cells are 27 MB per array. The caller must not
    modify the array once it is on the device."""
    dtype = np.dtype(dtype)
    size = int(np.prod(shape)) * dtype.itemsize
    buf = np.empty(size + align, np.uint8)
    off = (-buf.ctypes.data) % align
    return buf[off:off + size].view(dtype).reshape(shape)


def _gather(a, rows, n_rows: int, fill, dtype):
    """``a[rows]`` in ``dtype`` with rows appended up to ``n_rows``, filled with ``fill``.

    ``rows`` are valid indices; ``mode="clip"`` only spares ``np.take`` the buffered copy that
    its default ``mode="raise"`` makes of ``out`` (10-50x slower on a full MERL table)."""
    out = _aligned_empty((n_rows,) + a.shape[1:], dtype)
    if a.dtype == out.dtype:
        np.take(a, rows, axis=0, out=out[: len(rows)], mode="clip")
    else:
        out[: len(rows)] = a[rows]
    out[len(rows) :] = fill
    return out


#: How samples are weighted against each other (:func:`measure_weight`); the first is the default
#: (the choices of the ``weighting`` option, :data:`brdffit.config.OPTIONS`).
WEIGHTINGS = OPTIONS["weighting"].choices


def measure_weight(samples, rows, weighting: str = "angles"):
    """``(len(rows),)`` multipliers of the squared residuals of ``samples[rows]``, or ``None``
    for none: ``SampleSet.weight`` under ``weighting="angles"`` (where the layout gives one and
    the samples carry no ``σ``), that times the density of direction pairs under
    ``"solid-angle"`` (:func:`brdffit.metrics.solid_angle_weight`), nothing under ``"samples"``
    (checked by :func:`select`)."""
    weight = getattr(samples, "weight", None)
    if weighting == "samples" or getattr(samples, "sigma", None) is not None:
        return None
    if weighting == "solid-angle":
        from ..metrics import solid_angle_weight

        wi, wo = np.asarray(samples.wi, float)[rows], np.asarray(samples.wo, float)[rows]
        return solid_angle_weight(wi, wo, None if weight is None else
                                  np.asarray(weight, float)[rows])
    if weight is None:
        return None
    return np.asarray(weight, float)[rows]


def select(samples, loss: Loss, *, cutoff=None, subsample=None, seed=0, dtype="float64",
           weighting="angles"):
    """Build the :class:`Selection` of ``samples`` (a ``SampleSet``) under ``loss`` and
    ``weighting`` (:data:`WEIGHTINGS`)."""
    if weighting not in WEIGHTINGS:  # before any work
        raise UnknownNameError("weighting", str(weighting), list(WEIGHTINGS))
    dirs = _directions(samples, cutoff, as_subsample(subsample), seed, dtype)
    rows, chunks, wi, wo = dirs.rows, dirs.chunks, dirs.wi, dirs.wo
    n, k = len(wi), len(rows)
    rgb = _gather(np.asarray(samples.rgb, float), rows, n, 0.0, "float64")
    good = np.zeros(n, bool)
    good[:k] = np.asarray(samples.valid, bool)[rows]
    n_valid = int(np.count_nonzero(good))
    screened = screen(rgb, good)
    if screened:
        name = getattr(samples, "name", "")
        check_scale(name, screened, n_valid)
        warnings.warn(MaskedValuesWarning(screened_text(name, screened)), stacklevel=2)
    rgb[~good] = 0.0
    sw = loss.weight(rgb, wi[:, 2:3], wo[:, 2:3]) * good[:, None]
    if getattr(samples, "sigma", None) is not None:
        sigma = _gather(np.asarray(samples.sigma, float), rows, n, 1.0, "float64")
        sw = good[:, None] * sigma_weight(loss, rgb, sigma, wi[:, 2:3], wo[:, 2:3])
    if getattr(samples, "channels", 3) == 1:  # monochrome: one measurement, in channel 0
        sw[:, 1:] = 0.0
    measure = measure_weight(samples, rows, weighting)
    if measure is not None and np.any(good[:k]):
        # mean 1 over the cells used: the cost stays that of an average cell, and so does the
        # noise scale s² = Σ w r² / (m - p) of the covariance and the posterior
        mean = float(np.mean(measure[good[:k]]))
        if not mean > 0:
            raise ConfigError("every usable sample has weight 0 (SampleSet.weight); give the "
                              "samples positive weights or fit with weighting='samples'")
        sw[:k] *= np.sqrt(measure / mean)[:, None]
    rgb.flags.writeable = False  # aliased by its device copy (:func:`_aligned_empty`)
    arrays = [jax.device_put(a) for a in (rgb, sw)]  # explicit transfers are the fast path
    rgb_d, target, sw_d = _values(dirs.wi_device, dirs.wo_device, *arrays, loss=loss,
                                  chunks=chunks, dtype=dtype)
    data = FitData(dirs.wi_device, dirs.wo_device, rgb_d, target, sw_d,
                   float(getattr(samples, "value_epsilon", 0.0)))
    host = (wi[:k], wo[:k], rgb[:k], good[:k])
    return Selection(data, rows, len(samples.wi), dirs.n_usable, int(np.count_nonzero(good)),
                     chunks, host, screened)


#: The largest BRDF value (1/sr) taken as a measurement: larger values are masked as corrupt
#: (:func:`screen`). The specular peaks of real materials reach about 10^4 (the realistic
#: corpus, ``../shared/realistic``: 8.9e3 for alumina-oxide, 2.1e3 for aluminium, at most 8.9e3
#: over its 80 materials); 10^7/sr would put all reflected light into 10^-7 sr, a cone of
#: 0.01°, finer than any gonioreflectometer resolves. A flipped exponent bit of a stored value
#: multiplies it by 2^64 or more (10^19), far past this bound.
MAX_BRDF = 1e7


class MaskedValuesWarning(UserWarning):
    """Cells marked valid whose values cannot be measurements were masked (:func:`screen`)."""


def screen(rgb: np.ndarray, good: np.ndarray) -> tuple[tuple[str, int], ...]:
    """Clear ``good`` (in place) where a row of ``rgb`` holds a value that is not a measurement:
    not finite, negative, or above :data:`MAX_BRDF`. Returns ``(reason, count)`` of the rows
    that were ``good`` before and are not now, for each reason that masked any (a row counts
    under the first reason it meets)."""
    out = []
    with np.errstate(invalid="ignore"):
        for reason, bad in (("not finite", ~np.all(np.isfinite(rgb), axis=1)),
                            ("negative", np.any(rgb < 0, axis=1)),
                            (f"above {_power(MAX_BRDF)}/sr", np.any(rgb > MAX_BRDF, axis=1))):
            hit = np.count_nonzero(bad & good)
            if hit:
                out.append((reason, int(hit)))
                good &= ~bad
    return tuple(out)


def check_scale(name: str, screened, n_valid: int) -> None:
    """Raise :class:`FitError` when most valid cells are above :data:`MAX_BRDF`: that is not a
    few corrupt values but a table at the wrong scale (or in the wrong units), and no fit of it
    means anything. ``screened``: what :func:`screen` returned; ``n_valid``: the valid selected
    cells before the screening."""
    above = sum(count for reason, count in screened if reason.startswith("above"))
    if above and 2 * above > n_valid:
        raise FitError(
            f"table {name or '(unnamed)'}: {above:,} of its {n_valid:,} valid cells are above "
            f"{_power(MAX_BRDF)}/sr, beyond any physical reflectance (f_r cos θ integrates to at "
            f"most 1 over the hemisphere): check the data's units and scale")


def _power(x: float) -> str:
    """``1e7`` for 1e7 (``format`` writes ``1e+07``)."""
    mantissa, exponent = f"{x:.0e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def screened_text(name: str, screened) -> str:
    """The sentence of a :class:`MaskedValuesWarning`."""
    total = sum(count for _, count in screened)
    why = ", ".join(f"{count:,} {reason}" for reason, count in screened)
    return (f"table {name or '(unnamed)'}: masked {total:,} cell{'s' * (total != 1)} marked "
            f"valid whose values cannot be measurements ({why}); the fit ignores "
            f"{'it' if total == 1 else 'them'}. Check the data: it may be corrupt")


#: Bytes a fit holds per selected cell beyond its input, on the CPU (the host gathers of
#: :func:`select`, the device copies of the directions, values, targets and weights, the
#: solver's per-pass buffers): measured 200 bytes (address space) and 181 (resident) for
#: 2^22 cells of a ``ggx`` fit, and 7.3 GB of address space at the peak of a 2^24-cell fit
#: that held 2.7 GB before it; a margin allowed.
FIT_BYTES_PER_CELL = 256
#: Bytes on an accelerator's host (the host gathers only; the device holds the rest).
HOST_BYTES_PER_CELL = 112
#: What a fit maps besides the cells (the compiled programs, XLA's buffers): measured 0.3 GB
#: for small fits; a margin allowed.
FIT_FIXED_BYTES = 768 << 20


def _proc_kib(path: str, key: str) -> int | None:
    """The ``key:`` line of a ``/proc`` status file in bytes (``None`` where there is none)."""
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _gb(n: float) -> str:
    return f"{n / 2**30:.1f} GiB"


def check_memory(n_cells: int, name: str = "", backend: str | None = None) -> None:
    """Raise :class:`FitError` when a fit of ``n_cells`` cells would need more memory than the
    process may map (``RLIMIT_AS`` less what it maps now) or than the system has available
    (``MemAvailable``), by the estimate in the module docstring."""
    backend = jax.default_backend() if backend is None else backend
    per_cell = FIT_BYTES_PER_CELL if backend == "cpu" else HOST_BYTES_PER_CELL
    need = FIT_FIXED_BYTES + per_cell * int(n_cells)
    limits = []
    soft, _hard = (resource.getrlimit(resource.RLIMIT_AS) if resource is not None
                   else (None, None))
    mapped = _proc_kib("/proc/self/status", "VmSize")
    if soft not in (None, getattr(resource, "RLIM_INFINITY", None)) and mapped is not None:
        limits.append((soft - mapped, f"its address-space limit (ulimit -v, {_gb(soft)}) "
                                      f"leaves {_gb(max(soft - mapped, 0))}"))
    available = _proc_kib("/proc/meminfo", "MemAvailable")
    if available is not None:
        limits.append((available, f"the system has {_gb(available)} available"))
    for room, what in limits:
        if need > room:
            raise FitError(
                f"table {name or '(unnamed)'}: fitting {int(n_cells):,} cells needs about "
                f"{_gb(need)} more memory ({per_cell} bytes a cell) and {what}; fit fewer "
                f"cells (a `subsample`, a `cutoff`) or give the process more memory"
            )



@dataclasses.dataclass(frozen=True)
class _Directions:
    """The selected rows of a sample set and their directions: ``wi``, ``wo`` on the host
    (ascending, padded to whole blocks with normal incidence) and on the device (interleaved,
    :func:`_interleave`, in the compute dtype)."""

    rows: np.ndarray
    n_usable: int
    chunks: int
    wi: np.ndarray
    wo: np.ndarray
    wi_device: jax.Array
    wo_device: jax.Array


class _Frozen:
    """A read-only direction array as a cache key: equal to another when both view the same
    memory of the same read-only owner the same way (:func:`_frozen`). It keeps the owner alive
    while the key is cached, so that memory is not reused for other values."""

    __slots__ = ("array", "key", "owner")

    def __init__(self, array: np.ndarray, key: tuple, owner: np.ndarray):
        self.array, self.key, self.owner = array, key, owner

    def __hash__(self):
        return hash(self.key)

    def __eq__(self, other):
        return isinstance(other, _Frozen) and self.key == other.key


class _Unkeyed:
    """A value passed through a memoised function without being part of its key (all equal)."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def __hash__(self):
        return 0

    def __eq__(self, other):
        return isinstance(other, _Unkeyed)


def _frozen(a: np.ndarray) -> _Frozen | None:
    """``a`` as a key for its contents, which hold while ``a``'s owner is alive: ``a`` and the
    array that owns its memory are read-only (a MERL grid's cached cell directions,
    :func:`data_formats.merl.cell_directions`). ``None`` for any other array."""
    owner = a
    while isinstance(owner.base, np.ndarray):
        owner = owner.base
    if a.flags.writeable or owner.flags.writeable:
        return None
    return _Frozen(a, (id(owner), a.__array_interface__["data"][0], a.shape, a.strides,
                       a.dtype.str), owner)


def _directions(samples, cutoff, sub: Subsample | None, seed: int, dtype: str) -> _Directions:
    """The rows of ``samples`` that :func:`select` keeps (above the horizon, within ``cutoff``,
    the ``subsample`` drawn with ``seed``) and their directions, host and device.

    They depend on the directions alone, and every MERL table of a layout has the same ones
    (read-only views of one cached grid): for read-only directions the last result is
    memoised (:func:`_memo_directions`), so fitting table after table (a batch, a benchmark,
    several models) gathers, transfers and interleaves only the values. Writable directions (a
    sample list) are always computed.
    """
    wi, wo = np.asarray(samples.wi, float), np.asarray(samples.wo, float)
    name = getattr(samples, "name", "")
    fwi, fwo = _frozen(wi), _frozen(wo)
    if fwi is None or fwo is None:
        return _laid_out(wi, wo, cutoff, sub, seed, dtype, name)
    # the dtype as JAX makes it now (float32 for "float64" without x64) is part of the key
    made = str(jax.dtypes.canonicalize_dtype(np.dtype(dtype)))
    return _memo_directions(fwi, fwo, cutoff, sub, int(seed), dtype, made, chunk_cells(),
                            _Unkeyed(name))


@functools.lru_cache(maxsize=1)
def _memo_directions(wi: _Frozen, wo: _Frozen, cutoff, sub, seed, dtype, made, chunks,
                     name: _Unkeyed):
    """:func:`_laid_out` memoised for read-only directions. A pure function of its key (``made``,
    the dtype JAX makes, and ``chunks``, the block size, are there as keys only), so a hit gives
    what a fresh selection gives; one entry: the last selection. ``name`` labels a memory error
    and is not part of the key."""
    return _laid_out(wi.array, wo.array, cutoff, sub, seed, dtype, name.value)


def _laid_out(wi, wo, cutoff, sub, seed, dtype, name) -> _Directions:
    """:func:`_directions` computed: the rows kept, gathered, padded and laid out."""
    rows = _static_rows(wi, wo, cutoff)
    n_usable = len(rows)
    if sub is not None and n_usable:
        h = wi[rows] + wo[rows]
        theta_h = np.arccos(np.clip(h[:, 2] / np.linalg.norm(h, axis=1), -1, 1))
        rows = rows[sub.choose(theta_h, np.random.default_rng(seed))]
    chunks, pad = _blocks(len(rows))
    n = len(rows) + pad
    check_memory(n, name)
    # ascending rows: a sequential gather, 5x faster than gathering in the interleaved order
    up = (0.0, 0.0, 1.0)  # padding cells: normal incidence, zero weight
    wi_h, wo_h = _gather(wi, rows, n, up, "float64"), _gather(wo, rows, n, up, "float64")
    for a in (rows, wi_h, wo_h):
        a.flags.writeable = False
    wi_d, wo_d = (_interleave(jax.device_put(a), chunks=chunks, dtype=dtype)
                  for a in (wi_h, wo_h))
    return _Directions(rows, n_usable, chunks, wi_h, wo_h, wi_d, wo_d)


def sigma_weight(loss: Loss, rho, sigma, cos_i, cos_o) -> np.ndarray:
    r"""Residual weights ``1/σ_g`` for measurements ``ρ ± σ`` (NumPy, ``(n, 3)``).

    ``σ_g`` is ``σ`` carried through the loss's transform ``g`` by its secant slope over
    ``[max(ρ-σ, 0), ρ+σ]`` (first-order error propagation, kept finite where ``ρ < σ``):

    .. math::

        \sigma_g = \sigma\,\frac{g(\rho+\sigma) - g(\max(\rho-\sigma, 0))}
                                    {\rho+\sigma - \max(\rho-\sigma, 0)} .

    The residual ``(g(ρ̂) - g(ρ)) / σ_g`` is then in units of the measurement's standard
    deviation (so ``½Σr²`` is half of χ² near the optimum): the loss's own weight is replaced,
    its transform kept. Cells where ``σ_g`` is not positive get weight zero.
    """
    lo, hi = np.maximum(rho - sigma, 0.0), rho + sigma
    slope = (np.asarray(loss.transform(hi, cos_i, cos_o)) -
             np.asarray(loss.transform(lo, cos_i, cos_o))) / (hi - lo)
    sigma_g = sigma * slope
    ok = np.isfinite(sigma_g) & (sigma_g > 0)
    return np.where(ok, 1.0 / np.where(ok, sigma_g, 1.0), 0.0)


def _layout(a, chunks: int, dtype: str):
    """``a`` cast to ``dtype`` and its rows interleaved into ``chunks`` blocks.

    Interleaving: block ``b`` holds the rows ``k, k + chunks, k + 2 chunks, ...`` of the
    (ascending, padded) selection, in the MERL layout's ``θh``-major order, with the offset
    ``k = block_order(chunks)[b]``, so any leading blocks are an evenly spread subset of the
    table, specular peak included, which the start scan and the warm start of
    :mod:`brdffit.fitting.stages` fit first. The padding cells (zero weight) are the last rows
    before interleaving; a single block keeps the order.
    """
    a = a.astype(dtype)
    if chunks == 1:
        return a
    blocks = a.reshape((-1, chunks) + a.shape[1:]).swapaxes(0, 1)
    return blocks[block_order(chunks)].reshape(a.shape)


_interleave = jax.jit(_layout, static_argnames=("chunks", "dtype"))


@functools.partial(jax.jit, static_argnames=("loss", "chunks", "dtype"))
def _values(wi, wo, rgb, sw, *, loss: Loss, chunks: int, dtype: str):
    """``(rgb, g(rgb), sw)`` of :class:`FitData`: the values ``rgb`` and weights ``sw`` (host
    order, padded) laid out as the directions ``wi``, ``wo`` already are (:func:`_layout`),
    and the loss's transform of the values. One program per table layout and loss."""
    rgb, sw = _layout(rgb, chunks, dtype), _layout(sw, chunks, dtype)
    target = jnp.where(sw > 0, loss.transform(rgb, wi[:, 2:3], wo[:, 2:3]), 0.0)
    return rgb, target, sw


def block_order(chunks: int) -> np.ndarray:
    """The row offsets ``0 … chunks-1`` of the blocks in bit-reversed order (van der Corput's
    sequence): the first ``m`` offsets are spread evenly over ``[0, chunks)`` for every ``m``
    (``0, 128, 64, 192, …`` for 256 blocks), so the first ``m`` blocks are about every
    ``chunks/m``-th row, not ``m`` runs of adjacent rows (neighbouring ``φd`` cells)."""
    bits = max(1, int(chunks - 1).bit_length())
    rev = [int(format(k, f"0{bits}b")[::-1], 2) for k in range(chunks)]
    return np.argsort(rev, kind="stable")


def _blocks(n: int) -> tuple[int, int]:
    """Number of blocks and padding rows for ``n`` selected cells."""
    size = chunk_cells()
    if n <= size:
        return 1, 0
    chunks = -(-n // size)
    return chunks, chunks * size - n


def check_enough(selection: Selection, n_free: int, name: str = "") -> None:
    """Raise :class:`FitError` when the selection cannot determine ``n_free`` parameters."""
    need = MIN_CELLS_PER_PARAM * max(n_free, 1)
    if selection.n_used < need:
        raise FitError(
            f"table {name or '(unnamed)'} has {selection.n_used} usable valid cells out of "
            f"{selection.n_total} (above the horizon, within the cutoff, finite, non-negative, "
            f"at most {_power(MAX_BRDF)}/sr); "
            f"fitting {n_free} free parameters needs at least {need}. Check the validity mask "
            f"and NaNs in the data, or relax `cutoff`/`subsample`."
        )
