"""Benchmark: whole databases with ``brdffit batch`` (Dask) against a shell loop of ``brdffit fit``.

    .venv/bin/python benchmarks/bench_batch.py [--materials 80] [--loop 8] [--models-on 80]
        [--scaling-on 80] [--tiny 200] [--workdir DIR] [--skip STAGE ...] [--models a,b]

Stages (each prints its figures; ``--skip`` leaves some out):

1. ``render``: the realistic tables of ``../shared/realistic`` (``render.py``, full 90×90×180
   MERL layout, 35 MB each) into ``--workdir`` (a temporary folder by default; rendered tables
   are never kept in the checkout). Not part of any timing.
2. ``ggx``: ``brdffit batch DIR/*.binary --model ggx --workers 2`` in a subprocess, end to end
   (cluster start, compilation, every fit, the table), with an empty compilation cache (a fresh
   ``XDG_CACHE_HOME``): the cold time a user sees the first time.
3. ``loop``: the shell loop it replaces, ``for f in ...; do brdffit fit $f --model ggx --out
   ...; done``, on the first ``--loop`` tables, extrapolated to all of them (said so in the
   output); the ratio loop / batch. The loop gets an empty persistent compilation cache of its
   own, as a user's first loop would: its first process compiles, the others load the cache.
4. ``models``: ``--model ggx,beckmann,gtr,disney`` on ``--models-on`` tables (cache warm for ggx
   from stage 2 only).
5. ``scaling``: ``ggx`` on ``--scaling-on`` tables with 1 and with 2 workers, both with the
   compilation cache warm (stage 2 filled it), so the two differ only in parallelism.
6. ``overhead``: Dask's own cost per job: ``--tiny`` sample lists of 300 samples (``ggx`` fits of
   a few milliseconds) through ``fit_many`` on a warm 2-worker cluster, against the same fits in
   a plain loop in one process.
7. ``projection``: the MERL 100 × 10 models on 64 workers, from the per-job times of stage 4 (the
   mean of the four measured models stands for the six others) and the compile and overhead
   figures measured here, with what limits it.

The machine may be shared: the script prints the load average next to the timings. The figures
describe the fitter of the day (its speed and convergence on real data are still being worked on).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
REALISTIC = ROOT.parent / "shared" / "realistic"
BIN = Path(sys.executable).parent
FOUR = "ggx,beckmann,gtr,disney"
#: Fit options given to every batch and every `brdffit fit` of the loop (``--subsample``).
FIT_FLAGS: list[str] = []


def say(text: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}, load {os.getloadavg()[0]:.1f}] {text}", flush=True)


def render_one(args) -> str:
    name, out = args
    if not Path(out).exists():
        subprocess.run([sys.executable, str(REALISTIC / "render.py"), name, out + ".part"],
                       check=True)
        os.replace(out + ".part", out)
    return out


def render(workdir: Path, n: int) -> list[Path]:
    names = subprocess.run([sys.executable, str(REALISTIC / "render.py"), "--list"], check=True,
                           capture_output=True, text=True).stdout.split()[:n]
    folder = workdir / "tables"
    folder.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        paths = list(pool.map(render_one, [(m, str(folder / f"{m}.binary")) for m in names]))
    say(f"render: {len(paths)} tables in {time.perf_counter() - t:.0f} s (not timed below)")
    return [Path(p) for p in paths]


def batch(tables, models, workers, outdir, cache, extra=()) -> dict:
    """``brdffit batch`` in a subprocess (into an empty outdir): wall time and the table."""
    shutil.rmtree(outdir, ignore_errors=True)
    listing = Path(outdir).with_suffix(".txt")
    listing.write_text("".join(f"{p}\n" for p in tables))
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    cmd = [str(BIN / "brdffit"), "batch", str(listing), "--model", models, "--outdir",
           str(outdir), "--workers", str(workers), "--quiet", *FIT_FLAGS, *extra]
    t = time.perf_counter()
    run = subprocess.run(cmd, check=False, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    if run.returncode not in (0, 1):  # 1: some fits did not converge, which is data
        raise SystemExit(f"brdffit batch failed ({run.returncode}):\n{run.stderr}")
    import pandas as pd

    df = pd.read_csv(Path(outdir) / "results.csv")
    return {"wall": wall, "df": df, "stdout": run.stdout}


def describe(name, res, n_jobs) -> dict:
    df = res["df"]
    jt = df["job_time"].astype(float)
    out = {"wall_s": round(res["wall"], 1), "jobs": n_jobs, "converged": int(df["success"].sum()),
           "job_time_median_s": round(float(jt.median()), 3),
           "job_time_sum_s": round(float(jt.sum()), 1),
           "fit_time_median_s": round(float(df["time"].median()), 3)}
    say(f"{name}: {n_jobs} fits in {res['wall']:.1f} s end to end; {out['converged']} converged; "
        f"per job median {out['job_time_median_s']} s (fit {out['fit_time_median_s']} s), "
        f"sum {out['job_time_sum_s']} s")
    return out


def loop(tables, k, workdir) -> dict:
    """One ``brdffit fit`` process per table, as a shell loop runs them, each timed: the first
    (compiles) and the median of the others (load the persistent cache), extrapolated to all
    tables as ``first + median × (n - 1)``."""
    sub = tables[:k]
    out = workdir / "loop"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    cache = workdir / f"loop-cache-{os.getpid()}"  # empty: the first process compiles
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    walls = []
    for f in sub:
        cmd = [str(BIN / "brdffit"), "fit", str(f), "--model", "ggx", *FIT_FLAGS, "--out",
               str(out / f"{Path(f).stem}.json"), "--quiet"]
        t = time.perf_counter()
        subprocess.run(cmd, check=False, env=env, capture_output=True)  # a failed fit is data
        walls.append(time.perf_counter() - t)
    first, rest = walls[0], float(np.median(walls[1:])) if len(walls) > 1 else walls[0]
    total = first + rest * (len(tables) - 1)
    say(f"loop: {len(sub)} `brdffit fit` processes in {sum(walls):.1f} s: the first (compiles) "
        f"{first:.1f} s, the others (persistent cache) median {rest:.1f} s; extrapolated to "
        f"{len(tables)} tables: {total:.0f} s")
    return {"measured_on": len(sub), "wall_s": round(sum(walls), 1), "first_s": round(first, 2),
            "per_fit_s": round(rest, 2), "extrapolated_s": round(total, 1)}


def overhead(workdir, n) -> dict:
    """Per-job cost of Dask: fit_many of tiny sample lists vs the same fits in one process."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import brdffit
    from brdffit.batch.runner import open_client
    from data_formats.samples import SampleSet

    model = brdffit.get_model("ggx")
    rng = np.random.default_rng(0)
    lists = []
    from brdffit.models.evaluate import evaluate_model

    for i in range(n):
        wi = _hemisphere(rng, 300)
        wo = _hemisphere(rng, 300)
        truth = {"diffuse": [0.1, 0.08, 0.05], "f0": [0.9, 0.6, 0.3],
                 "alpha": float(rng.uniform(0.1, 0.4))}
        rgb = np.asarray(evaluate_model(model, truth, wi, wo))
        lists.append(SampleSet(wi, wo, rgb, np.ones(300, bool), name=f"tiny{i:03d}"))
    for s in lists[:3]:
        brdffit.fit(s, "ggx")
    t = time.perf_counter()
    for s in lists:
        brdffit.fit(s, "ggx")
    local = (time.perf_counter() - t) / n
    with open_client(workers=2) as (client, _):
        brdffit.fit_many(lists[:8], "ggx", client=client)  # compile on both workers
        t = time.perf_counter()
        df = brdffit.fit_many(lists, "ggx", client=client)
        wall = time.perf_counter() - t
    per_job = float(df["job_time"].median())
    dask = wall / n - float(df["job_time"].sum()) / n / 2
    say(f"overhead: {n} tiny fits: in one process {local * 1e3:.1f} ms each; fit_many on 2 "
        f"warm workers {wall:.1f} s ({wall / n * 1e3:.1f} ms per job of which the job itself "
        f"{per_job * 1e3:.1f} ms median); Dask's own cost ≈ {dask * 1e3:.1f} ms per job")
    return {"jobs": n, "in_process_ms": round(local * 1e3, 1), "batch_wall_s": round(wall, 2),
            "per_job_ms": round(wall / n * 1e3, 1), "job_median_ms": round(per_job * 1e3, 1),
            "dask_ms_per_job": round(dask * 1e3, 1), "converged": int(df["success"].sum())}


def _hemisphere(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def compile_cost(df) -> dict:
    """Per model: each worker's slowest job (its first, which compiles) minus the model's median
    job, averaged over the workers: the compilation (or cache load) per worker."""
    out = {}
    for model, g in df.groupby("model"):
        slowest = g.groupby("worker")["job_time"].max()
        out[model] = round(float(slowest.mean() - g["job_time"].median()), 1)
    return out


def projection(models_df, ovh, n_workers=64, n_materials=100, n_models=10) -> dict:
    per_model = models_df.groupby("model")["job_time"].median()
    job = float(per_model.mean())
    comp = compile_cost(models_df)
    compile_per_model = float(np.mean(list(comp.values())))
    jobs = n_materials * n_models
    fits = jobs * job / n_workers
    compiles = n_models * compile_per_model
    dask = jobs * ovh.get("dask_ms_per_job", 5.0) / 1e3 / n_workers
    data_gb = jobs * 34.992e6 / 1e9
    total = fits + compiles + dask
    say(f"projection: MERL {n_materials} × {n_models} models on {n_workers} workers ≈ "
        f"{total / 60:.1f} min = fits {fits:.0f} s ({jobs} jobs × {job:.2f} s / {n_workers}) + "
        f"compilation {compiles:.0f} s per worker ({n_models} models × {compile_per_model:.0f} s, "
        f"cold cache) + Dask {dask:.1f} s; reads {data_gb:.0f} GB of tables in all "
        f"({data_gb / n_workers:.2f} GB per worker)")
    return {"minutes": round(total / 60, 1), "fits_s": round(fits), "compile_s": round(compiles),
            "dask_s": round(dask, 1), "job_s_mean_of_models": round(job, 2),
            "compile_s_per_model": comp, "data_GB": round(data_gb)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--materials", type=int, default=80)
    ap.add_argument("--loop", type=int, default=8, help="tables for the shell loop")
    ap.add_argument("--models-on", type=int, default=80, help="tables for the four-model batch")
    ap.add_argument("--scaling-on", type=int, default=80, help="tables for 1 vs 2 workers")
    ap.add_argument("--tiny", type=int, default=200, help="sample lists for the overhead")
    ap.add_argument("--workdir", type=Path, help="keep rendered tables and results here")
    ap.add_argument("--subsample", type=int, help="fit on N cells of each table (batch and "
                    "loop alike); full tables by default")
    ap.add_argument("--skip", nargs="*", default=[],
                    choices=["ggx", "loop", "models", "scaling", "overhead"])
    ap.add_argument("--models", default=FOUR, help="the models of the ``models`` stage")
    args = ap.parse_args(argv)
    if args.subsample:
        FIT_FLAGS[:] = ["--subsample", str(args.subsample)]
    work = args.workdir or Path(tempfile.mkdtemp(prefix="bench-batch-"))
    work.mkdir(parents=True, exist_ok=True)
    report = {"cpus": os.cpu_count(), "load_at_start": os.getloadavg()[0],
              "fit_flags": FIT_FLAGS}
    tables = render(work, args.materials)
    cache = work / f"cache-{os.getpid()}"
    if "ggx" not in args.skip:
        res = batch(tables, "ggx", 2, work / "out-ggx", cache)
        report["ggx"] = describe("ggx, 2 workers, cold cache", res, len(tables))
        report["ggx"]["compile_s"] = compile_cost(res["df"])
        print(res["stdout"].splitlines()[0])
    if "loop" not in args.skip:
        report["loop"] = loop(tables, args.loop, work)
        if "ggx" in report:
            ratio = report["loop"]["extrapolated_s"] / report["ggx"]["wall_s"]
            report["loop"]["ratio_loop_over_batch"] = round(ratio, 1)
            say(f"batch is {ratio:.1f}× faster than the shell loop (loop extrapolated from "
                f"{report['loop']['measured_on']} tables)")
    if "models" not in args.skip:
        sub = tables[: args.models_on]
        res = batch(sub, args.models, 2, work / "out-four", cache)
        n_models = len(args.models.split(","))
        report["models"] = describe(f"{args.models}, 2 workers", res, n_models * len(sub))
        medians = res["df"].groupby("model")["job_time"].median()
        report["models"]["per_model_job_s"] = {m: round(float(v), 2) for m, v in medians.items()}
        report["models"]["converged_per_model"] = {
            m: int(v) for m, v in res["df"].groupby("model")["success"].sum().items()}
        report["models"]["compile_s"] = compile_cost(res["df"])
        models_df = res["df"]
    if "scaling" not in args.skip:
        sub = tables[: args.scaling_on]
        for w in (1, 2):
            res = batch(sub, "ggx", w, work / f"out-scaling-{w}", cache)
            report[f"scaling_{w}"] = describe(f"ggx, {w} worker(s), warm cache", res, len(sub))
        s = report["scaling_1"]["wall_s"] / report["scaling_2"]["wall_s"]
        report["speedup_2_over_1"] = round(s, 2)
        say(f"scaling: 2 workers {s:.2f}× faster than 1 on {len(sub)} tables")
    if "overhead" not in args.skip:
        report["overhead"] = overhead(work, args.tiny)
    if "models" not in args.skip:
        report["projection"] = projection(models_df, report.get("overhead", {}))
    report["load_at_end"] = os.getloadavg()[0]
    print(json.dumps(report, indent=1))
    (work / "report.json").write_text(json.dumps(report, indent=1))
    if args.workdir is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
