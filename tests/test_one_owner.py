"""Each concept has one owner: a lookup keeps no state on the caller's table, exporters come from
one registry, no package reaches into another's private names."""

from __future__ import annotations

import numpy as np
import pytest

from brdffit.export import TARGETS
from data_formats.merl import MERLTable, synthesize


def _table(shape=(6, 6, 12)):
    return synthesize(lambda wi, wo: np.full(wi.shape[:-1] + (3,), 0.25) + wi[..., 2:3] * 0.5,
                      name="toy", shape=shape)


def test_the_linear_lookup_grid_is_a_pure_function_the_table_keeps():
    from data_formats.merl._lookup import gather_grid

    table = _table()
    grid = table.gather_grid()
    np.testing.assert_array_equal(grid, gather_grid(table.rgb, table.valid))
    assert table.gather_grid() is grid  # built once
    wi = np.array([[0.0, 0.0, 1.0], [0.3, 0.1, 0.9]])
    before = table.lookup(wi, wi[::-1], method="linear")
    assert table.gather_grid() is grid
    other = MERLTable.from_rgb(np.asarray(table.rgb) * 2.0, table.valid)
    np.testing.assert_allclose(other.lookup(wi, wi[::-1], method="linear"), 2.0 * before)
    assert not hasattr(table, "_interp_cache")


# -- exporters: one registry, every entry tested -----------------------------------------------
def _native_result(model_name: str, table: str = "toy"):
    """A converged-looking result of ``model_name`` at its default parameters (no fit)."""
    from test_hostile_exports import _result

    return _result(model_name, table, {})


def _well_formed(text: str):
    import json
    import xml.etree.ElementTree as ET

    if text.lstrip().startswith("<"):
        return ET.fromstring(text)
    return json.loads(text, parse_constant=lambda token: pytest.fail(f"{token} is not JSON"))


def test_the_command_line_offers_the_registry():
    from brdffit.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices and "export" in a.choices)
    to = next(a for a in sub.choices["export"]._actions if a.dest == "to")
    assert list(to.choices) == list(TARGETS)
    assert all(name in sub.choices["export"].description for name in TARGETS)


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_every_target_exports_its_native_model_and_refuses_another(name, tmp_path, capsys):
    from brdffit.cli import main
    from brdffit.export import NoExactCounterpart, NotExportable, export

    target = TARGETS[name]
    result = _native_result(target.native)
    assert target.is_native(target.native)
    out = export(result, name)
    assert out.model_name == target.native and out.approximation is None
    _well_formed(out.text())
    with pytest.raises(NoExactCounterpart, match=rf"{target.renderer}.*--model {target.native}"):
        export(_native_result("ggx"), name)
    first = next(iter(result.params))
    with pytest.raises(NotExportable, match=rf"{first}.*not a finite number"):
        export((target.native, {first: float("nan")}), name)
    # and the command line writes it
    src, dst = tmp_path / "r.json", tmp_path / "material.out"
    result.to_json(src)
    assert main(["export", str(src), "--to", name.upper(), "-o", str(dst), "-q"]) == 0
    assert dst.read_text() == out.text()


def test_an_exporter_is_one_registry_entry(monkeypatch, tmp_path):
    """A new target needs its writer and its entry, nothing else: the API, the command line's
    choices and help, and the tests above take it from :data:`brdffit.export.TARGETS`."""
    from brdffit.cli import main
    from brdffit.export import Target, export

    toy = Target("toy-text", "one line per parameter", "Toy", "gltf-pbr",
                 lambda model: model == "gltf-pbr",
                 lambda model, params, note: "".join(f"{k} {v}\n" for k, v in params.items()))
    monkeypatch.setitem(TARGETS, toy.name, toy)
    result = _native_result("gltf-pbr")
    assert export(result, "toy-text").text().startswith("base_color ")
    src, dst = tmp_path / "r.json", tmp_path / "m.txt"
    result.to_json(src)
    assert main(["export", str(src), "--to", "toy-text", "-o", str(dst), "-q"]) == 0
    assert dst.read_text() == export(result, "toy-text").text()


# -- input formats: one registry entry each ------------------------------------------------------
def read_toy(path):
    """A toy input format for the test below: one measurement a line, ``θi φi θo φo r g b``
    (degrees; f_r in 1/sr)."""
    from data_formats import SampleSet

    rows = np.loadtxt(path, ndmin=2)

    def direction(theta, phi):
        t, p = np.radians(theta), np.radians(phi)
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)

    return SampleSet(direction(rows[:, 0], rows[:, 1]), direction(rows[:, 2], rows[:, 3]),
                     rows[:, 4:7].copy(), np.ones(len(rows), bool), name=path.stem, path=str(path))


def test_a_reader_is_one_registry_entry(monkeypatch, tmp_path, capsys):
    """A new input format needs its reader and one entry in :data:`brdffit.io.READERS`, nothing
    else: ``brdffit.fit``, the command line's help, ``info``, ``fit`` and ``batch``'s inputs take
    it from there."""
    import brdffit
    from brdffit.batch import inputs
    from brdffit.cli import main
    from brdffit.io import READERS

    monkeypatch.setitem(READERS, ".toy", ("toy list", __name__, "read_toy"))
    rng = np.random.default_rng(3)
    angles = np.column_stack([rng.uniform(0, 80, 600), rng.uniform(0, 360, 600),
                              rng.uniform(0, 80, 600), rng.uniform(0, 360, 600)])
    truth = {"alpha": 0.2, "f0": np.array([0.9, 0.6, 0.3]), "diffuse": np.full(3, 0.1),
             "grazing": 1.0}
    model = brdffit.get_model("ggx")
    t = np.radians(angles)
    wi = np.stack([np.sin(t[:, 0]) * np.cos(t[:, 1]), np.sin(t[:, 0]) * np.sin(t[:, 1]),
                   np.cos(t[:, 0])], -1)
    wo = np.stack([np.sin(t[:, 2]) * np.cos(t[:, 3]), np.sin(t[:, 2]) * np.sin(t[:, 3]),
                   np.cos(t[:, 2])], -1)
    rgb = np.asarray(model(truth, wi, wo))
    path = tmp_path / "m.toy"
    np.savetxt(path, np.column_stack([angles, rgb]), fmt="%.17g")

    assert main(["fit", "--help"]) == 0
    assert ".toy" in capsys.readouterr().out
    assert main(["info", str(path)]) == 0
    assert "600" in capsys.readouterr().out  # its measurements counted
    result = brdffit.fit(path, "ggx", fixed={"grazing": 1.0})
    assert result.success and result.params["alpha"] == pytest.approx(0.2, rel=1e-4)
    assert inputs.expand([str(path)]) == [str(path)]  # a batch input, not a list of paths


# -- no package reaches into another's private names -------------------------------------------
#: Private modules other packages may import, and why.
SHARED_PRIVATE = {
    # the physics layer's vector helpers (rank 0 of brdffit.terms), written for the models
    "brdffit.terms._math": "brdffit.models",
}


def _private(part: str) -> bool:
    return part.startswith("_") and not part.startswith("__")


def private_imports(module: str, source: str, is_package: bool) -> list[str]:
    """Imports in ``module`` of an underscore name of another module, or of a private module
    (``pkg._mod``) from outside its package ``pkg``, one line each."""
    import ast

    from test_layers import is_module

    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = module.split(".")[: len(module.split(".")) - node.level + is_package]
            package = ".".join(base + ([node.module] if node.module else []))
        else:
            package = node.module or ""
        if package.split(".")[0] not in ("brdffit", "data_formats"):
            continue
        for alias in node.names:
            target = f"{package}.{alias.name}"
            if not is_module(target):
                if _private(alias.name):
                    out.append(f"{module} (line {node.lineno}) imports {alias.name} from "
                               f"{package}: a private name; make it public or move the code")
                target = package
            parts = target.split(".")
            for i, part in enumerate(parts):
                owner = ".".join(parts[:i])
                if _private(part) and not (module == owner or module.startswith(owner + ".")):
                    shared = SHARED_PRIVATE.get(".".join(parts[: i + 1]), "")
                    if not (shared and (module == shared or module.startswith(shared + "."))):
                        out.append(f"{module} (line {node.lineno}) imports {target}: private to "
                                   f"{owner}; import its public surface")
                    break
    return list(dict.fromkeys(out))


def test_no_package_imports_private_names_of_another():
    from test_layers import sources

    found = [v for name, src, pkg in sources() for v in private_imports(name, src, pkg)]
    assert not found, "\n".join(found)


@pytest.mark.parametrize("module, source, message", [
    ("brdffit.config", "from data_formats._files import open_regular", "private to data_formats"),
    ("brdffit.export.render", "from ..plots import _style", "private to brdffit.plots"),
    ("brdffit.models.x", "from .registry import _REGISTRY", "imports _REGISTRY from"),
    ("brdffit.cli.export", "from .plotting import _read_result", "imports _read_result from"),
])
def test_a_private_import_is_reported(module, source, message):
    found = private_imports(module, source, False)
    assert len(found) == 1 and message in found[0], found


@pytest.mark.parametrize("module, source", [
    ("data_formats.merl._table", "from ._lookup import gather_grid"),
    ("brdffit.models.disney", "from ..terms._math import dot"),
    ("brdffit.cli.export", "from data_formats.files import writing"),
])
def test_a_public_or_own_import_passes(module, source):
    assert private_imports(module, source, False) == []


# -- a result is data; its uses live above the fitting layer -----------------------------------
def test_the_fitting_record_is_data_and_brdffit_fitresult_adds_its_uses():
    import brdffit
    from brdffit import fitting

    made = _native_result("gltf-pbr")
    fields = fitting.FitResult.__dataclass_fields__
    record = fitting.FitResult(**{f: getattr(made, f) for f in fields})
    assert not any(hasattr(record, m) for m in ("plot", "export", "render_merl"))
    text = record.to_json()
    result = brdffit.FitResult.from_json(text)
    assert type(result) is brdffit.FitResult and isinstance(result, fitting.FitResult)
    assert result.to_json() == text == brdffit.FitResult.of(record).to_json()  # same JSON
    assert result.export("gltf") == brdffit.export.export(record, "gltf").payload
    assert fitting.FitResult.from_json(text).summary() == result.summary()


# -- losses and solvers: one registry entry each -------------------------------------------------
def test_a_loss_and_a_solver_are_one_registry_entry_each(monkeypatch, tmp_path):
    """A new loss needs its functions and one :class:`Loss` entry in ``LOSSES``; a new solver one
    :class:`Solver` entry in ``SOLVERS``: ``brdffit.fit`` and the command line take them by name
    (in any case), and the result records them."""
    import dataclasses
    import json

    import brdffit
    from brdffit.cli import main
    from brdffit.fitting import LOSSES, SOLVERS
    from brdffit.fitting.losses import Loss
    from brdffit.fitting.solvers import Solver
    from data_formats.samplelist import write_samples

    toy = dataclasses.replace(LOSSES["cosine"], name="toy-loss", description="a toy")
    monkeypatch.setitem(LOSSES, "toy-loss", toy)
    monkeypatch.setitem(SOLVERS, "toy-lm", Solver("toy-lm", "LevenbergMarquardt", "a toy"))
    assert isinstance(LOSSES["toy-loss"], Loss)
    data = _table().to_samples()
    result = brdffit.fit(data, "ggx", loss="Toy-Loss", solver="TOY-LM", cutoff=90)
    reference = brdffit.fit(data, "ggx", loss="cosine", solver="lm", cutoff=90)
    assert result.loss == "toy-loss" and result.success
    assert result.cost == reference.cost
    src, out = tmp_path / "s.csv", tmp_path / "r.json"
    write_samples(src, data)
    assert main(["-q", "fit", str(src), "--model", "ggx", "--loss", "toy-loss", "--solver",
                 "toy-lm", "--cutoff", "90", "--out", str(out)]) == 0
    options = json.loads(out.read_text())["provenance"]["options"]
    assert (options["loss"], options["solver"]) == ("toy-loss", "toy-lm")
