"""The warnings a study cell's fit gives are kept in its record (column ``warnings``), listed in
report.md and not printed over the progress bar -- in this process and on Dask workers
(spcopyro.study.cell_warnings)."""

from __future__ import annotations

import json
import logging
import threading
import warnings
from pathlib import Path

import pytest
from study_setup import small_house_toml

from spcopyro._util import messages
from spcopyro.study import evaluate
from spcopyro.study.cell_warnings import captured_warnings, read_warnings, warnings_text
from spcopyro.study.cells import cells_of
from spcopyro.study.report import report_markdown
from spcopyro.study.run import run_study
from spcopyro.study.spec import load_study
from spcopyro.study.table import read_table

STUDY = """
[study]
name = "warned"
seeds = 2
sweeps = 3

[variants.low]
preset = "original-code"
gamma = 0.5

[variants.fine]
preset = "original-code"
gamma = 3.0

""" + small_house_toml(num_trials=1)
LOW_GAMMA = "gamma = 0.5 is below the Potts critical coupling"


class _Lines(logging.Handler):
    """The records that reach the ``spcopyro`` logger's handlers (as the CLI's stderr one)."""

    def __init__(self) -> None:
        super().__init__()
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@pytest.fixture
def spcopyro_handler():
    logger = logging.getLogger("spcopyro")
    handler, level = _Lines(), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    yield handler
    logger.removeHandler(handler)
    logger.setLevel(level)


def _study(tmp_path: Path):
    path = tmp_path / "warned.toml"
    path.write_text(STUDY)
    return load_study(path)


def _warnings_by_cell(out: Path) -> dict[tuple, list[str]]:
    rows = read_table(out / "results.csv")
    return {(r["variant"], r["seed"]): read_warnings(r["warnings"]) for r in rows}


@pytest.mark.filterwarnings("default:a Python warning:UserWarning")  # not an error: a warning
def test_a_cells_warnings_are_in_the_table_and_report_not_printed(
    tmp_path, monkeypatch, spcopyro_handler
):
    fit = evaluate._fit

    def warning_fit(cell, *args, **kwargs):  # a child logger's warning, Python's, warn_once's
        logging.getLogger("spcopyro.somewhere").warning("child logger says %s", "so")
        warnings.warn("a Python warning", UserWarning, stacklevel=1)
        messages.warn_once(("study warnings test",), "said once a process")
        return fit(cell, *args, **kwargs)

    monkeypatch.setattr(evaluate, "_fit", warning_fit)
    lines: list[str] = []
    run = run_study(_study(tmp_path), tmp_path / "out", progress=False, report=lines.append)
    assert (run.ran, run.failed) == (4, 0)
    said = _warnings_by_cell(tmp_path / "out")
    extra = ["child logger says so", "UserWarning: a Python warning", "said once a process"]
    for seed in (0, 1):  # warn_once's warning in every cell that gives it
        assert said["fine", seed] == extra
        assert said["low", seed][:3] == extra
        assert any(m.startswith(LOW_GAMMA) for m in said["low", seed][3:]), said["low", seed]
    assert ("study warnings test",) in messages._WARNED  # what it said is given back
    assert not [r for r in spcopyro_handler.records if r.levelno >= logging.WARNING]
    assert any("4 of them gave warnings" in line for line in lines), lines
    report = (tmp_path / "out" / "report.md").read_text()
    section = report.split("## Cells with warnings", 1)[1]
    assert "4 cells of 4 gave warnings" in section
    lines = section.splitlines()
    (low,) = [i for i, line in enumerate(lines) if line.startswith(f"- {LOW_GAMMA}")]
    assert lines[low + 1] == "  - cells: low / small / gibbs / seeds 0, 1"  # low's alone
    (child,) = [i for i, line in enumerate(lines) if line == "- child logger says so"]
    assert "low / small / gibbs / seeds 0, 1" in lines[child + 1]
    assert "fine / small / gibbs / seeds 0, 1" in lines[child + 1]
    assert section.count(LOW_GAMMA) == 1  # the same messages: one entry for both seeds


def test_cells_without_warnings_or_stored_before_the_column_have_no_section(tmp_path):
    out = tmp_path / "out"
    text = STUDY.replace("gamma = 0.5", "gamma = 3.5").replace("seeds = 2", "seeds = 1")
    path = tmp_path / "quiet.toml"
    path.write_text(text)
    study = load_study(path)
    run_study(study, out, progress=False)
    rows = read_table(out / "results.csv")
    assert [r["warnings"] for r in rows] == ["", ""]
    assert "Cells with warnings" not in (out / "report.md").read_text()
    keys = {c.key for c in cells_of(study)}
    for record_path in (out / "cells").glob("*.json"):  # as stored before records had it
        record = json.loads(record_path.read_text())
        del record["warnings"]
        record_path.write_text(json.dumps(record))
    again = run_study(study, out, progress=False)
    assert again.ran == 0 and {c.key for c in cells_of(study)} == keys  # cached, same keys
    assert [r["warnings"] for r in read_table(out / "results.csv")] == ["", ""]


def test_the_report_lists_each_warning_whole_once_with_its_cells():
    long = "word " * 200
    rows = [
        {"variant": "v", "data": "d", "method": "gibbs", "seed": s, "status": "ok",
         "warnings": warnings_text([long, long, "short"])}
        for s in (0, 1)
    ] + [{"variant": "v", "data": "d", "method": "gibbs", "seed": 2, "status": "ok",
          "warnings": None}]  # fmt: skip
    text = report_markdown(rows).split("## Cells with warnings", 1)[1]
    assert "2 cells of 3 gave warnings" in text
    assert text.count(long.strip()) == 1  # whole (it was cut at 300 characters), once
    assert text.count("  - cells: v / d / gibbs / seeds 0, 1") == 2  # the long one's, short's
    assert "\n- short\n" in text and " ..." not in text


def test_other_threads_and_info_records_go_where_they_went(spcopyro_handler):
    logger = logging.getLogger("spcopyro")
    with captured_warnings() as kept:
        logger.info("an info line")
        logger.warning("this cell's warning")
        other = threading.Thread(target=logger.warning, args=("another thread's warning",))
        other.start()
        other.join()
    logger.warning("after the cell")
    assert kept == ["this cell's warning"]
    passed = [r.getMessage() for r in spcopyro_handler.records]
    assert passed == ["an info line", "another thread's warning", "after the cell"]
    assert spcopyro_handler in logger.handlers and logger.propagate


def test_cells_on_two_threads_each_keep_a_warn_once_warning(monkeypatch, spcopyro_handler):
    """Two cells at once in one process (a --scheduler worker with --nthreads 2): each keeps the
    warn_once warning it meets, and a thread outside the cells does not repeat one the process
    gave before. Emptying the process's memory for each cell lost the second cell's (the first
    had said it meanwhile) and repeated the outside thread's."""
    monkeypatch.setattr(messages, "_WARNED", {("said before",)})
    step = {name: threading.Event() for name in ("b_in", "a_in", "b_said", "outside", "a_said")}
    said: dict[str, list[str]] = {}

    def cell_b() -> None:
        with captured_warnings() as kept:
            step["b_in"].set()
            step["a_in"].wait(10)
            messages.warn_once(("both cells",), "met by both cells")
            step["b_said"].set()
            step["a_said"].wait(10)
        said["b"] = kept

    def cell_a() -> None:
        step["b_in"].wait(10)
        with captured_warnings() as kept:
            step["a_in"].set()
            step["b_said"].wait(10)
            messages.warn_once(("both cells",), "met by both cells")
            step["outside"].wait(10)
            step["a_said"].set()
        said["a"] = kept

    threads = [threading.Thread(target=cell_b), threading.Thread(target=cell_a)]
    for thread in threads:
        thread.start()
    step["b_said"].wait(10)
    outside = messages.warn_once(("said before",), "said before the cells")
    step["outside"].set()
    for thread in threads:
        thread.join(10)
    assert all(event.is_set() for event in step.values())
    assert said == {"a": ["met by both cells"], "b": ["met by both cells"]}
    assert outside is False
    assert not [r.getMessage() for r in spcopyro_handler.records]
    assert {("said before",), ("both cells",)} <= messages._WARNED


def test_warnings_of_cells_on_a_local_cluster_are_kept(tmp_path):
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    run = run_study(_study(tmp_path), tmp_path / "dask", workers=2, progress=False,
                    start_in_process=False)  # fmt: skip
    assert run.ran == 4 and run.ran_here == 0
    said = _warnings_by_cell(tmp_path / "dask")
    for seed in (0, 1):
        assert any(m.startswith(LOW_GAMMA) for m in said["low", seed]), said
        assert not any(m.startswith("gamma =") for m in said["fine", seed]), said
    assert "  - cells: low / small / gibbs / seeds" in (tmp_path / "dask" / "report.md").read_text()


@pytest.mark.parametrize("ari_every", [0, 1])
def test_every_variant_cell_gets_the_degenerate_map_check(tmp_path, monkeypatch, ari_every):
    """A cell with ari_every fits by fit_spco, which never ran fit_house's degenerate-map check:
    its one-concept map went without the warning the others' gave. Both now get it."""
    import spcopyro.fit.map_warnings as map_warnings

    checked: list[tuple] = []

    def warning(labels, house, snap, sampled=True, **_):
        checked.append((labels.shape, house.grid.num_free))
        return "degenerate map (test)"

    monkeypatch.setattr(map_warnings, "house_map_warning", warning)
    path = tmp_path / "warned.toml"
    path.write_text(STUDY.replace("sweeps = 3", f"sweeps = 3\nari_every = {ari_every}"))
    study = load_study(path)
    assert study.ari_every == ari_every
    run = run_study(study, tmp_path / "out", progress=False)
    assert (run.ran, run.failed) == (4, 0)
    for key, said in _warnings_by_cell(tmp_path / "out").items():
        assert "degenerate map (test)" in said, (key, said)
    assert len(checked) == 4 and all(shape == (free,) for shape, free in checked), checked


def test_a_rows_degenerate_map_warning_names_its_fixed_settings(tmp_path, monkeypatch):
    """The comparison's SpCoMapping rows (variants named A-dp, A-orig-g3, B-dirichlet in
    ``spcopyro experiment``'s study) have fixed settings, yet their degenerate-map warning ended
    with the variants' advice "(in the study's variant: ...)". A row's names its settings and
    says a study with a variant of other settings can be run; a variant keeps its advice."""
    import numpy as np

    import spcopyro.fit.map_warnings as map_warnings
    from spcopyro.results.map_checks import degenerate_map_warning

    def warning(labels, house, snap, sampled=True, **_):  # one concept, words 5 m apart inside it
        cells, xy = np.array([0, labels.size - 1]), np.array([[0.0, 0.0], [5.0, 0.0]])
        return degenerate_map_warning(np.zeros_like(labels), cells, xy, [["a"], ["b"]], sampled)

    monkeypatch.setattr(map_warnings, "house_map_warning", warning)
    path = tmp_path / "rows.toml"
    path.write_text(
        STUDY.replace("seeds = 2", "seeds = 1").replace("[variants.fine]", "[variants.A-orig-g3]")
    )
    run = run_study(load_study(path), tmp_path / "out", progress=False)
    assert run.failed == 0
    said = {key: [m for m in messages if m.startswith("one concept (")]
            for key, messages in _warnings_by_cell(tmp_path / "out").items()}  # fmt: skip
    (row,) = said["A-orig-g3", 0]
    assert "in the study's variant" not in row
    assert row.endswith(
        "(the comparison's row A-orig-g3, SpCoMapping DP [original-code values, gamma 3], has "
        "fixed settings; a study with a variant of other settings -- a lower gamma, "
        'merge_moves = 0.2 so that regions can split, or preset = "coarse" -- can be run '
        "beside it)"
    ), row
    (variant,) = said["low", 0]
    assert variant.endswith(evaluate.advice(True)), variant


def test_a_variant_named_as_a_row_with_other_settings_keeps_the_variants_advice(
    tmp_path, monkeypatch
):
    """The row's advice went by the variant's name alone: a copy of experiment.toml whose
    A-orig-g3 took gamma = 2 was told that its settings are fixed. Only a variant with the row's
    settings (as the shipped studies' are) gets it; this one gets the variants' advice."""
    import numpy as np

    import spcopyro.fit.map_warnings as map_warnings
    from spcopyro.experiments.methods import spco_settings
    from spcopyro.results.map_checks import degenerate_map_warning

    def warning(labels, house, snap, sampled=True, **_):  # as in the test above
        cells, xy = np.array([0, labels.size - 1]), np.array([[0.0, 0.0], [5.0, 0.0]])
        return degenerate_map_warning(np.zeros_like(labels), cells, xy, [["a"], ["b"]], sampled)

    monkeypatch.setattr(map_warnings, "house_map_warning", warning)
    path = tmp_path / "rows.toml"
    path.write_text(
        STUDY.replace("seeds = 2", "seeds = 1")
        .replace("[variants.fine]", "[variants.A-orig-g3]")
        .replace("gamma = 3.0", "gamma = 2.0")
    )
    study = load_study(path)
    (changed,) = [v for v in study.variants if v.name == "A-orig-g3"]
    assert changed.spco_settings(None) != spco_settings("A-orig-g3", None)
    run = run_study(study, tmp_path / "out", progress=False)
    assert run.failed == 0
    (said,) = [m for m in _warnings_by_cell(tmp_path / "out")["A-orig-g3", 0]
               if m.startswith("one concept (")]  # fmt: skip
    assert "fixed settings" not in said
    assert said.endswith(evaluate.advice(True)), said


def test_the_shipped_comparisons_variants_are_their_rows():
    """experiment.toml's and experiment_quick.toml's variants have their rows' settings, so their
    degenerate-map warnings keep the row's advice."""
    from spcopyro.experiments.methods import spco_settings
    from spcopyro.study.cells import Cell

    studies = Path(evaluate.__file__).parent / "studies"
    for name in ("experiment.toml", "experiment_quick.toml"):
        study = load_study(studies / name)
        for variant in study.variants:
            cell = Cell(variant, variant.name, study.data[0], variant.method, 0, 1, 1)
            for categories in (5, 11):
                settings = variant.spco_settings(categories)
                assert settings == spco_settings(variant.name, categories), (name, variant.name)
                told = evaluate._cell_advice(cell, settings, categories)
                assert told(True) == evaluate.row_advice(variant.name)(True), (name, variant)
