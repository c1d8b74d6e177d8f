"""Reading a fit result's JSON: the source (a path or the text), the document, every field checked.

The format is what :meth:`FitResult.to_json` writes: one object whose keys are the fields of
:class:`~brdffit.fitting.result.FitResult` (``posterior``, which ``brdffit fit --mcmc --out``
adds, and ``uncertainty``, derived from the fields, are skipped), numbers that were not finite written as ``null``. ``brdffit fit -m a,b --out``
writes several results as ``{"results": [...]}``, best first; :func:`pick` chooses one by model.

Anything else raises :class:`ResultFormatError`, one line naming the source (the path, or
``<string>``) and the first problem found: text that is not UTF-8 or not JSON, a document that is
not an object (or not strict JSON: ``NaN``, ``Infinity``, a number beyond the float range), a
missing or unknown key, a value of the wrong type, a number out of range,
vectors of disagreeing lengths, ``names`` that are not the registered model's. A UTF-8
byte-order mark is skipped. A model name the registry does not know is read as it is, for the
caller to report (``result.model`` raises :class:`~brdffit.errors.UnknownNameError`).
"""

from __future__ import annotations

import errno
import json
import math
import numbers
import os
from pathlib import Path

import numpy as np

from ..errors import BrdffitError, canonical_name

#: A ``str`` longer than this is JSON text, never a path (Linux's ``PATH_MAX``).
_PATH_MAX = 4096


class ResultFormatError(BrdffitError):
    """A result file or string that is not a brdffit result. ``source``: its path or
    ``"<string>"``; ``problem``: what is wrong."""

    def __init__(self, source, problem: str):
        self.source, self.problem = str(source), " ".join(str(problem).split())
        super().__init__(f"{self.source}: not a brdffit result ({self.problem})")


class ResultChoiceError(BrdffitError):
    """A file of several results read without naming one, or naming one it does not hold.
    ``models``: the model names in the file, in its order; ``requested``: the name asked for."""

    def __init__(self, source, models: list, requested: str | None):
        self.source, self.models, self.requested = str(source), list(models), requested
        held = ", ".join(self.models)
        head = (f"{self.source} holds {len(self.models)} results ({held})" if requested is None
                else f"{self.source} holds no {requested} result (it holds {held})")
        super().__init__(f"{head}; pass model=NAME with one of them")


# -- the source ---------------------------------------------------------------------------------
def is_json_text(source) -> bool:
    """True when ``source`` is JSON text rather than a path: ``bytes``, or a ``str`` that, past
    a byte-order mark and white space, starts with ``{`` or ``[``, or that no file name can be
    (empty, white space, a leading byte-order mark, a newline or a NUL in it, longer than
    ``PATH_MAX``). ``os.PathLike`` is a path. A ``str`` read as a path that turns out to be no
    file name (a component too long), or to name no file while being JSON, is read as text
    (:func:`read_document`)."""
    if isinstance(source, (bytes, bytearray)):
        return True
    if not isinstance(source, str):
        return False
    head = source.lstrip("\ufeff \t\r\n")[:1]
    return (head in ("{", "[", "") or source.startswith("\ufeff") or "\n" in source
            or "\0" in source or len(source) > _PATH_MAX)


def read_document(source):
    """``(name, document)``: the parsed JSON of a path or of JSON text (:func:`is_json_text`)."""
    if is_json_text(source):
        return "<string>", parse_text("<string>", source)
    if not isinstance(source, (str, os.PathLike)):
        raise TypeError(f"expected a path or JSON text, got {type(source).__name__}")
    try:
        raw = Path(source).read_bytes()
    except OSError as exc:
        # A str that no file name can be (a component too long) or that names no file but is
        # JSON ('"x"', 'null') was meant as text: the format's own error says what it holds.
        if isinstance(source, str) and (exc.errno == errno.ENAMETOOLONG or _is_json(source)):
            return "<string>", parse_text("<string>", source)
        raise
    return os.fspath(source), parse_text(os.fspath(source), raw)


def _is_json(text: str) -> bool:
    try:
        json.loads(text)
    except (ValueError, RecursionError):
        return False
    return True


def parse_text(name, raw):
    """The JSON document of ``raw`` (``str``, or ``bytes`` in UTF-8), past a byte-order mark."""
    if isinstance(raw, (bytes, bytearray)):
        try:
            raw = bytes(raw).decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            problem = f"not UTF-8 text: {exc.reason} at byte {exc.start}"
            raise ResultFormatError(name, problem) from None
    if not isinstance(raw, str):
        raise TypeError(f"expected JSON text (str or bytes), got {type(raw).__name__}")
    try:
        return json.loads(raw.removeprefix("\ufeff"), parse_constant=_no_constant,
                          parse_float=_finite)
    except RecursionError:
        raise ResultFormatError(name, "JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError; an integer of more digits than Python reads
        raise ResultFormatError(name, f"not JSON: {exc}") from None


def _no_constant(token):
    raise ValueError(f"{token} is not JSON (the format writes null for a number that is not "
                     f"finite)")


def _finite(text):
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:30]} is beyond the float range")
    return value


def entries(name, document) -> list:
    """The result objects of a document: itself, or the items of ``{"results": [...]}``."""
    if isinstance(document, dict) and set(document) == {"results"}:
        items = document["results"]
        if not isinstance(items, list) or not items:
            kind = "an empty list" if items == [] else _kind(items)
            raise ResultFormatError(name, f"'results' is {kind}, expected a list of results")
        return items
    return [document]


def pick(name, results: list, model: str | None):
    """The result of ``model`` among ``results`` (checked ones); the only one when ``model`` is
    None and there is one. :class:`ResultChoiceError` otherwise."""
    names = [r.model_name for r in results]
    twice = [n for n in names if names.count(n) > 1]
    if twice:
        raise ResultFormatError(name, f"'results' holds more than one {twice[0]!r} result")
    if model is None and len(results) == 1:
        return results[0]
    chosen = canonical_name(model, names)  # model names ignore case
    if chosen is not None:
        return results[names.index(chosen)]
    raise ResultChoiceError(name, names, model)


# -- the fields ---------------------------------------------------------------------------------
class _Bad(Exception):
    """A field's problem (turned into :class:`ResultFormatError` with the source)."""


def _kind(v) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "true/false",
            type(None): "null"}.get(type(v), "a number" if isinstance(v, numbers.Number)
                                     else type(v).__name__)


def _text(v, where):
    if not isinstance(v, str):
        raise _Bad(f"{where} is {_kind(v)}, expected a string")
    return v


def _flag(v, where):
    if not isinstance(v, (bool, np.bool_)):
        raise _Bad(f"{where} is {_kind(v)}, expected true or false")
    return bool(v)


def _count(v, where):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral) or v < 0:
        raise _Bad(f"{where} is {v!r:.40}, expected a whole number ≥ 0")
    return int(v)


def _real(v, where):
    """A number; ``null`` is NaN (how :func:`~brdffit.fitting.result.json_safe` wrote it)."""
    if v is None:
        return math.nan
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        raise _Bad(f"{where} is {_kind(v)}, expected a number")
    try:
        return float(v)
    except OverflowError:
        raise _Bad(f"{where} is an integer beyond the float range") from None


def _reals(v, where):
    if not isinstance(v, (list, tuple, np.ndarray)):
        raise _Bad(f"{where} is {_kind(v)}, expected a list of numbers")
    return [_real(a, f"{where}[{i}]") for i, a in enumerate(v)]


def _value(v, where):
    """A parameter's value: a number, or a list of numbers (RGB)."""
    return _reals(v, where) if isinstance(v, (list, tuple, np.ndarray)) else _real(v, where)


def _names(v, where):
    if not isinstance(v, (list, tuple)):
        raise _Bad(f"{where} is {_kind(v)}, expected a list of names")
    return [_text(a, f"{where}[{i}]") for i, a in enumerate(v)]


def _mapping(check):
    def checked(v, where):
        if not isinstance(v, dict):
            raise _Bad(f"{where} is {_kind(v)}, expected an object")
        return {_text(k, f"a key of {where}"): check(a, f"{where}[{k!r:.40}]")
                for k, a in v.items()}
    return checked


def _matrix(v, where):
    if not isinstance(v, (list, tuple, np.ndarray)):
        raise _Bad(f"{where} is {_kind(v)}, expected a list of rows")
    return [_reals(row, f"{where}[{i}]") for i, row in enumerate(v)]


def _pair(v, where):
    out = _reals(v, where)
    if len(out) != 2:
        raise _Bad(f"{where} has {len(out)} numbers, expected [lower, upper]")
    return out


def _provenance(v, where):
    """Free-form, but the keys the result's methods read must have their shapes."""
    if not isinstance(v, dict):
        raise _Bad(f"{where} is {_kind(v)}, expected an object")
    if v.get("tied") is not None:
        _mapping(_text)(v["tied"], f"{where}.tied")
    options = v.get("options")
    if options is not None and not isinstance(options, dict):
        raise _Bad(f"{where}.options is {_kind(options)}, expected an object")
    if options and options.get("bounds") is not None:
        _mapping(_pair)(options["bounds"], f"{where}.options.bounds")
    return v


def _check_entry(v, where):
    if not isinstance(v, dict):
        raise _Bad(f"{where} is {_kind(v)}, expected an object")
    missing = [k for k in ("name", "passed", "value", "limit", "meaning") if k not in v]
    if missing:
        raise _Bad(f"{where} has no {', '.join(map(repr, missing))}")
    passed = None if v["passed"] is None else _flag(v["passed"], f"{where}.passed")
    return {"name": _text(v["name"], f"{where}.name"), "passed": passed,
            "value": _real(v["value"], f"{where}.value"),
            "limit": _real(v["limit"], f"{where}.limit"),
            "meaning": _text(v["meaning"], f"{where}.meaning")}


def _plausibility(v, where):
    """The verdict record (:func:`brdffit.fitting.plausibility.verdict_record`); ``{}`` is a
    result written before the verdict existed."""
    if not isinstance(v, dict):
        raise _Bad(f"{where} is {_kind(v)}, expected an object")
    if not v:
        return {}
    if "plausible" not in v or "checks" not in v:
        raise _Bad(f"{where} needs 'plausible' and 'checks'")
    checks = v["checks"]
    if not isinstance(checks, list):
        raise _Bad(f"{where}.checks is {_kind(checks)}, expected a list")
    return {"plausible": _flag(v["plausible"], f"{where}.plausible"),
            "checks": [_check_entry(c, f"{where}.checks[{i}]") for i, c in enumerate(checks)]}


#: Every field and its check, in :class:`FitResult`'s order (a test holds the keys to the
#: dataclass's fields, so a new field cannot be left unread).
FIELDS = {
    "model_name": _text, "params": _mapping(_value), "stderr": _mapping(_value),
    "names": _names, "x": _reals, "cov": _matrix, "free": _names, "fixed": _names,
    "at_bound": _mapping(_text), "cost": _real, "metrics": _mapping(_real), "success": _flag,
    "status": _text, "message": _text, "steps": _count, "starts": _reals, "loss": _text,
    "solver": _text, "n_cells": _count, "n_total": _count, "init": _mapping(_value),
    "wall_time": _real, "timings": _mapping(_real), "table": _text, "covariance": _text,
    "optimality": _real, "provenance": _provenance, "not_identified": _names,
    "plausibility": _plausibility, "total_steps": _count,
}
#: Keys a result may carry beyond its fields (skipped): the posterior of ``--mcmc``;
#: ``uncertainty``, derived from the fields (:meth:`FitResult.uncertainty`); ``derived``,
#: recomputed from the parameters (:attr:`FitResult.derived`).
EXTRA = ("posterior", "uncertainty", "derived")


def fields(name, d, required) -> dict:
    """``d``'s fields, each checked and converted (``x``, ``cov`` as arrays); ``required``: the
    keys that have no default."""
    if not isinstance(d, dict):
        raise ResultFormatError(name, f"the document is {_kind(d)}, expected an object")
    missing = [k for k in required if k not in d]
    unknown = sorted(str(k) for k in set(d) - set(FIELDS) - set(EXTRA))
    if missing or unknown:
        raise ResultFormatError(name, "; ".join(
            ([f"missing {', '.join(map(repr, missing))}"] if missing else [])
            + ([f"unknown key(s) {', '.join(map(repr, unknown))}"] if unknown else [])))
    try:
        out = {k: FIELDS[k](d[k], repr(k)) for k in FIELDS if k in d}
        _consistent(out)
    except _Bad as exc:
        raise ResultFormatError(name, str(exc)) from None
    out["x"] = np.asarray(out["x"], float)
    out["cov"] = np.asarray(out["cov"], float).reshape(len(out["x"]), len(out["x"]))
    return out


def _consistent(d) -> None:
    n = len(d["x"])
    if len(d["names"]) != n:
        raise _Bad(f"'names' has {len(d['names'])} entries and 'x' {n}; they must agree")
    if len(d["cov"]) != n or any(len(row) != n for row in d["cov"]):
        raise _Bad(f"'cov' must be {n} x {n}, the length of 'x'")
    flat = _flat_names(d["model_name"])
    if flat is not None and d["names"] != flat:
        raise _Bad(f"'names' are not the {d['model_name']} model's {', '.join(flat)}")
    names = set(d["names"])
    for key in ("free", "fixed", "at_bound", "not_identified"):
        if key not in d:  # not_identified: absent from files older than the field
            continue
        stray = [a for a in d[key] if a not in names]
        if stray:
            raise _Bad(f"{key!r} names {stray[0]!r}, which is not in 'names'")


def _flat_names(model_name):
    """The registered model's flat parameter names; None for a name the registry lacks."""
    from ..errors import UnknownNameError
    from ..models.registry import get_model

    try:
        return get_model(model_name).flat_names()
    except UnknownNameError:
        return None
