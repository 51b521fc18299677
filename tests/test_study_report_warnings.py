"""The commands' own reports (ablation.md, comparison.md, table.md, studies.md, robustness.md)
list the cells whose fit gave warnings, as report.md does: results.csv had them in its column
``warnings`` and these reports said nothing of them."""

from __future__ import annotations

import contextlib
import logging

import pytest

from spcopyro.cli.main import main
from spcopyro.study import evaluate
from spcopyro.study.report import with_warnings
from spcopyro.synthetic import HouseSpec

SAID = "test: every cell warns this"
SMALL = HouseSpec(height=30, width=40, num_rooms=2, num_open_plan=0, min_room_size=10)


@pytest.fixture
def warning_cells(monkeypatch):
    """Every cell run in this process gives the warning :data:`SAID` (logger ``spcopyro``)."""
    threads = evaluate.torch_threads

    @contextlib.contextmanager
    def warning(count):
        logging.getLogger("spcopyro.test").warning(SAID)
        with threads(count):
            yield

    monkeypatch.setattr(evaluate, "torch_threads", warning)


@pytest.fixture
def writes(monkeypatch):
    """Every file replaced whole (:func:`spcopyro._util.outputs.replace_file`, which
    ``replace_text`` calls) in this test, as (name, bytes), in order."""
    from spcopyro._util import outputs

    replace_file = outputs.replace_file
    written: list[tuple[str, bytes]] = []

    def recorded(path, write):
        result = replace_file(path, write)
        written.append((result.name, result.read_bytes()))
        return result

    monkeypatch.setattr(outputs, "replace_file", recorded)
    return written


def _written_once(writes: list[tuple[str, bytes]], name: str) -> bytes:
    """The bytes of the one write of ``name``: a second, adding the warnings to a first written
    without them, left this run's report without them when a Ctrl-C came between the two."""
    mine = [data for written, data in writes if written == name]
    assert len(mine) == 1, f"{name} written {len(mine)} times"
    return mine[0]


def _listed(text: str, heading: str = "## Cells with warnings", table: str = "results.csv"):
    assert f"{heading}\n\n" in text
    assert f"gave warnings while fitted (column `warnings` of {table} holds each cell's)" in text
    assert f"\n- {SAID}\n  - cells: " in text


def test_ablation_md_lists_the_cells_warnings(tmp_path, warning_cells, capsys, writes):
    out = tmp_path / "abl"
    code = main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--houses", "dense", "--sweeps", "2", "--no-off", "--baselines",
                 "--variant", "g:preset=original-code"])  # fmt: skip
    assert code == 0
    text = (out / "ablation.md").read_text()
    assert _written_once(writes, "ablation.md") == text.encode("utf-8")
    _listed(text)
    assert "  - cells: g / dense / gibbs / seed 0\n" in text
    assert text == (out / "ablation.md").read_text() and text in capsys.readouterr().out


def test_comparison_md_lists_the_cells_warnings(tmp_path, warning_cells, writes):
    from spcopyro.experiments.comparison_report import table_markdown
    from spcopyro.experiments.inference_comparison import ComparisonSettings
    from spcopyro.study.comparison import run_comparison
    from spcopyro.study.table import read_table

    settings = ComparisonSettings(variants=("lbp",), seeds=1, house_types=("synthetic",),
                                  quick=True, iterations={"lbp": 2})  # fmt: skip
    summary = run_comparison(tmp_path, settings)
    text = (tmp_path / "comparison.md").read_text()
    assert _written_once(writes, "comparison.md") == text.encode("utf-8")
    # the bytes the two writes (the table, then it read back and the warnings added) left
    rows = read_table(tmp_path / "results.csv")
    assert text == with_warnings(table_markdown(summary), rows)
    _listed(text)
    assert "  - cells: lbp / synthetic / lbp / seed 0\n" in text


def test_the_experiments_table_md_lists_the_cells_warnings(tmp_path, warning_cells):
    from spcopyro.study.experiment import EXPERIMENT_QUICK, experiment_study, run_experiment
    from spcopyro.study.spec import load_study

    study = experiment_study(load_study(EXPERIMENT_QUICK), public=False, methods=["A-dp"],
                             seeds=1, sweeps=2)  # fmt: skip
    run_experiment(tmp_path, study)
    text = (tmp_path / "table.md").read_text()
    _listed(text)
    assert "  - cells: A-dp / synthetic / gibbs / seed 0\n" in text


def test_studies_md_lists_each_side_studys_warnings(tmp_path, warning_cells):
    from spcopyro.study.side_studies import write_studies

    markdown = write_studies(tmp_path, sweeps=2, seeds=(0,))
    assert (tmp_path / "studies.md").read_text() == markdown
    for name in ("modality", "sentences"):
        _listed(markdown, f"## Cells with warnings: {name}", f"studies/{name}/results.csv")


def test_robustness_md_lists_each_studys_warnings(tmp_path, warning_cells):
    from spcopyro.study.robustness import write_robustness

    markdown = write_robustness(tmp_path, sweeps=2, seeds=(0,), chains=2, spec=SMALL)
    assert (tmp_path / "robustness.md").read_text() == markdown
    for name in ("stability", "sensitivity"):
        _listed(markdown, f"## Cells with warnings: {name}", f"robustness/{name}/results.csv")


def test_a_report_without_warned_cells_is_unchanged():
    rows = [{"variant": "a", "data": "d", "method": "gibbs", "seed": 0, "warnings": ""}]
    assert with_warnings("# report\n", rows) == "# report\n"
    rows[0]["warnings"] = '["careful"]'
    assert with_warnings("# report\n", rows).startswith("# report\n\n## Cells with warnings\n")


def test_a_long_warning_is_listed_whole_once_with_its_cells():
    """comparison.md cut each warning at 300 characters ("... annealed ..."), losing SVI's
    flat-q warning's advice ("Try ..."); each distinct warning is listed once, whole, with the
    cells that gave it."""
    import json

    advice = "Try --method gibbs, or anneal over more steps (the end of a long warning)."
    long = "q(C) ends near uniform: " + "annealed " * 60 + advice
    other = "a short one"
    rows = [
        {"variant": "svi", "data": "synthetic", "method": "svi", "seed": 0,
         "warnings": json.dumps([long, other])},
        {"variant": "svi", "data": "synthetic", "method": "svi", "seed": 1,
         "warnings": json.dumps([long])},
        {"variant": "sv", "data": "synthetic", "method": "stochastic-vi", "seed": 0,
         "warnings": json.dumps([long])},
        {"variant": "gibbs", "data": "synthetic", "method": "gibbs", "seed": 0, "warnings": ""},
    ]  # fmt: skip
    text = with_warnings("# report\n", rows)
    assert len(long) > 500 and text.count(advice) == 1, text
    assert f"\n- {long}\n  - cells: svi / synthetic / svi / seeds 0, 1; sv / synthetic / " in text
    assert "stochastic-vi / seed 0\n" in text
    assert f"\n- {other}\n  - cells: svi / synthetic / svi / seed 0\n" in text
    assert "3 cells of 4 gave warnings while fitted" in text
