"""The public surface of ``brdffit.fitting`` (the rule in its package docstring): code elsewhere
in ``brdffit`` imports only the names of ``brdffit.fitting.__all__``, from ``brdffit.fitting``
itself; tests and benchmarks may import the engine's modules, but no underscore name. Read from
the source (``ast``), every import statement counted, also those inside functions."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "brdffit.fitting"


def public_names() -> set[str]:
    tree = ast.parse((ROOT / "brdffit" / "fitting" / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and [ast.unparse(t) for t in node.targets] == ["__all__"]:
            return set(ast.literal_eval(node.value))
    raise AssertionError("brdffit/fitting/__init__.py has no __all__")


def module_of(path: Path) -> tuple[str, bool]:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        return ".".join(parts[:-1]), True
    return ".".join(parts), False


def fitting_imports(path: Path):
    """``(line, module, name)`` for every import of ``brdffit.fitting`` or one of its modules in
    ``path`` (``name`` is ``None`` for ``import module``)."""
    module, is_package = module_of(path)
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == PACKAGE or alias.name.startswith(PACKAGE + "."):
                    yield node.lineno, alias.name, None
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")[: len(module.split(".")) - node.level + is_package]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            for alias in node.names:
                if source == PACKAGE or source.startswith(PACKAGE + "."):
                    yield node.lineno, source, alias.name
                elif f"{source}.{alias.name}" == PACKAGE:  # from brdffit import fitting
                    yield node.lineno, PACKAGE, None


def sources(folder: str, exclude: str | None = None) -> list[Path]:
    paths = sorted((ROOT / folder).rglob("*.py"))
    return [p for p in paths if exclude is None or exclude not in p.relative_to(ROOT).parts[:2]]


def attribute_uses(path: Path) -> set[str]:
    """Attributes read off a name ``fitting`` bound to the package (``fitting.fit``)."""
    bound = any(m == PACKAGE and n is None for _, m, n in fitting_imports(path))
    if not bound:
        return set()
    return {node.attr for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
            and node.value.id == "fitting"}


@pytest.mark.parametrize("path", sources("brdffit", exclude="fitting"),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_the_rest_of_brdffit_imports_only_the_public_surface(path):
    public = public_names()
    for line, module, name in fitting_imports(path):
        where = f"{path.relative_to(ROOT)}:{line}"
        assert module == PACKAGE, f"{where} imports the module {module}; import from {PACKAGE}"
        assert name is None or name in public, f"{where} imports {name!r}, not in {PACKAGE}.__all__"
    unknown = attribute_uses(path) - public
    assert not unknown, f"{path.relative_to(ROOT)} uses fitting.{sorted(unknown)}, not public"


@pytest.mark.parametrize("path", sources("tests") + sources("benchmarks"),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_tests_and_benchmarks_import_no_private_name_of_fitting(path):
    for line, module, name in fitting_imports(path):
        private = [part for part in module.split(".") + [name or ""] if part.startswith("_")]
        assert not private, f"{path.relative_to(ROOT)}:{line} imports {private} from {module}"


def test_the_lazy_exports_of_brdffit_are_public_names_of_fitting():
    tree = ast.parse((ROOT / "brdffit" / "__init__.py").read_text())
    lazy = next(ast.literal_eval(n.value) for n in tree.body if isinstance(n, ast.Assign)
                and [ast.unparse(t) for t in n.targets] == ["_LAZY"])
    from_fitting = {name for name, module in lazy.items() if module == ".fitting"}
    assert from_fitting and from_fitting <= public_names()


def test_the_public_names_exist():
    import brdffit.fitting

    assert sorted(brdffit.fitting.__all__) == sorted(public_names())
    missing = [n for n in brdffit.fitting.__all__ if not hasattr(brdffit.fitting, n)]
    assert not missing
