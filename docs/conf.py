"""Sphinx configuration of spcopyro's documentation site.

Build it with ``sphinx-build -W --keep-going -b html docs OUT`` (``tests/test_docs.py`` does, with
warnings as errors). The pages are the Markdown files of ``docs/`` (MyST), the notebooks of
``notebooks/`` rendered with their stored outputs (myst-nb, nothing executed; ``docs/notebooks/``
holds one small link file per notebook, read by ``_ext/notebook_link.py``), and an API reference
generated from the docstrings (``api.rst``: autosummary, recursive over the public packages).
Nothing is fetched from the network: no intersphinx.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from sphinx.ext.napoleon.docstring import GoogleDocstring

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))  # notebook_link, the reader of docs/notebooks/*.nblink
sys.path.insert(0, str(ROOT))  # the checkout's spcopyro, installed or not

import spcopyro  # noqa: E402

project = "spcopyro"
author = "spcopyro contributors"
copyright = "spcopyro contributors, MIT licence"  # noqa: A001
release = spcopyro.__version__
version = release

extensions = [
    "myst_nb",  # Markdown pages (it registers myst-parser) and notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]

exclude_patterns = ["_build", "_templates", "_ext", "**.ipynb_checkpoints"]
templates_path = ["_templates"]
root_doc = "index"

# --- MyST (Markdown pages) ------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3  # [text](page.md#a-heading) links to headings down to ###

# --- myst-nb (notebooks) --------------------------------------------------------------------
nb_execution_mode = "off"  # the notebooks are stored with their outputs; the tests run them
nb_custom_formats = {".nblink": "notebook_link.read_link"}  # docs/notebooks/NAME.nblink

# --- API reference --------------------------------------------------------------------------
# api.rst's autosummary writes one page per module into docs/api/ (git-ignored). Removed first,
# so a module that was moved or deleted leaves no stale page (an orphan page would be a warning).
GENERATED = DOCS / "api"
shutil.rmtree(GENERATED, ignore_errors=True)
autosummary_generate = True
autosummary_imported_members = False
# Members defined in each module only: a package re-exporting a class (its __all__) would
# document it twice, and every cross-reference to it would find two targets.
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_class_signature = "separated"
napoleon_google_docstring = True
napoleon_numpy_docstring = False  # the docstrings are Google style (Args:, Returns:)
napoleon_use_ivar = True  # dataclass fields listed once, not twice


def _attribute_docstring_as_written(self):
    """An attribute's docstring as written. This package writes attribute docstrings as
    "[N, L] what it is: more"; napoleon would read the part before the colon as the attribute's
    type (Google style's "type: description") and cross-reference its words. The type shown is
    the annotation's, as autodoc gives it."""
    return self._dedent(self._consume_to_end())


GoogleDocstring._parse_attribute_docstring = _attribute_docstring_as_written

# --- HTML -----------------------------------------------------------------------------------
html_theme = "alabaster"
html_title = f"spcopyro {release}"
html_theme_options = {
    "description": "SpCoMapping semantic mapping in Pyro",
    "fixed_sidebar": True,
    "page_width": "1200px",  # 100-column code without a scroll bar
    "sidebar_width": "260px",
}
