"""The published fits of Ngan 2005, Löw 2012 and Bagher 2012, and bbm's reference values.

:func:`folder` is ``../shared/published`` beside the checkout when it is there (every fit line
of the 80 development materials; ``.fit`` files under ``fits/``), otherwise ``data/published``:
the same files cut to the ten materials of :mod:`realistic` (``.fit`` and reference values side
by side), so the transcription tests run on a clean clone too.
"""

from __future__ import annotations

from pathlib import Path

from data_formats.published import read_fit_file, read_reference_values

EMBEDDED = Path(__file__).resolve().parent / "data" / "published"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "published"

#: The stems of the published files: one model of one study each.
STEMS = sorted(p.name[: -len(".fit")] for p in EMBEDDED.glob("*.fit"))


def folder() -> Path:
    return SHARED if (SHARED / "fits").is_dir() else EMBEDDED


def fit_path(stem: str) -> Path:
    base = folder()
    return base / "fits" / f"{stem}.fit" if base == SHARED else base / f"{stem}.fit"


def load(stem: str):
    """``(fits, reference values)`` of one published file, in the same material order."""
    fits = read_fit_file(fit_path(stem))
    ref = read_reference_values(folder() / f"{stem}.bbm_values.npz")
    assert [f.material for f in fits] == list(ref.materials), stem
    return fits, ref
