"""Import layers: every import in ``brdffit/`` and ``data_formats/`` runs downward.

The layers, lowest first (``docs/extending.md``):

1. ``data_formats``: file formats, NumPy only (never ``brdffit`` or JAX);
2. ``brdffit.terms``: the physics pieces; inside it ``_math`` first, then ``ndf``, ``masking``,
   ``fresnel``, then ``diffuse``, ``microfacet``, then ``energy``, ``aps`` (a piece imports only
   pieces of a lower rank);
3. ``brdffit.models``: the registry and the registered models;
4. everything else in ``brdffit`` (fitting, posterior, export, plots, batch, api, config, ...),
   which may import one another;
5. ``brdffit.cli``, which nothing else imports.

Inside the application layer, the fitting layer is the lowest of the packages built on one
another: ``brdffit.fitting`` imports none of export, plots, posterior, batch and the API
(:data:`BUILT_ON`), so that a result is data and its renderings live above it. No module
imports itself through others: the import graph of ``brdffit`` and ``data_formats`` has no
circle (:func:`circles`).

``brdffit`` itself, ``brdffit.errors`` and ``brdffit._lazy`` may be imported from anywhere in
``brdffit``; a name taken from ``brdffit`` that the package exports lazily counts as an import of
the module defining it. Every ``import`` statement counts, also those inside functions. Modules
named by strings (``brdffit.io.READERS``) are not seen.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("brdffit", "data_formats")
#: The pieces of ``brdffit.terms`` by rank: a piece may import pieces of a lower rank only.
TERMS_RANK = {"_math": 0, "ndf": 1, "masking": 1, "fresnel": 1, "diffuse": 2, "microfacet": 2,
              "energy": 3, "aps": 3}
LAYERS = ("data_formats", "terms", "models", "application", "cli")
#: Layer -> the layers it may import (besides ``brdffit``, ``brdffit.errors``, ``brdffit._lazy``).
ALLOWED = {
    "data_formats": {"data_formats"},
    "terms": {"data_formats", "terms"},
    "models": {"data_formats", "terms", "models"},
    "application": {"data_formats", "terms", "models", "application"},
    "cli": set(LAYERS),
}
BASE = {"brdffit", "brdffit.errors", "brdffit._lazy"}
#: Application package -> the application packages built on it, which it must not import.
BUILT_ON = {
    "brdffit.fitting": ("brdffit.export", "brdffit.plots", "brdffit.posterior", "brdffit.batch",
                        "brdffit.api"),
    "brdffit.export": ("brdffit.posterior", "brdffit.batch", "brdffit.api"),
    "brdffit.plots": ("brdffit.posterior", "brdffit.batch", "brdffit.api"),
}
#: Third-party packages ``data_formats`` must not import (it is NumPy only).
NOT_IN_DATA_FORMATS = {"brdffit", "jax", "jaxlib", "equinox", "optimistix"}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def lazy_exports() -> dict[str, str]:
    """``brdffit.__init__``'s ``_LAZY`` (name -> defining module), read without importing it."""
    tree = ast.parse((ROOT / "brdffit" / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and [ast.unparse(t) for t in node.targets] == ["_LAZY"]:
            return {k: "brdffit" + v for k, v in ast.literal_eval(node.value).items()}
    raise AssertionError("brdffit/__init__.py has no _LAZY dict")


def imports(module: str, source: str, is_package: bool, lazy: dict[str, str]):
    """``(line, imported module)`` for every import statement in ``source``, resolved."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")[: len(module.split(".")) - node.level + is_package]
                package = ".".join(base + ([node.module] if node.module else []))
            else:
                package = node.module
            for alias in node.names:
                sub = f"{package}.{alias.name}"
                if is_module(sub):
                    yield node.lineno, sub
                elif package == "brdffit" and alias.name in lazy:
                    yield node.lineno, lazy[alias.name]
                else:
                    yield node.lineno, package


def layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "data_formats":
        return "data_formats"
    if parts[0] != "brdffit" or module in BASE:
        return None
    # brdffit._program is the console script's first module: the command line's, outside the
    # brdffit.cli package only so that its handlers are in place before that package imports.
    return {"terms": "terms", "models": "models", "cli": "cli",
            "_program": "cli"}.get(parts[1], "application")


def within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def violations(module: str, source: str, is_package: bool, lazy: dict[str, str]) -> list[str]:
    """What is wrong with the imports of ``module``, one line each (empty when nothing is)."""
    own, out = layer(module), []
    for line, target in dict.fromkeys(imports(module, source, is_package, lazy)):
        top = target.split(".")[0]
        where = f"{module} (line {line}) imports {target}"
        if own == "data_formats" and top in NOT_IN_DATA_FORMATS:
            out.append(f"{where}: data_formats is NumPy only; move the code that needs {top} "
                       "into brdffit")
            continue
        theirs = layer(target)
        if own is None or theirs is None:
            continue
        above = next((up for pkg, ups in BUILT_ON.items() if within(module, pkg)
                      for up in ups if within(target, up)), None)
        if above:
            out.append(f"{where}: {above} is built on {module.split('.')[0]}."
                       f"{module.split('.')[1]}; hand the work to the layer above (a function "
                       "there taking what this layer returns)")
            continue
        if theirs not in ALLOWED[own]:
            out.append(f"{where}: the {own} layer may import only {sorted(ALLOWED[own])}; move "
                       f"what both need down into the lower layer")
        elif own == theirs == "terms":
            mine, its = module.split(".")[2:3], target.split(".")[2:3]
            if mine and its and mine != its and TERMS_RANK[its[0]] >= TERMS_RANK[mine[0]]:
                out.append(f"{where}: terms.{its[0]} (rank {TERMS_RANK[its[0]]}) is not below "
                           f"terms.{mine[0]} (rank {TERMS_RANK[mine[0]]}); see TERMS_RANK")
    return out


def sources():
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            yield module_name(path), path.read_text(), path.name == "__init__.py"


def test_imports_run_downward():
    lazy = lazy_exports()
    found = [v for name, src, pkg in sources() for v in violations(name, src, pkg, lazy)]
    assert not found, "imports that run upward:\n" + "\n".join(found)


def graph() -> dict[str, set[str]]:
    """Module -> the modules of ``brdffit`` and ``data_formats`` it imports (any import
    statement, also inside functions; ``brdffit``, ``brdffit.errors``, ``brdffit._lazy`` left
    out, as everything may import them)."""
    lazy, out = lazy_exports(), {}
    for name, src, pkg in sources():
        out[name] = {t for _, t in imports(name, src, pkg, lazy)} - BASE - {name}
    return {name: targets & out.keys() for name, targets in out.items()}


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The import circles: strongly connected sets of more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while not part or part[-1] != v:
                part.append(stack.pop())
                on.discard(part[-1])
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_no_import_circle():
    found = circles(graph())
    assert not found, "import circles (break each by moving what both need down):\n" + "\n".join(
        " <-> ".join(c) for c in found)


def test_a_circle_is_found():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_every_terms_piece_has_a_rank():
    pieces = {p.stem for p in (ROOT / "brdffit" / "terms").iterdir()
              if p.suffix == ".py" or (p / "__init__.py").is_file()} - {"__init__"}
    assert pieces == set(TERMS_RANK), f"brdffit/terms/ holds {sorted(pieces)}; give each a rank"


def test_the_scanner_resolves_real_imports():
    """The resolver sees relative, nested and lazy imports (else the layer test passes vacuously)."""
    lazy = lazy_exports()
    found = {t for name, src, pkg in sources() if name == "brdffit.models.aps"
             for _, t in imports(name, src, pkg, lazy)}
    assert {"brdffit.terms.aps.brdf", "brdffit.models.registry"} <= found, found
    src = "def f():\n    from . import fit\n    from .fitting import solve\n"
    assert {t for _, t in imports("brdffit", src, True, lazy)} == {"brdffit.api",
                                                                   "brdffit.fitting.solve"}


@pytest.mark.parametrize("module, source, message", [
    ("brdffit.terms.fresnel", "from ..models.registry import Model",
     "the terms layer may import only ['data_formats', 'terms']"),
    ("brdffit.terms.masking", "def g():\n    from ..fitting import fit",
     "imports brdffit.fitting"),
    ("brdffit.models.standard", "import brdffit.cli", "the models layer may import only"),
    ("brdffit.fitting.solve", "from brdffit import cli", "the application layer may import only"),
    ("brdffit.terms.masking", "from .diffuse import lambert",
     "terms.diffuse (rank 2) is not below terms.masking (rank 1)"),
    ("brdffit.terms.ndf.ggx", "from ..fresnel import schlick",
     "terms.fresnel (rank 1) is not below terms.ndf (rank 1)"),
    ("data_formats.merl", "import jax.numpy as jnp", "data_formats is NumPy only"),
    ("data_formats.samples", "from brdffit.terms._math import dot", "data_formats is NumPy only"),
    ("brdffit.fitting.result", "def f():\n    from ..export import export_payload",
     "brdffit.export is built on brdffit.fitting"),
    ("brdffit.fitting.result", "def f():\n    from ..plots import plot_result",
     "brdffit.plots is built on brdffit.fitting"),
    ("brdffit.export.gltf", "from ..api import FitResult",
     "brdffit.api is built on brdffit.export"),
])
def test_an_upward_import_is_reported(module, source, message):
    found = violations(module, source, False, lazy_exports())
    assert len(found) == 1 and message in found[0], found


@pytest.mark.parametrize("module, source", [
    ("brdffit.models.disney", "from ..terms.ndf import GGX\nfrom .registry import Model"),
    ("brdffit.terms.energy.multiscatter", "from ..microfacet import microfacet_specular"),
    ("brdffit.terms.ndf.gtr", "from .ggx import GGX"),
    ("brdffit.cli.fitting", "from ..api import fit\nfrom data_formats.merl import write_merl"),
    ("brdffit.export.approximate", "from ..fitting import fit"),
    ("brdffit.api", "from . import fitting\nfrom .export import export_payload"),
])
def test_a_downward_import_passes(module, source):
    assert violations(module, source, False, lazy_exports()) == []
