"""Hostile names in exports, result JSON from anywhere, several-model result files.

- A table's name reaches the exported files (the XML's leading comment, the glTF ``extras``):
  names that end a comment (``a--b``, ``-->``), inject elements, or hold control characters and
  lone surrogates must leave well-formed files that say the name as data. Checked with
  ``xml.etree``/``xml.dom.minidom``, strict JSON, and Mitsuba's own loader where installed.
- ``FitResult.from_json`` reads a path or JSON text (with or without a byte-order mark); every
  malformed document, mutated the ways a fuzzer does, raises ``ResultFormatError`` in one line.
- ``brdffit fit -m ggx,gltf-pbr --out r.json`` writes several results; ``export``, ``render``
  and ``plot --fit`` pick one with ``--model`` and refuse the file without it, naming that flag.
"""

from __future__ import annotations

import ast
import json
import math
import os
import xml.dom.minidom
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit import FitResult
from brdffit.cli import main
from brdffit.export import TARGETS, NotExportable, export, mitsuba_xml
from brdffit.fitting import ResultChoiceError, ResultFormatError

import gltf_validator

HOSTILE_NAMES = [
    "a--b",
    'x --> <bsdf type="diffuse" id="evil"/> <!-- y',
    "-->",
    "ends-",
    "ends--",
    "<![CDATA[ ]]> &amp; &#0; <?xml?>",
    "quote ' \" \\ back",
    "ctl \x01\x08\x0b\x1b\x7f tab\tnl\ncr\r",
    "bytes \udcff\udc80 (a non-UTF-8 file name)",
    "non-characters \ufffe\uffff \u2028",
]

NATIVE = {
    "mitsuba-principled": dict(base_color=[0.6, 0.3, 0.1], roughness=0.4),
    "mitsuba-roughconductor": dict(alpha=0.2, eta=[0.14, 0.37, 1.44], k=[3.98, 2.39, 1.60]),
    "gltf-pbr": dict(base_color=[0.6, 0.3, 0.1], metallic=0.2, roughness=0.5),
}


def _result(model_name: str, table: str, params=None) -> FitResult:
    """A converged-looking result of ``model_name`` for ``table`` (no fit: the names are what
    is under test), as ``brdffit fit --out`` would write it."""
    model = brdffit.get_model(model_name)
    full = model.complete(params if params is not None else NATIVE[model_name])
    values = {k: (np.asarray(v, float).tolist() if np.ndim(v) else float(v))
              for k, v in full.items()}
    x = np.concatenate([np.ravel(np.asarray(full[p.name], float)) for p in model.params])
    names = model.flat_names()
    return FitResult(
        model_name=model_name, params=values, stderr={k: 0.0 for k in values}, names=names, x=x,
        cov=np.zeros((len(x), len(x))), free=names, fixed=[], at_bound={}, cost=1e-3,
        metrics={"rmse": 0.01, "rmse_cosine": 0.01, "rmse_log": 0.01, "rel_error": 0.01},
        success=True, status="successful", message="", steps=3, starts=[1e-3], loss="log",
        solver="lm", n_cells=1000, n_total=1000, init=values, wall_time=0.1, timings={},
        table=table)


def _strict_json(text: str):
    def refuse(token):
        raise AssertionError(f"{token} is not JSON")

    return json.loads(text, parse_constant=refuse)


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _mitsuba():
    mi = pytest.importorskip("mitsuba", reason="mitsuba not installed: pip install -e '.[mitsuba]'")
    mi.set_variant("scalar_rgb")
    return mi


# -- names in exported files ------------------------------------------------------------------
def _export_cli(tmp_path, result, target, capsys, *extra):
    src = tmp_path / "r.json"
    result.to_json(src)
    out = tmp_path / ("e.xml" if target == "mitsuba-xml" else "e.json")
    assert main(["export", str(src), "--to", target, "-o", str(out), "-q", *extra]) == 0, \
        capsys.readouterr().err
    return out


@pytest.mark.parametrize("model", ["mitsuba-principled", "mitsuba-roughconductor"])
@pytest.mark.parametrize("name", HOSTILE_NAMES)
def test_a_hostile_table_name_stays_data_in_mitsuba_xml(tmp_path, capsys, model, name):
    """Before: ``a--b`` gave a file that is not well-formed XML, the injection an extra
    ``<bsdf id="evil">``; control characters and lone surrogates broke the file too."""
    out = _export_cli(tmp_path, _result(model, name), "mitsuba-xml", capsys)
    raw = out.read_bytes()
    root = ET.fromstring(raw)  # comments, then one scene holding one bsdf: well-formed
    assert root.tag == "scene" and [b.get("id") for b in root.iter("bsdf")] == ["brdffit-material"]
    doc = xml.dom.minidom.parseString(raw)
    comments = [n for n in doc.childNodes if n.nodeType == n.COMMENT_NODE]
    notes = [c for c in comments if " fit of " in c.data]  # the provenance; also the export error
    assert len(notes) == 1 and len(doc.getElementsByTagName("bsdf")) == 1
    literal = notes[0].data.split(" fit of ", 1)[1].rsplit(", exact", 1)[0]
    assert ast.literal_eval(literal) == name  # the name, exactly, as a Python literal


@pytest.mark.parametrize("name", HOSTILE_NAMES[:3])
def test_mitsuba_loads_the_xml_of_a_hostile_name_with_one_bsdf(tmp_path, capsys, name):
    mi = _mitsuba()
    xml_text = _export_cli(tmp_path, _result("mitsuba-principled", name), "mitsuba-xml",
                           capsys).read_text(encoding="utf-8")
    scene = mi.load_string(xml_text.replace("</scene>", '<shape type="sphere">'
                           '<ref id="brdffit-material"/></shape></scene>'))
    (shape,) = scene.shapes()
    assert shape.bsdf().id() == "brdffit-material"
    ids = {child.id() for child in scene.shapes()} | {shape.bsdf().id()}
    assert "evil" not in ids and "evil" not in xml_text.split("-->", 1)[1]


@pytest.mark.parametrize("name", HOSTILE_NAMES)
def test_a_hostile_table_name_stays_data_in_gltf(tmp_path, capsys, name):
    out = _export_cli(tmp_path, _result("gltf-pbr", name), "gltf", capsys)
    doc = _strict_json(out.read_bytes().decode("utf-8"))  # strict UTF-8, strict JSON
    (material,) = doc["materials"]
    assert material["name"] == "brdffit-material" and set(doc) == {
        "asset", "materials", "scene", "scenes", "nodes", "meshes", "buffers", "bufferViews",
        "accessors"}
    note = material["extras"]["brdffit"]
    assert ast.literal_eval(note.split(" fit of ", 1)[1].rsplit(", exact", 1)[0]) == name


@pytest.mark.parametrize("name", HOSTILE_NAMES)
def test_the_gltf_of_a_hostile_name_passes_the_khronos_validator(tmp_path, capsys, name):
    """The Khronos glTF validator (npm ``gltf-validator``, run by Node) finds no error in the
    file; skipped, saying why, where Node or the package is missing."""
    out = _export_cli(tmp_path, _result("gltf-pbr", name), "gltf", capsys)
    gltf = out.with_suffix(".gltf")
    out.rename(gltf)
    report = gltf_validator.validate(gltf)
    errors = [m for m in report["messages"] if m["severity"] == 0]
    assert report["numErrors"] == 0, errors


def test_xml_attributes_are_escaped_and_unrepresentable_ones_refused():
    model = brdffit.get_model("mitsuba-principled")
    params = model.complete(NATIVE["mitsuba-principled"])
    root = ET.fromstring(mitsuba_xml(model, params, bsdf_id='a"b<c>&\'d\n', fragment=True))
    assert root.get("id") == 'a"b<c>&\'d\n'
    with pytest.raises(ValueError, match="XML cannot carry"):
        mitsuba_xml(model, params, bsdf_id="a\x01b")


@pytest.mark.parametrize("target", sorted(TARGETS))
def test_a_parameter_that_is_not_finite_is_refused_not_written(target):
    """Before: ``NaN`` in the glTF text (not JSON) and ``value="nan"`` in the XML."""
    model = TARGETS[target].native
    for bad in (math.nan, math.inf):
        with pytest.raises(NotExportable, match="roughness.*not a finite number"):
            export((model, dict(NATIVE[model], roughness=bad)), target)


# -- FitResult.from_json: a path or the text ---------------------------------------------------
@pytest.fixture(scope="module")
def good():
    return _result("mitsuba-principled", "t")


def test_from_json_reads_text_with_or_without_a_bom(tmp_path, good):
    """Before: a string with a BOM was taken for a path (``OSError: File name too long``); a
    file with one failed in the JSON decoder."""
    text, want = good.to_json(), good.summary()
    (tmp_path / "bom.json").write_bytes(b"\xef\xbb\xbf" + text.encode())
    (tmp_path / "{odd}.json").write_text(text)
    for source in ["\ufeff" + text, "\n  " + text, text.encode("utf-8-sig"), tmp_path / "bom.json",
                   str(tmp_path / "bom.json"), Path(tmp_path / "{odd}.json")]:
        assert FitResult.from_json(source).summary() == want, source[:20]
    assert FitResult.from_json_string("\ufeff" + text).summary() == want
    with pytest.raises(ResultFormatError, match=r"<string>: not a brdffit result \(not JSON"):
        FitResult.from_json_string("r.json")  # text only: never taken for a path
    with pytest.raises(FileNotFoundError):
        FitResult.from_json(str(tmp_path / "absent.json"))


@pytest.mark.parametrize("text", ['"x"', "null", "1e3", "x" * 300, "y" * 4000])
def test_a_str_that_names_no_file_and_is_json_or_no_file_name_is_read_as_text(text):
    """Before: ``FileNotFoundError`` for '"x"' and ``OSError: File name too long`` for a long
    word: neither names a file, and the format's own error says what the text holds."""
    with pytest.raises(ResultFormatError, match=r"^<string>: not a brdffit result"):
        FitResult.from_json(text)


def _mutations(d: dict):
    """The 340-style cases: truncations, each field of each wrong type, each key missing, extra
    keys, huge and special numbers, deep nesting, other documents."""
    text = json.dumps(d)
    for cut in range(0, len(text), max(1, len(text) // 40)):
        yield "truncated", text[:cut]
    wrong = [None, True, "x", 3, -1, 1.5, [], [None], {}, {"a": "b"}, [[1, 2]], 10**400]
    for key in d:
        for value in wrong:
            yield f"{key}={value!r:.20}", json.dumps({**d, key: value})
        yield f"no {key}", json.dumps({k: v for k, v in d.items() if k != key})
    yield "extra key", json.dumps({**d, "surprise": 1})
    yield "results wrapper", json.dumps({"results": [d, {**d, "model_name": "gltf-pbr"}]})
    yield "empty results", json.dumps({"results": []})
    yield "same model twice", json.dumps({"results": [d, d]})
    yield "huge", text.replace('"steps": 3', '"steps": ' + "9" * 5000)
    yield "huge float", text.replace('"cost": 0.001', '"cost": 1e999')
    yield "NaN tokens", text.replace('"cost": 0.001', '"cost": NaN').replace("0.01", "Infinity")
    yield "deep", "[" * 100000 + "]" * 100000
    yield "x short", json.dumps({**d, "x": d["x"][:-1]})
    yield "cov ragged", json.dumps({**d, "cov": [row[:-1] for row in d["cov"]]})
    yield "free stray", json.dumps({**d, "free": ["nope"]})
    yield "bounds", json.dumps({**d, "provenance": {"options": {"bounds": {"alpha": 1}}}})
    yield "tied", json.dumps({**d, "provenance": {"tied": [1]}})
    for doc in ["", "null", "[]", '"text"', "{", "{}", "\ufeff", "\x00", "\udcff"]:
        yield "other", doc


def test_from_json_fuzz_raises_its_own_error_in_one_line(good):
    """Every mutation either reads (and then summarizes, prints, round-trips) or raises
    ``ResultFormatError`` / ``ResultChoiceError`` in one line; nothing else escapes."""
    d = json.loads(good.to_json())
    seen = {"read": 0, "refused": 0}
    for label, text in _mutations(d):
        for source in (text, text.encode("utf-8", "surrogatepass"), "\ufeff" + text):
            try:
                r = FitResult.from_json_string(source)
            except (ResultFormatError, ResultChoiceError) as exc:
                assert "\n" not in str(exc) and str(exc).startswith("<string"), (label, str(exc))
                seen["refused"] += 1
                continue
            r.summary(), repr(r)
            try:
                brdffit.get_model(r.model_name)
            except brdffit.UnknownNameError:  # read as it is; the model is needed for rows
                with pytest.raises(brdffit.UnknownNameError):
                    r.rows()
            else:
                r.rows()
            assert FitResult.from_json(r.to_json()).summary() == r.summary(), label
            seen["read"] += 1
    assert seen["refused"] > 1000 and seen["read"] > 10, seen


@pytest.mark.parametrize("text, needle", [
    ('{"model_name": "ggx"}', "missing 'params', 'stderr'"),
    ("TRUNC", "not JSON"),
    ('{"results": [1]}', "the document is a number"),
])
def test_from_json_names_what_is_wrong(good, text, needle):
    text = good.to_json()[:200] if text == "TRUNC" else text
    with pytest.raises(ResultFormatError, match=needle):
        FitResult.from_json(text)


def test_from_dict_keeps_reading_what_to_dict_writes(good):
    assert FitResult.from_dict(good.to_dict()).summary() == good.summary()


def test_the_reader_checks_every_field_of_a_result():
    """The JSON reader's table of fields is the dataclass's: a field added to ``FitResult``
    without a check would be refused as an unknown key in every file that holds it."""
    import dataclasses

    from brdffit.fitting.result_json import FIELDS

    assert list(FIELDS) == [f.name for f in dataclasses.fields(FitResult)]


def test_parameters_not_identified_are_read_back(good):
    d = good.to_dict()
    d["not_identified"] = [d["free"][0]]
    assert FitResult.from_dict(d).not_identified == [d["free"][0]]
    d["not_identified"] = ["no-such-parameter"]
    with pytest.raises(ResultFormatError, match="not_identified"):
        FitResult.from_dict(d)


# -- several-model result files ---------------------------------------------------------------
@pytest.fixture(scope="module")
def multi(tmp_path_factory):
    """``brdffit fit t.csv -m ggx,gltf-pbr --out multi.json`` on a small synthetic list whose
    name would end an XML comment."""
    from brdffit.cli.synth import synthesize_samples
    from data_formats.samplelist import write_samples

    folder = tmp_path_factory.mktemp("multi")
    table = folder / "a--b -->.csv"
    write_samples(table, synthesize_samples(brdffit.get_model("gltf-pbr"), NATIVE["gltf-pbr"],
                                            3000, seed=1, name=table.stem))
    out = folder / "multi.json"
    assert main(["fit", str(table), "-m", "ggx,gltf-pbr", "--out", str(out), "-q"]) in (0, 1)
    return table, out


def _run(capsys, argv):
    code = main(argv)
    return code, capsys.readouterr().err


@pytest.mark.parametrize("command", ["export", "render", "plot"])
def test_a_several_model_file_without_model_is_refused_naming_the_flag(tmp_path, capsys, multi,
                                                                       command):
    """Before: "--fit multi.json: not a brdffit result (KeyError: 'stderr')", with ``--fit``
    named by export and render, which have no such option."""
    table, result = multi
    argv = {"export": ["export", str(result), "--to", "gltf", "-o", str(tmp_path / "e.gltf")],
            "render": ["render", str(result), "-o", str(tmp_path / "s.png")],
            "plot": ["plot", str(table), "--fit", str(result), "-o", str(tmp_path / "f.png")]}
    held = ", ".join(r["model_name"] for r in json.loads(result.read_text())["results"])
    assert sorted(held.split(", ")) == ["ggx", "gltf-pbr"]
    code, err = _run(capsys, argv[command])
    line = _one_line(err)
    assert code == 2 and f"holds 2 results ({held})" in line and "--model NAME" in line
    assert ("--fit" in line) == (command == "plot"), line
    assert [p for p in os.listdir(tmp_path) if not p.startswith(".brdffit-")] == []  # no output
    code, err = _run(capsys, argv[command] + ["--model", "disney"])
    assert code == 2 and f"holds no disney result (it holds {held})" in _one_line(err)


def test_export_picks_the_model_of_a_several_model_file(tmp_path, capsys, multi):
    _, result = multi
    out = tmp_path / "e.gltf"
    assert main(["export", str(result), "--to", "gltf", "-o", str(out), "-q",
                 "--model", "gltf-pbr"]) == 0
    doc = _strict_json(out.read_text(encoding="utf-8"))
    picked = FitResult.from_json(result, model="gltf-pbr")
    pbr = doc["materials"][0]["pbrMetallicRoughness"]
    assert pbr["roughnessFactor"] == picked.params["roughness"]
    assert ast.literal_eval(doc["materials"][0]["extras"]["brdffit"].split(" fit of ")[1]
                            .rsplit(", exact")[0]) == "a--b -->"


def test_plot_draws_the_picked_model(tmp_path, capsys, multi):
    table, result = multi
    assert main(["plot", str(table), "--fit", str(result), "--model", "ggx", "-q",
                 "-o", str(tmp_path / "f.png")]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix == ".png") == [
        "f-albedo.png", "f-peaks.png", "f-slice.png", "f-spheres.png"]


def test_result_messages_name_the_argument_of_the_command_run(tmp_path, capsys):
    absent = str(tmp_path / "absent.json")
    for argv in (["export", absent, "--to", "gltf", "-o", str(tmp_path / "e")],
                 ["render", absent, "-o", str(tmp_path / "s.png")]):
        code, err = _run(capsys, argv)
        assert code == 2 and "--fit" not in _one_line(err) and "absent.json: no such file" in err
    (tmp_path / "r.json").write_bytes(b"\xef\xbb\xbf" + _result("gltf-pbr", "t").to_json().encode())
    code, err = _run(capsys, ["export", str(tmp_path / "r.json"), "--to", "gltf", "-o",
                              str(tmp_path / "e.gltf"), "-q", "--model", "ggx"])
    assert code == 2 and "r.json holds no ggx result (it holds gltf-pbr)" in _one_line(err)
    assert main(["export", str(tmp_path / "r.json"), "--to", "gltf", "-q", "-o",
                 str(tmp_path / "e.gltf")]) == 0  # a BOM is read past
