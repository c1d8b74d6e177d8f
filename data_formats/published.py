"""Published BRDF fits in the BSDF benchmark project's ``.fit`` format, and its reference values.

The classic MERL-fitting studies (Ngan, Durand & Matusik 2005; Löw et al. 2012; Bagher, Soler &
Holzschuch 2012) published a parameter set per material; the BSDF benchmark project (bbm,
``fits/``) collected them with exact model definitions. A ``.fit`` file is UTF-8 text: ``#``
comment lines, blank lines, and one fit per line::

    alumina-oxide = Aggregate(Lambertian(albedo = [0.32, 0.30, 0.25]), LowCookTorrance(albedo = [0.009, 0.010, 0.035], roughness = 0.0065, eta = 2.78))

The right-hand side is parsed with :mod:`ast` and its literals with :func:`ast.literal_eval`:
nothing is ever evaluated. A fit is an ``Aggregate`` of a ``Lambertian(albedo = [r, g, b])`` and
one model call whose keyword arguments are numbers or (nested) lists of numbers; the parameter
names and conventions are bbm's (its ``include/bsdfmodel/*.h``), not the papers' notation.

The ``*.bbm_values.npz`` beside such a file holds, for every fit line, ``f_r`` (RGB, no cosine)
computed by bbm's own C++ at shared direction pairs: keys ``materials`` (names), ``wi``, ``wo``
(``(P, 3)`` unit vectors, ``z`` the normal) and ``f`` (``(materials, P, 3)``).

NumPy only, like every format here.
"""

from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path

import numpy as np

from ._files import open_regular

#: The largest ``.fit`` file read (the published ones are under 40 KB).
MAX_BYTES = 16 << 20


class PublishedFitFormatError(ValueError):
    """A ``.fit`` file or reference-value archive that does not follow the format."""


@dataclasses.dataclass(frozen=True)
class PublishedFit:
    """One line of a ``.fit`` file.

    Attributes:
        material: the material's name (left of ``=``).
        albedo: the Lambertian albedo ``(3,)`` (bbm's ``Lambertian``: ``f = albedo/π``).
        model: bbm's class name of the specular model (``LowCookTorrance``, ``Bagher`` …).
        params: its keyword arguments as given: floats, or float arrays for lists.
        source: ``path:line`` of the line, for messages.
    """

    material: str
    albedo: np.ndarray
    model: str
    params: dict
    source: str = ""


def _literal(node, where: str):
    try:
        value = ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        raise PublishedFitFormatError(f"{where}: {ast.unparse(node)[:60]!r} is not a number or "
                                      f"a list of numbers") from None
    arr = np.asarray(value, dtype=object)
    try:
        out = np.asarray(value, dtype=float)
    except (ValueError, TypeError):
        raise PublishedFitFormatError(f"{where}: {ast.unparse(node)[:60]!r} is not a number or "
                                      f"a list of numbers") from None
    if arr.dtype == object and any(isinstance(v, (bool, str, complex)) for v in arr.flat):
        raise PublishedFitFormatError(f"{where}: {ast.unparse(node)[:60]!r} is not a number or "
                                      f"a list of numbers")
    if not np.all(np.isfinite(out)):
        raise PublishedFitFormatError(f"{where}: {ast.unparse(node)[:60]!r} is not finite")
    return float(out) if out.ndim == 0 else out


def _call(node, where: str, name: str | None = None) -> tuple[str, dict]:
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
        raise PublishedFitFormatError(f"{where}: expected a call such as Model(param = value), "
                                      f"got {ast.unparse(node)[:60]!r}")
    if name is not None and node.func.id != name:
        raise PublishedFitFormatError(f"{where}: expected {name}(...), got {node.func.id}(...)")
    if node.args:
        raise PublishedFitFormatError(f"{where}: {node.func.id}(...) takes keyword arguments "
                                      f"only (name = value)")
    kwargs = {}
    for kw in node.keywords:
        if kw.arg is None or kw.arg in kwargs:
            raise PublishedFitFormatError(f"{where}: {node.func.id}(...) has a repeated or "
                                          f"unnamed argument")
        kwargs[kw.arg] = _literal(kw.value, f"{where}: {node.func.id}.{kw.arg}")
    return node.func.id, kwargs


def parse_fit_line(line: str, where: str = "<line>") -> PublishedFit | None:
    """One ``.fit`` line as a :class:`PublishedFit`; ``None`` for a comment or blank line."""
    text = line.strip()
    if not text or text.startswith("#"):
        return None
    material, sep, rhs = text.partition("=")
    material = material.strip()
    if not sep or not material or any(c.isspace() for c in material):
        raise PublishedFitFormatError(f"{where}: expected 'material = Aggregate(...)'")
    try:
        tree = ast.parse(rhs.strip(), mode="eval").body
    except (SyntaxError, ValueError, MemoryError, RecursionError) as exc:
        raise PublishedFitFormatError(f"{where}: not a fit expression ({exc.__class__.__name__}: "
                                      f"{getattr(exc, 'msg', exc)})") from None
    if not (isinstance(tree, ast.Call) and isinstance(tree.func, ast.Name)
            and tree.func.id == "Aggregate" and len(tree.args) == 2 and not tree.keywords):
        raise PublishedFitFormatError(f"{where}: expected Aggregate(Lambertian(albedo = [r, g, "
                                      f"b]), Model(...))")
    _, lambert = _call(tree.args[0], where, "Lambertian")
    albedo = np.asarray(lambert.get("albedo", math.nan), dtype=float)
    if set(lambert) != {"albedo"} or albedo.shape != (3,):
        raise PublishedFitFormatError(f"{where}: Lambertian takes one argument, albedo = [r, g, b]")
    model, params = _call(tree.args[1], where)
    return PublishedFit(material, albedo, model, params, where)


def read_fit_file(path) -> list[PublishedFit]:
    """Every fit of a ``.fit`` file, in file order; a bad line raises
    :class:`PublishedFitFormatError` naming the file and line."""
    path = Path(path)
    with open_regular(path, "rb") as fh:
        data = fh.read(MAX_BYTES + 1)
    if len(data) > MAX_BYTES:
        raise PublishedFitFormatError(f"{path}: larger than {MAX_BYTES >> 20} MiB; a .fit file "
                                      f"holds one short line per material")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise PublishedFitFormatError(f"{path}: not UTF-8 text (byte {exc.start}); a .fit file "
                                      f"is text") from None
    fits, seen = [], set()
    for lineno, line in enumerate(text.splitlines(), 1):
        fit = parse_fit_line(line, f"{path}:{lineno}")
        if fit is None:
            continue
        if fit.material in seen:
            raise PublishedFitFormatError(f"{path}:{lineno}: material {fit.material!r} appears "
                                          f"twice")
        seen.add(fit.material)
        fits.append(fit)
    if not fits:
        raise PublishedFitFormatError(f"{path}: no fit lines ('material = Aggregate(...)')")
    return fits


@dataclasses.dataclass(frozen=True)
class ReferenceValues:
    """bbm's ``f_r`` for the fits of one ``.fit`` file at shared direction pairs."""

    materials: tuple[str, ...]
    wi: np.ndarray  # (P, 3)
    wo: np.ndarray  # (P, 3)
    f: np.ndarray  # (materials, P, 3)

    def of(self, material: str) -> np.ndarray:
        """``(P, 3)`` reference values of one material."""
        try:
            return self.f[self.materials.index(material)]
        except ValueError:
            raise KeyError(f"no reference values for {material!r}") from None


def read_reference_values(path) -> ReferenceValues:
    """A ``*.bbm_values.npz`` archive (keys ``materials``, ``wi``, ``wo``, ``f``)."""
    path = Path(path)
    try:
        with open_regular(path, "rb") as fh, np.load(fh, allow_pickle=False) as z:
            arrays = {k: np.asarray(z[k]) for k in ("materials", "wi", "wo", "f")}
    except KeyError as exc:
        raise PublishedFitFormatError(f"{path}: no array {exc}; expected materials, wi, wo, "
                                      f"f") from None
    except (OSError, ValueError, EOFError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise PublishedFitFormatError(f"{path}: not a reference-value archive ({exc})") from None
    m, p = len(arrays["materials"]), len(arrays["wi"])
    if (arrays["wi"].shape != (p, 3) or arrays["wo"].shape != (p, 3)
            or arrays["f"].shape != (m, p, 3)):
        raise PublishedFitFormatError(f"{path}: shapes do not match (wi {arrays['wi'].shape}, "
                                      f"wo {arrays['wo'].shape}, f {arrays['f'].shape}, "
                                      f"{m} materials)")
    return ReferenceValues(tuple(str(s) for s in arrays["materials"]),
                           arrays["wi"].astype(float), arrays["wo"].astype(float),
                           arrays["f"].astype(float))
