"""Progress for fits and posteriors: ``progress=True`` is a tqdm bar, a callable gets events.

Both :func:`brdffit.fit` and :func:`brdffit.sample_posterior` take ``progress``:

* ``None`` or ``False``: silent;
* ``True``: a progress bar from ``tqdm.auto`` (a text bar on a terminal, a widget in Jupyter
  when ipywidgets is installed: ``pip install brdffit[notebook]``), written to ``sys.stderr``;
* a callable ``progress(event, info)``: called with the event name and a dict (the fitter's
  events are listed in :func:`brdffit.fitting.fit`; the sampler sends ``sample-step``
  with ``step`` and ``of``).

Progress is presentation only: a fit with any of them runs the same compiled program as a
silent one (:mod:`brdffit.fitting.events`).

:func:`resolve` turns the argument into a callable or ``None``, and :class:`Bar` is the
callable behind ``True``: for a fit, a bar that counts the solver's steps, with where the fit
is (the start, the stage) and the cost of the last step beside it; for a posterior, one
position per emcee step.
"""

from __future__ import annotations

import os
import sys
import threading
import warnings
from collections.abc import Callable

#: What a fit's step events say about the stage they come from (:mod:`brdffit.fitting.stages`).
STAGES = {"scan-step": "scan", "warm-step": "warm start", "step": "all cells"}
#: A fit's bar while its total is unknown: the steps so far and the time, without a rate (the
#: first step waits for the compilation, and the steps of the stages differ in cost).
COUNTING = "{desc}: {n_fmt} steps [{elapsed}{postfix}]"
#: The size of a terminal that does not tell its own (tqdm would take it for -1 × -1 and draw
#: nothing).
COLUMNS, ROWS = 100, 24


class Bar:
    """A ``progress(event, info)`` callback drawing ``tqdm.auto`` bars (``file``: where the
    text bar goes, ``sys.stderr`` by default).

    Fit events: ``setup`` opens a bar named after the model (or ``desc``). Its total is not
    known ahead (each stage of each start runs until it converges, up to ``max_steps``), so
    it counts: every solver step (``step``, ``scan-step``, ``warm-step``, and the same
    prefixed ``base-`` for the simpler model a refined model is started from) advances it
    by one, with the start (``start k/n``), the stage and the cost of the step beside it.
    ``done`` sets the total to the steps taken and closes the bar (full), saying whether the
    fit converged; the next fit's ``setup`` opens another. The fit sends its step events as
    each compiled round of steps returns (:mod:`brdffit.fitting.events`), so the count moves
    by up to that many steps at a time. Sampler events: ``sample-step`` (``step``, ``of``)
    advances a bar of ``of`` steps by one.

    The bar is drawn under a lock (a command line's signal handler may close it from another
    thread). :meth:`close` is idempotent.
    """

    def __init__(self, desc: str = "", file=None):
        self.desc, self.file, self.bar = desc, file, None
        self._lock = threading.RLock()
        self._where = ""  # "start k/n" of the fit, and whose it is (the simpler model's)

    def _open(self, total, desc: str, postfix: str | None = None):
        tqdm = _auto_tqdm()
        if self.bar is None:
            columns = _columns(self.file or sys.stderr)
            size = {} if columns is None else {"ncols": columns, "nrows": ROWS}
            self.bar = tqdm(total=total, desc=desc, unit="step", file=self.file, postfix=postfix,
                            dynamic_ncols=columns is None, leave=True,
                            bar_format=COUNTING if total is None else None, **size)
        return self.bar

    def __call__(self, event: str, info: dict) -> None:
        with self._lock:
            self._event(event, info)

    def _event(self, event: str, info: dict) -> None:
        base = event.startswith("base-")
        name = event.removeprefix("base-")
        if event == "setup":
            self.close()
            self._where = ""
            self._open(None, self.desc or f"fit {info.get('model', '')}".strip(),
                       f"{info.get('n_cells')} cells, {info.get('n_free')} free parameters")
        elif name == "start":
            self._where = (f"start {info.get('start', 0) + 1}/{info.get('of', 1)}"
                           + (" of the simpler model" if base else ""))
            self._fit_bar().set_postfix_str(self._where)  # drawn now: the solve begins
        elif name in STAGES:
            cost = float(info.get("cost", float("nan")))
            bar = self._fit_bar()
            bar.set_postfix_str(f"{self._where}, {STAGES[name]}, cost {cost:.5g}",
                                refresh=False)
            bar.update(1)
        elif event == "base":
            self._fit_bar().set_postfix_str(f"{info.get('model')} fitted first, "
                                            f"cost {float(info.get('cost', float('nan'))):.5g}")
        elif event == "sample-step":
            bar = self._open(info.get("of"), self.desc)
            bar.update(1)
        elif event == "done":
            if self.bar is not None:  # the total is known now: the bar ends full
                word = "converged" if info.get("success") else "did not converge"
                self.bar.total, self.bar.bar_format = self.bar.n, None
                self.bar.set_postfix_str(
                    f"{word}, cost {float(info.get('cost', float('nan'))):.5g}", refresh=False)
            self.close()

    def _fit_bar(self):
        """The fit's bar (opened here for events without a ``setup`` before them)."""
        return self._open(None, self.desc or "fit")

    def close(self) -> None:
        with self._lock:
            if self.bar is not None:
                self.bar.close()
                self.bar = None


def _auto_tqdm():
    """``tqdm.auto.tqdm``; in Jupyter without ipywidgets, tqdm's "IProgress not found" warning
    on its first import is replaced by one that names the extra that brings the widget."""
    if "tqdm.auto" in sys.modules:
        return sys.modules["tqdm.auto"].tqdm
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from tqdm.auto import tqdm
    for w in caught:
        if "IProgress" in str(w.message):
            warnings.warn("progress=True draws a text bar: the notebook's progress widget needs "
                          "ipywidgets (pip install 'brdffit[notebook]')", stacklevel=2)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return tqdm


def _columns(file) -> int | None:
    """The width of a bar drawn on ``file``: ``None`` (tqdm follows the terminal's size as it
    redraws) where ``file`` is a terminal that tells its width or no terminal at all, and
    :data:`COLUMNS` for a terminal that says 0 (a pseudo-terminal nobody sized)."""
    try:
        width = os.get_terminal_size(file.fileno()).columns
    except (AttributeError, OSError, ValueError):  # not a terminal, or no descriptor
        return None
    return width if width > 0 else COLUMNS


def resolve(progress, desc: str = "") -> tuple[Callable | None, Bar | None]:
    """``(callback, bar)`` for a ``progress`` argument: ``True`` → a new :class:`Bar`; a
    :class:`Bar` is used as is; either is also returned as ``bar``, for the caller to close
    when the work ends, also by an exception (a bar left open would take the next line of
    the terminal); another callable is used as is; ``None``/``False`` → ``(None, None)``.
    Anything else is a ``TypeError`` saying what is accepted."""
    if progress is None or progress is False:
        return None, None
    if progress is True:
        progress = Bar(desc)
    if isinstance(progress, Bar):
        return progress, progress
    if callable(progress):
        return progress, None
    raise TypeError(
        f"progress must be True (a tqdm progress bar), False/None (silent) or a callable "
        f"progress(event, info); got {type(progress).__name__} {progress!r}"
    )
