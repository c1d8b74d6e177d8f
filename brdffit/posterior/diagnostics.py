r"""Is the chain long enough to trust? Acceptance, autocorrelation time, effective sample size.

Following emcee's own guidance (Foreman-Mackey et al., emcee docs "Autocorrelation analysis &
convergence"; Goodman & Weare 2010):

* **acceptance fraction** per walker; emcee suggests roughly 0.2–0.5 for the stretch move.
* **integrated autocorrelation time** ``τ`` per parameter, estimated by
  :func:`emcee.autocorr.integrated_time` (walker-averaged autocorrelation, Sokal's automatic
  window with ``c = 5``) on the post-burn, *unthinned* chain.
* **effective sample size** per parameter: ``n_walkers × n_kept_steps / τ``.
* the chain is **too short** when ``n_kept_steps < tol × τ`` with emcee's ``tol = 50``; the
  ``τ`` estimate itself is then unreliable, and :func:`check` warns with
  :class:`ChainTooShortWarning` saying how many steps to ask for.
"""

from __future__ import annotations

import dataclasses
import warnings

import emcee
import numpy as np

#: emcee's default: trust ``τ`` once the chain is longer than this many ``τ``.
TAU_TOL = 50
#: emcee's suggested range for the stretch move's acceptance fraction.
ACCEPTANCE_RANGE = (0.2, 0.5)


class ChainTooShortWarning(UserWarning):
    """The chain is shorter than ``50 τ`` or the walkers rarely move: estimates are unreliable."""


@dataclasses.dataclass(frozen=True)
class Diagnostics:
    """Convergence figures of one run (plain values, JSON-friendly through ``to_dict``).

    Attributes:
        acceptance: mean acceptance fraction over walkers; acceptance_min/max: its spread.
        tau: name → integrated autocorrelation time (steps).
        ess: name → effective sample size.
        n_kept: post-burn steps the estimates use (unthinned). tol: the ``tol`` used.
        too_short: whether ``n_kept < tol × max τ``. messages: the warnings issued (text).
    """

    acceptance: float
    acceptance_min: float
    acceptance_max: float
    tau: dict
    ess: dict
    n_kept: int
    tol: int
    too_short: bool
    messages: tuple

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["messages"] = list(self.messages)
        return d


def _messages(acc, tau_max, n_kept, tol, nsteps_total):
    out = []
    if not np.isfinite(tau_max) or n_kept < tol * tau_max:
        if np.isfinite(tau_max):
            need = int(np.ceil(tol * tau_max))
            ask = f"at least {tol} x tau = {need} (tau = {tau_max:.3g}); pass nsteps >= " \
                  f"{nsteps_total - n_kept + need}"
        else:
            ask = "enough steps to estimate tau at all; pass a larger nsteps"
        out.append(
            f"the chain is too short to trust: {n_kept} post-burn steps, emcee asks for {ask} "
            f"(or use a smaller subsample to make steps cheaper)."
        )
    lo, hi = ACCEPTANCE_RANGE
    if not lo <= acc <= hi:
        out.append(
            f"mean acceptance fraction {acc:.3f} is outside emcee's suggested {lo}–{hi}: "
            f"the posterior may be multimodal, very narrow against the start ball, or pinned "
            f"at a prior bound; check the corner plot and the least-squares fit."
        )
    return tuple(out)


def diagnose(chain, acceptance, names, burn: int, tol: int = TAU_TOL) -> Diagnostics:
    """Figures for ``chain`` (``(nsteps, nwalkers, ndim)``, unthinned, burn-in included)."""
    kept = np.asarray(chain)[burn:]
    n_kept, nwalkers = kept.shape[0], kept.shape[1]
    if n_kept > 1:
        tau = emcee.autocorr.integrated_time(kept, tol=0, quiet=True)
    else:
        tau = np.full(kept.shape[2], np.nan)
    acc = np.asarray(acceptance, float)
    tau_max = float(np.max(tau)) if np.all(np.isfinite(tau)) else float("nan")
    msgs = _messages(float(acc.mean()), tau_max, n_kept, tol, len(chain))
    return Diagnostics(
        acceptance=float(acc.mean()), acceptance_min=float(acc.min()),
        acceptance_max=float(acc.max()),
        tau={n: float(t) for n, t in zip(names, tau)},
        ess={n: float(nwalkers * n_kept / t) if t > 0 else float("nan")
             for n, t in zip(names, tau)},
        n_kept=int(n_kept), tol=int(tol),
        too_short=bool(not np.isfinite(tau_max) or n_kept < tol * tau_max), messages=msgs,
    )


def check(diag: Diagnostics) -> None:
    """Issue each of ``diag.messages`` as a :class:`ChainTooShortWarning`."""
    for text in diag.messages:
        warnings.warn(text, ChainTooShortWarning, stacklevel=3)
