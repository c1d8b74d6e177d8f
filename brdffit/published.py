"""Published fits as results: ``load_published(path) -> [PublishedResult]``.

A ``.fit`` file of the BSDF benchmark project (:mod:`data_formats.published`: read with
:mod:`ast`, never evaluated) holds one published fit per material. Each line becomes a
:class:`PublishedResult`: a :class:`brdffit.FitResult` of the registered model that means the
same function (:func:`brdffit.models.published.published_params`), so a published fit is
plotted (``result.plot(table)``), exported (``result.export("mitsuba-dict")``), rendered, scored
and ranked (:mod:`brdffit.compare`) like a fit of brdffit's own.

It is **not** a fit brdffit converged: nothing was optimised here, there are no standard errors
(NaN), no cost and no metrics of a fit (scores come from :func:`brdffit.compare.score`), every
parameter is listed as fixed, and the result says where it comes from:

* ``status`` is ``"published"``, ``success`` is ``True`` (a valid set of parameters, not a
  failed fit), ``solver`` is ``"none"``, ``loss`` is ``"published"``;
* ``source`` (also ``message``) is ``"published: Löw 2012 E2"``: the study of the registered
  form (:class:`~brdffit.models.published.PublishedForm`) and the variant the file's name
  carries (``low_cooktorrance_E2.fit`` → ``E2``);
* ``provenance["published"]`` records the file, its SHA-256, the line, the material, bbm's class
  and the parameters as the line gives them.

A file whose lines name a bbm class without a registered form raises
:class:`~brdffit.errors.UnknownNameError` (a folder skips such files, with a warning that names
them: the literature's models may not all be registered).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from pathlib import Path

import numpy as np

from .api import FitResult
from .errors import BrdffitError, UnknownNameError

#: The suffix of a ``.fit`` file.
SUFFIX = ".fit"
_VARIANT = re.compile(r"_(E\d+)$")


class PublishedFitError(BrdffitError):
    """A published-fit file or folder that cannot be read (one line: what and where)."""


class PublishedResult(FitResult):
    """A published fit as a :class:`brdffit.FitResult` (module docstring): the same fields, JSON,
    plot and export; its summary and report say that it was published, not fitted."""

    @property
    def source(self) -> str:
        """``"published: Löw 2012 E2"``: where the parameters come from."""
        return self.message

    @property
    def study(self) -> str:
        """``"Löw 2012 E2"``."""
        return (self.provenance.get("published") or {}).get("study", "")

    def summary(self) -> str:
        lines = [f"{self.model_name} of {self.table or 'table'}: {self.source} (not fitted here: "
                 f"no standard errors)"]
        for name, value in zip(self.names, np.asarray(self.x, float)):
            lines.append(f"  {name:>18} = {value:.6g}")
        where = self.provenance.get("published") or {}
        if where.get("line"):
            lines.append(f"  from {where.get('file')}:{where.get('line')} ({where.get('bbm_class')})")
        return "\n".join(lines)

    def report(self, *, min_correl: float = 0.1) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        import html

        return "<pre>" + html.escape(self.summary()) + "</pre>"


def variant(path) -> str:
    """The protocol a published file's name carries: ``low_cooktorrance_E2.fit`` → ``"E2"``,
    ``""`` for none."""
    m = _VARIANT.search(Path(path).name[: -len(SUFFIX)] if str(path).endswith(SUFFIX)
                        else Path(path).stem)
    return m.group(1) if m else ""


def result_of(fit, *, path=None, sha256: str | None = None) -> PublishedResult:
    """One :class:`~data_formats.published.PublishedFit` (a ``.fit`` line) as a
    :class:`PublishedResult` of its registered model; ``path`` the file it came from."""
    from .models.published import published_form, published_params

    form = published_form(fit.model)
    model, params = published_params(fit)
    x = np.asarray(model.flatten(params), float)
    names = list(model.flat_names())
    study = " ".join(s for s in (form.study, variant(path) if path else "") if s)
    source = f"published: {study or fit.model}"
    file, _, line = (fit.source or "").rpartition(":")
    nan = {k: (np.full(np.shape(v), math.nan).tolist() if np.ndim(v) else math.nan)
           for k, v in params.items()}
    record = {
        "study": study, "bbm_class": fit.model, "material": fit.material,
        "file": str(Path(path).resolve()) if path else (file or None),
        "sha256": sha256, "line": int(line) if line.isdigit() else None,
        "albedo": np.asarray(fit.albedo, float).tolist(),
        "params": {k: (np.asarray(v).tolist() if np.ndim(v) else float(v))
                   for k, v in fit.params.items()},
    }
    return PublishedResult(
        model_name=model.name,
        params={k: (np.asarray(v, float).tolist() if np.ndim(v) else float(v))
                for k, v in params.items()},
        stderr=nan, names=names, x=x, cov=np.zeros((len(x), len(x))), free=[],
        fixed=list(names), at_bound={}, cost=math.nan, metrics={}, success=True,
        status="published", message=source, steps=0, starts=[], loss="published",
        solver="none", n_cells=0, n_total=0, init={}, wall_time=0.0, timings={},
        table=fit.material, covariance="none", provenance={"published": record})


def _read(path: Path):
    from data_formats.published import PublishedFitFormatError, read_fit_file

    from .io import sha256

    try:
        return read_fit_file(path), sha256(path)
    except PublishedFitFormatError as exc:
        raise PublishedFitError(str(exc)) from None


def published_files(path) -> list[Path]:
    """The ``.fit`` files of ``path``: the file itself, or those of a folder (sorted by name);
    :class:`PublishedFitError` when there are none, ``FileNotFoundError`` for no such path."""
    p = Path(os.fspath(path))
    if not p.exists():
        raise FileNotFoundError(2, "No such file or directory", str(p))
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.name.endswith(SUFFIX) and f.is_file())
        if not files:
            raise PublishedFitError(f"{p}: no published fits (*{SUFFIX} files) in this folder")
        return files
    if not p.name.endswith(SUFFIX):
        raise PublishedFitError(f"{p}: not a published fit file (*{SUFFIX}, the BSDF benchmark "
                                f"project's format)")
    return [p]


def load_published(path, material: str | None = None) -> list[PublishedResult]:
    """The published fits of a ``.fit`` file, or of every ``.fit`` file of a folder (such as
    ``../shared/published/fits``), as :class:`PublishedResult` objects, in file then line order.

    ``material`` keeps the lines of that material only (a table's name: the file stem of
    ``alumina-oxide.binary``). In a folder, a file whose lines name a bbm class without a
    registered model is skipped with a :class:`UserWarning` naming it; a single such file
    raises :class:`~brdffit.errors.UnknownNameError`. A malformed file raises
    :class:`PublishedFitError` naming the file and line.
    """
    files = published_files(path)
    folder = len(files) > 1 or Path(os.fspath(path)).is_dir()
    out, skipped = [], []
    for f in files:
        fits, digest = _read(f)
        fits = [fit for fit in fits if material is None or fit.material == material]
        try:
            out.extend(result_of(fit, path=f, sha256=digest) for fit in fits)
        except UnknownNameError:
            if not folder:
                raise
            skipped.append(f"{f.name} ({fits[0].model if fits else '?'})")
    if skipped:
        warnings.warn(f"published fits skipped, no registered model for their bbm class: "
                      f"{', '.join(skipped)}", UserWarning, stacklevel=2)
    return out


__all__ = ["PublishedFitError", "PublishedResult", "load_published", "published_files",
           "result_of", "variant"]

