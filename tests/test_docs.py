"""The documentation site builds with warnings as errors: ``sphinx-build -W --keep-going -b html
docs OUT``, as a reader or CI would build it. The pages (``docs/*.md``), the five notebooks
rendered from their stored outputs and the API reference generated from the docstrings all come
out, so a broken docstring, a page left out of the table of contents or a dead link within the
site fails here.

The site is built from a copy of ``docs/`` in a temporary folder, beside links to the rest of the
checkout (``spcopyro/``, ``notebooks/``, ``benchmarks/``, ...: ``conf.py``, the notebook links and
``benchmarks.md``'s include find them as ``docs/..``), because the build writes the generated API
pages into its source folder (``docs/api/``): two builds of the checkout's ``docs/`` at once (two
test runs, pytest-xdist) would remove each other's pages mid-build."""

from __future__ import annotations

import importlib.util
import shutil
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


def _snapshot(folder: Path) -> dict[str, int]:
    """Each file under ``folder`` but ``_build/`` (relative path) -> 0, or its modification time
    in ns under ``api/``, the generated pages (the pages a person edits meanwhile are no
    change of the build's)."""
    snapshot = {}
    for path in folder.rglob("*"):
        parts = path.relative_to(folder).parts
        if path.is_file() and parts[0] != "_build":
            snapshot["/".join(parts)] = path.stat().st_mtime_ns if parts[0] == "api" else 0
    return snapshot


def _source_tree(tree: Path) -> Path:
    """A copy of ``docs/`` under ``tree`` (without the generated ``api/`` and ``_build/``), beside
    links to the checkout's other top-level entries, so that the paths ``conf.py`` and the pages
    take relative to ``docs/..`` lead to the checkout. Returns the copy's ``docs/``."""
    tree.mkdir(parents=True, exist_ok=True)
    for entry in ROOT.iterdir():
        if entry.name != "docs" and not entry.name.startswith("."):
            (tree / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    source = tree / "docs"
    shutil.copytree(
        DOCS, source, ignore=lambda folder, names: {"api", "_build"} if Path(folder) == DOCS else ()
    )
    return source


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> tuple[Path, dict[str, int], dict[str, int]]:
    """The built site (once for this module's tests), and docs/'s files before and after."""
    missing = _missing_tools()
    if missing:
        pytest.skip(f"{', '.join(missing)} not installed: pip install -e '.[dev]' (or .[docs])")
    out = tmp_path_factory.mktemp("docs")
    html = out / "html"
    before = _snapshot(DOCS)
    source = _source_tree(out / "tree")
    command = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
               "-d", str(out / "doctrees"), str(source), str(html)]  # fmt: skip
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=TIMEOUT_SECONDS, cwd=ROOT, check=False
    )
    assert result.returncode == 0, (
        f"sphinx-build failed (exit {result.returncode}):\n{result.stderr[-8000:]}"
    )
    return html, before, _snapshot(DOCS)


@pytest.fixture(scope="module")
def site(built) -> Path:
    """The built site's HTML folder."""
    return built[0]


@pytest.mark.slow
def test_site_builds_without_warnings(site):
    assert (site / "index.html").is_file()


@pytest.mark.slow
def test_the_build_leaves_the_checkouts_docs_as_they_were(built):
    """No generated API page (docs/api/) nor anything else is written into, or removed from, the
    checkout's docs/: a concurrent build of it would otherwise race this one."""
    _, before, after = built
    assert after == before, (
        f"the docs build changed docs/: added {sorted(after.keys() - before.keys())[:5]}, "
        f"removed {sorted(before.keys() - after.keys())[:5]}, "
        f"rewritten {sorted(k for k in before.keys() & after.keys() if before[k] != after[k])[:5]}"
    )


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
