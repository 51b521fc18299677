"""The ```python blocks of docs/variational.md, docs/studies.md and docs/robot.md run as shown
(tests/test_readme.py does the README's and docs/library.md's), on a small synthetic house with
few iterations: the only edits are the exact replacements of :data:`SMALLER`. The pages' blocks
use ``house`` and ``settings`` as the library guide's first block makes them (each says so),
and no other name from outside: :data:`SETUP` defines those two alone. The Slurm cluster
script of studies.md needs dask-jobqueue and a cluster: it is only compiled. The study block
runs in a child process, as a script (its LocalCluster's workers re-import the main module)."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
SETUP = """
from spcopyro.synthetic import HouseSpec, make_house
from spcopyro.config import preset
house = make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3))
settings = preset("original-code", gamma=3.0)
"""
SMALLER = {  # page -> {snippet text -> what the test runs instead (each must occur)}
    "variational.md": {
        'method="cavi", sweeps=100,': 'method="cavi", sweeps=6,',
        "anneal_iterations=20": "anneal_iterations=2",
        'method="cavi", sweeps=500,': 'method="cavi", sweeps=6,',
        "range(300)": "range(3)",
        "anneal_passes=10": "anneal_passes=2",
        "sweeps=60)": "sweeps=6)",
    },
    "studies.md": {
        '"seeds": 3, "sweeps": 500': '"seeds": 1, "sweeps": 5',
        "for g in (2.5, 3.0, 3.5)": "for g in (2.5, 3.0)",
        '{"synthetic": "default"}': '{"synthetic": "default", "height": 40, "width": 50, '
        '"num_rooms": 3}',
    },
    "robot.md": {"sweeps=1000)": "sweeps=6)", "sweeps=100,": "sweeps=4,"},
}


def python_blocks(page: str) -> list[str]:
    text = (DOCS / page).read_text(encoding="utf-8")
    return re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)


def shrink(page: str, snippet: str) -> str:
    for original, smaller in SMALLER[page].items():
        snippet = snippet.replace(original, smaller)
    return snippet


@pytest.fixture(scope="module")
def setup() -> dict[str, object]:
    namespace: dict[str, object] = {}
    exec(SETUP, namespace)  # noqa: S102
    return namespace


def test_the_snippets_are_found_and_shrunk():
    counts = {"variational.md": 4, "studies.md": 2, "robot.md": 1}
    for page, count in counts.items():
        blocks = python_blocks(page)
        assert len(blocks) == count, f"docs/{page}: {len(blocks)} python blocks, not {count}"
        code = "\n".join(blocks)
        for original in SMALLER[page]:
            assert original in code, f"docs/{page} no longer holds {original!r}: update SMALLER"


def test_the_variational_snippets_run(setup):
    first, numba, svi, stochastic = (
        shrink("variational.md", b) for b in python_blocks("variational.md")
    )
    namespace = dict(setup)
    exec(first, namespace)  # noqa: S102
    result = namespace["result"]  # [N, L] q(C_i = l), rows summing to 1
    assert result.marginals.shape[1] == setup["settings"].model.num_concepts
    assert abs(float(result.marginals.sum(1).min()) - 1) < 1e-4
    assert 1 <= result.trace.objective.shape[0] <= 6
    namespace = dict(setup)
    exec(numba, namespace)  # noqa: S102
    assert 1 <= namespace["out"].trace.objective.shape[0] <= 6
    namespace = dict(setup)
    exec(svi, namespace)  # noqa: S102
    assert namespace["draws"]["labels"].shape[0] == 10
    namespace = dict(setup)
    exec(stochastic, namespace)  # noqa: S102
    assert 1 <= namespace["result"].trace.objective.shape[0] <= 6


def test_the_robot_snippet_runs(setup):
    (snippet,) = python_blocks("robot.md")
    namespace = dict(setup)
    exec(shrink("robot.md", snippet), namespace)  # noqa: S102
    new, old = namespace["new"], namespace["old"]
    assert new.trace.objective.shape == (4,)
    assert old.trace.objective.shape == (6,)
    assert "new_words" in new.inference["update_of"]


def test_the_cluster_script_compiles():
    """The dask-jobqueue script: compiled only (no cluster, dask-jobqueue not installed)."""
    cluster, _ = python_blocks("studies.md")
    compile(cluster, "cluster.py", "exec")
    assert "SLURMCluster(" in cluster and "cluster.scale(jobs=64)" in cluster


def test_the_study_snippet_runs(tmp_path):
    _, study = python_blocks("studies.md")
    script = shrink("studies.md", study) + textwrap.dedent("""
        assert len(rows) == 2, rows
        assert all(row["status"] == "ok" for row in rows), rows
        assert {row["sweeps"] for row in rows} == {5}, rows
    """).replace("\n", "\n    ")
    (tmp_path / "g.py").write_text(script, encoding="utf-8")
    done = subprocess.run([sys.executable, "g.py"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "out" / "g" / "results.csv").is_file()


def test_the_svi_snippet_starts_its_own_guide_after_another(setup, caplog):
    # the block made its MeanFieldGuide in Pyro's global param store as it found it: run after
    # docs/library.md's recipe in one session, its guide took that guide's trained values
    # (its own seeded start lost), as the guide now warns
    import pyro

    from spcopyro.fit.house import prepare_model_data
    from spcopyro.guides import MeanFieldGuide

    _, data = prepare_model_data(setup["house"], setup["settings"])
    pyro.clear_param_store()
    MeanFieldGuide(data, setup["settings"].model).marginals()  # an earlier guide's params
    svi = python_blocks("variational.md")[2]
    namespace = dict(setup)
    exec(shrink("variational.md", svi).replace("range(3)", "range(0)"), namespace)  # noqa: S102
    assert not [r for r in caplog.records if "already holds" in r.getMessage()]
    pyro.clear_param_store()
