"""Reading and writing RGL ``.bsdf`` files: the fields Mitsuba 3's ``measured`` plugin requires.

A ``.bsdf`` file is a tensor file (:mod:`data_formats.tensorfile`) with the fields checked by
the constructor of ``src/bsdfs/measured.cpp`` (Mitsuba 3), all float32 unless said:

========================  =====================================================================
``description``           uint8 ``(k,)``: free text (UTF-8)
``jacobian``              uint8 ``(1,)``: 1 when the tables are divided by ``D / (4σ)``
``theta_i``, ``phi_i``    ``(n_θ,)``, ``(n_φ,)`` incidence nodes, radians, increasing
``ndf``, ``sigma``        ``(H, W)`` each (``H, W >= 2``)
``vndf``                  ``(n_φ, n_θ, H, W)``
``luminance``             ``(n_φ, n_θ, n, n)``
``rgb``                   ``(n_φ, n_θ, 3, n, n)``  (an RGB file: no ``wavelengths`` field)
``spectra``               ``(n_φ, n_θ, n_λ, n, n)`` with ``wavelengths`` ``(n_λ,)`` nm
``valid``                 optional, uint8; not read by Mitsuba
========================  =====================================================================

Beyond Mitsuba's structural checks the reader requires finite values, increasing nodes, a
non-negative ``ndf`` and ``vndf`` with mass in every slice and a positive ``sigma`` (what the
evaluation divides by), so that a file it accepts evaluates to finite values everywhere; and a
measurement pattern (``n_φ x n_θ x n x n`` direction pairs, what a fit reads) of at most
:data:`MAX_PATTERN_PAIRS`, because the pattern and its weights take about 350 bytes a pair,
some 20 times the bytes a pair takes in the file (RGL's own files have well under a million).
"""

from __future__ import annotations

import os

import numpy as np

from ..tensorfile import TensorFileError, read_tensor_file, write_tensor_file
from ._material import RGLMaterial

__all__ = ["RGLFormatError", "read_rgl", "write_rgl", "MAX_PATTERN_PAIRS"]

_FIX = "the file is not an RGL material (.bsdf) or is corrupt"
#: Most direction pairs a file's measurement pattern may have (``n_φ n_θ n²``; module docstring).
MAX_PATTERN_PAIRS = 1 << 22


class RGLFormatError(TensorFileError):
    """A file that is not a well-formed RGL ``.bsdf`` material (one line: path and problem)."""


def _field(path, fields, name, ndim, dtype="float32"):
    if name not in fields:
        raise RGLFormatError(path, f"missing field {name!r} (found: {', '.join(sorted(fields))})"
                             f"; {_FIX}")
    arr = fields[name]
    if arr.ndim != ndim or arr.dtype != np.dtype(dtype):
        raise RGLFormatError(path, f"field {name!r} is {arr.dtype} with shape {arr.shape}, "
                             f"expected {dtype} with {ndim} dimension(s); {_FIX}")
    return arr


def _shape(path, name, arr, want):
    """``want``: a tuple of ints or None (any)."""
    if len(arr.shape) != len(want) or any(w is not None and s != w
                                          for s, w in zip(arr.shape, want)):
        spelled = "(" + ", ".join("*" if w is None else str(w) for w in want) + ")"
        raise RGLFormatError(path, f"field {name!r} has shape {arr.shape}, expected {spelled} "
                             f"(from theta_i, phi_i and the table sizes); {_FIX}")


def _check_values(path, f, table_name):
    for name in ("theta_i", "phi_i", "ndf", "sigma", "vndf", "luminance", table_name,
                 "wavelengths"):
        if name in f and not np.all(np.isfinite(f[name])):
            raise RGLFormatError(path, f"field {name!r} holds NaN or infinite values; {_FIX}")
    for name in ("theta_i", "phi_i"):
        if np.any(np.diff(f[name]) <= 0):
            raise RGLFormatError(path, f"field {name!r} is not strictly increasing "
                                 f"({f[name][:8].tolist()}...); {_FIX}")
    for name, arr in (("ndf", f["ndf"]), ("vndf", f["vndf"])):
        if np.any(arr < 0):
            raise RGLFormatError(path, f"field {name!r} has negative values; {_FIX}")
    if np.any(f["sigma"] <= 0):
        raise RGLFormatError(path, f"field 'sigma' (projected area) has values <= 0; {_FIX}")
    if np.any(f["vndf"].reshape(-1, *f["vndf"].shape[2:]).sum(axis=(1, 2)) <= 0):
        raise RGLFormatError(path, f"field 'vndf' has a slice without mass; {_FIX}")


def _validate(path, f):
    theta = _field(path, f, "theta_i", 1)
    phi = _field(path, f, "phi_i", 1)
    for name in ("ndf", "sigma"):
        arr = _field(path, f, name, 2)
        if min(arr.shape) < 2:
            raise RGLFormatError(path, f"field {name!r} has shape {arr.shape}; Mitsuba needs "
                                 f"at least 2 x 2; {_FIX}")
    nt, npf = len(theta), len(phi)
    if nt < 1 or npf < 1:
        raise RGLFormatError(path, f"theta_i and phi_i need at least one node; {_FIX}")
    vndf = _field(path, f, "vndf", 4)
    _shape(path, "vndf", vndf, (npf, nt, None, None))
    lum = _field(path, f, "luminance", 4)
    _shape(path, "luminance", lum, (npf, nt, None, lum.shape[2]))
    if min(vndf.shape[2:]) < 2 or lum.shape[2] < 2:
        raise RGLFormatError(path, f"the vndf and luminance tables must be at least 2 x 2, "
                             f"found {vndf.shape[2:]} and {lum.shape[2:]}; {_FIX}")
    n = lum.shape[2]
    pairs = npf * nt * n * n
    if pairs > MAX_PATTERN_PAIRS:
        raise RGLFormatError(path, f"the measurement pattern has {pairs:,} direction pairs "
                             f"({npf} phi_i x {nt} theta_i slices x {n} x {n} nodes), more than "
                             f"the reader's limit of {MAX_PATTERN_PAIRS:,}; {_FIX}")
    if "wavelengths" in f:
        wl = _field(path, f, "wavelengths", 1)
        table_name = "spectra"
        _shape(path, "spectra", _field(path, f, "spectra", 5), (npf, nt, len(wl), n, n))
    else:
        table_name = "rgb"
        _shape(path, "rgb", _field(path, f, "rgb", 5), (npf, nt, 3, n, n))
    _field(path, f, "description", 1, "uint8")
    _shape(path, "jacobian", _field(path, f, "jacobian", 1, "uint8"), (1,))
    if "valid" in f and f["valid"].dtype not in (np.uint8, np.bool_):
        raise RGLFormatError(path, f"field 'valid' is {f['valid'].dtype}, expected uint8; {_FIX}")
    _check_values(path, f, table_name)
    return table_name


def read_rgl(path) -> RGLMaterial:
    """Read an RGL ``.bsdf`` file (module docstring) into an :class:`RGLMaterial`.

    Everything malformed (not a tensor file, truncated, a missing field, a wrong dtype or
    shape, values the evaluation cannot use) raises :class:`RGLFormatError`, one line naming
    the path and the problem; nothing is allocated beyond the file's own size.
    """
    p = os.fspath(path)
    f = read_tensor_file(p, error=RGLFormatError)
    table = _validate(p, f)
    desc = bytes(f["description"]).decode("utf-8", errors="replace")
    return RGLMaterial(
        theta_i=f["theta_i"], phi_i=f["phi_i"], ndf=f["ndf"], sigma=f["sigma"], vndf=f["vndf"],
        luminance=f["luminance"], rgb=f.get("rgb") if table == "rgb" else None,
        spectra=f["spectra"] if table == "spectra" else None,
        wavelengths=f.get("wavelengths") if table == "spectra" else None,
        jacobian=bool(f["jacobian"][0]), description=desc, valid=f.get("valid"),
        name=os.path.splitext(os.path.basename(p))[0], path=p)


def write_rgl(path, material: RGLMaterial) -> None:
    """Write ``material`` as an RGL ``.bsdf`` file that Mitsuba 3's ``measured`` plugin loads
    (the inverse of :func:`read_rgl`), atomically. Tables are stored as float32. A material
    that :func:`read_rgl` would refuse (shapes that do not match, values the evaluation cannot
    use) raises ``ValueError`` before anything is written."""
    if not isinstance(material, RGLMaterial):
        raise TypeError(f"write_rgl: expected an RGLMaterial, got {type(material).__name__}")
    m = material
    f32 = {k: np.ascontiguousarray(getattr(m, k), dtype=np.float32)
           for k in ("theta_i", "phi_i", "ndf", "sigma", "vndf", "luminance")}
    fields = {"description": m.description.encode("utf-8"),
              "jacobian": np.array([1 if m.jacobian else 0], dtype=np.uint8), **f32}
    if m.rgb is not None:
        fields["rgb"] = np.ascontiguousarray(m.rgb, dtype=np.float32)
    else:
        fields["spectra"] = np.ascontiguousarray(m.spectra, dtype=np.float32)
        fields["wavelengths"] = np.ascontiguousarray(m.wavelengths, dtype=np.float32)
    if m.valid is not None:
        fields["valid"] = np.ascontiguousarray(m.valid, dtype=np.uint8)
    check = {k: (np.frombuffer(v, np.uint8) if isinstance(v, bytes) else v)
             for k, v in fields.items()}
    try:  # what read_rgl (and Mitsuba) would refuse is not written
        _validate(os.fspath(path), check)
    except RGLFormatError as exc:
        raise ValueError(f"write_rgl: the material cannot be written as an RGL file: "
                         f"{exc.problem.split('; ')[0]}") from None
    write_tensor_file(path, fields)
