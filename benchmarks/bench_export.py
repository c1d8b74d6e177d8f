"""Export error on the realistic corpus: every native and approximate export, measured in the
target renderer (Mitsuba 3's ``BSDF.eval``, the glTF reference BRDF) against the measurement.

For each material of ``../shared/realistic`` (the neural proxies of 80 MERL materials, see its
README) ``--cells`` MERL cells are drawn (seeded; lower cell corners above the horizon, with the
cells' ``θh`` weights, as ``tests/realistic.py`` draws them) and evaluated by the corpus's
``render.brdf``. On those cells:

* **native** exports: ``gltf-pbr`` and ``gltf-pbr-sheen`` → ``gltf``, ``mitsuba-principled`` and
  ``mitsuba-roughconductor`` → ``mitsuba-xml`` (the ``mitsuba-dict`` target loads the same
  BSDF);
* **approximate** exports: ``ggx`` and ``disney`` → ``gltf`` and ``mitsuba-xml``
  (``--approximate``: the target model fitted to the source fit).

Each row: the fit's ``rmse_log`` and ``peak_log`` and the export's, on the same cells
(:mod:`brdffit.export.faithful`), the target model, and for ``gltf-pbr`` its ``metallic``.
The summary gives, per (source, target), the median and worst export ``rmse_log``, the median
and worst *excess* over the fit's (export − fit), and the worst ``peak_log``.

Run: ``nice -n 5 /work/venv/bin/python benchmarks/bench_export.py [--materials a,b]
[--cells 20000] [--csv out.csv]`` (about 30 s a material on one core; all 80 by default).
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REALISTIC = HERE.parent.parent / "shared" / "realistic"

#: (source model, target, approximate?)
CASES = (
    ("gltf-pbr", "gltf", False),
    ("gltf-pbr-sheen", "gltf", False),
    ("mitsuba-principled", "mitsuba-xml", False),
    ("mitsuba-roughconductor", "mitsuba-xml", False),
    ("ggx", "gltf", True),
    ("ggx", "mitsuba-xml", True),
    ("disney", "gltf", True),
    ("disney", "mitsuba-xml", True),
)


def cells(render, name: str, n: int, seed: int = 0):
    """``n`` MERL cells of material ``name`` as a :class:`~data_formats.SampleSet`."""
    from data_formats import SampleSet
    from data_formats.merl import (MERL_SHAPE, above_horizon, cell_directions,
                                   theta_h_weights)

    ok = np.flatnonzero(above_horizon(MERL_SHAPE).ravel())
    rows = np.sort(np.random.default_rng(seed).choice(ok, size=n, replace=False))
    i = np.unravel_index(rows, MERL_SHAPE)[0]
    wi, wo = (a.reshape(-1, 3)[rows] for a in cell_directions(MERL_SHAPE))
    rgb = np.maximum(np.asarray(render.brdf(name, wi, wo), float), 0.0)
    return SampleSet(wi, wo, rgb, np.ones(n, bool), name=name, weight=theta_h_weights(MERL_SHAPE)[i])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--materials", help="comma-separated names (default: all of the corpus)")
    ap.add_argument("--cells", type=int, default=20000)
    ap.add_argument("--csv", help="write the rows here")
    args = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import brdffit
    from brdffit.export import export

    if not (REALISTIC / "render.py").exists():
        sys.exit(f"bench_export: {REALISTIC} is missing (the development corpus)")
    sys.path.insert(0, str(REALISTIC))
    import render

    names = args.materials.split(",") if args.materials else render.names()
    rows = []
    for name in names:
        t0 = time.perf_counter()
        data = cells(render, name, args.cells)
        fits = {m: brdffit.fit(data, m, throw=False) for m in {c[0] for c in CASES}}
        for source, to, approx in CASES:
            out = export(fits[source], to, approximate=approx, data=data,
                         error_cells=args.cells)
            e = out.error
            row = dict(material=name, source=source, target=to, model=out.model_name,
                       fit_rmse_log=e.fit["rmse_log"], export_rmse_log=e.export["rmse_log"],
                       fit_peak_log=e.fit["peak_log"], export_peak_log=e.export["peak_log"],
                       metallic=float(out.params.get("metallic", np.nan)))
            rows.append(row)
            print(f"{name:28s} {source:24s} -> {to:11s} ({out.model_name:18s}) rmse_log fit "
                  f"{row['fit_rmse_log']:.4f} export {row['export_rmse_log']:.4f}  peak_log fit "
                  f"{row['fit_peak_log']:.3f} export {row['export_peak_log']:.3f}"
                  + (f"  metallic {row['metallic']:.3f}" if out.model_name.startswith("gltf") else ""),
                  flush=True)
        print(f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
    if args.csv:
        with open(args.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    print(f"\nsummary over {len(names)} materials ({args.cells} cells each):")
    for source, to, approx in CASES:
        sel = [r for r in rows if r["source"] == source and r["target"] == to]
        ex = [r["export_rmse_log"] for r in sel]
        excess = [r["export_rmse_log"] - r["fit_rmse_log"] for r in sel]
        print(f"  {source:24s} -> {to:11s} {'approx' if approx else 'native'}: export rmse_log "
              f"median {statistics.median(ex):.4f} worst {max(ex):.4f}; excess over the fit "
              f"median {statistics.median(excess):+.2e} worst {max(excess):+.2e}; peak_log worst "
              f"{max(r['export_peak_log'] for r in sel):.3f}")


if __name__ == "__main__":
    main()
