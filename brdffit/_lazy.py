"""Lazy package exports (PEP 562): names resolve to their modules' attributes on first use."""

from __future__ import annotations

import importlib


def lazy_exports(package: str, namespace: dict, names: dict[str, str]):
    """``(__getattr__, __dir__)`` for ``package`` exporting ``names`` (name → relative module,
    or ``"module:attribute"`` for a name exported under another than its module's).

    The first access imports the module and stores the value in ``namespace`` (the package's
    ``globals()``), so later accesses are plain lookups.
    """

    def __getattr__(name: str):
        try:
            module, _, attribute = names[name].partition(":")
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(module, package), attribute or name)
        namespace[name] = value
        return value

    def __dir__():
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__
