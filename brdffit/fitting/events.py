"""The progress events of one fit, delivered to that fit's callback only.

A fit sends ``setup``, ``start``, ``scan``, ``warm-done``, ``start-done`` and ``done`` from its
own code, and one event per solver step (``step``, or ``scan-step``/``warm-step`` in a stage on
a subset of the cells) with the cost the step left the fit at.

Progress is presentation, never another program: the compiled solve calls nothing back. It
records the cost after each of its steps (:class:`.bounded.Optimality`, ``history``), and the
fit's own thread sends the step events of a solve's steps when the solve returns, between the
compiled rounds of at most ``ROUND_STEPS`` steps (:meth:`.stages.Run.solve`). So a fit with a
progress callback runs the very program of a fit without one, at no cost to it, and each fit's
events reach only its own callback, also with fits running in several threads at once.
"""

from __future__ import annotations

import contextlib

import numpy as np


class Events:
    """Where one fit is (start, stage, the cost floor of the running solve) and its callback
    ``callback(event, info)`` (or ``None``)."""

    def __init__(self, callback=None):
        self.callback = callback
        self.start = 0
        self.stage = None  # None, or a solve on a subset of the cells ("warm", "scan")
        self.floor = 0.0  # the constant the solver's cost carries (Problem.cost_floor)
        self.prefix = ""  # "base-" while the simpler model of a refined fit runs
        #: every solver step of the fit so far, in every solve (scan candidates, warm stages,
        #: starts, a refined model's simpler fit), counted with or without a callback
        self.solver_steps = 0

    def emit(self, event: str, **info) -> None:
        if self.callback is not None:
            self.callback(self.prefix + event, info)

    @contextlib.contextmanager
    def nested(self, prefix: str):
        """Every event of the fit run inside (a refined model's simpler model, say) is sent with
        ``prefix`` in front of its name: ``base-start``, ``base-step``..."""
        self.prefix = prefix
        try:
            yield
        finally:
            self.prefix, self.start = "", 0

    @contextlib.contextmanager
    def in_stage(self, stage: str):
        """Marks the step events of a solve on a subset of the cells while it runs."""
        self.stage = stage
        try:
            yield
        finally:
            self.stage = None

    def steps(self, first: int, solved) -> None:
        """One step event per step of a solve that returned (a :class:`.solve.Solved`: its
        ``costs``, the solver's cost after each step, floor included), numbered from
        ``first``; every solve's steps count in :attr:`solver_steps`."""
        self.solver_steps += int(solved.steps)
        if self.callback is None:
            return
        name = "step" if self.stage is None else f"{self.stage}-step"
        costs = np.asarray(solved.costs, dtype=float)[: int(solved.steps)]
        for k, loss in enumerate(costs):
            self.emit(name, start=self.start, step=first + k, cost=float(loss) - self.floor)
