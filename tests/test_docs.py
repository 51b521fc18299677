"""The documentation site builds with warnings as errors: ``sphinx-build -W --keep-going -b html
docs OUT``, as a reader or CI would build it. The pages (``docs/*.md``), the five notebooks
rendered from their stored outputs and the API reference generated from the docstrings all come
out, so a broken docstring, a page left out of the table of contents or a dead link within the
site fails here."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
TIMEOUT_SECONDS = 900


def _missing_tools() -> list[str]:
    return [name for name in ("sphinx", "myst_nb") if importlib.util.find_spec(name) is None]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The built site (once for this module's tests)."""
    missing = _missing_tools()
    if missing:
        pytest.skip(f"{', '.join(missing)} not installed: pip install -e '.[dev]' (or .[docs])")
    out = tmp_path_factory.mktemp("docs")
    html = out / "html"
    command = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
               "-d", str(out / "doctrees"), str(DOCS), str(html)]  # fmt: skip
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=TIMEOUT_SECONDS, cwd=ROOT, check=False
    )
    assert result.returncode == 0, (
        f"sphinx-build failed (exit {result.returncode}):\n{result.stderr[-8000:]}"
    )
    return html


@pytest.mark.slow
def test_site_builds_without_warnings(site):
    assert (site / "index.html").is_file()


@pytest.mark.slow
def test_every_notebook_is_rendered_with_its_figures(site):
    assert NOTEBOOKS, "notebooks/ holds no notebook"
    for notebook in NOTEBOOKS:
        page = site / "notebooks" / f"{notebook.stem}.html"
        assert page.is_file(), f"{notebook.name} is not rendered in the site"
        assert "<img" in page.read_text(encoding="utf-8"), f"{page.name} shows no figure"


@pytest.mark.slow
def test_api_reference_covers_the_public_packages_only(site):
    pages = {page.stem for page in (site / "api").glob("*.html")}
    for name in ("spcopyro", "spcopyro.model", "spcopyro.gibbs", "spcopyro.guides",
                 "spcopyro.fit", "spcopyro.results"):  # fmt: skip
        assert name in pages, f"no API page for {name}"
    private = sorted(page for page in pages if "._" in page)
    assert not private, f"private modules in the API reference: {private}"


def test_every_notebook_has_a_link_page():
    """docs/notebooks/NAME.nblink for each notebook (the site renders the notebook through it,
    without a copy in docs/), and no link to a notebook that is gone."""
    links = {path.stem for path in (DOCS / "notebooks").glob("*.nblink")}
    assert links == {path.stem for path in NOTEBOOKS}
