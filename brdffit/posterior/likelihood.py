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

``σ`` is either **fixed** at the least-squares estimate ``s² = Σr²/(m − p)`` (the same ``s²``
as the fit's covariance, :mod:`brdffit.fitting.statistics`, but evaluated on the cells the
posterior uses), given as a number, or **sampled** as one more parameter ``sigma`` with a
log-uniform (Jeffreys) prior on ``[s/100, 100 s]``, or, for data with measurement
uncertainties (a sample list with ``sigma`` columns), **measured**: ``σ = 1``. The fit's weights
are then ``1/σ_kc`` carried through ``g`` (:func:`brdffit.fitting.data.sigma_weight`), so
``r_kc`` is already in units of each sample's own standard deviation and the likelihood above
is the Gaussian measurement likelihood ``Π N(ρ_kc; ρ̂_kc, σ_kc²)`` to first order in ``σ``.
"measured" is the default when the data carry ``sigma``.

Warning: the model assumes homoscedastic, independent residuals under the chosen loss. Measured
tables violate this (model error is smooth and correlated across cells), so on real data the
posterior, like the least-squares standard errors, measures how well the *model family* pins
the parameters down given scatter ``σ``, not the true measurement uncertainty.
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
NOISE_MODES = ("fixed", "sampled", "measured")


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
    """

    problem: Problem
    data: FitData
    prior: PriorBox
    sigma: jax.Array
    n_obs: float = eqx.field(static=True)
    center: jax.Array
    sample_sigma: bool = eqx.field(static=True)

    def __call__(self, theta):
        n_free = len(self.problem.free)
        lp = self.prior.log_prior(theta)
        inside = jnp.isfinite(lp)
        x = jnp.where(inside, theta[:n_free], self.center)
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
        if noise == "fixed":
            return s_hat, False, []
        span = LogUniform(s_hat / SIGMA_PRIOR_SPAN, s_hat * SIGMA_PRIOR_SPAN)
        return s_hat, True, [("sigma", span)]
    try:
        value = float(noise)
    except (TypeError, ValueError):
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise ConfigError(f"noise must be 'fixed', 'sampled' or a positive number, got {noise!r}")
    return value, False, []
