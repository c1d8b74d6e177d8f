"""Fuzz the command line and the API with hostile input, by hand, and count what went wrong.

Run from the repository root (the default run: about 12 minutes on two busy cores)::

    python benchmarks/fuzz_hostile.py [--only CAT,...] [--cases CAT=N,...] [--seed 0]
                                      [--hang 10] [--fit-hang 60] [--memory 1024]
    python benchmarks/fuzz_hostile.py --list          # the categories and their default counts

Every category is a seeded generator and an oracle; each prints one row of the table at the end.
The readers (the first round): ``merl``, ``csv``, ``npz`` (``info FILE``), ``preset`` (``fit -c``)
and ``result`` (``plot --fit``), run in this process and the first ``--subprocess`` of each also
through a real ``brdffit`` process. Then, each through the command or the API it names:

* ``staging``: ``export`` (every target) and ``render`` of valid results; any ``.brdffit-*``
  (or other new file) beside the output after the command = a **leftover**.
* ``paths``: ``batch`` with inputs whose names are path tricks (``...csv`` → material ``..``,
  ``..csv``, lists with ``../`` and absolute paths) and with ``OUTDIR/<material>`` or
  ``OUTDIR/<material>/<model>.json`` a symlink to a folder or file outside OUTDIR; any file
  created or changed outside OUTDIR = an **escape**.
* ``inject``: result files whose table name holds XML/JSON metacharacters (``-->``, ``--``,
  ``<bsdf id="evil"/>``, quotes, control characters), exported to mitsuba-xml, mitsuba-dict and
  gltf; output that does not parse, or whose elements/keys differ from the same result's export
  under a plain name = an **injection**.
* ``from_json``: ``FitResult.from_json`` on JSON text (plain, BOM, whitespace), paths, bytes and
  mutated text; a valid document that does not load, or an exception other than the format's
  own (``ValueError``/``JSONDecodeError``, a ``BrdffitError``; ``OSError`` only for a path that
  is not there, ``TypeError`` only for bytes) = a **crash**.
* ``corrupt_fit``: ``fit TABLE -m ggx --max-steps 40`` on a full MERL table with 15-141 flipped
  bits or NaN/inf/huge values in valid cells; a run past ``--fit-hang`` = a **hang**.
* ``degenerate``: ``fit`` on zeros, a constant, a handful of cells, a perfect synthetic table, a
  table times 1e30; ``success: true`` on the data that cannot determine the model (all but the
  synthetic ones), or with NaN in the parameters or metrics, a free parameter off its bounds
  without a standard error, every free parameter on a bound, or ``rel_error`` ≥ 0.99 (the
  model explains nothing) = a **false success** (NaN in a result counts even without success).
* ``errorbar``: ``fit`` on constant tables; a finite standard error on a parameter that changes
  nothing in the model's values at the optimum = a **false success** (an error bar for nothing).
* ``info_memory``: ``info`` on the largest legal NPZ sample list (7 deflated columns of 2^24
  values) and a 512 MiB CSV whose body is one line; a peak RSS past ``--memory`` = a
  **memory peak** (and past ``--hang`` a hang).
* ``batch_list``: ``batch LIST`` where LIST is not UTF-8 (0xff, Latin-1, UTF-16) or is 1 GiB;
  anything but exit 2 with one line, a memory peak, or OUTDIR created = counted.
* ``open_door``: while a local ``batch`` runs, every TCP port its processes listen on is probed
  from outside: a Dask scheduler that runs a task for a client without credentials, and any
  HTTP server (the dashboard, 8787) = an **open door** (in the escapes column).
* ``scheduler``: ``batch --scheduler`` with malformed or unreachable addresses, and a read-only
  OUTDIR (the process runs without ``CAP_DAC_OVERRIDE`` so root obeys the mode bits); anything
  but exit 2 with one line, a message naming a temporary file, or fits run before the refusal =
  a **wrong exit**.
* ``render_opts``: ``render`` with inf/NaN/negative/huge ``--environment``, ``--spp``,
  ``--size`` (under an 8 GiB address-space limit); anything but exit 2 with one line = a wrong
  exit, past ``3 * --hang`` a hang.
* ``multimodel``: a ``fit -m A,B --out`` file into ``export``, ``render`` and ``plot --fit``;
  a traceback, or a message naming a flag the command does not have = a wrong exit.

Counted per category (all must be zero): **crashes** (an exception escaping ``main`` or the API
beyond the format's error, a process killed by a signal), **tracebacks** (``Traceback`` on
stderr), **hangs**, **memory peaks**, **leftovers**, **wrong exits** (an exit code the command
must not give there, exit 2 without exactly one stderr line, a message naming an absent flag),
and **esc/inj/false** (escapes, injections, open doors, false successes). Exits 1 when any count
is not zero.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import re
import resource
import shutil
import signal
import socket
import stat
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



# -- counting ---------------------------------------------------------------------------------
COLUMNS = ("cases", "crashes", "tracebacks", "hangs", "memory_peaks", "leftovers", "wrong_exits",
           "violations")
HEADS = ("cases", "crashes", "tracebacks", "hangs", "memory", "leftovers", "wrong exits",
         "esc/inj/false")


class Counts:
    """One category's counts and its first few examples."""

    def __init__(self, name: str):
        self.name = name
        for c in COLUMNS:
            setattr(self, c, 0)
        self.examples: list[str] = []
        self.seconds = 0.0

    def note(self, what: str, detail: str) -> None:
        setattr(self, what, getattr(self, what) + 1)
        if len(self.examples) < 6:
            self.examples.append(f"{what}: {detail}"[:400])

    def total(self) -> int:
        return sum(getattr(self, c) for c in COLUMNS[1:])


class Outcome:
    def __init__(self, argv, code, out="", err="", dt=0.0, peak_mb=None, exc=None,
                 timed_out=False):
        self.argv, self.code, self.out, self.err, self.dt = argv, code, out, err, dt
        self.peak_mb, self.exc, self.timed_out = peak_mb, exc, timed_out

    def __str__(self):
        command = " ".join(map(str, self.argv))[:160]
        return f"{command}: exit {self.code}, stderr {self.err[-200:]!r}"


def run_in_process(argv, cwd: Path) -> Outcome:
    """``brdffit.cli.main(argv)`` in ``cwd``, stdout and stderr captured."""
    from brdffit.cli import main

    err, out = io.StringIO(), io.StringIO()
    old = os.getcwd()
    os.chdir(cwd)
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main([str(a) for a in argv])
        exc = None
    except BaseException as e:  # noqa: BLE001 - that is what is counted
        code, exc = None, e
    finally:
        os.chdir(old)
    return Outcome(argv, code, out.getvalue(), err.getvalue(), time.perf_counter() - t0, exc=exc)


#: Runs a command and writes its peak RSS (KiB) to a file: ``python -c PEAK OUT LIMIT CMD...``.
#: A child's ``ru_maxrss`` counts the resident size of the process it was forked from (Linux
#: keeps the old address space's high-water mark across ``exec``), so the command is started by
#: this small process, not by the fuzzer (or pytest), whose own size would be counted.
#: ``LIMIT`` (bytes, 0 for none) is the command's address-space limit; the exit status (a
#: death by a signal included) is the command's.
PEAK = r"""
import os, resource, signal, subprocess, sys
out, limit, *cmd = sys.argv[1:]
if int(limit):
    resource.setrlimit(resource.RLIMIT_AS, (int(limit), int(limit)))
p = subprocess.Popen(cmd)
while True:
    try:
        _, status, usage = os.wait4(p.pid, 0)
        break
    except InterruptedError:
        continue
with open(out, "w") as fh:
    fh.write(str(usage.ru_maxrss))
code = os.waitstatus_to_exitcode(status)
if code < 0:
    signal.signal(-code, signal.SIG_DFL)
    os.kill(os.getpid(), -code)
sys.exit(code)
"""


def peak_command(cmd, peak_file, address_space: int | None = None) -> list:
    """``cmd`` started through :data:`PEAK`, which writes its peak RSS to ``peak_file``."""
    return [sys.executable, "-c", PEAK, str(peak_file), str(address_space or 0), *map(str, cmd)]


def run_process(argv, cwd: Path, timeout: float, *, address_space: int | None = None,
                prefix=(), env=None, on_start=None) -> Outcome:
    """A real ``brdffit`` process (``cli.py``) in its own session, started through
    :data:`PEAK` (its peak RSS, not the fuzzer's); killed with its group past ``timeout``.
    ``on_start(popen)`` runs while it runs (and may take time)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}

    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err, \
            tempfile.NamedTemporaryFile("r") as peak:
        t0 = time.perf_counter()
        cmd = peak_command([sys.executable, str(ROOT / "cli.py"), *argv], peak.name,
                           address_space)
        p = subprocess.Popen([*prefix, *cmd], cwd=cwd, env=env, stdout=out, stderr=err,
                             stdin=subprocess.DEVNULL, start_new_session=True)
        if on_start is not None:
            on_start(p)
        timed_out, status, usage = False, None, None
        while p.returncode is None:  # on_start may have reaped it (Popen.poll)
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                p.returncode = os.waitstatus_to_exitcode(status)
                break
            if time.perf_counter() - t0 > timeout:
                timed_out = True
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                _, status, usage = os.wait4(p.pid, 0)
                p.returncode = os.waitstatus_to_exitcode(status)
                break
            time.sleep(0.02)
        dt = time.perf_counter() - t0
        with contextlib.suppress(ProcessLookupError):  # stray Dask workers of a killed batch
            os.killpg(p.pid, signal.SIGKILL)
        out.seek(0)
        err.seek(0)
        code = None if timed_out else p.returncode
        peak.seek(0)
        text = peak.read().strip()
        rss = int(text) if text else usage.ru_maxrss if usage else 0
        return Outcome(argv, code, out.read(), err.read(), dt, rss / 1024, timed_out=timed_out)


def judge(o: Outcome, counts: Counts, *, allowed=(0, 2), hang: float, memory: float | None = None,
          one_line_exit=2, flags_of: str | None = None) -> None:
    """The checks every command shares: crash, traceback, exit code, one-line error, hang,
    memory, and (``flags_of``: the command) a message that names a flag the command lacks."""
    counts.cases += 1
    if o.exc is not None:
        counts.note("crashes", f"{o}: {type(o.exc).__name__}: {o.exc}")
    elif o.code is not None and o.code < 0:
        counts.note("crashes", f"{o}: killed by signal {-o.code}")
    if "Traceback" in o.err:
        counts.note("tracebacks", f"{o}")
    elif o.code is not None and o.code >= 0:
        lines = o.err.strip().splitlines()
        if o.code not in allowed:
            counts.note("wrong_exits", f"{o} (expected {allowed})")
        elif o.code == one_line_exit and len(lines) != 1:
            counts.note("wrong_exits", f"{o}: {len(lines)} stderr lines")
        elif flags_of and o.code != 0:
            said = re.sub(r"`[^`]*`", "", o.err)  # `brdffit fit ... --out`: another command
            absent = sorted(set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", said)) - flags(flags_of))
            if absent:
                counts.note("wrong_exits", f"{o}: names {absent}, which `{flags_of}` lacks")
    if o.timed_out or o.dt > hang:
        counts.note("hangs", f"{o}: {o.dt:.1f} s")
    if memory is not None and o.peak_mb is not None and o.peak_mb > memory:
        counts.note("memory_peaks", f"{o}: peak RSS {o.peak_mb:.0f} MB")


def flags(command: str) -> set:
    from brdffit.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {s for a in sub.choices[command]._actions for s in a.option_strings}


def snapshot(folder: Path) -> dict:
    """``{relative path: (kind, size, mtime_ns)}`` of everything under ``folder`` (links not
    followed)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st = p.lstat()
            out[str(p.relative_to(folder))] = (stat.S_IFMT(st.st_mode), st.st_size, st.st_mtime_ns)
    return out


def new_entries(before: dict, after: dict) -> list[str]:
    return sorted(k for k, v in after.items() if before.get(k) != v)


def clear(folder: Path, keep=()) -> None:
    for p in folder.iterdir():
        if p.name in keep:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)


# -- shared inputs (built once per run, in the run's temporary folder) ------------------------
class Fixtures:
    def __init__(self, folder: Path):
        self.folder = folder
        self._cache: dict = {}

    def _once(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def synth(self, model: str, suffix: str = ".csv", samples: int = 400, params=()) -> Path:
        def make():
            path = self.folder / f"synth-{model}-{samples}-{'-'.join(params)}{suffix}"
            argv = ["synth", "-m", model, "-o", path, "-q", "--seed", "1"]
            argv += ["--samples", str(samples)] if suffix != ".binary" else []
            for p in params:
                argv += ["-p", p]
            o = run_in_process(argv, self.folder)
            assert o.code == 0, o
            return path
        return self._once(("synth", model, suffix, samples, params), make)

    def result(self, model: str) -> Path:
        """A converged single-model result (``fit --out``) of a synthetic table of ``model``."""
        def make():
            table = self.synth(model)
            path = self.folder / f"result-{model}.json"
            o = run_in_process(["fit", table, "-m", model, "--out", path, "-q", "--max-steps",
                                "60"], self.folder)
            assert o.code in (0, 1) and path.is_file(), o
            return path
        return self._once(("result", model), make)

    def multi(self) -> Path:
        """What ``fit -m gltf-pbr,mitsuba-roughconductor --out`` writes (``{"results": [...]}``)."""
        def make():
            table = self.synth("gltf-pbr")
            path = self.folder / "result-multi.json"
            o = run_in_process(["fit", table, "-m", "gltf-pbr,mitsuba-roughconductor", "--out",
                                path, "-q", "--max-steps", "60"], self.folder)
            assert path.is_file(), o
            return path
        return self._once("multi", make)


def sandbox(base: Path, name: str) -> Path:
    d = base / name
    if d.exists():
        shutil.rmtree(d)
    d.mkdir()
    return d

# -- the categories ---------------------------------------------------------------------------
CATEGORIES: dict = {}


def category(name: str, default: int):
    def wrap(fn):
        CATEGORIES[name] = (default, fn)
        return fn
    return wrap


class Context:
    def __init__(self, args, tmp: Path):
        self.args, self.tmp, self.fx = args, tmp, Fixtures(tmp / "fixtures")
        self.fx.folder.mkdir()


def _readers(make, suffix, argv_of):
    def run(rng, n, ctx, counts):
        folder = sandbox(ctx.tmp, "readers")
        for k in range(n):
            path = folder / f"in{suffix}"
            make(rng, path)
            keep = {path.name}
            runs = [run_in_process(argv_of(path.name), folder)]
            if k < ctx.args.subprocess:
                runs.append(run_process(argv_of(path.name), folder, ctx.args.hang * 6))
            for o in runs:
                judge(o, counts, hang=ctx.args.hang, memory=ctx.args.memory)
                if o.peak_mb is None:  # in this process: its own peak, counted once
                    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
                    if peak > ctx.self_memory:
                        counts.note("memory_peaks", f"{o}: this process's peak RSS {peak:.0f} MB")
                        ctx.self_memory = peak + 1e9
                extra = sorted(set(os.listdir(folder)) - keep)
                if extra:
                    counts.note("leftovers", f"{o}: {extra}")
                    clear(folder, keep)
            path.unlink()
    return run


category("merl", 2000)(_readers(merl_file, ".binary", lambda p: ["info", p]))
category("csv", 500)(_readers(csv_file, ".csv", lambda p: ["info", p]))
category("npz", 500)(_readers(npz_file, ".npz", lambda p: ["info", p]))
category("preset", 200)(_readers(preset_file, ".toml",
                                 lambda p: ["fit", "absent.csv", "--model", "ggx", "-c", p]))
category("result", 200)(_readers(result_file, ".json",
                                 lambda p: ["plot", "absent.csv", "--fit", p, "-o", "fig.png"]))


EXPORTS = [("gltf-pbr", "gltf", ".gltf"), ("mitsuba-roughconductor", "mitsuba-xml", ".xml"),
           ("mitsuba-roughconductor", "mitsuba-dict", ".json"), ("gltf-pbr", "mitsuba-xml", ".xml")]


@category("staging", 24)
def staging(rng, n, ctx, counts):
    """export/render of valid results: nothing but the output may appear beside it."""
    folder = sandbox(ctx.tmp, "staging")
    for k in range(n):
        clear(folder)
        render = k % 6 == 5
        model, target, suffix = EXPORTS[int(rng.integers(len(EXPORTS)))]
        if render:
            model, suffix = "mitsuba-roughconductor", ".png"
        result = shutil.copy(ctx.fx.result(model), folder / "r.json")
        where = folder / ("sub" if rng.random() < 0.4 else "")
        where.mkdir(exist_ok=True)
        out = where / f"out{k}{suffix}"
        argv = (["render", result, "-o", out, "--size", "16", "--spp", "2"] if render
                else ["export", result, "--to", target, "-o", out])
        if rng.random() < 0.3:
            out.write_text("old")
            argv.append("--force")
        before = snapshot(folder)
        o = run_in_process(argv, folder)
        judge(o, counts, hang=ctx.args.hang)
        extra = [e for e in new_entries(before, snapshot(folder))
                 if not (o.code == 0 and (folder / e) == out) and (folder / e) != where]
        if extra:
            counts.note("leftovers", f"{o}: {extra}")


def _batch_argv(inputs, outdir, *extra):
    return ["batch", *inputs, "-m", "ggx", "-o", outdir, "--workers", "1", "--subsample", "100",
            "--max-steps", "20", "-q", *extra]


def _outside(snap: dict) -> dict:
    """Entries outside OUTDIR (``in/out``); a folder by its existence only (creating OUTDIR
    changes its parent's mtime)."""
    return {k: (v[0],) if v[0] == stat.S_IFDIR else v for k, v in snap.items()
            if k != "in/out" and not k.startswith("in/out/")}


@category("paths", 5)
def paths(rng, n, ctx, counts):
    """batch with material names that are path tricks and symlinks in OUTDIR."""
    table = ctx.fx.synth("ggx", samples=300)
    for k in range(n):
        box = sandbox(ctx.tmp, "paths")
        (box / "in").mkdir()
        (box / "other").mkdir()
        outdir = box / "in" / "out"
        trick = k % 5
        if trick == 0:  # a file named '...csv': its material is '..'
            inputs = [shutil.copy(table, box / "in" / "...csv")]
        elif trick == 1:  # '..csv': material '.', i.e. OUTDIR itself
            inputs = [shutil.copy(table, box / "in" / "..csv")]
        elif trick == 2:  # a list with '../' and absolute paths, one name a dotted '...'
            shutil.copy(table, box / "other" / "...csv")
            shutil.copy(table, box / "b.csv")
            lst = box / "in" / "list.txt"
            lst.write_text(f"../other/...csv\n{box / 'b.csv'}\n")
            inputs = [lst]
        elif trick == 3:  # OUTDIR/<material> is a symlink to a folder outside
            inputs = [shutil.copy(table, box / "in" / "mat.csv")]
            outdir.mkdir()
            (outdir / "mat").symlink_to(box / "other", target_is_directory=True)
        else:  # OUTDIR/<material>/<model>.json is a symlink to a file outside
            inputs = [shutil.copy(table, box / "in" / "mat.csv")]
            (outdir / "mat").mkdir(parents=True)
            (box / "other" / "victim.json").write_text("{}")
            (outdir / "mat" / "ggx.json").symlink_to(box / "other" / "victim.json")
            (outdir / "mat" / "ggx.meta.json").symlink_to(box / "other" / "victim.meta.json")
        before = _outside(snapshot(box))
        o = run_process(_batch_argv([os.path.relpath(i, box / "in") for i in inputs], "out"),
                        box / "in", ctx.args.fit_hang * 2)
        judge(o, counts, allowed=(0, 1, 2), hang=ctx.args.fit_hang)
        after = _outside(snapshot(box))
        escaped = new_entries(before, after)
        # what a link inside OUTDIR points to is outside OUTDIR too
        victim = box / "other" / "victim.json"
        if trick == 4 and victim.exists() and victim.read_text() != "{}":
            escaped.append("other/victim.json (written through a link)")
        if escaped:
            counts.note("violations", f"escape: {o}: wrote {escaped}")
    shutil.rmtree(ctx.tmp / "paths", ignore_errors=True)


HOSTILE_NAMES = ['x --> <bsdf type="diffuse" id="evil"/> <!-- y', "a--b", "a-", "-", "--",
                 '"><bsdf id="evil"/>', "<![CDATA[x]]>", "]]>", "&amp;&lt;", "a&b", "\x00",
                 "\x1b[31m", "\x0c", "\u2028\u2029", "\ud800", '", "evil": "1', "\\", "}{",
                 "<?xml version='1.0'?>", "\ufeff", "a\nb", "\t"]


def _xml_shape(text):
    import xml.etree.ElementTree as ET

    root = ET.fromstring(text)  # comments are dropped: elements and attributes stay
    return [(e.tag, sorted(e.attrib)) for e in root.iter()]


def _json_shape(value):
    if isinstance(value, dict):
        return {k: _json_shape(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_shape(v) for v in value]
    return type(value).__name__


@category("inject", 60)
def inject(rng, n, ctx, counts):
    """exports of results whose table name holds markup: parse, compare with a plain name."""
    folder = sandbox(ctx.tmp, "inject")
    plain = {}
    for k in range(n):
        model, target, _ = EXPORTS[k % 3]
        doc = json.loads(ctx.fx.result(model).read_text())
        if (model, target) not in plain:
            path = folder / "plain.json"
            path.write_text(json.dumps(doc))
            o = run_in_process(["export", path, "--to", target, "-o", "plain.out", "--force"],
                               folder)
            assert o.code == 0, o
            text = (folder / "plain.out").read_text()
            plain[model, target] = _xml_shape(text) if target == "mitsuba-xml" else _json_shape(
                json.loads(text))
        parts = rng.choice(HOSTILE_NAMES + ["mat", "gold", " "], int(rng.integers(1, 4)))
        name = "".join(parts)
        doc["table"] = name
        doc.setdefault("provenance", {}).setdefault("input", {})["name"] = name
        path = folder / "r.json"
        path.write_text(json.dumps(doc))
        out = folder / f"out{k}"
        o = run_in_process(["export", path, "--to", target, "-o", out], folder)
        judge(o, counts, hang=ctx.args.hang)
        if o.code != 0:
            continue
        text = out.read_bytes().decode("utf-8", "replace")
        try:
            shape = _xml_shape(text) if target == "mitsuba-xml" else _json_shape(json.loads(text))
        except Exception as exc:  # noqa: BLE001 - not well-formed
            counts.note("violations", f"injection: {target} of table {name!r}: not well-formed "
                        f"({type(exc).__name__}: {exc})")
            continue
        if shape != plain[model, target]:
            counts.note("violations", f"injection: {target} of table {name!r}: elements/keys "
                        "differ from the plain export")
        out.unlink()


@category("from_json", 300)
def from_json(rng, n, ctx, counts):
    """FitResult.from_json on text, paths and junk: a result, or the format's own error."""
    from brdffit.errors import BrdffitError
    from brdffit.fitting.result import FitResult

    folder = sandbox(ctx.tmp, "from_json")
    valid = ctx.fx.result("ggx").read_text()
    for k in range(n):
        kind = k % 10
        must_load = False
        if kind == 0:  # the text itself, as written
            arg, must_load = valid, True
        elif kind == 1:  # the text, compact or with leading whitespace/newlines
            arg = rng.choice(["", " ", "\n", "\t\r\n"]) + json.dumps(json.loads(valid))
            must_load = True
        elif kind == 2:  # with a byte order mark, as a string
            arg = "\ufeff" + valid
        elif kind == 3:  # a path (str or Path), the file plain or with a BOM
            p = folder / f"r{k}.json"
            p.write_bytes((b"\xef\xbb\xbf" if rng.random() < 0.5 else b"") + valid.encode())
            arg = str(p) if rng.random() < 0.5 else p
            must_load = not p.read_bytes().startswith(b"\xef")
        elif kind == 4:  # bytes
            arg = valid.encode()
        elif kind == 5:  # a path that does not exist, or a folder
            arg = str(folder / "absent.json") if rng.random() < 0.5 else str(folder)
        elif kind == 6:  # valid JSON that is not a result
            arg = json.dumps([[], {}, "x", 1, None, {"model_name": "ggx"}, {"results": []}][
                int(rng.integers(7))])
        elif kind == 7:  # mutated text
            arg = mutate(rng, valid.encode()).decode("utf-8", "replace")
        elif kind == 8:  # a long string that is neither (a file name too long, a JSON-ish line)
            arg = rng.choice(["{", "[", "x", " {"]) * int(rng.integers(1, 5000))
        else:  # a result with a field removed or of the wrong type
            d = json.loads(valid)
            key = list(d)[int(rng.integers(len(d)))]
            if rng.random() < 0.5:
                del d[key]
            else:
                d[key] = [None, "x", [], {}, 1e308][int(rng.integers(5))]
            arg = json.dumps(d)
        counts.cases += 1
        t0 = time.perf_counter()
        try:
            r = FitResult.from_json(arg)
            if not isinstance(r, FitResult):
                counts.note("crashes", f"kind {kind}: returned {type(r).__name__}")
        except (ValueError, BrdffitError) as exc:  # JSONDecodeError is a ValueError
            if must_load:
                counts.note("crashes", f"kind {kind}: a valid result does not load: "
                            f"{type(exc).__name__}: {exc}")
        except TypeError as exc:  # bytes are neither a path nor a string: a TypeError is fair
            if kind != 4:
                counts.note("crashes", f"kind {kind}: {type(exc).__name__}: {str(exc)[:120]}")
        except (FileNotFoundError, IsADirectoryError) as exc:
            # a path that names no file (kind 5; kind 8's short words are file names too)
            if not (kind == 5 or kind == 8 and set(arg) == {"x"} and len(arg) <= 255):
                counts.note("crashes", f"kind {kind}: {type(exc).__name__}: {str(exc)[:120]}")
        except Exception as exc:  # noqa: BLE001 - that is what is counted
            counts.note("crashes", f"kind {kind}: {type(exc).__name__}: {str(exc)[:120]}")
        if time.perf_counter() - t0 > ctx.args.hang:
            counts.note("hangs", f"kind {kind}: {time.perf_counter() - t0:.1f} s")


def corrupt_table(rng, clean: bytes) -> tuple[bytes, str]:
    """A full MERL table with 15-141 flipped bits or special values in valid cells, mostly
    finite (the reader refuses NaN/inf, so those end early; finite ones reach the fit)."""
    body = np.frombuffer(clean, "<f8", offset=12).copy()
    valid = np.flatnonzero(body >= 0)
    if rng.random() < 0.5:
        bits = int(rng.integers(15, 142))
        words = body.view("<u8")
        for _ in range(bits):
            cell = int(rng.choice(valid))
            flipped = words[cell] ^ np.uint64(1 << int(rng.integers(64)))
            if rng.random() < 0.9 and not np.isfinite(np.array(flipped).view("<f8")):
                continue  # mostly keep the table readable
            words[cell] = flipped
        what = f"{bits} flipped bits"
    else:
        values = [1e300, 1.7e308, 1e30, 1e200, 5e-324, 1e-300]
        values += [np.nan, np.inf] if rng.random() < 0.25 else []  # refused by the reader
        cells = rng.choice(valid, int(rng.integers(1, 200)), replace=False)
        body[cells] = rng.choice(values, cells.size)
        what = f"{cells.size} special values" + (" (with NaN/inf)" if len(values) > 6 else "")
    return clean[:12] + body.astype("<f8").tobytes(), what


@category("corrupt_fit", 5)
def corrupt_fit(rng, n, ctx, counts):
    """fit --max-steps 40 on a corrupted full table: must end (or refuse) in bounded time."""
    folder = sandbox(ctx.tmp, "corrupt")
    clean = ctx.fx.synth("ggx", ".binary", params=("alpha=0.2",)).read_bytes()
    for k in range(n):
        raw, what = corrupt_table(rng, clean)
        (folder / "t.binary").write_bytes(raw)
        o = run_process(["fit", "t.binary", "-m", "ggx", "--max-steps", "40", "-q"], folder,
                        ctx.args.fit_hang * 1.5)
        o.argv = [*o.argv, f"({what})"]
        judge(o, counts, allowed=(0, 1, 2), hang=ctx.args.fit_hang)
        clear(folder)


def _degenerate_table(rng, k, fx, folder) -> tuple[Path, str]:
    header = "theta_i,phi_i,theta_o,phi_o,r,g,b\n"
    m = int(rng.integers(200, 600))
    angles = np.column_stack([rng.uniform(0, 85, m), rng.uniform(0, 360, m),
                              rng.uniform(0, 85, m), rng.uniform(0, 360, m)])
    kind = k % 8
    if kind in (0, 1, 2):  # zeros, one constant, one constant per channel
        value = [0.0, float(rng.choice([1e-3, 0.05, 0.3, 2.0])), None][kind]
        rgb = (np.full((m, 3), value) if value is not None
               else np.broadcast_to(rng.uniform(0.01, 1, 3), (m, 3)))
        what = ["zeros", f"constant {value}", "constant per channel"][kind]
    elif kind == 3:  # a handful of cells
        m = int(rng.integers(1, 5))
        angles, rgb, what = angles[:m], rng.uniform(0.01, 1, (m, 3)), f"{m} cells"
    elif kind == 4:  # a perfect synthetic ggx sample list
        return fx.synth("ggx", samples=2000), "perfect synthetic ggx"
    elif kind == 5:  # a synthetic table times 1e30 (finite)
        data = np.loadtxt(fx.synth("ggx", samples=2000), delimiter=",", skiprows=1)
        angles, rgb, what = data[:, :4], data[:, 4:] * 1e30, "synthetic ggx x 1e30"
    else:  # a full MERL table of zeros, or times 1e30 (finite)
        clean = fx.synth("ggx", ".binary", params=("alpha=0.2",)).read_bytes()
        body = np.frombuffer(clean, "<f8", offset=12).copy()
        body[body > 0] *= 0.0 if kind == 6 else 1e30
        path = folder / "full.binary"
        path.write_bytes(clean[:12] + body.tobytes())
        return path, "full MERL table of zeros" if kind == 6 else "synthetic full MERL ggx x 1e30"
    path = folder / "t.csv"
    rows = np.column_stack([angles, rgb])
    path.write_text(header + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path, what


def _nan_in(value) -> bool:
    return value is None or (isinstance(value, float) and not np.isfinite(value)) or (
        isinstance(value, list) and any(_nan_in(v) for v in value))


@category("degenerate", 8)
def degenerate(rng, n, ctx, counts):
    """fits on data that cannot determine the model: never success with NaN or all on bounds."""
    folder = sandbox(ctx.tmp, "degenerate")
    for k in range(n):
        table, what = _degenerate_table(rng, k, ctx.fx, folder)
        determined = what.startswith(("perfect", "synthetic"))  # the others cannot determine ggx
        out = folder / "r.json"
        out.unlink(missing_ok=True)
        o = run_in_process(["fit", table, "-m", "ggx", "--out", out, "-q"], folder)
        o.argv = [*o.argv, f"({what})"]
        judge(o, counts, allowed=(0, 1, 2), hang=ctx.args.fit_hang)
        if o.code not in (0, 1) or not out.is_file():
            continue
        d = json.loads(out.read_text())
        nan = [f"params.{k2}" for k2, v in d["params"].items() if _nan_in(v)]
        nan += [f"metrics.{k2}" for k2, v in d.get("metrics", {}).items() if _nan_in(v)]
        at = d.get("at_bound", {})
        free = d.get("free", [])

        def on_bound(c):
            return c in at or c.split("[")[0] in at

        unbounded = sorted({c.split("[")[0] for c in free if not on_bound(c)
                            and _nan_in(d["stderr"].get(c.split("[")[0]))})
        all_bound = bool(free) and all(on_bound(c) for c in free)
        problems = nan + [f"stderr.{u} null off the bounds" for u in unbounded] * d["success"]
        if d["success"] and all_bound:
            problems.append("every free parameter on a bound")
        if d["success"] and (d.get("metrics", {}).get("rel_error") or 0) >= 0.99:
            problems.append(f"success with rel_error {d['metrics']['rel_error']:.3g}")
        if d["success"] and not determined:
            problems.append("success on data that cannot determine the model")
        if problems:
            counts.note("violations", f"false success ({what}): success={d['success']}, "
                        f"status {d.get('status')!r}: {problems}")


@category("errorbar", 3)
def errorbar(rng, n, ctx, counts):
    """constant tables: no finite error bar on a parameter the model's values ignore there."""
    import brdffit

    folder = sandbox(ctx.tmp, "errorbar")
    model = brdffit.get_model("ggx")
    for k in range(n):
        m, value = 400, float([0.05, 0.3, 1e-3, 0.8][k % 4])
        angles = np.column_stack([rng.uniform(0, 85, m), rng.uniform(0, 360, m),
                                  rng.uniform(0, 85, m), rng.uniform(0, 360, m)])
        rows = np.column_stack([angles, np.full((m, 3), value)])
        (folder / "t.csv").write_text("theta_i,phi_i,theta_o,phi_o,r,g,b\n" + "\n".join(
            ",".join(repr(float(v)) for v in r) for r in rows) + "\n")
        out = folder / "r.json"
        out.unlink(missing_ok=True)
        o = run_in_process(["fit", "t.csv", "-m", "ggx", "--out", out, "-q"], folder)
        judge(o, counts, allowed=(0, 1, 2), hang=ctx.args.fit_hang)
        if not out.is_file():
            continue
        d = json.loads(out.read_text())
        th_i, ph_i = np.radians(rng.uniform(0, 85, 500)), np.radians(rng.uniform(0, 360, 500))
        th_o, ph_o = np.radians(rng.uniform(0, 85, 500)), np.radians(rng.uniform(0, 360, 500))
        wi = np.column_stack([np.sin(th_i) * np.cos(ph_i), np.sin(th_i) * np.sin(ph_i),
                              np.cos(th_i)])
        wo = np.column_stack([np.sin(th_o) * np.cos(ph_o), np.sin(th_o) * np.sin(ph_o),
                              np.cos(th_o)])
        params = {k2: np.asarray(v, float) for k2, v in d["params"].items()}
        base = np.asarray(model(params, wi, wo))
        for p in model.params:
            err = d["stderr"].get(p.name)
            if _nan_in(err) or not np.all(np.asarray(err, float) > 0):
                continue
            moved = dict(params)
            moved[p.name] = np.full_like(params[p.name], p.lower + 0.37 * (p.upper - p.lower))
            change = np.max(np.abs(np.asarray(model(moved, wi, wo)) - base))
            if change <= 1e-12 * max(np.max(np.abs(base)), 1e-300):
                counts.note("violations", f"false success (constant {value}): {p.name} = "
                            f"{d['params'][p.name]} ± {err}, but moving it changes nothing")


def legal_max_npz(path: Path, value: float = 0.0) -> None:
    """The largest sample list the reader accepts: 7 deflated float64 columns of 2^24 values."""
    from data_formats.samplelist import MAX_SAMPLES

    column = np.full(MAX_SAMPLES, value)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b"]:
            member = io.BytesIO()
            np.lib.format.write_array(member, column)
            z.writestr(f"{name}.npy", member.getvalue())


@category("info_memory", 3)
def info_memory(rng, n, ctx, counts):
    """info on the largest legal files: bounded memory, bounded time."""
    folder = sandbox(ctx.tmp, "info_memory")
    for k in range(n):
        kind = k % 3
        if kind < 2:  # the legal-max NPZ, of zeros or of a constant
            path = folder / "legal-max.npz"
            legal_max_npz(path, [0.0, 0.25][kind])
        else:  # a 512 MiB CSV whose body is one line (sparse: NUL bytes)
            path = folder / "one-line.csv"
            with open(path, "wb") as fh:
                fh.write(b"theta_i,phi_i,theta_o,phi_o,r,g,b\n")
                fh.truncate(512 << 20)
        o = run_process(["info", path.name], folder, ctx.args.hang * 12)
        judge(o, counts, hang=ctx.args.hang, memory=ctx.args.memory)
        clear(folder)


@category("batch_list", 6)
def batch_list(rng, n, ctx, counts):
    """batch LIST with a list that is not UTF-8 or is huge: exit 2, one line, nothing made."""
    folder = sandbox(ctx.tmp, "batch_list")
    table = ctx.fx.synth("ggx", samples=300)
    for k in range(n):
        clear(folder)
        shutil.copy(table, folder / "a.csv")
        kind = k % 6
        lst = folder / "list.txt"
        if kind == 0:
            lst.write_bytes(b"\xff" + b"a.csv\n")
        elif kind == 1:  # Latin-1 file name in the list
            lst.write_bytes("a.csv\nmat\xe9riau.csv\n".encode("latin-1"))
        elif kind == 2:  # UTF-16 with its BOM
            lst.write_bytes("a.csv\n".encode("utf-16"))
        elif kind == 3:  # random bytes
            lst.write_bytes(bytes(rng.integers(0, 256, int(rng.integers(1, 300))).astype(np.uint8)))
        elif kind == 4:  # 1 GiB, one line (sparse)
            with open(lst, "wb") as fh:
                fh.write(b"a.csv")
                fh.truncate(1 << 30)
        else:  # 1 GiB of blank lines and comments after a valid path (sparse would be NULs)
            with open(lst, "wb") as fh:
                fh.write(b"a.csv\n" + b"#" * (1 << 20) + b"\n")
                fh.seek((1 << 30) - 2)
                fh.write(b"\n\n")
        o = run_process(["batch", "list.txt", "-m", "ggx", "-o", "out", "--workers", "1", "-q",
                         "--subsample", "50", "--max-steps", "5"], folder, ctx.args.hang * 6)
        o.argv = [*o.argv, f"(list kind {kind})"]
        judge(o, counts, allowed=(2,), hang=ctx.args.hang, memory=ctx.args.memory)
        if (folder / "out").exists():
            counts.note("leftovers", f"{o}: OUTDIR created for a refused list")


def _listening(pids) -> list[tuple[str, int]]:
    import psutil

    return sorted({(c.laddr.ip, c.laddr.port) for c in psutil.net_connections("tcp")
                   if c.status == psutil.CONN_LISTEN and c.pid in pids})


PROBE = """
import sys
from distributed import Client
c = Client(sys.argv[1], timeout=5)
print("RAN", c.submit(lambda: 6 * 7, pure=False).result(timeout=10))
c.close()
"""


def _http(ip, port) -> bool:
    try:
        with socket.create_connection((ip if ip not in ("0.0.0.0", "::") else "127.0.0.1", port),
                                      timeout=3) as s:
            s.sendall(b"GET / HTTP/1.0\r\nHost: localhost\r\n\r\n")
            return s.recv(16).startswith(b"HTTP/")
    except OSError:
        return False


def open_doors(pids, seen: set) -> list[str]:
    """Probe each port the processes ``pids`` listen on and ``seen`` lacks (then added): an HTTP
    answer, or a Dask scheduler that runs a task for a client without credentials, is an open
    door; returns what was found."""
    found = []
    for ip, port in _listening(pids):
        if (ip, port) in seen:
            continue
        seen.add((ip, port))
        host = "127.0.0.1" if ip in ("0.0.0.0", "::", "127.0.0.1") else ip
        if _http(ip, port):
            found.append(f"HTTP server on {ip}:{port}")
            continue
        r = subprocess.run([sys.executable, "-c", PROBE, f"tcp://{host}:{port}"],
                           capture_output=True, text=True, timeout=30,
                           env={**os.environ, "PYTHONPATH": str(ROOT)})
        if "RAN 42" in r.stdout:
            found.append(f"a Dask scheduler on {ip}:{port} ran a task for a client without "
                         "credentials")
    return found


@category("open_door", 1)
def open_door(rng, n, ctx, counts):
    """while a local batch runs: nobody without credentials may run a task; no HTTP server."""
    import psutil

    folder = sandbox(ctx.tmp, "open_door")
    for k in range(n):
        for name in "abc":
            shutil.copy(ctx.fx.synth("ggx", samples=4000), folder / f"{name}.csv")
        found: list[str] = []

        def probe(p):
            deadline = time.perf_counter() + ctx.args.fit_hang
            seen: set = set()
            while time.perf_counter() < deadline and p.poll() is None:
                try:
                    tree = {p.pid, *(c.pid for c in psutil.Process(p.pid).children(True))}
                except psutil.Error:
                    break
                found += open_doors(tree, seen)
                if found:
                    break
                time.sleep(0.5)

        o = run_process(["batch", "a.csv", "b.csv", "c.csv", "-m", "ggx,beckmann", "-o", "out",
                         "--workers", "1", "-q", "--force"], folder, ctx.args.fit_hang * 4,
                        on_start=probe)
        o.err = ""  # the probe's own connections make Dask log errors there: not counted
        judge(o, counts, allowed=(0, 1), hang=ctx.args.fit_hang * 4)
        for f in found:
            counts.note("violations", f"open door: {f}")
        clear(folder)


SCHEDULERS = ["foo", "inproc://x", "tcp://[::1", "ucx://127.0.0.1:1", "tcp://127.0.0.1:1",
              "tcp://127.0.0.1:99999", "tls://", "://", "tcp://", "tcp://host name:1",
              "tcp://127.0.0.1:-1", "tcp://127.0.0.1:8786x"]


@category("scheduler", 13)
def scheduler(rng, n, ctx, counts):
    """bad --scheduler values and a read-only OUTDIR: exit 2, one line, before any fit."""
    folder = sandbox(ctx.tmp, "scheduler")
    shutil.copy(ctx.fx.synth("ggx", samples=300), folder / "a.csv")
    shutil.copy(ctx.fx.synth("ggx", samples=300), folder / "b.csv")
    for k in range(n):
        if k % (len(SCHEDULERS) + 1) == len(SCHEDULERS):  # a read-only OUTDIR
            ro = folder / "ro"
            ro.mkdir(exist_ok=True)
            ro.chmod(0o555)
            o = run_process(["batch", "a.csv", "b.csv", "-m", "ggx", "-o", "ro", "--workers",
                             "1", "--subsample", "100"], folder, ctx.args.fit_hang * 2,
                            prefix=["setpriv", "--bounding-set",
                                    "-dac_override,-dac_read_search,-fowner"])
            judge(o, counts, allowed=(2,), hang=ctx.args.fit_hang)
            if o.code == 2 and re.search(r"\.brdffit-|\.tmp|\.[\w.]+\.[a-z0-9_]{8}", o.err):
                counts.note("wrong_exits", f"{o}: names a temporary file, not OUTDIR")
            if re.search(r"\bfits?\b.*(succeeded|failed|converged)|\bggx\b", o.out):
                counts.note("wrong_exits", f"{o}: fits ran before the refusal: {o.out[:120]!r}")
            ro.chmod(0o755)
            shutil.rmtree(ro)
            continue
        address = SCHEDULERS[k % (len(SCHEDULERS) + 1)]
        o = run_process(["batch", "a.csv", "-m", "ggx", "-o", "out", "--scheduler", address,
                         "-q"], folder, ctx.args.fit_hang)
        judge(o, counts, allowed=(2,), hang=ctx.args.fit_hang / 2)
        clear(folder, {"a.csv", "b.csv"})


RENDER_OPTIONS = [("--environment", "inf"), ("--environment", "nan"), ("--environment", "-1"),
                  ("--environment", "1e300"), ("--spp", "100000000"), ("--spp", "0"),
                  ("--spp", "-4"), ("--size", "60000"), ("--size", "0"), ("--size", "-5"),
                  ("--size", "nan"), ("--environment", "-inf")]


@category("render_opts", 12)
def render_opts(rng, n, ctx, counts):
    """render with absurd numeric options: exit 2 with one line, before any work."""
    folder = sandbox(ctx.tmp, "render_opts")
    shutil.copy(ctx.fx.result("mitsuba-roughconductor"), folder / "r.json")
    for k in range(n):
        flag, value = RENDER_OPTIONS[k % len(RENDER_OPTIONS)]
        argv = ["render", "r.json", "-o", "s.png", f"{flag}={value}"]
        argv += [] if flag == "--size" else ["--size", "32"]
        o = run_process(argv, folder, ctx.args.hang * 3, address_space=8 << 30)
        judge(o, counts, allowed=(2,), hang=ctx.args.hang * 3)
        clear(folder, {"r.json"})


@category("multimodel", 6)
def multimodel(rng, n, ctx, counts):
    """a multi-model result into export/render/plot: accepted, or refused naming its own flags."""
    folder = sandbox(ctx.tmp, "multimodel")
    shutil.copy(ctx.fx.multi(), folder / "multi.json")
    shutil.copy(ctx.fx.synth("gltf-pbr"), folder / "t.csv")
    commands = [("export", ["export", "multi.json", "--to", "gltf", "-o", "o.gltf"]),
                ("export", ["export", "multi.json", "--to", "mitsuba-xml", "-o", "o.xml"]),
                ("export", ["export", "multi.json", "--to", "mitsuba-dict", "-o", "o.json"]),
                ("render", ["render", "multi.json", "-o", "o.png", "--size", "16", "--spp", "2"]),
                ("plot", ["plot", "t.csv", "--fit", "multi.json", "-o", "o.png"]),
                ("export", ["export", "multi.json", "--to", "gltf", "-o", "o.gltf",
                            "--approximate"])]
    for k in range(n):
        command, argv = commands[k % len(commands)]
        before = snapshot(folder)
        o = run_in_process(argv, folder)
        judge(o, counts, hang=ctx.args.fit_hang, flags_of=command)
        extra = new_entries(before, snapshot(folder))
        if o.code != 0 and extra:
            counts.note("leftovers", f"{o}: {extra}")
        elif o.code == 0 and any(".brdffit-" in e for e in extra):
            counts.note("leftovers", f"{o}: {extra}")
        clear(folder, {"multi.json", "t.csv"})


# -- the run ----------------------------------------------------------------------------------
def parse_counts(text: str) -> dict:
    out = {}
    for item in filter(None, (text or "").split(",")):
        name, _, value = item.partition("=")
        if name not in CATEGORIES or not value.isdigit():
            raise SystemExit(f"--cases {item!r}: expected CAT=N with CAT one of {list(CATEGORIES)}")
        out[name] = int(value)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="comma-separated categories to run (default: all)")
    ap.add_argument("--cases", help="CAT=N,... case counts overriding the defaults")
    ap.add_argument("--list", action="store_true", help="list the categories and exit")
    ap.add_argument("--merl", type=int, help="merl cases (as --cases merl=N)")
    ap.add_argument("--lists", type=int, help="sample lists, half CSV and half NPZ")
    ap.add_argument("--presets", type=int, help="preset cases")
    ap.add_argument("--results", type=int, help="result-file cases (plot --fit)")
    ap.add_argument("--subprocess", type=int, default=10,
                    help="of each reader category, also in a process")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hang", type=float, default=10.0, help="seconds that count as a hang")
    ap.add_argument("--fit-hang", type=float, default=60.0,
                    help="seconds that count as a hang for a command that fits")
    ap.add_argument("--memory", type=float, default=1024.0, help="peak RSS (MB) that counts")
    args = ap.parse_args()
    if args.list:
        for name, (default, fn) in CATEGORIES.items():
            print(f"{name:12s} {default:5d}  {(fn.__doc__ or '').strip()}")
        return 0
    counts_of = {name: default for name, (default, _) in CATEGORIES.items()}
    legacy = {"merl": args.merl, "presets": args.presets, "results": args.results}
    for key, cat in (("merl", "merl"), ("presets", "preset"), ("results", "result")):
        if legacy[key] is not None:
            counts_of[cat] = legacy[key]
    if args.lists is not None:
        counts_of["csv"], counts_of["npz"] = args.lists - args.lists // 2, args.lists // 2
    counts_of.update(parse_counts(args.cases))
    chosen = list(CATEGORIES) if not args.only else [c.strip() for c in args.only.split(",")]
    unknown = [c for c in chosen if c not in CATEGORIES]
    if unknown:
        raise SystemExit(f"--only: unknown {unknown}; categories: {', '.join(CATEGORIES)}")
    import functools
    import warnings

    import jax

    warnings.filterwarnings("ignore", "Duplicate name", UserWarning)  # the generator's own zips
    warnings.filterwarnings("ignore", r"os\.fork\(\) was called", RuntimeWarning)  # then exec
    jax.config.update("jax_enable_x64", True)
    import brdffit.cli

    # one parser for every in-process run (building it is 80% of a small run's time; parse_args
    # does not change it): the code under test is the same
    brdffit.cli.build_parser = functools.lru_cache(maxsize=1)(brdffit.cli.build_parser)
    print(f"fuzz_hostile: seed {args.seed}, hang {args.hang} s (fits {args.fit_hang} s), memory "
          f"{args.memory:.0f} MB; code under test: {brdffit.__file__}", flush=True)
    results = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="fuzz-hostile-") as tmp:
        ctx = Context(args, Path(tmp))
        ctx.self_memory = args.memory
        for name in chosen:
            rng = np.random.default_rng([args.seed, list(CATEGORIES).index(name)])
            counts = Counts(name)
            t1 = time.perf_counter()
            try:
                CATEGORIES[name][1](rng, counts_of[name], ctx, counts)
            except Exception as exc:  # noqa: BLE001 - the fuzzer's own failure, reported
                import traceback

                counts.note("crashes", f"the category itself failed: {type(exc).__name__}: {exc}")
                traceback.print_exc()
            counts.seconds = time.perf_counter() - t1
            results.append(counts)
            print(f"{name:12s} {counts.cases:6d} cases in {counts.seconds:6.1f} s: "
                  f"{counts.total()} problems", flush=True)
        os.chdir(ROOT)
    print_table(results)
    print(f"total {sum(c.cases for c in results)} cases in {time.perf_counter() - t0:.0f} s")
    return 1 if any(c.total() for c in results) else 0


def print_table(results) -> None:
    widths = [12] + [max(6, len(h)) for h in HEADS]
    line = "  ".join(h.rjust(w) if i else h.ljust(w) for i, (h, w) in
                     enumerate(zip(("category", *HEADS), widths)))
    print("\n" + line + "\n" + "-" * len(line))
    for c in results:
        cells = [c.name.ljust(widths[0])] + [str(getattr(c, col)).rjust(w) for col, w in
                                             zip(COLUMNS, widths[1:])]
        print("  ".join(cells))
    print()
    for c in results:
        for example in c.examples:
            print(f"  {c.name}: {example}")


if __name__ == "__main__":
    sys.exit(main())
