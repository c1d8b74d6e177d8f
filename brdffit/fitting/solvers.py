"""The solver registry: each least-squares solver a fit may use, by name.

A solver is an optimistix solver of the Gauss–Newton family, named here by its class; the fit
makes it bounded and adds the optimality test (:func:`brdffit.fitting.bounded.make_solver`).
This module imports neither JAX nor optimistix, so the command line's ``--solver`` help
(:data:`brdffit.config.OPTIONS`) and its checks read the registry without them. A new solver is
one :class:`Solver` entry below; ``tests/test_mcmc_options.py`` checks that the help lists the
registry and ``tests/test_fit_units.py`` runs a fit with each entry.
"""

from __future__ import annotations

import dataclasses

from ..errors import UnknownNameError, canonical_name


@dataclasses.dataclass(frozen=True)
class Solver:
    """A registered solver.

    Attributes:
        name: registry name (any case on input).
        optimistix: the name of its class in :mod:`optimistix` (an
            ``AbstractLeastSquaresSolver`` with a ``descent`` and, for the trust-region ones, a
            ``search`` that :func:`~brdffit.fitting.bounded.make_solver` replaces).
        description: one line for humans.
    """

    name: str
    optimistix: str
    description: str = ""


#: The solvers by name, the default first.
SOLVERS: dict[str, Solver] = {s.name: s for s in (
    Solver("lm", "LevenbergMarquardt",
           "Levenberg–Marquardt, the bounded damped step; robust from poor starts"),
    Solver("gauss-newton", "GaussNewton",
           "Gauss–Newton, the bounded undamped step; fast near the optimum, may diverge far off"),
    Solver("dogleg", "Dogleg", "Powell's dogleg, its step projected onto the box"),
)}

#: The solver :func:`brdffit.fit` uses unless told otherwise (the default of
#: :class:`brdffit.config.FitOptions`).
DEFAULT_SOLVER = "lm"


def get_solver(name) -> Solver:
    """The :class:`Solver` registered as ``name`` (any case); :class:`UnknownNameError` (which
    lists the registry) for any other name."""
    try:
        return SOLVERS[canonical_name(name, SOLVERS) or name]
    except (KeyError, TypeError):
        raise UnknownNameError("solver", str(name), SOLVERS) from None
