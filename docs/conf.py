"""Sphinx configuration of the probaff API reference.

Build (from the repository root, with ``pip install -e ".[docs]"``)::

    python -m sphinx -W --keep-going -n -b html docs docs/_build/html

then open ``docs/_build/html/index.html``. The build must stay free of warnings, broken
cross-references included (``-n``); ``tests/test_docs.py`` builds it that way.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))

import probaff  # noqa: E402

project = "probaff"
author = "probaff contributors"
copyright = "probaff contributors"
release = probaff.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "myst_parser",
    "probaff_api",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build"]
root_doc = "index"

# Single backticks. The docstrings write names of classes, functions, arguments, fields and
# array shapes in single backticks (`MixtureOfGPExperts`, `n_experts`, `(N, D)`). The default
# role, "probaff-name" (docs/_ext/probaff_api.py), makes each a Python cross-reference: a name of
# a probaff object described in the reference renders as a link, anything else (an argument, a
# field, a shape, a third-party name) as code, without a warning. Explicit roles (:py:class:`...`)
# and the links of signatures and type annotations are checked: one that resolves to nothing
# fails the build under -n.
default_role = "probaff-name"

# The pages: api/NAME.rst for each subpackage (its public face and the table of its modules) and
# api/modules/NAME.rst, written by the extension when the build starts, for each public module
# and nested package, one page each. The probaff-package and probaff-module directives describe
# each object once, under the name a user imports it by, on the page of the module that defines
# it. The extension also resolves a reference that Sphinx cannot as Python would in the module
# that writes it, links probaff's public names and leaves third-party, standard-library, private
# and type-variable names as text (no intersphinx: the build needs no network).
#
# autodoc: class members in source order; type hints go into the parameter lists napoleon
# writes (with short names), leaving signatures readable; defaults as the source writes them.
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented_params"
autodoc_typehints_format = "short"
autodoc_class_signature = "mixed"
autodoc_preserve_defaults = True

# napoleon: the docstrings are Google style.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_attr_annotations = True
napoleon_use_rtype = False
# Attributes sections as fields of their class, not as separate objects (autodoc describes
# the properties and fields that carry their own docstrings; two objects of one name would
# clash). Napoleon would read the words before the first colon of a property's docstring as
# its type; the extension puts them back (probaff gives types as annotations).
napoleon_use_ivar = True
# Package docstrings list their modules (and probaff.experiments its studies) Google-style,
# "Modules:" then "name: what it holds", rendered as a field list like the other sections.
napoleon_custom_sections = [("Modules", "params_style"), ("Studies", "params_style")]

html_theme = "furo"
html_title = f"probaff {release}"
html_static_path: list[str] = []
