"""Hostile inputs, round two: corrupt values, legal files at the size limits, out of memory.

Each test is built from a reproducer of the audit: a table whose flipped bits made values of
1e76 in valid cells; the largest sample list the reader accepts (seven deflated columns of
2^24 zeros, under 1 MB on disk); a CSV whose body is one 512 MiB line (a sparse file, no disk);
a fit under an address-space cap. Memory caps are set in a subprocess (``_cli``); everything
else runs in-process through ``main(argv)``.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit.cli import main
from brdffit.errors import FitError
from brdffit.fitting.data import MAX_BRDF, MaskedValuesWarning, check_memory, screen
from data_formats.samplelist import (
    MAX_LINE, MAX_SAMPLES, iter_samples, read_samples, write_samples,
)

from test_hostile import _one_line_error

ROOT = Path(__file__).resolve().parent.parent
HEADER = "theta_i,phi_i,theta_o,phi_o,r,g,b\n"


def _cli(*args, cwd, limit_as=None, rss_file=None):
    """``python cli.py ARGS`` in a subprocess, its address space capped at ``limit_as`` bytes;
    with ``rss_file``, a small wrapper process writes the peak resident memory (KiB) of the
    command there (``ru_maxrss`` of its one child: no other process of the test run counts)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    argv = [sys.executable, str(ROOT / "cli.py"), *map(str, args)]
    if limit_as:  # set in a small exec wrapper: preexec_fn would fork this multithreaded process
        argv = [sys.executable, "-c", "import os, resource, sys; resource.setrlimit(resource."
                f"RLIMIT_AS, ({limit_as}, {limit_as})); os.execv(sys.argv[1], sys.argv[1:])",
                *argv]
    if rss_file:
        argv = [sys.executable, "-c", "import resource, subprocess, sys; rc = subprocess.call("
                "sys.argv[2:]); open(sys.argv[1], 'w').write(str(resource.getrusage("
                "resource.RUSAGE_CHILDREN).ru_maxrss)); sys.exit(rc)", str(rss_file), *argv]
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def _samples(n=400):
    from brdffit.cli.synth import synthesize_samples

    return synthesize_samples(brdffit.get_model("ggx"), {"alpha": 0.2}, n, seed=3)


def _legal_max_npz(path: Path, rows: int = MAX_SAMPLES) -> Path:
    """Seven deflated columns of ``rows`` zeros (every direction the normal): a legal sample
    list of the most samples the reader accepts, 914 KB on disk."""
    zeros = io.BytesIO()
    np.lib.format.write_array(zeros, np.zeros(rows))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in HEADER.strip().split(","):
            archive.writestr(f"{name}.npy", zeros.getvalue())
    return path


# -- corrupt values in valid cells --------------------------------------------------------------
def test_corrupt_values_are_masked_with_a_count_and_the_steps_stay_bounded():
    """Values no measurement gives (1e76 from a flipped exponent bit, 1e300, NaN) in valid
    cells: masked before the fit, one warning naming how many and why, and the solver's steps
    within ``(scan candidates + warm + full) × max_steps`` (before: no word, the values went
    into the fit)."""
    s = _samples()
    s.rgb[3] = 7.6e76
    s.rgb[50, 1] = 1e300
    s.rgb[51, 2] = 5 * MAX_BRDF
    s.rgb[7, 0] = np.nan
    events = []
    with pytest.warns(MaskedValuesWarning) as caught:
        res = brdffit.fit(s, "ggx", max_steps=5, throw=False, cutoff=None,  # every cell
                          progress=lambda event, info: events.append(event))
    assert len(caught) == 1
    assert ("masked 4 cells marked valid whose values cannot be measurements (1 not finite, "
            "3 above 1e7/sr)") in str(caught[0].message)
    assert res.n_cells == 396 and res.n_total == 400
    steps = sum(e.endswith("step") for e in events)
    assert 0 < steps <= (3 + 1 + 1) * 5


def test_the_cli_says_how_many_cells_it_masked(tmp_path, capsys):
    s = _samples()
    s.rgb[10] = 1e200
    path = write_samples(tmp_path / "flipped.csv", s)
    code = main(["fit", str(path), "-m", "ggx", "-q", "--max-steps", "5"])
    err = capsys.readouterr().err
    assert code in (0, 1), err
    warning = [line for line in err.splitlines() if "masked" in line]
    assert warning == ["brdffit fit: warning: table flipped: masked 1 cell marked valid whose "
                       "values cannot be measurements (1 above 1e7/sr); the fit ignores it. "
                       "Check the data: it may be corrupt"]
    assert "Traceback" not in err and "UserWarning" not in err


def test_no_cell_of_a_real_material_is_masked():
    """The bound is two decades above the peaks of the realistic corpus (the embedded
    materials' MERL cells nearest the peak, where their largest values are)."""
    from data_formats.merl import MERL_SHAPE, cell_angles

    import realistic

    i, j, k = np.meshgrid(np.arange(12), np.arange(0, 90, 3), np.arange(0, 180, 6),
                          indexing="ij")
    th, td, pd = cell_angles(i.ravel(), j.ravel(), k.ravel(), MERL_SHAPE)
    for name in realistic.names():
        rgb = realistic.brdf_hd(name, th, td, pd)
        good = np.ones(len(rgb), bool)
        assert screen(rgb, good) == () and good.all(), name
        assert rgb.max() < MAX_BRDF / 100, name


# -- out of memory ------------------------------------------------------------------------------
def test_a_fit_too_large_for_the_memory_is_refused_up_front():
    with pytest.raises(FitError, match=r"fitting 1,000,000,000,000 cells needs about .* GiB "
                                       r"more memory \(256 bytes a cell\) and the system has"):
        check_memory(10**12, "huge", backend="cpu")
    check_memory(1000, "small", backend="cpu")  # no error


@pytest.mark.parametrize("text", [
    "RESOURCE_EXHAUSTED: Out of memory allocating 402653184 bytes.",  # jax.device_put
    "INTERNAL: Error dispatching computation: Out of memory allocating 402653184 bytes.",
])
def test_xla_out_of_memory_is_the_documented_line(monkeypatch, capsys, text):
    """XLA's out-of-memory (raised by JAX as a ValueError from a transfer, or as a
    JaxRuntimeError from a running program) anywhere in a command: one line, exit 2 (before: a
    35-line traceback, exit 1)."""
    from brdffit.cli import info

    def exhausted(args):
        try:
            raise ValueError(text)
        except ValueError as exc:
            raise RuntimeError("while fitting") from exc

    monkeypatch.setattr(info, "run", exhausted)
    assert main(["info", "x.npz"]) == 2
    _one_line_error(capsys.readouterr().err, "brdffit info: error: out of memory")
    monkeypatch.setattr(info, "run", lambda args: 1 / 0)
    with pytest.raises(ZeroDivisionError):  # any other exception is still a bug, not a refusal
        main(["info", "x.npz"])


def test_fit_of_the_legal_maximum_under_a_4_gib_cap_is_refused_in_one_line(tmp_path):
    """``prlimit --as=4GiB brdffit fit legalmax.npz`` (before: RESOURCE_EXHAUSTED traceback,
    exit 1; under 6 GiB an abort)."""
    _legal_max_npz(tmp_path / "legalmax.npz")
    p = _cli("fit", "legalmax.npz", "-m", "ggx", "-q", cwd=tmp_path, limit_as=4 << 30)
    assert p.returncode == 2, p.stderr
    _one_line_error(p.stderr, "fitting 16,777,216 cells needs about",
                    "address-space limit (ulimit -v, 4.0 GiB)", "`--subsample`")


# -- readers at the size limits ----------------------------------------------------------------
def test_info_of_the_legal_maximum_streams_under_a_1_5_gib_cap(tmp_path):
    """``info legal-max.npz`` (before: 2.8 GB peak; under this cap a MemoryError, exit 2):
    the figures, read piece by piece."""
    _legal_max_npz(tmp_path / "legalmax.npz")
    assert (tmp_path / "legalmax.npz").stat().st_size < 1_000_000
    p = _cli("info", "legalmax.npz", cwd=tmp_path, limit_as=3 << 29)
    assert p.returncode == 0, p.stderr
    assert "samples      16,777,216 direction pairs" in p.stdout
    assert "valid        16,777,216 (100.0%)" in p.stdout


def test_pieces_give_the_figures_and_samples_of_the_whole(tmp_path):
    from brdffit.cli.info import sample_info, streamed_info

    s = _samples(1000)
    s.valid[::7] = False
    for suffix in (".npz", ".csv"):
        path = write_samples(tmp_path / f"s{suffix}", s)
        whole = read_samples(path)
        pieces = list(iter_samples(path, rows=77))
        n = len(whole)  # the valid rows of s: write_samples stores no others
        assert [len(p) for p in pieces] == [77] * (n // 77) + [n % 77]
        for name in ("wi", "wo", "rgb", "valid"):
            np.testing.assert_array_equal(np.concatenate([getattr(p, name) for p in pieces]),
                                          getattr(whole, name))
        assert streamed_info(iter(pieces), n=n) == sample_info(whole)
        rgb = whole.rgb[whole.valid]
        figures = sample_info(whole)
        assert figures["r_median"] == float(np.median(rgb[:, 0]))


def test_errors_in_a_later_piece_name_their_row_in_the_file(tmp_path):
    from data_formats.samplelist import SampleListFormatError

    s = _samples(300)
    path = tmp_path / "bad.npz"
    cols = dict(np.load(write_samples(tmp_path / "ok.npz", s)))
    cols["r"][250] = -1.0
    np.savez(path, **cols)
    with pytest.raises(SampleListFormatError, match=r"bad.npz: row 250, column 'r'"):
        list(iter_samples(path, rows=100))
    csv = tmp_path / "bad.csv"
    write_samples(csv, s)
    lines = csv.read_text().splitlines()
    fields = lines[201].split(",")  # line 202: data row 200
    fields[2] = "-5"  # theta_o
    lines[201] = ",".join(fields)
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(SampleListFormatError, match=r"bad.csv: line 202, column 'theta_o'"):
        read_samples(csv)


def test_a_csv_body_of_one_huge_line_is_refused_at_its_first_mib(tmp_path):
    """A 512 MiB CSV whose body is one line (a sparse file: no disk used): one line, exit 2,
    and the peak resident memory within 64 MiB of ``info`` on a two-row CSV (before: the whole
    line read, split and converted, 1.3-3.2 GB). Resident memory, not an address-space cap: what
    allocators reserve without touching differs between machines (pyarrow's default mimalloc
    pool alone reserved 1 GiB here), and a cap measured that instead of the reader."""
    (tmp_path / "two.csv").write_text(HEADER + "0.1,0,0.2,3,0.1,0.1,0.1\n0.2,0,0.3,3,0.1,0.1,0.1\n")
    base = _cli("info", "two.csv", cwd=tmp_path, rss_file=tmp_path / "two.rss")
    assert base.returncode == 0, base.stderr
    path = tmp_path / "one.csv"
    with open(path, "wb") as fh:
        fh.write(HEADER.encode())
        fh.truncate(fh.tell() + (512 << 20))
    p = _cli("info", "one.csv", cwd=tmp_path, rss_file=tmp_path / "one.rss")
    assert p.returncode == 2, p.stderr
    _one_line_error(p.stderr, f"one.csv: line 2 is longer than {MAX_LINE:,} bytes")
    peak, baseline = (int((tmp_path / f"{n}.rss").read_text()) for n in ("one", "two"))
    assert peak < baseline + (64 << 10), (peak, baseline)


def test_long_lines_are_refused_in_the_preamble_too(tmp_path):
    path = tmp_path / "c.csv"
    path.write_bytes(b"#" * (MAX_LINE + 5) + b"\n" + HEADER.encode() + b"0,0,0,0,1,1,1\n")
    from data_formats.samplelist import SampleListFormatError

    with pytest.raises(SampleListFormatError, match="line 1 is longer than .* before any header"):
        read_samples(path)
