"""Sphinx configuration for the galerkin_vi documentation.

Build (warnings are errors, as in CI)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# Let autodoc import the package from the checkout even when it is not installed.
sys.path.insert(0, str(ROOT))

import galerkin_vi  # noqa: E402

project = "galerkin_vi"
author = "galerkin_vi developers"
copyright = "galerkin_vi developers"  # noqa: A001
version = release = galerkin_vi.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]

# Pages are MyST Markdown; the API pages are reStructuredText because autodoc
# emits reStructuredText (footnotes in docstrings resolve only in an rST page).
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]

# MyST: $...$ and $$...$$ maths, LaTeX environments, anchors for links to headings
# (theory.md#order-of-accuracy and similar).
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

# API reference from the NumPy-style docstrings.
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# "Attributes" sections as field lists, not attribute entries: a property named
# there and also listed in :members: (Galerkin.order) would be described twice,
# a duplicate-object warning.
napoleon_use_ivar = True
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the docstrings carry the types, with shapes

html_theme = "alabaster"
html_title = f"galerkin_vi {release}"
html_theme_options = {
    "description": "Higher-order Galerkin variational integrators from SymPy Lagrangians",
    "fixed_sidebar": True,
    "page_width": "1100px",
    "sidebar_width": "240px",
}
html_sidebars = {"**": ["about.html", "navigation.html", "searchbox.html"]}


# NumPy-style "References" sections number their entries [1], [2], ... in every
# docstring. On one HTML page these labels collide (duplicate and unknown
# targets), so in each docstring the entries cited as [1]_ become auto-numbered
# footnotes with a label private to that object (numpydoc renames them too),
# and entries that are listed but not cited become plain lines "[1] ...".
_FOOTNOTE_DEFINITION = re.compile(r"^(\s*)\.\. \[(\d+)\]")
_FOOTNOTE_REFERENCE = re.compile(r"\[(\d+)\]_")


def _private_footnotes(app, what, name, obj, options, lines):
    defined = {m.group(2) for m in map(_FOOTNOTE_DEFINITION.match, lines) if m}
    if not defined:
        return
    cited = {label for line in lines for label in _FOOTNOTE_REFERENCE.findall(line)}
    prefix = re.sub(r"[^A-Za-z0-9]+", "-", name).strip("-")

    def definition(m: re.Match) -> str:
        indent, label = m.group(1), m.group(2)
        if label in cited:
            return f"{indent}.. [#{prefix}-{label}]"
        return f"{indent}| [{label}]"

    def reference(m: re.Match) -> str:
        label = m.group(1)
        return f"[#{prefix}-{label}]_" if label in defined else m.group(0)

    for i, line in enumerate(lines):
        line = _FOOTNOTE_DEFINITION.sub(definition, line)
        lines[i] = _FOOTNOTE_REFERENCE.sub(reference, line)


def setup(app):
    app.connect("autodoc-process-docstring", _private_footnotes)
