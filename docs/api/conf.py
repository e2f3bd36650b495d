"""Sphinx configuration of rbody's API reference: every public module, from its docstrings (autodoc).

Build: python -m sphinx -W -b html docs/api docs/api/_build (tests/test_docs.py builds it with -W, so a
docstring that breaks the reference fails the suite)."""

import os
import sys

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))

project = "rbody"
author = "rbody's developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
# The docstrings are plain text with shapes and units (``pos: (n, 3) ... [m]``), not reStructuredText: they are
# shown as written, preformatted, rather than parsed (a formula's * or | would otherwise read as markup).
napoleon_google_docstring = False
napoleon_numpy_docstring = False
exclude_patterns = ["_build"]
html_theme = "alabaster"


def preformatted(app, what, name, obj, options, lines):
    """Every docstring as a literal block: shown exactly as written in the code."""
    if any(line.strip() for line in lines):
        lines[:] = ["::", ""] + ["    " + line for line in lines] + [""]


def setup(app):
    app.connect("autodoc-process-docstring", preformatted)
