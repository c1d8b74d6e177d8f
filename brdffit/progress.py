"""Progress for fits and posteriors: ``progress=True`` is a tqdm bar, a callable gets events.

Both :func:`brdffit.fit` and :func:`brdffit.sample_posterior` take ``progress``:

* ``None`` or ``False``: silent;
* ``True``: a progress bar from ``tqdm.auto`` (a text bar on a terminal, a widget in Jupyter),
  written to ``sys.stderr``;
* a callable ``progress(event, info)``: called with the event name and a dict (the fitter's
  events are listed in :func:`brdffit.fitting.fit`; the sampler sends ``sample-step``
  with ``step`` and ``of``).

:func:`resolve` turns the argument into a callable or ``None``, and :class:`Bar` is the
callable behind ``True``: for a fit, one bar position per start (the extra starts of
``multistart``) with the current step and cost as postfix; for a posterior, one position per
emcee step.
"""

from __future__ import annotations

from collections.abc import Callable


class Bar:
    """A ``progress(event, info)`` callback drawing a ``tqdm.auto`` bar.

    Fit events: ``setup`` names the bar (the model), ``start`` opens it with the number of
    starts as its total, ``step``/``warm-step`` update the postfix (``step``, ``cost``; so do
    ``base-step``/``base-warm-step``, the simpler model a refined model is started from),
    ``start-done`` advances the bar by one, ``done`` closes it. Sampler events: ``sample-step``
    (``step``, ``of``) advances by one step. :meth:`close` is idempotent.
    """

    def __init__(self, desc: str = "", file=None):
        self.desc, self.file, self.bar = desc, file, None

    def _open(self, total, unit):
        from tqdm.auto import tqdm

        if self.bar is None:
            self.bar = tqdm(total=total, desc=self.desc, unit=unit, file=self.file,
                            dynamic_ncols=True, leave=True)
        return self.bar

    def __call__(self, event: str, info: dict) -> None:
        if event == "setup":
            self.desc = self.desc or f"fit {info.get('model', '')}".strip()
        elif event == "start":
            bar = self._open(info.get("of"), "start")
            if bar.total != info.get("of"):
                bar.total = info.get("of")
                bar.refresh()
        elif event in ("step", "warm-step", "base-step", "base-warm-step"):
            stage = {"step": "step", "warm-step": "warm"}.get(event, "simpler model")
            self._open(None, "start").set_postfix_str(
                f"{stage} {info.get('step')}, cost {float(info.get('cost', float('nan'))):.5g}"
            )
        elif event == "start-done":
            self._open(None, "start").update(1)
        elif event == "sample-step":
            bar = self._open(info.get("of"), "step")
            bar.update(1)
        elif event == "done":
            self.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def resolve(progress, desc: str = "") -> tuple[Callable | None, Bar | None]:
    """``(callback, bar)`` for a ``progress`` argument: ``True`` → a new :class:`Bar` (also
    returned, so the caller can close it when the work raises); a callable is used as is;
    ``None``/``False`` → ``(None, None)``. Anything else is a ``TypeError`` saying what is
    accepted."""
    if progress is None or progress is False:
        return None, None
    if progress is True:
        bar = Bar(desc)
        return bar, bar
    if callable(progress):
        return progress, None
    raise TypeError(
        f"progress must be True (a tqdm progress bar), False/None (silent) or a callable "
        f"progress(event, info); got {type(progress).__name__} {progress!r}"
    )
