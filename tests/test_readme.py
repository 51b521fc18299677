"""The README's code runs as shown: the Python snippets of "Using the library", each after the
first one, on a smaller house with fewer sweeps (the only edits: the exact replacements below)."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"

SMALLER = {  # README text -> what the test runs instead (each must occur in the snippets)
    "make_house(seed=0)": "make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3))",
    "sweeps=1000": "sweeps=12",
    "sweeps=100,": "sweeps=5,",
    "anneal_sweeps=200": "anneal_sweeps=4",
    "advance(chain, 500)": "advance(chain, 6)",
    "num_samples=500, warmup_steps=500": "num_samples=5, warmup_steps=5",
    "range(300)": "range(3)",
}


def library_snippets() -> list[str]:
    """The ```python blocks of the README's "Using the library" section (its subsections too)."""
    text = README.read_text(encoding="utf-8")
    section = text.split("\n## Using the library\n", 1)[1]
    section = re.split(r"\n## ", section, maxsplit=1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)


def test_the_snippets_are_found_and_shrunk():
    snippets = library_snippets()
    assert len(snippets) >= 3
    code = "\n".join(snippets)
    for original in SMALLER:
        assert original in code, f"README no longer holds {original!r}: update SMALLER"


def test_the_library_snippets_run(capsys):
    first, *rest = library_snippets()
    for original, smaller in SMALLER.items():
        first = first.replace(original, smaller)
        rest = [snippet.replace(original, smaller) for snippet in rest]
    setup: dict[str, object] = {}
    exec("from spcopyro.synthetic import HouseSpec\n" + first, setup)  # noqa: S102
    assert setup["result"].trace.objective.shape == (12,)
    checked = set()
    for snippet in rest:  # each later snippet needs only the first one's names
        namespace = dict(setup)
        exec(snippet, namespace)  # noqa: S102
        if "mcmc" in namespace:
            L = setup["settings"].model.num_concepts
            assert namespace["mcmc"].get_samples()["pi"].shape == (5, L)
            checked.add("mcmc")
        if "svi" in namespace:  # the SVI recipe
            assert namespace["draws"]["labels"].shape[0] == 10
            checked.add("svi")
    assert checked == {"mcmc", "svi"}
