"""Sphinx configuration: the user guide (Markdown, MyST) and the API reference (autodoc).

Build, with warnings as errors (as ``.ci/run`` does):
``python -m sphinx -W --keep-going -b html docs /tmp/brdffit-docs``.
"""

import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)

project = "brdffit"
author = "the brdffit authors"
copyright = "the brdffit authors"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]

# Docstrings are Google style (Args:/Returns:/Raises:) with RST roles and ``:math:``.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
autosummary_generate = True
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "description"
autodoc_typehints_format = "short"
# Type hints that name a class Sphinx cannot resolve are not errors of the docs.
nitpicky = False

# Markdown: `#anchor` links to headings, and $…$ math in the guide pages.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

html_theme = "alabaster"
html_title = "brdffit"

# Docstrings of classes that subclass another library's (optimistix's solvers, matplotlib's
# Figure) are that library's business, in its own markup: not inherited into these pages.
autodoc_inherit_docstrings = False

_documented: set[tuple[str, str]] = set()


def _skip_member(app, what, name, obj, skip, options):
    """One entry per object: a name re-exported by a package (``brdffit.FitResult``,
    ``data_formats.MERLTable``) is documented where it is first met, the package page, and
    skipped in the page of the module that defines it; members another library defines on a
    subclass (matplotlib's generated ``Artist.set``) are left out. ``None``: autodoc's own
    choice (private names left out)."""
    module = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if not isinstance(module, str) or not isinstance(qualname, str):
        return None
    if not module.startswith(("brdffit", "data_formats")):
        return True if what == "class" else None
    if what == "module" and (callable(obj) or isinstance(obj, type)):
        key = (module, qualname)
        if key in _documented:
            return True
        _documented.add(key)
    return None


def setup(app):
    app.connect("autodoc-skip-member", _skip_member)
