"""Error types. Every user-facing mistake raises a subclass of :class:`BrdffitError`.

The command line prints such errors as one line on stderr and exits with code 2; file-format
errors come from :mod:`data_formats` (e.g. ``MERLFormatError``) and are treated the same way.
"""

from __future__ import annotations

import difflib


class BrdffitError(ValueError):
    """Base class of the errors a user can fix (bad names, bad values, bad configs)."""


class UnknownNameError(BrdffitError, KeyError):
    """A name (model, parameter, loss, solver, config key) that is not in its registry."""

    def __init__(self, kind: str, name: str, valid, owner: str = "", note: str = ""):
        """``owner`` (e.g. ``"model 'ggx'"``) makes the sentence "model 'ggx' has no parameter
        'F0'"; without it: "unknown loss 'lgo'". A suggestion follows: ``note`` when given (what
        the name is instead and what to use), else a name differing only in case, else the
        closest one (``difflib``)."""
        valid = sorted(str(v) for v in valid)
        same_case = [v for v in valid if v.lower() == str(name).lower()]
        close = same_case or difflib.get_close_matches(str(name), valid, n=1)
        hint = f" {note}" if note else f" Did you mean {close[0]!r}?" if close else ""
        self.kind, self.name, self.valid = kind, name, valid
        head = f"{owner} has no {kind} {name!r}" if owner else f"unknown {kind} {name!r}"
        super().__init__(f"{head}; valid choices: {', '.join(valid)}.{hint}")

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return self.args[0]


def canonical_name(name, valid):
    """The entry of ``valid`` that ``name`` names, ignoring case (registry names are
    case-insensitive where a user types them: ``GGX`` is ``ggx``); ``name`` itself when it is an
    entry; ``None`` when no entry matches (or ``name`` is not a string)."""
    if not isinstance(name, str):
        return None
    if name in valid:
        return name
    folded = [v for v in valid if isinstance(v, str) and v.casefold() == name.casefold()]
    return folded[0] if len(folded) == 1 else None


class ConfigError(BrdffitError):
    """A preset or option with a wrong key, type or value."""


class FitError(BrdffitError):
    """A fit that cannot run (no usable data) or that failed with ``throw=True``.

    ``result``: the :class:`~brdffit.fitting.FitResult` of a fit that ran and failed (the step
    limit, a non-finite cost, data that determine nothing: ``success=False``, its ``status``
    and ``message`` say why), as ``throw=False`` would have returned it; ``None`` for a fit
    that could not start. It survives pickling (a Dask worker's error keeps its result).
    """

    def __init__(self, message: str, result=None):
        super().__init__(message)
        self.result = result

    def __reduce__(self):
        return type(self), (self.args[0] if self.args else "", self.result)
