"""The README stays short and its code runs as shown, and so does the library guide's: the Python
snippet of the README's "Using the library", then those of ``docs/library.md``, each after the
first one, on a smaller house with fewer sweeps (the only edits: the exact replacements below)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
LIBRARY = ROOT / "docs" / "library.md"
MAX_README_LINES = 250
"""The README says what spcopyro is, the two commands, the commands and a short example; the
rest lives in docs/ (issue 23)."""

SMALLER = {  # snippet text -> what the test runs instead (each must occur in the library page)
    "make_house(seed=0)": "make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3))",
    "sweeps=1000": "sweeps=12",
    "sweeps=100,": "sweeps=5,",
    "anneal_sweeps=200": "anneal_sweeps=4",
    "advance(chain, 500)": "advance(chain, 6)",
    "num_samples=500, warmup_steps=500": "num_samples=5, warmup_steps=5",
    "range(300)": "range(3)",
}


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)


def readme_snippets() -> list[str]:
    """The ```python blocks of the README's "Using the library" section."""
    text = README.read_text(encoding="utf-8")
    section = text.split("\n## Using the library\n", 1)[1]
    section = re.split(r"\n## ", section, maxsplit=1)[0]
    return python_blocks(section)


def library_snippets() -> list[str]:
    """The ```python blocks of docs/library.md, the library guide."""
    return python_blocks(LIBRARY.read_text(encoding="utf-8"))


def shrink(snippet: str) -> str:
    for original, smaller in SMALLER.items():
        snippet = snippet.replace(original, smaller)
    return snippet


def run_first(snippet: str) -> dict[str, object]:
    namespace: dict[str, object] = {}
    exec("from spcopyro.synthetic import HouseSpec\n" + shrink(snippet), namespace)  # noqa: S102
    assert namespace["result"].trace.objective.shape == (12,)
    return namespace


def test_the_readme_is_short():
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_README_LINES, f"README.md has {lines} lines (at most {MAX_README_LINES})"


def test_the_readme_starts_with_the_two_commands():
    """After the title, the first two code blocks are the install-and-fit line and the tests."""
    blocks = re.findall(r"```bash\n(.*?)```", README.read_text(encoding="utf-8"), re.DOTALL)
    assert 'pip install -e ".[dev]" && spcopyro fit --out out/demo' in blocks[0]
    assert "python -m pytest" in blocks[1]


def test_the_cpu_build_advice_installs_into_the_environment():
    """The advice for a machine without a GPU said to ``pip install torch --index-url ...cpu``
    "before the command above", whose first step makes the environment: followed as written, the
    CPU build went to the system's Python and the command's ``pip install`` then brought the CUDA
    build into ``.venv`` anyway. The advice now makes and activates the environment first, and
    takes torchvision from the same index (from PyPI it could ask for another torch)."""
    text = " ".join(README.read_text(encoding="utf-8").split())  # the advice spans lines
    advice = re.search(r"`([^`]*pip install torch[^`]*download\.pytorch\.org/whl/cpu)`", text)
    assert advice, "README.md no longer advises PyTorch's CPU build"
    command = advice.group(1)
    install = command.index("pip install torch")
    assert ". .venv/bin/activate" in command[:install], command
    assert "torchvision" in command[install:], command


def test_the_snippets_are_found_and_shrunk():
    assert len(readme_snippets()) == 1
    snippets = library_snippets()
    assert len(snippets) >= 3
    code = "\n".join(snippets)
    for original in SMALLER:
        assert original in code, f"docs/library.md no longer holds {original!r}: update SMALLER"


def test_the_readme_snippet_runs():
    (snippet,) = readme_snippets()
    run_first(snippet)


def test_the_library_snippets_run(capsys, tmp_path, monkeypatch):
    first, *rest = library_snippets()
    setup = run_first(first)
    monkeypatch.chdir(tmp_path)  # the semantic-map snippet writes out/api_demo
    rest = [shrink(snippet) for snippet in rest]
    checked = set()
    for snippet in rest:  # each later snippet needs only the first one's names
        namespace = dict(setup)
        exec(snippet, namespace)  # noqa: S102
        if "mcmc" in namespace:
            L = setup["settings"].model.num_concepts
            assert namespace["mcmc"].get_samples()["pi"].shape == (5, L)
            checked.add("mcmc")
            # plain ArviZ on the small sites; diagnostics' sweeps count the warm-up too
            small_sites = {"log_joint", "num_concepts", "pi"}
            assert set(namespace["plain"].posterior.data_vars) == small_sites
            assert namespace["sweeps"] == {"chain 0": 10.0}  # 5 warm-up + 5 kept
        if "svi" in namespace:  # the SVI recipe
            draws, data = namespace["draws"], namespace["data"]
            L = setup["settings"].model.num_concepts
            assert draws["labels"].shape == (10, data.num_free)
            assert draws["pi"].shape == (10, 1, L)  # the shape the page gives
            checked.add("svi")
        if "terms" in namespace:  # the model under poutine.trace: the terms the page names
            check_trace_terms(namespace)
            checked.add("trace")
        if "fit8" in namespace:  # the variants
            assert namespace["fit8"].get_samples()["pi"].shape == (5, 6)
            assert namespace["data8"].neighbours.shape[1] == 8
            assert namespace["fit3"].get_samples()["objects_probs"].shape == (5, L, 5)
            checked.add("variants")
        if "as_command" in namespace:  # the embedded house fitted as spcopyro fit fits it
            check_semantic_map(namespace)
            checked.add("semantic map")
    assert checked == {"trace", "mcmc", "svi", "variants", "semantic map"}


def check_semantic_map(namespace: dict[str, object]) -> None:
    """The semantic map is on the result's grid, the saved labels.npy is it, the figures are
    written, and the fit ran what spcopyro fit runs (the preset's point estimate)."""
    import numpy as np

    result, out = namespace["as_command"], namespace["out"]
    semantic_map = namespace["semantic_map"]
    assert semantic_map.shape == result.grid.shape == namespace["kitchen"].region.shape
    assert np.array_equal(np.load(out / "labels.npy"), semantic_map)
    assert (out / "semantic_map.png").is_file() and (out / "kitchen.png").is_file()
    assert result.inference["point_estimate"] == "vi"  # preset_fit_kwargs("coarse") reached it


def check_trace_terms(namespace: dict[str, object]) -> None:
    """The trace snippet's terms are the model's sites in the page's order, their sum is the
    trace's log joint, and potts is gamma times the agreeing neighbour pairs."""
    import torch

    from spcopyro.model import potts_agreements

    terms, trace, data = namespace["terms"], namespace["trace"], namespace["data"]
    config = namespace["settings"].model
    names = ["pi", "theta", "w", "labels", "potts", "images", "words"]
    assert list(terms) == names, list(terms)
    total = float(trace.log_prob_sum())
    assert abs(sum(terms.values()) - total) <= 1e-9 * abs(total)
    labels = trace.nodes["labels"]["value"]
    potts = config.gamma * float(potts_agreements(labels, data.pairs))
    assert terms["potts"] == potts
    pi = trace.nodes["pi"]["value"]
    assert abs(terms["labels"] - float(torch.log(pi)[labels].sum())) <= 1e-9 * abs(terms["labels"])


def test_the_trace_comment_names_each_methods_objective():
    """The README's and docs/library.md's ``result.trace.objective`` comment said "the ELBO for a
    variational method"; loopy BP's trace is its Bethe approximation, not a bound."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    names = {m.objective_name for m in INFERENCE_METHODS.values()}
    assert names == {"log joint", "ELBO", "Bethe ELBO"}, names  # a new one: say it below too
    for page in (README, LIBRARY):
        (line,) = [s for s in page.read_text().splitlines() if s.startswith("result.trace.obj")]
        assert all(name in line for name in names), (page.name, line)
        assert "lbp: Bethe ELBO, no bound" in line, (page.name, line)


def test_the_command_table_asks_the_fit_the_first_command_wrote():
    """The table's where, navigate and export read ``out/sim``, which only a fit of the simulated
    house writes; the first command writes ``out/demo``, and every command on a fit reads it."""
    text = README.read_text(encoding="utf-8")
    first = re.findall(r"```bash\n(.*?)```", text, re.DOTALL)[0]
    (demo,) = re.findall(r"spcopyro fit --out (\S+)", first)
    on_a_fit = re.findall(r"`spcopyro (?:where|navigate|export) (\S+)", text)
    assert len(on_a_fit) >= 3 and set(on_a_fit) == {demo}, on_a_fit
