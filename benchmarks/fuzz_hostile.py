"""Fuzz the readers through the command line, by hand, and count what went wrong.

Run from the repository root (a few minutes)::

    .venv/bin/python benchmarks/fuzz_hostile.py [--merl 10000] [--lists 5000] [--presets 500]
                                                [--results 500] [--subprocess 60] [--seed 0]

Seeded generators write hostile files into a temporary folder: MERL tables (random and
mutated headers and bodies, NaN/inf, truncation, padding, sparse files with huge legal
headers), sample lists (CSV token soup, mutated valid CSVs, NPZ archives with random dtypes,
shapes, mutations, lying ``.npy`` headers and small zip bombs), TOML presets and result JSON.
Each goes through ``brdffit.cli.main`` in this process (``info FILE``, ``fit absent.csv -c
PRESET``, ``plot absent.csv --fit RESULT``), and ``--subprocess`` of them also through a real
``brdffit`` process (to see exit codes and signals a process would show).

Counted (all must be zero): **crashes** (an exception escaping ``main``, or a process killed by
a signal), **tracebacks** (``Traceback`` on stderr), **bad errors** (exit code 2 without exactly
one stderr line, or an exit code other than 0/2), **hangs** (a call over ``--hang`` seconds),
**memory peaks** (the process's peak RSS growing past ``--memory`` MB), **leftovers** (any file
the call left in the folder besides its input). Exits 1 when any count is not zero.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

HEADER = "theta_i,phi_i,theta_o,phi_o,r,g,b\n"
TOKENS = ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "wix", "wiy", "wiz", "wox",
          "woy", "woz", ",", ",", ",", ",", "\n", "\n", "\r\n", "#", " ", "0", "1", "45", "89.9",
          "90", "91", "-1", "1e308", "-1e308", "nan", "inf", "1_0", "+.5", "0x10", "x", "\xe9", '"']
COLUMNS = ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "wix", "wiy", "wiz", "wox",
           "woy", "woz", "x"]
DTYPES = ["<f8", "<f4", ">f8", "<i8", "<u2", "<c16", "<m8[s]", "|b1", "<U3", "|O", "<f2"]
PRESET_KEYS = ["model", "loss", "cutoff", "subsample", "seed", "multistart", "description",
               "cutof", "[solver]", "[init]", "[fixed]", "[bounds]", "name", "rtol", "atol",
               "max_steps", "alpha", "f0", "diffuse", "[[x]]", "a.b"]
PRESET_VALUES = ['"ggx"', '"log"', '"nope"', "0", "-1", "1", "80", "95", "1e-8", "1e-300",
                 "nan", "inf", "-inf", "9223372036854775807", "-9223372036854775808", "true",
                 "[0.1, 0.5]", "[0.5, 0.1]", "[1e-300, 1e-299]", "[1, 2, 3]", "[0.9, 0.6, 0.3]",
                 "[]", '"x"', "{a = 1}", "0.5", "1979-05-27", '"""\nx"""', "[[1]]"]


def mutate(rng, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(rng.integers(1, 5)):
        kind = rng.integers(3)
        if kind == 0 and out:
            out[rng.integers(len(out))] ^= int(rng.integers(1, 256))
        elif kind == 1:
            del out[rng.integers(len(out) + 1):]
        else:
            out += bytes(rng.integers(0, 256, rng.integers(1, 64)).astype(np.uint8))
    return bytes(out)


def merl_file(rng, path: Path) -> None:
    kind = rng.integers(6)
    if kind == 5:  # a sparse file with a legal header: huge (refused) or up to 2^20 cells
        dims = np.array([rng.integers(1, 10_001), rng.integers(1, 10_001), rng.integers(1, 50)])
        if rng.random() < 0.1:
            dims = np.array([rng.integers(1, 129), rng.integers(1, 129), rng.integers(1, 65)])
        with open(path, "wb") as fh:
            fh.write(dims.astype("<i4").tobytes())
            fh.truncate(12 + 24 * int(np.prod(dims.astype(object))))
        return
    dims = rng.integers(1, 6, 3) if kind < 4 else rng.integers(-5, 100_000, 3)
    body = rng.normal(0, 10, 3 * int(np.prod(np.abs(dims)) % 4096))
    body[rng.random(body.size) < 0.01] = rng.choice([np.nan, np.inf, -np.inf, -1.0])
    raw = dims.astype("<i4").tobytes() + body.astype("<f8").tobytes()
    path.write_bytes(mutate(rng, raw) if kind in (2, 3) else raw)


def csv_file(rng, path: Path) -> None:
    if rng.random() < 0.5:
        text = (HEADER if rng.random() < 0.7 else "") + "".join(
            rng.choice(TOKENS, rng.integers(0, 120)))
        path.write_bytes(text.encode())
        return
    n = int(rng.integers(1, 40))
    rows = np.column_stack([rng.uniform(0, 90, n), rng.uniform(0, 360, n), rng.uniform(0, 90, n),
                            rng.uniform(0, 360, n), rng.uniform(0, 5, (n, 3))])
    text = HEADER + "\n".join(",".join(f"{v:.6g}" for v in r) for r in rows) + "\n"
    path.write_bytes(mutate(rng, text.encode()))


def _npy(shape_text: str, descr: str, body: bytes) -> bytes:
    header = ("{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape_text
              + ", }").encode()
    header += b" " * (63 - len(header) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + body


def npz_file(rng, path: Path) -> None:
    kind = rng.integers(5)
    names = list(rng.choice(COLUMNS[:7], 7, replace=False)) if kind < 3 else list(
        rng.choice(COLUMNS, rng.integers(0, 10)))
    n = int(rng.integers(0, 6))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED if rng.random() < 0.5 else 0) as z:
        for name in names:
            if kind == 3 and rng.random() < 0.3:  # a lying header or a small bomb
                shape = str((int(10 ** rng.integers(3, 16)),))
                body = bytes(int(rng.integers(0, 4)) * (1 << 20))
                z.writestr(f"{name}.npy", _npy(shape, "<f8", body))
                continue
            dtype = rng.choice(DTYPES) if kind != 0 else "<f8"
            shape = [(n,), (n, 2), ()][int(rng.integers(3))] if kind != 0 else (n,)
            arr = np.full(shape, 10, dtype=object) if dtype == "|O" else np.full(shape, 10).astype(dtype)
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=True)
            z.writestr(f"{name}.npy", member.getvalue())
    if kind == 4:
        path.write_bytes(mutate(rng, path.read_bytes()))


def preset_file(rng, path: Path) -> None:
    lines = []
    for _ in range(rng.integers(0, 9)):
        key = rng.choice(PRESET_KEYS)
        lines.append(key if key.startswith("[") else f"{key} = {rng.choice(PRESET_VALUES)}")
    raw = "\n".join(lines).encode() + b"\n"
    path.write_bytes(mutate(rng, raw) if rng.random() < 0.2 else raw)


def result_file(rng, path: Path) -> None:
    values = [None, True, 1, -1, 0.1, 1e308, float("nan"), "x", [0.1, 0.2], [0.9, 0.6, 0.3], {},
              [1, [2]], 10**30]
    d = {"model_name": rng.choice(["ggx", "beckmann", "nope"]),
         "params": {k: values[rng.integers(len(values))] for k in
                    rng.choice(["alpha", "f0", "diffuse", "zz"], rng.integers(0, 4))},
         "success": bool(rng.random() < 0.5)}
    text = json.dumps(d) if rng.random() < 0.8 else json.dumps(values[rng.integers(len(values))])
    path.write_bytes(mutate(rng, text.encode()) if rng.random() < 0.2 else text.encode())


class Counts:
    def __init__(self):
        self.n = self.crashes = self.tracebacks = self.bad_errors = 0
        self.hangs = self.memory_peaks = self.leftovers = 0
        self.examples: list[str] = []

    def note(self, what: str, detail: str) -> None:
        setattr(self, what, getattr(self, what) + 1)
        if len(self.examples) < 12:
            self.examples.append(f"{what}: {detail}")

    def total(self) -> int:
        return (self.crashes + self.tracebacks + self.bad_errors + self.hangs
                + self.memory_peaks + self.leftovers)


def run_in_process(argv, folder: Path, keep: set, counts: Counts, args) -> None:
    from brdffit.cli import main

    err, out = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main(argv)
    except BaseException as exc:  # noqa: BLE001 - that is what is counted
        counts.note("crashes", f"{argv}: {type(exc).__name__}: {exc}"[:300])
        code = None
    dt = time.perf_counter() - t0
    check(argv, code, err.getvalue(), dt, folder, keep, counts, args)


def check(argv, code, err, dt, folder, keep, counts, args) -> None:
    counts.n += 1
    lines = err.strip().splitlines()
    if "Traceback" in err:
        counts.note("tracebacks", f"{argv}: {err[-300:]}")
    elif code is not None and code < 0:
        counts.note("crashes", f"{argv}: killed by signal {-code}")
    elif code not in (None, 0, 2) or (code == 2 and len(lines) != 1):
        counts.note("bad_errors", f"{argv}: exit {code}, stderr {err[:300]!r}")
    if dt > args.hang:
        counts.note("hangs", f"{argv}: {dt:.1f} s")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    if peak > args.memory:
        counts.note("memory_peaks", f"{argv}: peak RSS {peak:.0f} MB")
        args.memory = peak + 1e9  # count once
    extra = sorted(set(os.listdir(folder)) - keep)
    if extra:
        counts.note("leftovers", f"{argv}: {extra}")
        for name in extra:
            p = folder / name
            if p.is_dir():
                import shutil

                shutil.rmtree(p, ignore_errors=True)
            else:
                p.unlink(missing_ok=True)


def run_subprocess(argv, folder: Path, keep: set, counts: Counts, args) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    try:
        r = subprocess.run([sys.executable, str(ROOT / "cli.py"), *argv], cwd=folder, env=env,
                           capture_output=True, text=True, timeout=args.hang * 6)
        code, err = r.returncode, r.stderr
    except subprocess.TimeoutExpired:
        code, err = None, ""
        counts.note("hangs", f"{argv}: subprocess timed out")
    check(argv, code, err, (time.perf_counter() - t0) / 6, folder, keep, counts, args)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--merl", type=int, default=10_000)
    ap.add_argument("--lists", type=int, default=5_000, help="sample lists (half CSV, half NPZ)")
    ap.add_argument("--presets", type=int, default=500)
    ap.add_argument("--results", type=int, default=500)
    ap.add_argument("--subprocess", type=int, default=60, help="of each kind, also in a process")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hang", type=float, default=10.0, help="seconds that count as a hang")
    ap.add_argument("--memory", type=float, default=1024.0, help="peak RSS (MB) that counts")
    args = ap.parse_args()
    import warnings

    import jax

    warnings.filterwarnings("ignore", "Duplicate name", UserWarning)  # the generator's own zips

    jax.config.update("jax_enable_x64", True)
    import functools

    import brdffit.cli

    # one parser for every in-process run (building it is 80% of a small run's time; parse_args
    # does not change it): the code under test is the same
    brdffit.cli.build_parser = functools.lru_cache(maxsize=1)(brdffit.cli.build_parser)
    rng = np.random.default_rng(args.seed)
    kinds = [("merl", args.merl, ".binary", merl_file, lambda p: ["info", p]),
             ("csv", args.lists - args.lists // 2, ".csv", csv_file, lambda p: ["info", p]),
             ("npz", args.lists // 2, ".npz", npz_file, lambda p: ["info", p]),
             ("preset", args.presets, ".toml", preset_file,
              lambda p: ["fit", "absent.csv", "--model", "ggx", "-c", p]),
             ("result", args.results, ".json", result_file,
              lambda p: ["plot", "absent.csv", "--fit", p, "-o", "fig.png"])]
    counts, t0 = Counts(), time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        os.chdir(folder)
        for name, n, suffix, make, argv_of in kinds:
            t1 = time.perf_counter()
            for k in range(n):
                path = folder / f"in{suffix}"
                make(rng, path)
                keep = {path.name}
                run_in_process(argv_of(path.name), folder, keep, counts, args)
                if k < args.subprocess:
                    run_subprocess(argv_of(path.name), folder, keep, counts, args)
                path.unlink()
                if (k + 1) % 1000 == 0:
                    print(f"  {name} {k + 1}: {counts.total()} problems so far", flush=True)
            print(f"{name:7s} {n:6d} files in {time.perf_counter() - t1:6.1f} s", flush=True)
        os.chdir(ROOT)
    print(f"{counts.n} runs in {time.perf_counter() - t0:.0f} s: crashes {counts.crashes}, "
          f"tracebacks {counts.tracebacks}, bad errors {counts.bad_errors}, hangs {counts.hangs}, "
          f"memory peaks {counts.memory_peaks}, leftovers {counts.leftovers}; peak RSS "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    for line in counts.examples:
        print("  " + line)
    return 1 if counts.total() else 0


if __name__ == "__main__":
    sys.exit(main())
