"""Fuzzing every reader and the command line's option parsing (hypothesis, bounded for CI).

The property everywhere: a reader returns a well-formed object or raises the format's own
error (``MERLFormatError``, ``SampleListFormatError``, ``ConfigError`` / ``UnknownNameError``,
the CLI's ``UsageError``); the command line returns exit code 2 with exactly one line on
stderr, and leaves nothing behind. Any other exception is a bug. ``benchmarks/fuzz_hostile.py``
runs the same generators much longer, by hand.

The second part is the short version of the fuzzer's later categories (staging folders, paths
from data, markup in exported names, ``FitResult.from_json`` on text, information-free fits,
batch lists and scheduler addresses, render options, multi-model results, the local cluster's
open ports, ``info``'s memory): a few seeded cases each, with the fuzzer's oracles.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdffit.config import check_fit_options, load_config
from brdffit.errors import BrdffitError, FitError
from data_formats.merl import MERLFormatError, MERLTable, read_merl
from data_formats.samplelist import SampleListFormatError, read_samples
from data_formats.samples import SampleSet

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))  # the fuzzer's oracles (fuzz_hostile.py)

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
    from brdffit.cli.plotting import read_result

    path = tmp_path_factory.mktemp("json") / "r.json"
    path.write_text(text)
    try:
        read_result(path)
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


# -- hostile input, round two: the short version of benchmarks/fuzz_hostile.py's categories --
# Each test is a few seeded cases of one category, with the same oracle as the fuzzer; each
# failed on the code before the category's fix.


def _run(argv, cwd, monkeypatch):
    """``main(argv)`` in ``cwd``: ``(code, stdout, stderr)``; an escaping exception fails."""
    from brdffit.cli import main

    monkeypatch.chdir(cwd)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def _one_line_refusal(code, err):
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, (code, err)


@pytest.fixture(scope="module")
def fuzz_results(tmp_path_factory):
    """Converged single-model results (gltf-pbr, mitsuba-roughconductor) and a multi-model file
    as ``fit -m A,B --out`` writes it: ``{"results": [...]}``."""
    import brdffit
    from brdffit.cli import main

    folder = tmp_path_factory.mktemp("fuzz-results")
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["synth", "-m", "gltf-pbr", "--samples", "400", "--seed", "1", "-q",
                     "-o", str(folder / "t.csv")]) == 0
    out = {}
    for model in ("gltf-pbr", "mitsuba-roughconductor"):
        res = brdffit.fit(folder / "t.csv", model, max_steps=60)
        out[model] = folder / f"{model}.json"
        res.to_json(out[model])
    out["multi"] = folder / "multi.json"
    both = [json.loads(out[m].read_text()) for m in ("gltf-pbr", "mitsuba-roughconductor")]
    out["multi"].write_text(json.dumps({"results": both}))
    out["table"] = folder / "t.csv"
    return out


@pytest.mark.parametrize("model, argv", [
    ("gltf-pbr", ["export", "r.json", "--to", "gltf", "-o", "sub/o.gltf"]),
    ("mitsuba-roughconductor", ["export", "r.json", "--to", "mitsuba-xml", "-o", "o.xml"]),
    ("mitsuba-roughconductor", ["export", "r.json", "--to", "mitsuba-dict", "-o", "o.json"]),
    ("gltf-pbr", ["export", "r.json", "--to", "mitsuba-xml", "-o", "refused.xml"]),
    ("mitsuba-roughconductor", ["render", "r.json", "-o", "o.png", "--size", "8", "--spp", "1"]),
])
def test_staging_leaves_only_the_output(fuzz_results, model, argv, tmp_path, monkeypatch):
    shutil.copy(fuzz_results[model], tmp_path / "r.json")
    (tmp_path / "sub").mkdir()
    code, _, err = _run(argv, tmp_path, monkeypatch)
    assert code in (0, 2), err
    made = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    expected = ["r.json", "sub"] + ([argv[argv.index("-o") + 1]] if code == 0 else [])
    assert made == sorted(expected)


@pytest.mark.parametrize("name", ['x --> <bsdf type="diffuse" id="evil"/> <!-- y', "a--b",
                                  "a-", "\x0c\ufeff", '"><x/>', "]]>&amp;"])
@pytest.mark.parametrize("model, target", [
    ("mitsuba-roughconductor", "mitsuba-xml"),
    ("mitsuba-roughconductor", "mitsuba-dict"), ("gltf-pbr", "gltf")])
def test_exports_are_well_formed_whatever_the_table_name(fuzz_results, name, model, target,
                                                         tmp_path, monkeypatch):
    from fuzz_hostile import _json_shape, _xml_shape

    doc = json.loads(fuzz_results[model].read_text())
    shapes = []
    for table in ("plain", name):
        doc["table"] = table
        doc["provenance"]["input"]["name"] = table
        (tmp_path / "r.json").write_text(json.dumps(doc))
        code, _, err = _run(["export", "r.json", "--to", target, "-o", "o", "--force"],
                            tmp_path, monkeypatch)
        assert code == 0, err
        text = (tmp_path / "o").read_text()
        xml = target == "mitsuba-xml"
        shapes.append(_xml_shape(text) if xml else _json_shape(json.loads(text)))
    assert shapes[0] == shapes[1]  # no element, attribute or key more or less


def test_from_json_takes_text_and_paths_and_raises_the_formats_error(fuzz_results, tmp_path):
    from brdffit.errors import BrdffitError, FitError
    from brdffit.fitting.result import FitResult

    text = fuzz_results["gltf-pbr"].read_text()
    (tmp_path / "bom.json").write_bytes(b"\xef\xbb\xbf" + text.encode())
    for good in (text, "\n " + text, json.dumps(json.loads(text)), fuzz_results["gltf-pbr"],
                 str(fuzz_results["gltf-pbr"])):
        assert FitResult.from_json(good).model_name == "gltf-pbr"
    for bad in ("\ufeff" + text, tmp_path / "bom.json", "x" * 5000, "{" * 300, "[]", "{}",
                json.dumps({"model_name": "ggx"}), text[: len(text) // 2]):
        try:
            FitResult.from_json(bad)
        except (ValueError, BrdffitError):
            pass  # the format's own error (JSONDecodeError is a ValueError)


def _write_samples(path, rgb, seed=0):
    rng = np.random.default_rng(seed)
    m = len(rgb)
    rows = np.column_stack([rng.uniform(0, 85, m), rng.uniform(0, 360, m), rng.uniform(0, 85, m),
                            rng.uniform(0, 360, m), rgb])
    path.write_text(HEADER + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path


@pytest.mark.parametrize("what", ["zeros", "constant", "1e30"])
def test_information_free_data_is_no_success(what, tmp_path, monkeypatch):
    import brdffit
    from fuzz_hostile import _nan_in

    if what == "1e30":  # a whole synthetic MERL table times 1e30 (finite)
        assert _run(["synth", "-m", "ggx", "-p", "alpha=0.2", "-q", "-o", "t.binary"], tmp_path,
                    monkeypatch)[0] == 0
        raw = (tmp_path / "t.binary").read_bytes()
        body = np.frombuffer(raw, "<f8", offset=12).copy()
        body[body > 0] *= 1e30
        table = tmp_path / "big.binary"
        table.write_bytes(raw[:12] + body.tobytes())
    else:
        rgb = np.zeros((300, 3)) if what == "zeros" else np.full((300, 3), 0.05)
        table = _write_samples(tmp_path / "t.csv", rgb)
    if what == "1e30":  # every cell beyond any measurable value: refused before the fit
        with pytest.raises(FitError, match="units and scale"):
            brdffit.fit(table, "ggx", throw=False)
        return
    d = json.loads(brdffit.fit(table, "ggx", throw=False).to_json())
    assert not any(_nan_in(v) for v in d["params"].values())
    assert not any(_nan_in(v) for v in d["metrics"].values())
    on_bound = [c in d["at_bound"] or c.split("[")[0] in d["at_bound"] for c in d["free"]]
    assert not (d["success"] and all(on_bound))
    assert not (d["success"] and d["metrics"]["rel_error"] >= 0.99)  # explains nothing
    if what != "1e30":
        assert not d["success"] and d["status"] in ("degenerate", "not identified")


def test_no_error_bar_for_a_parameter_that_changes_nothing(tmp_path):
    import brdffit

    model = brdffit.get_model("ggx")
    res = brdffit.fit(_write_samples(tmp_path / "t.csv", np.full((400, 3), 0.05)), "ggx",
                      throw=False)
    rng = np.random.default_rng(2)
    wi = rng.normal(size=(500, 3))
    wo = rng.normal(size=(500, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    params = {k: np.asarray(v, float) for k, v in res.params.items()}
    base = np.asarray(model(params, wi, wo))
    for p in model.params:
        err = res.stderr.get(p.name)
        if err is None or not np.all(np.isfinite(np.asarray(err, float))):
            continue
        moved = {**params, p.name: np.full_like(params[p.name],
                                                   p.lower + 0.37 * (p.upper - p.lower))}
        change = np.max(np.abs(np.asarray(model(moved, wi, wo)) - base))
        assert change > 1e-12 * np.max(np.abs(base)), f"{p.name} ± {err} changes nothing"


@pytest.mark.parametrize("raw", [b"\xff" + b"a.csv\n", "mat\xe9riau.csv\n".encode("latin-1"),
                                 "a.csv\n".encode("utf-16")])
def test_batch_list_that_is_not_utf8_is_refused_in_one_line(raw, tmp_path, monkeypatch):
    (tmp_path / "list.txt").write_bytes(raw)
    _write_samples(tmp_path / "a.csv", np.full((20, 3), 0.1))
    code, _, err = _run(["batch", "list.txt", "-m", "ggx", "-o", "out"], tmp_path, monkeypatch)
    _one_line_refusal(code, err)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("address", ["foo", "inproc://x", "tcp://[::1", "tcp://", "://"])
def test_batch_scheduler_address_is_checked_in_one_line(address, tmp_path, monkeypatch):
    _write_samples(tmp_path / "a.csv", np.full((20, 3), 0.1))
    try:
        code, _, err = _run(["batch", "a.csv", "-m", "ggx", "-o", "out", "--scheduler", address],
                            tmp_path, monkeypatch)
    except Exception as exc:  # noqa: BLE001 - an escaping exception is the failure
        pytest.fail(f"{type(exc).__name__}: {exc}")
    _one_line_refusal(code, err)


def _without_dac_override():
    """setpriv dropping the capabilities that let root ignore a folder's mode bits."""
    if shutil.which("setpriv") is None:
        return None
    probe = subprocess.run(["setpriv", "--bounding-set", "-dac_override,-dac_read_search,-fowner",
                            "true"], capture_output=True)
    return (["setpriv", "--bounding-set", "-dac_override,-dac_read_search,-fowner"]
            if probe.returncode == 0 else None)


def test_batch_read_only_outdir_is_refused_before_any_fit(tmp_path):
    prefix = _without_dac_override() if os.geteuid() == 0 else []
    if prefix is None:
        pytest.skip("running as root without setpriv: a read-only folder is writable")
    _write_samples(tmp_path / "a.csv", np.full((50, 3), 0.1))
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o555)
    try:
        r = subprocess.run([*prefix, sys.executable, str(ROOT / "cli.py"), "batch", "a.csv", "-m",
                            "ggx", "-o", "ro", "--workers", "1"], cwd=tmp_path, capture_output=True,
                           text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    finally:
        (tmp_path / "ro").chmod(0o755)
    _one_line_refusal(r.returncode, r.stderr)
    assert re.search(r"(^|[\s'/])ro\b", r.stderr), r.stderr  # names OUTDIR ...
    assert ".brdffit-" not in r.stderr and ".parquet." not in r.stderr  # ... not a temporary
    assert "fits:" not in r.stdout  # refused before the batch ran


@pytest.mark.parametrize("option", [
    ["--environment", "inf"],
    ["--environment", "nan"],
    ["--environment", "-1"],
    ["--size", "0"], ["--size", "-5"], ["--spp", "0"],
    ["--spp", "100000000"],
    ["--size", "60000"]])
def test_render_options_out_of_range_are_refused(fuzz_results, option, tmp_path, monkeypatch):
    shutil.copy(fuzz_results["mitsuba-roughconductor"], tmp_path / "r.json")
    argv = ["render", "r.json", "-o", "s.png", f"{option[0]}={option[1]}"]
    if option[0] == "--spp" and option[1] != "0" or option[0] == "--size" and option[1] != "0":
        # values a range must refuse before any work; run in a process with a memory cap and a
        # generous limit so that the code before the fix does not take the machine down
        r = subprocess.run([sys.executable, "-c", "import resource, runpy, sys; "
                            "resource.setrlimit(resource.RLIMIT_AS, (8 << 30, 8 << 30)); "
                            "sys.argv = ['brdffit', *sys.argv[1:]]; "
                            f"runpy.run_path({str(ROOT / 'cli.py')!r}, run_name='__main__')",
                            *argv], cwd=tmp_path, capture_output=True, text=True, timeout=60,
                           env={**os.environ, "PYTHONPATH": str(ROOT)})
        code, err = r.returncode, r.stderr
    else:
        small = [] if option[0] == "--size" else ["--size", "8"]  # never override the option
        code, _, err = _run(argv + small, tmp_path, monkeypatch)
    _one_line_refusal(code, err)
    assert not (tmp_path / "s.png").exists()


@pytest.mark.parametrize("command, argv", [
    ("export", ["export", "multi.json", "--to", "gltf", "-o", "o.gltf"]),
    ("export", ["export", "multi.json", "--to", "mitsuba-xml", "-o", "o.xml"]),
    ("render", ["render", "multi.json", "-o", "o.png", "--size", "8", "--spp", "1"]),
    ("plot", ["plot", "t.csv", "--fit", "multi.json", "-o", "o.png"]),
])
def test_multi_model_result_accepted_or_refused_naming_its_own_flags(fuzz_results, command, argv,
                                                                     tmp_path, monkeypatch):
    from fuzz_hostile import flags

    shutil.copy(fuzz_results["multi"], tmp_path / "multi.json")
    shutil.copy(fuzz_results["table"], tmp_path / "t.csv")
    code, _, err = _run(argv, tmp_path, monkeypatch)
    assert code in (0, 2) and "Traceback" not in err and "KeyError" not in err, err
    if code == 2:
        _one_line_refusal(code, err)
        said = re.sub(r"`[^`]*`", "", err)
        assert set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", said)) <= flags(command), err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["multi.json", "t.csv"]


def _batch_process(argv, cwd):
    return subprocess.run([sys.executable, str(ROOT / "cli.py"), "batch", *argv, "-m", "ggx",
                           "--workers", "1", "--subsample", "100", "--max-steps", "20", "-q"],
                          cwd=cwd, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if not p.is_dir())


def test_batch_material_named_dot_dot_stays_in_outdir(tmp_path):
    (tmp_path / "in").mkdir()
    _write_samples(tmp_path / "in" / "...csv", np.random.default_rng(0).uniform(0, 1, (200, 3)))
    r = _batch_process(["...csv", "-o", "out"], tmp_path / "in")
    assert r.returncode in (0, 1, 2), r.stderr
    outside = [f for f in _files(tmp_path) if not f.startswith("in/out/")]
    assert outside == ["in/...csv"], r.stderr


def test_batch_does_not_write_through_a_symlink_in_outdir(tmp_path):
    (tmp_path / "other").mkdir()
    _write_samples(tmp_path / "mat.csv", np.random.default_rng(0).uniform(0, 1, (200, 3)))
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "mat").symlink_to(tmp_path / "other", target_is_directory=True)
    r = _batch_process(["mat.csv", "-o", "out"], tmp_path)
    assert list((tmp_path / "other").iterdir()) == []
    _one_line_refusal(r.returncode, r.stderr)
    assert "out/mat" in r.stderr or "symbolic link" in r.stderr or "symlink" in r.stderr


def test_local_batch_cluster_is_closed_to_other_clients(tmp_path):
    import time

    psutil = pytest.importorskip("psutil")
    from fuzz_hostile import open_doors

    for name in "abc":
        _write_samples(tmp_path / f"{name}.csv", np.random.default_rng(1).uniform(0, 1, (3000, 3)))
    p = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "batch", "a.csv", "b.csv",
                          "c.csv", "-m", "ggx,beckmann", "-o", "out", "--workers", "1", "-q"],
                         cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)},
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    doors, probed = [], set()
    try:
        while p.poll() is None and not doors:
            try:
                tree = {p.pid, *(c.pid for c in psutil.Process(p.pid).children(True))}
            except psutil.Error:
                break
            doors += open_doors(tree, probed)
            time.sleep(0.2)
    finally:
        p.kill()
        p.wait()
    assert probed, "the batch ended before any of its ports could be probed"
    assert doors == []


def test_info_on_the_largest_legal_sample_list_stays_small(tmp_path):
    from fuzz_hostile import legal_max_npz, peak_command

    legal_max_npz(tmp_path / "legal-max.npz")
    peak = tmp_path / "peak"
    r = subprocess.run(peak_command([sys.executable, ROOT / "cli.py", "info", "legal-max.npz"],
                                    peak), cwd=tmp_path, stdout=subprocess.DEVNULL,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode in (0, 2)
    mb = int(peak.read_text()) / 1024  # the command's own peak, not this process's size
    assert mb < 1024, f"peak RSS {mb:.0f} MB"
