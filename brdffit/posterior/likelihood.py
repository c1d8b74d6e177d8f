r"""The log-posterior handed to emcee: one jitted, vectorized JAX function of the walkers.

Noise model (the one convention, stated once). The fit's residual of cell ``k``, channel ``c``
under the chosen loss (:mod:`brdffit.fitting.losses`) is
``r_kc(θ) = w_kc (g(ρ̂_kc(θ)) - g(ρ_kc))``; the likelihood treats the ``m`` residuals with
non-zero weight as independent Gaussians of one scale ``σ``:

.. math::

    \log p(\rho \mid \theta, \sigma) = -\frac{1}{2\sigma^2}\sum_{kc} r_{kc}(\theta)^2
        - m \log\sigma - \frac{m}{2}\log 2\pi .

So the posterior sees the data exactly as the least-squares fit does (same cells, same
transform ``g``, same weights ``w``, which include each cell's share of the angles under the
default ``weighting="angles"``, scaled to mean 1, so that ``σ`` is the scatter of an average
cell), and with a flat prior its mode is the least-squares optimum. With a Huber loss the residual is already Huberized, so the "Gaussian" becomes Huber's
density (quadratic core, linear tails) — a robust likelihood, on purpose.

``σ`` is learned from the residuals unless the data carry their own uncertainties:

* **sandwich** (the default for a fit whose covariance is the sandwich, as it is by default):
  ``σ = s`` with ``s² = Σr²/(m − p)`` on the cells the posterior uses, and the likelihood's
  curvature *calibrated* to the sandwich covariance of the same residuals
  (:func:`sandwich_adjustment`, the curvature adjustment of Ribatet, Cooley & Davison 2012,
  "Bayesian inference from composite likelihoods", Statistica Sinica 22; Chandler & Bate 2007):

  .. math::

      \log p_{\mathrm{adj}}(\rho \mid \theta) = \log p(\rho \mid \hat\theta + C(\theta - \hat\theta), s),
      \qquad C^\top H C = B^{-1},

  with ``θ̂`` the least-squares optimum on these cells, ``H = JᵀJ/s²`` the Gaussian
  likelihood's curvature and ``B`` the sandwich covariance
  :math:`\frac{m}{m-p}(J^\top J)^{-1}(\sum_i r_i^2 J_i^\top J_i)(J^\top J)^{-1}` of
  :mod:`brdffit.fitting.statistics`; ``C = H^{-1/2} B^{-1/2}`` (symmetric roots, in units of
  each scalar's standard error). The mode stays at ``θ̂`` and, near it, the posterior's
  covariance is ``B``: it does not assume that every residual has the same spread (under the
  ``log`` loss, multiplicative noise gives the peak cells a hundred times the spread of a dark
  diffuse floor; the one-``σ`` Gaussian then puts its intervals in the wrong places).
  Scalars with no sandwich error (on a bound, not identified) are left unadjusted.
* **fixed**: ``σ = s`` and the plain Gaussian above (the classical ``s²(JᵀJ)⁻¹`` near the
  mode: the default for a fit whose covariance is ``"gn"``);
* **sampled**: ``sigma`` is one more parameter with a log-uniform (Jeffreys, ``∝ 1/σ``) prior
  on ``[s/100, 100 s]``;
* a number: ``σ`` given;
* **measured**, for data with measurement uncertainties (a sample list with ``sigma``
  columns): ``σ = 1``. The fit's weights are then ``1/σ_kc`` carried through ``g``
  (:func:`brdffit.fitting.data.sigma_weight`), so ``r_kc`` is already in units of each sample's
  own standard deviation and the likelihood above is the Gaussian measurement likelihood
  ``Π N(ρ_kc; ρ̂_kc, σ_kc²)`` to first order in ``σ``. The default when the data carry
  ``sigma``.

Warning: every mode treats the residuals of different cells as independent. The residuals of a
model fitted to a measured table are mostly model error, smooth and correlated across cells, so
on real data the posterior, like the least-squares standard errors, measures how well the
*model family* pins the parameters down on these cells, not the uncertainty of the material,
and it does not cover the model error (the summary says so:
:func:`brdffit.posterior.result.interval_meaning`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ConfigError
from ..fitting import FitData, Problem
from .priors import LogUniform, PriorBox

#: The sampled noise scale's prior spans this factor either side of the least-squares ``s``.
SIGMA_PRIOR_SPAN = 100.0
NOISE_MODES = ("sandwich", "fixed", "sampled", "measured")


class LogPosterior(eqx.Module):
    """``log p(θ | data)`` up to a constant, for one ``θ`` (free scalars, then ``sigma``).

    Attributes:
        problem: the fit's :class:`~brdffit.fitting.problem.Problem` (model, loss, free scalars,
            fixed values); its ``residual_x`` is the residual the likelihood uses.
        data: the selected cells (:class:`~brdffit.fitting.data.FitData`).
        prior: the :class:`~.priors.PriorBox` (its arrays become constants of the program).
        sigma: the fixed noise scale (ignored when sampled).
        n_obs: ``m``, the number of residuals with non-zero weight.
        center: a point inside the prior box where the model is evaluated for walkers that
            fall outside it (their value is ``-inf`` anyway; this keeps NaNs out).
        sample_sigma: whether the last entry of ``θ`` is ``sigma``.
        adjust, anchor: the curvature adjustment ``C`` and its centre ``θ̂`` (mode
            ``"sandwich"``): the likelihood is evaluated at ``θ̂ + C(θ − θ̂)``; ``None`` for
            the plain likelihood.
        lo, hi: the free scalars' physical bounds; an adjusted point outside them is moved to
            the nearest point inside (the adjustment is a local map about ``θ̂``: a walker far
            from it, in a user's prior that excludes ``θ̂``, would otherwise have no density at
            all, and the sampler could not start).
    """

    problem: Problem
    data: FitData
    prior: PriorBox
    sigma: jax.Array
    n_obs: float = eqx.field(static=True)
    center: jax.Array
    sample_sigma: bool = eqx.field(static=True)
    adjust: jax.Array | None = None
    anchor: jax.Array | None = None
    lo: jax.Array | None = None
    hi: jax.Array | None = None

    def __call__(self, theta):
        n_free = len(self.problem.free)
        lp = self.prior.log_prior(theta)
        inside = jnp.isfinite(lp)
        x = theta[:n_free]
        if self.adjust is not None:
            x = jnp.clip(self.anchor + self.adjust @ (x - self.anchor), self.lo, self.hi)
        x = jnp.where(inside, x, self.center)
        r = self.problem.residual_x(x, self.data).astype(theta.dtype)
        sigma = jnp.where(inside, theta[n_free], 1.0) if self.sample_sigma else self.sigma
        ll = -0.5 * jnp.sum(jnp.square(r)) / sigma**2 - self.n_obs * (
            jnp.log(sigma) + 0.5 * jnp.log(2.0 * jnp.pi)
        )
        return jnp.where(inside & jnp.isfinite(ll), lp + ll, -jnp.inf)


@eqx.filter_jit
def log_posterior_batch(post: LogPosterior, thetas):
    """``(B, d) -> (B,)``: :class:`LogPosterior` over a batch of walkers (``jax.vmap``)."""
    return jax.vmap(post)(thetas)


def n_observations(data: FitData) -> int:
    """``m``: residuals that carry weight (masked cells have ``sqrt_weight == 0``)."""
    return int(np.count_nonzero(np.asarray(data.sqrt_weight) > 0))


@eqx.filter_jit
def _sum_squares(problem: Problem, x_free, data: FitData):
    return jnp.sum(jnp.square(problem.residual_x(x_free, data)))


def least_squares_sigma(problem: Problem, x_free, data: FitData) -> float:
    """``s = sqrt(Σr² / (m - p))`` at ``x_free`` on ``data`` (``p`` free scalars).

    Jitted: run op by op, a model with a numerical Λ (``gtr``) would compile each primitive of
    its quadrature separately, far slower than one compile of the whole."""
    ssq = float(_sum_squares(problem, jnp.asarray(x_free), data))
    dof = max(n_observations(data) - len(problem.free), 1)
    return float(np.sqrt(ssq / dof))


def noise_setup(noise, s_hat: float):
    """``(sigma, sample_sigma, extra_prior)`` for ``noise`` = ``"fixed"``, ``"sampled"``,
    ``"measured"`` (``σ = 1``: residuals already divided by each sample's ``σ``) or a positive
    number; ``extra_prior`` is ``[("sigma", LogUniform)]`` when sampled."""
    if isinstance(noise, str):
        if noise == "measured":
            return 1.0, False, []
        if noise not in NOISE_MODES:
            raise ConfigError(
                f"noise must be one of {', '.join(NOISE_MODES)} or a positive number, got "
                f"{noise!r}"
            )
        if not (np.isfinite(s_hat) and s_hat > 0):
            raise ConfigError(
                f"the least-squares noise estimate is {s_hat!r} (a perfect fit?): pass "
                f"`noise=<positive number>` to set the noise scale yourself"
            )
        if noise in ("fixed", "sandwich"):
            return s_hat, False, []
        span = LogUniform(s_hat / SIGMA_PRIOR_SPAN, s_hat * SIGMA_PRIOR_SPAN)
        return s_hat, True, [("sigma", span)]
    try:
        value = float(noise)
    except (TypeError, ValueError):
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise ConfigError(f"noise must be one of {', '.join(NOISE_MODES)} or a positive number, "
                          f"got {noise!r}")
    return value, False, []


@eqx.filter_jit
def _jacobian(problem: Problem, x_free, data: FitData):
    """The residual and its Jacobian in the free physical scalars, ``(r, J)``."""
    r = problem.residual_x(x_free, data)
    return r, jax.jacfwd(lambda x: problem.residual_x(x, data))(x_free)


def _root(a, power: float) -> np.ndarray:
    """``a^power`` of a symmetric positive definite matrix (eigenvalues clipped above 0)."""
    w, v = np.linalg.eigh(a)
    w = np.clip(w, 1e-300 + 1e-14 * max(float(w.max()), 0.0), None)
    return (v * w**power) @ v.T


def sandwich_adjustment(problem: Problem, x_free, data: FitData, keep) -> np.ndarray:
    """The curvature adjustment ``C`` (module docstring) over the free scalars, at the
    least-squares optimum ``x_free`` on ``data``: ``C = S H_y^{-1/2} B_y^{-1/2} S^{-1}`` over
    the ``keep`` scalars, in the coordinates ``y = S⁻¹x`` with ``S`` their sandwich standard
    errors (so both roots are of well-scaled matrices); the identity elsewhere."""
    r, jac = (np.asarray(a, float) for a in _jacobian(problem, jnp.asarray(x_free), data))
    c = np.eye(len(x_free))
    k = np.flatnonzero(np.asarray(keep, bool))
    m = n_observations(data)
    if len(k) == 0 or m <= len(k):
        return c
    jk = jac[:, k]
    jtj = jk.T @ jk
    meat = (jk * (r**2)[:, None]).T @ jk
    s2 = float(r @ r) / (m - len(k))
    inv = np.linalg.pinv(jtj, hermitian=True)
    b = inv @ meat @ inv * (m / (m - len(k)))
    scale = np.sqrt(np.clip(np.diag(b), 1e-300, None))
    hy = jtj / s2 * np.outer(scale, scale)
    by = b / np.outer(scale, scale)
    c[np.ix_(k, k)] = (_root(hy, -0.5) @ _root(by, -0.5)) * scale[:, None] / scale[None, :]
    return c
