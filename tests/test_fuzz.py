"""Fuzzing every reader and the command line's option parsing (hypothesis, bounded for CI).

The property everywhere: a reader returns a well-formed object or raises the format's own
error (``MERLFormatError``, ``SampleListFormatError``, ``ConfigError`` / ``UnknownNameError``,
the CLI's ``UsageError``); the command line returns exit code 2 with exactly one line on
stderr, and leaves nothing behind. Any other exception is a bug. ``benchmarks/fuzz_hostile.py``
runs the same generators much longer, by hand.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import zipfile

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdffit.config import check_fit_options, load_config
from brdffit.errors import BrdffitError
from data_formats.merl import MERLFormatError, MERLTable, read_merl
from data_formats.samplelist import SampleListFormatError, read_samples
from data_formats.samples import SampleSet

FUZZ = settings(max_examples=80, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def _merl_bytes(dims, body) -> bytes:
    return np.asarray(dims, "<i4").tobytes() + np.asarray(body, "<f8").tobytes()


VALID_MERL = _merl_bytes((2, 3, 4), np.linspace(-1, 5, 72))


def _mutate(data: bytes, edits) -> bytes:
    """Apply ``(kind, position, value)`` edits: flip a byte, truncate, or append."""
    out = bytearray(data)
    for kind, pos, value in edits:
        if kind == "flip" and out:
            out[pos % len(out)] ^= value or 1
        elif kind == "cut":
            del out[pos % (len(out) + 1):]
        else:
            out += bytes([value]) * (pos % 64)
    return bytes(out)


EDITS = st.lists(st.tuples(st.sampled_from(["flip", "cut", "add"]), st.integers(0, 10**6),
                           st.integers(0, 255)), max_size=4)


@FUZZ
@given(dims=st.tuples(*[st.integers(-3, 70_000)] * 3), n=st.integers(0, 200), edits=EDITS)
def test_merl_reader(tmp_path_factory, dims, n, edits):
    path = tmp_path_factory.mktemp("merl") / "f.binary"
    raw = _merl_bytes(dims, np.arange(n) - 3.0) if n % 3 else _mutate(VALID_MERL, edits)
    path.write_bytes(raw)
    try:
        table = read_merl(path)
    except MERLFormatError as exc:
        assert str(path) in str(exc)
        return
    assert isinstance(table, MERLTable) and np.isfinite(table.rgb).all()


CSV_TOKENS = ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "wix", "wiy", "wiz", "wox",
              "woy", "woz", ",", ",", ",", "\n", "\n", "\r\n", "#", " ", "0", "1", "45", "89.9",
              "90", "-1", "1e308", "nan", "inf", "1_0", "+.5", "x", "\xe9", ""]
HEADER = "theta_i,phi_i,theta_o,phi_o,r,g,b\n"


@FUZZ
@given(tokens=st.lists(st.sampled_from(CSV_TOKENS), max_size=60), headed=st.booleans(),
       junk=st.binary(max_size=8))
def test_csv_reader(tmp_path_factory, tokens, headed, junk):
    path = tmp_path_factory.mktemp("csv") / "s.csv"
    path.write_bytes(((HEADER if headed else "") + "".join(tokens)).encode() + junk)
    _read_sample_list(path)


def _read_sample_list(path):
    try:
        s = read_samples(path)
    except SampleListFormatError as exc:
        assert str(path) in str(exc)
        return None
    assert isinstance(s, SampleSet) and len(s) > 0 and np.isfinite(s.rgb).all()
    assert (s.rgb >= 0).all() and (s.wi[:, 2] >= 0).all()
    return s


@FUZZ
@given(rows=st.lists(st.tuples(st.floats(0, 90), st.floats(-720, 720), st.floats(0, 90),
                               st.floats(-720, 720), st.floats(0, 1e6), st.floats(0, 1e6),
                               st.floats(0, 1e6)), min_size=1, max_size=30),
       spaced=st.booleans(), comment=st.booleans())
def test_csv_fast_and_slow_parsers_agree(tmp_path_factory, rows, spaced, comment):
    """pyarrow's typed parser and the line-by-line fallback give the same numbers."""
    from pathlib import Path

    from data_formats import samplelist

    sep = ", " if spaced else ","
    lines = [sep.join(repr(float(v)) for v in row) for row in rows]
    if comment:
        lines.insert(len(lines) // 2, "# a comment line, with, commas, in, it, ok")
    path = Path(tmp_path_factory.mktemp("csv2")) / "s.csv"
    path.write_text(HEADER + "\n".join(lines) + "\n")
    _header, data, _rows = samplelist._read_csv(path)
    with open(path, "rb") as fh:
        fh.readline()
        slow = samplelist._parse_slowly(path, fh, list(HEADER.strip().split(",")), 1)
    np.testing.assert_array_equal(data, slow)
    np.testing.assert_array_equal(data, np.array(rows, float))


DTYPES = ["<f8", "<f4", ">f8", "<i8", "<u2", "<c16", "<m8[s]", "|b1", "<U3", "|O"]
COLUMNS = ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "wix", "x"]


@st.composite
def npz_archives(draw):
    names = draw(st.lists(st.sampled_from(COLUMNS), min_size=0, max_size=9))
    n = draw(st.integers(0, 5))
    buf = io.BytesIO()
    arrays = {}
    for name in names:
        dtype = draw(st.sampled_from(DTYPES))
        shape = draw(st.sampled_from([(n,), (n, 2), ()]))
        values = np.full(shape, 10, dtype=object if dtype == "|O" else None)
        arrays[name] = values.astype(dtype) if dtype != "|O" else values
    with zipfile.ZipFile(buf, "w", draw(st.sampled_from([zipfile.ZIP_STORED,
                                                          zipfile.ZIP_DEFLATED]))) as z:
        for name, arr in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=True)
            z.writestr(f"{name}.npy", member.getvalue())
    return _mutate(buf.getvalue(), draw(EDITS) if draw(st.booleans()) else [])


@FUZZ
@given(raw=npz_archives())
def test_npz_reader(tmp_path_factory, raw):
    path = tmp_path_factory.mktemp("npz") / "s.npz"
    path.write_bytes(raw)
    _read_sample_list(path)


TOML_KEYS = ["model", "loss", "cutoff", "subsample", "seed", "multistart", "description",
             "cutof", "[solver]", "[init]", "[fixed]", "[bounds]", "name", "rtol", "atol",
             "max_steps", "alpha", "f0", "diffuse"]
TOML_VALUES = ['"ggx"', '"log"', "0", "-1", "1", "80", "95", "1e-8", "1e-300", "nan", "inf",
               "9223372036854775807", "true", "[0.1, 0.5]", "[0.5, 0.1]", "[1e-300, 1e-299]",
               "[1, 2, 3]", "[0.9, 0.6, 0.3]", "[]", '"x"', "{a = 1}", "0.5"]


@FUZZ
@given(lines=st.lists(st.tuples(st.sampled_from(TOML_KEYS), st.sampled_from(TOML_VALUES)),
                      max_size=8), junk=st.binary(max_size=4))
def test_preset_reader(tmp_path_factory, lines, junk):
    import brdffit

    path = tmp_path_factory.mktemp("toml") / "p.toml"
    text = "\n".join(k if k.startswith("[") else f"{k} = {v}" for k, v in lines)
    path.write_bytes(text.encode() + b"\n" + junk)
    try:
        options = load_config(path)
        check_fit_options(options.fit_kwargs())  # a loaded preset is always in range
        options.check_params(brdffit.get_model("ggx"))
    except BrdffitError as exc:  # ConfigError, UnknownNameError
        assert str(exc).strip() and "\n" not in str(exc).strip()


JSON = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
                    lambda kids: st.lists(kids, max_size=4)
                    | st.dictionaries(st.text(max_size=8), kids, max_size=4), max_leaves=20)


@st.composite
def results(draw):
    base = {"model_name": draw(st.sampled_from(["ggx", "beckmann", "nope", 3])),
            "params": draw(st.dictionaries(st.sampled_from(["alpha", "f0", "diffuse", "zz"]),
                                           JSON, max_size=3)),
            "success": draw(st.booleans())}
    for key in draw(st.lists(st.sampled_from(["cost", "message", "loss", "x", "stderr"]),
                             max_size=3)):
        base[key] = draw(JSON)
    return json.dumps(base) if draw(st.booleans()) else json.dumps(draw(JSON))


@settings(FUZZ, max_examples=60)
@given(text=results())
def test_result_json_reader(tmp_path_factory, text):
    from brdffit.cli._common import UsageError
    from brdffit.cli.plotting import _read_result

    path = tmp_path_factory.mktemp("json") / "r.json"
    path.write_text(text)
    try:
        _read_result(path)
    except UsageError as exc:
        assert "\n" not in str(exc)


FLAG_TOKENS = ["--model", "ggx", "nope", "--loss", "cosine", "cosin", "--cutoff", "--fix",
               "--init", "alpha=0.1", "alpha=nan", "f0=1,2", "alpha=0.3", "--subsample", "inf",
               "0.5", "1e5", "0", "--seed", "-1", "--multistart", "100000000", "2", "--out",
               "o.json", "--plot", "f.png", "--table", "t.binary", "--force", "--json", "-q",
               "--bogus", "--config", "nope.toml", "--solver", "x", "--mcmc", "--steps", "-5",
               "--chain", "c.npz", "=", "--", ""]


@FUZZ
@given(command=st.sampled_from(["fit", "plot", "info"]),
       tokens=st.lists(st.sampled_from(FLAG_TOKENS), max_size=10))
def test_cli_option_parsing(tmp_path, monkeypatch, command, tokens):
    """Random flags around an input that does not exist: exit 2, one line, nothing written."""
    from brdffit.cli import main

    monkeypatch.chdir(tmp_path)
    argv = [command, "absent.csv", *tokens]
    if command == "plot" and "-o" not in tokens:
        argv += ["-o", "fig.png"]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    lines = err.getvalue().strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in lines[0], (argv, err.getvalue())
    assert os.listdir(tmp_path) == []
