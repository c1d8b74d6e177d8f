"""The progress events of one fit, delivered to that fit's callback only.

A fit sends ``setup``, ``start``, ``scan``, ``warm-done``, ``start-done`` and ``done`` from its
own code, and one event per solver step (``step``, or ``scan-step``/``warm-step`` in a stage on
a subset of the cells) from inside the compiled solve, through ``jax.debug.callback``. That
callback may run on another thread than the fit's, so neither a thread-local nor a context
variable of the caller reaches it; several fits can run at once (a batch runner's threads, a
notebook's background job). So each fit's :class:`Events` is registered under an integer id
while the fit runs, the solver's ``verbose`` hook (:class:`StepReporter`) carries that id as an
*operand* of the callback (an array of the solver: every fit runs the same compiled program),
and the callback looks the fit up by it.

Progress is presentation, never a different program: every fit's solver carries a
:class:`StepReporter`, with or without a callback. A fit without one carries the id ``0``
(:data:`SILENT`) and is not registered; inside the program the callback sits in a
``lax.cond`` on ``id != 0``, so a silent fit runs the same compiled program as one with a
progress bar and never calls back to the host.
"""

from __future__ import annotations

import contextlib
import itertools

import equinox as eqx
import jax
import numpy as np

#: The fits running now, by id (a fit with a callback registers itself for the duration of
#: its solves).
_RUNNING: dict[int, Events] = {}
_IDS = itertools.count(1)
#: The id a fit without a callback carries: its step events are never sent (see the module
#: docstring).
SILENT = 0


class Events:
    """Where one fit is (start, stage, the cost floor of the running solve) and its callback
    ``callback(event, info)`` (or ``None``). Use as a context manager around the solves."""

    def __init__(self, callback=None):
        self.callback = callback
        self.id = SILENT if callback is None else next(_IDS)
        self.start = 0
        self.stage = None  # None, or a solve on a subset of the cells ("warm", "scan")
        self.floor = 0.0  # the constant the solver's cost carries (Problem.cost_floor)
        self.prefix = ""  # "base-" while the simpler model of a refined fit runs

    def __enter__(self) -> Events:
        if self.id != SILENT:
            _RUNNING[self.id] = self
        return self

    def __exit__(self, *exc) -> None:
        _RUNNING.pop(self.id, None)

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

    def step(self, step, loss) -> None:
        cost = float(loss) - self.floor  # the solver's cost carries the constant floor
        self.emit("step" if self.stage is None else f"{self.stage}-step", start=self.start,
                  step=int(step), cost=cost)

    def reporter(self) -> StepReporter:
        """The solver's ``verbose`` hook for this fit (one that sends nothing without a
        callback: the same program either way)."""
        return StepReporter(np.asarray(self.id, np.int32))


def _report(fit_id, step, loss) -> None:
    events = _RUNNING.get(int(fit_id))
    if events is not None:
        events.step(step, loss)


class StepReporter(eqx.Module):
    """optimistix ``verbose`` callable: sends (step, cost) to the :class:`Events` of fit
    ``fit_id``, which is an operand of the callback (see the module docstring); nothing, and no
    call to the host, when ``fit_id`` is :data:`SILENT`."""

    fit_id: jax.Array

    def __call__(self, **kwargs) -> None:
        def send(fit_id, step, loss):
            jax.debug.callback(_report, fit_id, step, loss)

        def skip(fit_id, step, loss):
            del fit_id, step, loss

        jax.lax.cond(self.fit_id != SILENT, send, skip, self.fit_id,
                     kwargs["num_steps"][1], kwargs["loss_this_step"][1])
