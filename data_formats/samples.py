"""A format-neutral set of measured BRDF samples: the common currency of every reader.

Every reader in :mod:`data_formats` can hand its data over as a :class:`SampleSet`; the fitter
consumes nothing else. Shapes are static: missing measurements stay in the arrays, marked by
``valid == False`` (so every table of the same layout compiles once downstream).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass
class SampleSet:
    """Measured direction pairs with RGB BRDF values.

    Attributes:
        wi, wo: unit directions ``(N, 3)`` in the shading frame (``z`` is the normal).
        rgb: BRDF values ``f_r`` (no cosine factor), ``(N, 3)``; undefined where not ``valid``.
        valid: ``(N,)`` bool; ``False`` marks a missing or unusable measurement.
        name: a short label (the file stem), used in titles and summaries.
        path: the source file, if any.
        sigma: ``None``, or the measurement's standard deviation per sample and channel
            ``(N, 3)``, in the units of ``rgb`` (1/sr), > 0 where ``valid``. The fitter then
            weights each residual by it (:func:`brdffit.fitting.data.select`).
        channels: 3 for RGB; 1 for a monochrome measurement, stored in all three columns of
            ``rgb`` (so every consumer sees RGB); a fit uses channel 0 only and fits a grey
            model (:func:`brdffit.api.fit`).
        weight: ``None`` (every sample stands for the same share of the angle domain), or
            ``(N,)`` finite weights ``≥ 0``: the share of the Rusinkiewicz angle domain
            ``(θh, θd, φd)`` that each sample stands for, relative to the layout's average
            sample (so about 1 on average). A layout that samples some angles more densely
            than others says so here (a MERL table: the width in ``θh`` of each cell, which
            undoes the format's ``θh`` warp, :func:`data_formats.merl.theta_h_weights`), and
            the fitter's default ``weighting="angles"`` multiplies each squared residual by it.
        value_epsilon: the relative precision of ``rgb`` as the source stored it: the epsilon
            of its float type (``np.finfo(np.float32).eps`` for an RGL file's float32 tables),
            or 0 for values stored in float64 (MERL tables) or of unknown precision. A fit
            judges its optimality against at least the cost this rounding makes
            (:meth:`brdffit.fitting.problem.Problem.cost_floor`): no model is known to be
            closer to the data than their storage.
    """

    wi: np.ndarray
    wo: np.ndarray
    rgb: np.ndarray
    valid: np.ndarray
    name: str = ""
    path: str | None = None
    sigma: np.ndarray | None = None
    channels: int = 3
    weight: np.ndarray | None = None
    value_epsilon: float = 0.0

    def __post_init__(self):
        if self.channels not in (1, 3):
            raise ValueError(f"SampleSet.channels must be 1 or 3, got {self.channels!r}")
        if not 0.0 <= self.value_epsilon < 1.0:
            raise ValueError(f"SampleSet.value_epsilon must be in [0, 1), got "
                             f"{self.value_epsilon!r}")
        n = len(self.rgb)
        for field in ("wi", "wo", "rgb"):
            arr = getattr(self, field)
            if arr.shape != (n, 3):
                raise ValueError(f"SampleSet.{field} must have shape ({n}, 3), got {arr.shape}")
        if self.sigma is not None and np.shape(self.sigma) != (n, 3):
            raise ValueError(f"SampleSet.sigma must have shape ({n}, 3), got {np.shape(self.sigma)}")
        if self.valid.shape != (n,):
            raise ValueError(f"SampleSet.valid must have shape ({n},), got {self.valid.shape}")
        if self.weight is not None:
            w = np.asarray(self.weight)
            if w.shape != (n,):
                raise ValueError(f"SampleSet.weight must have shape ({n},), got {w.shape}")
            if not (np.all(np.isfinite(w)) and np.all(w >= 0)):
                raise ValueError("SampleSet.weight must be finite and >= 0")

    def __len__(self) -> int:
        return len(self.rgb)

    @property
    def n_valid(self) -> int:
        return int(np.count_nonzero(self.valid))

    def to_samples(self) -> "SampleSet":
        return self
