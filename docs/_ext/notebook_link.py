"""Read a notebook of ``notebooks/`` through a small link file, so the site renders the notebooks
without a copy of them inside ``docs/`` (Sphinx reads only files under its source folder).

A link file ``docs/notebooks/NAME.nblink`` holds one JSON object, ``{"path":
"notebooks/NAME.ipynb"}``, the path relative to the repository's root; ``conf.py`` registers the
suffix with myst-nb (``nb_custom_formats``), which calls :func:`read_link` with the link's text.
"""

from __future__ import annotations

import json
from pathlib import Path

import nbformat

ROOT = Path(__file__).resolve().parents[2]
"""The repository's root: link paths are relative to it."""


def read_link(text: str) -> nbformat.NotebookNode:
    """The notebook a link file's text names, read as stored (outputs included, not executed)."""
    path = ROOT / json.loads(text)["path"]
    return nbformat.reads(path.read_text(encoding="utf-8"), as_version=4)
