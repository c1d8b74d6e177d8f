"""Realistic reflectance embedded in the tests: neural proxies of a few real MERL materials.

``data/realistic_materials.npz`` holds, for a handful of MERL materials, the weights of the
6-21-21-3 ReLU networks of Sztrajman, Rainer, Ritschel & Weyrich 2021, "Neural BRDF
Representation and Importance Sampling" (Computer Graphics Forum 40(6); networks released under
the MIT licence), each trained on the real MERL measurement of that material (Matusik et al.
2003), copied from the development corpus ``../shared/realistic/merl_nbrdf_dev.npz`` (keys
``NAME/w1 b1 w2 b2 w3 b3``, 675 numbers a material). ``data/realistic_published.csv`` holds the
Beckmann roughness ``m`` of the Cook–Torrance fits of Ngan, Durand & Matusik 2005 and Löw et al.
2012 (E2) for them, as collected by the BSDF benchmark project.

:func:`brdf_hd` is a transcription of the corpus's ``render.py``: input the Rusinkiewicz half
vector with ``φh = 0`` and the difference vector, output ``exp(y) - 1`` clipped at 0, the BRDF
``f_r`` per RGB channel as MERL stores it. The tests evaluate it on MERL cell corners, so no
35 MB table is ever written.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from data_formats import SampleSet
from data_formats.merl import (
    MERL_SHAPE, above_horizon, cell_angles, cell_directions, theta_h_weights,
)

DATA = Path(__file__).resolve().parent / "data"
_WEIGHTS = None


def weights() -> dict:
    global _WEIGHTS
    if _WEIGHTS is None:
        _WEIGHTS = dict(np.load(DATA / "realistic_materials.npz"))
    return _WEIGHTS


def names() -> list[str]:
    return sorted({k.split("/")[0] for k in weights()})


def published() -> dict[str, tuple[float, float]]:
    """Material → (Ngan 2005 m, Löw 2012 m)."""
    with open(DATA / "realistic_published.csv") as f:
        return {r["material"]: (float(r["ngan2005_cooktorrance_m"]),
                                float(r["low2012_cooktorrance_E2_m"])) for r in csv.DictReader(f)}


def brdf_hd(name: str, th, td, pd) -> np.ndarray:
    """``f_r`` ``(..., 3)`` at Rusinkiewicz angles (radians)."""
    w = weights()
    x = np.stack([np.sin(th), np.zeros_like(th), np.cos(th), np.sin(td) * np.cos(pd),
                  np.sin(td) * np.sin(pd), np.cos(td)], -1)
    for i in (1, 2, 3):
        x = x @ w[f"{name}/w{i}"].astype(np.float64) + w[f"{name}/b{i}"].astype(np.float64)
        if i < 3:
            x = np.maximum(x, 0.0)
    return np.maximum(np.expm1(x), 0.0)


def merl_cells(name: str, n_cells: int, seed: int = 0) -> SampleSet:
    """``n_cells`` MERL cells (above the horizon, a seeded random choice, ascending in file
    order), with the material's values at their lower corners and the cells' ``θh`` widths as
    weights (what ``MERLTable.to_samples`` gives), as a :class:`SampleSet`."""
    ok = np.flatnonzero(above_horizon(MERL_SHAPE).ravel())
    rows = np.sort(np.random.default_rng(seed).choice(ok, size=n_cells, replace=False))
    i, j, k = np.unravel_index(rows, MERL_SHAPE)
    th, td, pd = cell_angles(i, j, k)
    wi, wo = (a.reshape(-1, 3)[rows] for a in cell_directions(MERL_SHAPE))
    rgb = brdf_hd(name, th, td, pd)
    return SampleSet(wi, wo, rgb, np.ones(len(rows), bool), name=name,
                     weight=theta_h_weights(MERL_SHAPE)[i])
