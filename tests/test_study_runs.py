"""Studies (issue 26) run: the tiny study in this process (the module's ``in_process``,
run once) gives the tidy table; a LocalCluster gives the same numbers; interrupting,
resuming, adding seeds, failing cells, `spcopyro study`'s command line, cells other source
computed (the source digest), the stored label maps, parquet; a cell's own scores.

Tiny synthetic houses and 5-10 sweeps: the numbers are checked for equality between runs,
never for their values.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from study_setup import TINY, TINY_DICT, _write, on_a_cluster

from spcopyro._util.folder_lock import LOCK_NAME
from spcopyro.cli.main import main
from spcopyro.study import evaluate
from spcopyro.study.cells import cells_of
from spcopyro.study.run import run_study
from spcopyro.study.spec import load_study, study_from_dict
from spcopyro.study.table import COLUMNS, read_table

TIMING = {"seconds", "cpu_seconds"}


WORKER_STATE = """(
    __import__("os").environ.get("MALLOC_TRIM_THRESHOLD_"),
    __import__("os").environ.get("OMP_NUM_THREADS"),
    "spcopyro.study.evaluate" in __import__("sys").modules,
    __import__("dask").config.get("distributed.worker.profile.enabled"),
)"""
"""In a worker, before any cell: its MALLOC_TRIM_THRESHOLD_ and OMP_NUM_THREADS, whether the
cells' code is imported, and whether its statistical profiler is on."""


def _scores(rows: list[dict]) -> list[dict]:
    """The rows without their timings (which differ between any two runs)."""
    return [{k: v for k, v in row.items() if k not in TIMING} for row in rows]


@pytest.fixture(scope="module")
def in_process(tmp_path_factory) -> tuple[Path, Path]:
    """The tiny study run in this process: (study file, output folder)."""
    root = tmp_path_factory.mktemp("study")
    path = _write(root)
    out = root / "out"
    run = run_study(load_study(path), out, workers=1, progress=False)
    assert (run.cells, run.ran, run.failed, run.cached) == (6, 6, 0, 0)
    return path, out


def test_a_one_concept_map_of_a_study_cell_is_advised_in_the_study_files_terms():
    """The warning of a study cell's one-concept map told a study user to try
    ``GibbsOptions(merge_moves=0.2) (fit's --merge-moves 0.2)`` and ``fit's --preset coarse``,
    where the study file says ``merge_moves = 0.2`` and ``preset = "coarse"`` in a variant."""
    from spcopyro.study.cell_warnings import read_warnings

    values = json.loads(json.dumps(TINY_DICT))
    values["study"].update(seeds=1, sweeps=2, baselines=[])
    values["variants"] = {"one": {"num_concepts": 1}}  # every cell in one concept
    (cell,) = cells_of(study_from_dict(values))
    record, _, _ = evaluate.run_cell(cell)
    assert record["status"] == "ok", record["error"]
    (collapsed,) = [m for m in read_warnings(record[evaluate.WARNINGS]) if "holds 100" in m]
    assert collapsed.endswith(evaluate.advice(True)), collapsed
    assert "merge_moves = 0.2" in collapsed and 'preset = "coarse"' in collapsed, collapsed
    assert "--merge-moves" not in collapsed and "GibbsOptions" not in collapsed, collapsed


def test_sampled_hyperparameters_are_in_the_table(tmp_path):
    """A variant's ``hyper.*`` ran, but where the chain took alpha and gamma was nowhere in
    ``results.csv``: a study of hyperparameter sampling could not read its own result."""
    text = TINY.replace("gamma = 3.0", 'gamma = 3.0\nhyper.alpha = true\nhyper.gamma = "exchange"')
    study = load_study(_write(tmp_path, text.replace("seeds = 2", "seeds = 1")))
    run_study(study, tmp_path / "out", progress=False)
    rows = {r["variant"]: r for r in read_table(tmp_path / "out" / "results.csv")}
    sampled = json.loads(rows["og3"]["hyperparameters"])
    assert sorted(sampled) == ["alpha", "gamma"]
    assert sampled["gamma"]["initial"] == 3.0 and sampled["gamma"]["posterior_mean"] > 0
    assert not rows["dp"]["hyperparameters"] and not rows["F-geometry"]["hyperparameters"]


def test_in_process_run_gives_the_tidy_table(in_process):
    _, out = in_process
    rows = read_table(out / "results.csv")
    assert len(rows) == 6 and list(rows[0]) == list(COLUMNS)
    assert {(r["variant"], r["seed"]) for r in rows} == {
        (v, s) for v in ("og3", "dp", "F-geometry") for s in (0, 1)
    }
    for row in rows:
        assert row["status"] == "ok", row["error"]
        assert row["data"] == "small" and row["data_kind"] == "synthetic"
        for score in ("ari", "matching_rate", "top1", "top3", "mean_rank", "largest_share",
                      "concepts_1pct", "free_cells", "seconds"):  # fmt: skip
            assert isinstance(row[score], int | float), (score, row)
        assert row["held_out_trial"] == row["seed"] % 2
    fits = [r for r in rows if r["method"] == "gibbs"]
    assert all(r["iterations"] == 8 and (out / r["trace"]).is_file() for r in fits)
    report = (out / "report.md").read_text()
    assert "| og3 | gibbs | 2 |" in report and "+-" in report
    assert "](quality_time.png)" in report and (out / "quality_time.png").is_file()


def test_the_table_says_which_objective_best_objective_is(in_process):
    """best_objective held a sampler's log joint and a variational fit's ELBO in one column
    with nothing saying which (compare-inference on the synthetic houses: Gibbs about +112,000,
    CAVI about -14,000): column objective names it; a baseline, with no objective, leaves it
    empty."""
    _, out = in_process
    rows = read_table(out / "results.csv")
    fits = [r for r in rows if r["method"] == "gibbs"]
    assert fits and all(r["objective"] == "log joint" for r in fits), fits
    assert all(isinstance(r["best_objective"], float) for r in fits)
    assert all(r["objective"] in ("", None) for r in rows if r["method"] == "baseline")


@pytest.mark.parametrize("start_in_process", [False, True])
def test_local_cluster_gives_the_same_numbers(in_process, tmp_path, monkeypatch, start_in_process):
    """On the workers only, or partly in this process while they start: the same numbers."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    on_a_cluster(monkeypatch)  # 6 short cells: the cluster path all the same
    path, out = in_process
    run = run_study(load_study(path), tmp_path / "dask", workers=2, progress=False,
                    start_in_process=start_in_process)  # fmt: skip
    assert run.where == "LocalCluster(2 workers)" and run.ran == 6 and run.failed == 0
    assert run.ran_here <= 6 if start_in_process else run.ran_here == 0
    local = read_table(out / "results.csv")
    dask = read_table(tmp_path / "dask" / "results.csv")
    assert _scores(dask) == _scores(local)


@pytest.mark.parametrize("method", ["spawn", "forkserver"])
def test_local_cluster_is_made_without_dasks_malloc_trim_threshold(monkeypatch, method):
    """Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in each spawned worker, which turns off glibc's
    dynamic mmap threshold: cells ran 1.5-2x slower there than in-process. The LocalCluster the
    study starts is made with it unset (None: the nanny leaves it out of the worker's
    environment), whichever way its workers start."""
    distributed = pytest.importorskip("distributed")
    import dask

    from spcopyro.study import local_cluster

    seen = {}

    class Stop(Exception):
        pass

    def fake_cluster(*args, **kwargs):
        seen.update(dask.config.get(local_cluster.PRE_SPAWN_ENVIRON))
        seen["method"] = dask.config.get(local_cluster.MULTIPROCESSING_METHOD)
        seen["loops"] = {key: dask.config.get(key) for key in local_cluster.QUIET_LOOPS}
        raise Stop

    monkeypatch.setattr(distributed, "LocalCluster", fake_cluster)
    monkeypatch.setattr(local_cluster, "start_forkserver", lambda: None)
    with pytest.raises(Stop):
        local_cluster.local_cluster(2, method)
    assert "MALLOC_TRIM_THRESHOLD_" in seen and seen["MALLOC_TRIM_THRESHOLD_"] is None
    assert seen["method"] == method
    assert seen["loops"] == local_cluster.QUIET_LOOPS  # the workers' profiler off, and so on
    assert dask.config.get(local_cluster.PRE_SPAWN_ENVIRON)["MALLOC_TRIM_THRESHOLD_"] is not None
    assert dask.config.get("distributed.worker.profile.enabled") is True  # only for the cluster


def test_forked_workers_start_with_the_cells_code_and_one_thread(monkeypatch):
    """The study's LocalCluster forks its workers from a server that imported the cells' code
    with one BLAS thread and without MALLOC_TRIM_THRESHOLD_, even when this process has it
    (Dask's nanny leaves it in the parent's environment after spawning a worker)."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    from distributed import Client

    from spcopyro.study import local_cluster

    if not local_cluster.forkserver_available():
        pytest.skip("no forkserver on this platform")
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    cluster = local_cluster.local_cluster(1)
    try:
        with Client(cluster) as client:
            seen = client.run(eval, WORKER_STATE)  # a builtin: the worker imports nothing
    finally:
        cluster.close()
    [(malloc_trim, threads, preloaded, profiled)] = seen.values()
    assert malloc_trim is None and threads == "1" and preloaded
    assert profiled is False  # QUIET_LOOPS reached the worker, not only this process


def test_interrupted_study_runs_only_the_missing_cells(in_process, tmp_path, monkeypatch):
    path, _ = in_process
    study = load_study(path)
    real = evaluate.run_cell
    calls: list[str] = []

    def stops_at_the_third(cell):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", stops_at_the_third)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, tmp_path / "out", progress=False)
    assert len(read_table(tmp_path / "out" / "results.csv")) == 2  # the finished cells, kept
    report = (tmp_path / "out" / "report.md").read_text()  # it read as the whole study
    assert "2 cells in the table of the study's 6: 4 not run yet" in report
    first = list(calls)

    def counts(cell):
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", counts)
    run = run_study(study, tmp_path / "out", progress=False)
    assert (run.cached, run.ran) == (2, 4)
    assert set(calls[2:]).isdisjoint(first) and len(calls) == 6
    lines: list[str] = []
    again = run_study(study, tmp_path / "out", progress=False, report=lines.append)
    assert again.ran == 0 and again.cached == 6 and len(calls) == 6
    assert lines and lines[0].startswith("nothing to run: all 6 cells")
    assert "not run yet" not in (tmp_path / "out" / "report.md").read_text()


def test_an_interrupted_study_command_says_so_once(in_process, tmp_path, monkeypatch, capsys):
    """`spcopyro study` printed "interrupted after 2 cells: ..." and then "interrupted" again."""
    monkeypatch.setenv("CI", "1")  # no progress bar
    path, _ = in_process
    real, calls = evaluate.run_cell, []

    def stops_at_the_third(cell):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", stops_at_the_third)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 130
    captured = capsys.readouterr()
    said = (captured.out + captured.err).splitlines()
    assert [line for line in said if "interrupted" in line] == [
        "interrupted after 2 cells: 4 left; run the same command again to continue"
    ]


def test_added_seed_runs_only_new_cells_and_names_do_not_count(in_process, tmp_path):
    path, out = in_process
    renamed = TINY.replace("[variants.og3]", "[variants.gamma3]").replace("seeds = 2", "seeds = 3")
    run = run_study(load_study(_write(tmp_path, renamed)), out, progress=False)
    assert (run.cached, run.ran) == (6, 3)  # seed 2 only; og3 renamed gamma3 reuses its cells
    rows = read_table(out / "results.csv")
    assert {r["variant"] for r in rows} == {"gamma3", "dp", "F-geometry"}
    longer = TINY.replace("sweeps = 8", "sweeps = 9")
    keys = {c.key for c in cells_of(load_study(_write(tmp_path, longer)))}
    before = {c.key for c in cells_of(load_study(path))}
    assert len(keys & before) == 2  # only the baseline's cells (it has no sweeps) are shared


def test_failing_cell_is_recorded_and_the_study_goes_on(tmp_path, monkeypatch):
    text = TINY + '\n[variants.broken]\npreset = "original-code"\ngamma = 2.9\n'
    fit = evaluate._fit

    def failing(cell, *args, **kwargs):  # a fit that fails at run time, as one on bad data
        if cell.row == "broken":
            raise ValueError("this fit needs marginal_samples > 0")
        return fit(cell, *args, **kwargs)

    monkeypatch.setattr(evaluate, "_fit", failing)
    lines: list[str] = []
    run = run_study(load_study(_write(tmp_path, text)), tmp_path / "out", progress=False,
                    report=lines.append)  # fmt: skip
    assert (run.ran, run.failed) == (8, 2)
    rows = read_table(tmp_path / "out" / "results.csv")
    broken = [r for r in rows if r["variant"] == "broken"]
    assert [r["status"] for r in broken] == ["error", "error"]
    assert broken[0]["error_type"] == "ValueError" and "marginal_samples" in broken[0]["error"]
    assert broken[0]["ari"] is None
    assert all(r["status"] == "ok" for r in rows if r["variant"] != "broken")
    assert any("failed: ValueError" in line for line in lines)
    assert "Failed cells" in (tmp_path / "out" / "report.md").read_text()
    lines.clear()
    again = run_study(load_study(_write(tmp_path, text)), tmp_path / "out", progress=False,
                      report=lines.append)  # fmt: skip
    assert again.ran == 0  # a failure is kept, and said to be (not "all finished" alone) ...
    assert again.failed_before == 2
    assert any("2 cell(s) failed in an earlier run" in line and "--retry-failed" in line
               for line in lines)  # fmt: skip
    path = _write(tmp_path, text)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 1
    retried = run_study(load_study(_write(tmp_path, text)), tmp_path / "out", progress=False,
                        retry_failed=True)  # fmt: skip
    assert (retried.ran, retried.failed) == (2, 2)  # ... until asked to retry


def test_cli_runs_resumes_and_redraws(in_process, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CI", "1")  # no progress bar
    path, _ = in_process
    out = tmp_path / "cli"
    assert main(["study", str(path), "--out", str(out), "--workers", "1"]) == 0
    assert "| og3 | gibbs |" in capsys.readouterr().out
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--rerun-stale"]) == 0
    assert "nothing to run" in capsys.readouterr().out
    assert main(["study", str(path), "--out", str(tmp_path / "dry"), "--dry-run"]) == 0
    planned = capsys.readouterr().out
    assert "6 of 6 cells to run" in planned and "| small | og3 | gibbs | 8 | 2 |" in planned
    assert "| small | F-geometry | baseline | 0 | 2 |" in planned  # no iterations: not 8
    assert not (tmp_path / "dry").exists()
    assert main(["study", str(path), "--out", str(out), "--dry-run"]) == 0
    assert "0 of 6 cells to run (6 finished before" in capsys.readouterr().out
    report = (out / "report.md").read_text()
    (out / "report.md").unlink()
    assert main(["study", str(path), "--out", str(out), "--report-only"]) == 0
    assert (out / "report.md").read_text() == report
    assert main(["study", str(tmp_path / "none.toml"), "--out", str(out)]) == 2
    assert "ablation_small" in capsys.readouterr().err


def test_finished_study_restarted_does_nothing_and_says_so(in_process, tmp_path, monkeypatch):
    """Issue 26: a restarted finished study runs no cell, says so, and leaves its table and
    report as they were."""
    path, finished = in_process
    out = tmp_path / "out"
    shutil.copytree(finished, out)  # other tests add cells to the shared folder

    def must_not_run(cell):
        raise AssertionError(f"cell {cell.key} ran again")

    monkeypatch.setattr(evaluate, "run_cell", must_not_run)
    before: dict[str, bytes] = {}
    for _ in range(2):
        lines: list[str] = []
        run = run_study(load_study(path), out, progress=False, report=lines.append)
        assert (run.ran, run.cached, run.failed) == (0, 6, 0)
        assert lines == [f"nothing to run: all 6 cells of study 'tiny' are finished in {out} "
                         "(delete cells/ there to run them again)"]  # fmt: skip
        now = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
        now.pop(LOCK_NAME)  # the run's process and start time: not an output
        assert now == (before or now)
        before = now
    assert len(read_table(out / "results.csv")) == 6


def test_cells_other_source_computed_are_named_kept_and_rerun_when_asked(in_process, tmp_path):
    """Each record holds the digest of the source that computed it. A restarted finished study
    whose cells other source computed (or no digest names) still runs nothing, says how many
    and its report says so; --rerun-stale runs exactly those again."""
    from spcopyro.study.cells import source_digest

    path, finished = in_process
    out = tmp_path / "out"
    shutil.copytree(finished, out)
    rows = read_table(out / "results.csv")
    assert {r["source_digest"] for r in rows} == {source_digest()}
    changed = [out / "cells" / f"{row['key']}.json" for row in rows[:2]]  # of this study
    for stored, digest in zip(changed, ("0123456789abcdef", None), strict=True):
        record = json.loads(stored.read_text())
        record.pop("source_digest")
        if digest is not None:
            record["source_digest"] = digest
        stored.write_text(json.dumps(record))
    lines: list[str] = []
    run = run_study(load_study(path), out, progress=False, report=lines.append)
    assert (run.ran, run.cached) == (0, 6)
    assert lines[0].startswith("nothing to run: all 6 cells")
    assert lines[1].startswith("2 of the finished cells were computed by other spcopyro source")
    assert "--rerun-stale" in lines[1] and source_digest() in lines[1]
    assert "**Cells of 3 versions of spcopyro's source**" in (out / "report.md").read_text()
    again = run_study(load_study(path), out, progress=False, rerun_stale=True)
    assert (again.ran, again.cached) == (2, 4)
    assert {r["source_digest"] for r in read_table(out / "results.csv")} == {source_digest()}
    assert "versions of spcopyro's source" not in (out / "report.md").read_text()
    lines.clear()
    run_study(load_study(path), out, progress=False, report=lines.append, rerun_stale=True)
    assert len(lines) == 1 and lines[0].startswith("nothing to run")


def test_package_digest_covers_python_sources_only(tmp_path):
    from spcopyro.study.cells import package_digest

    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    first = package_digest(tmp_path)
    (tmp_path / "notes.md").write_text("not code")
    (tmp_path / "sub" / "b.pyc").write_bytes(b"compiled")
    assert package_digest(tmp_path) == first
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    assert package_digest(tmp_path) != first
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    (tmp_path / "sub" / "b.py").rename(tmp_path / "b2.py")
    assert package_digest(tmp_path) != first  # a file's path counts


def test_cells_store_their_label_maps_and_the_report_draws_them(in_process, tmp_path):
    from spcopyro.study.maps import load_label_map
    from spcopyro.study.report import write_report

    _, out = in_process
    rows = read_table(out / "results.csv")
    for row in rows:
        stored = load_label_map(out, row)
        assert stored is not None and row["label_map"] == f"maps/{row['key']}.npz"
        assert stored.labels.shape == stored.grid.shape == stored.truth.shape
        free = stored.grid.free
        assert (stored.labels[free] >= 0).all() and (stored.labels[~free] == -1).all()
    report = (out / "report.md").read_text()
    assert "![maps_small](maps_small.png)" in report
    copy = tmp_path / "copy"  # the table and the stored maps alone redraw it
    copy.mkdir()
    (copy / "results.csv").write_bytes((out / "results.csv").read_bytes())
    (copy / "maps").symlink_to(out / "maps")
    write_report(copy / "results.csv", copy / "report.md", title="tiny")
    assert (copy / "maps_small.png").stat().st_size > 1000
    assert (copy / "report.md").read_text() == report


def test_results_parquet_equals_the_csv(in_process):
    pytest.importorskip("pyarrow", reason="the parquet extra (pyarrow)")
    from spcopyro.study.table import PARQUET, read_parquet

    _, out = in_process
    csv_rows, parquet_rows = read_table(out / "results.csv"), read_parquet(out / PARQUET)
    assert parquet_rows == csv_rows and list(parquet_rows[0]) == list(COLUMNS)
    assert isinstance(parquet_rows[0]["seed"], int) and isinstance(parquet_rows[0]["ari"], float)


def test_no_parquet_without_pyarrow(tmp_path, monkeypatch):
    from spcopyro.study.table import write_parquet

    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow raises ImportError
    assert write_parquet(tmp_path / "results.parquet", [{"seed": 1}]) is None
    assert not (tmp_path / "results.parquet").exists()


def test_held_out_folds_of_a_one_trial_house_name_it():
    """The message began ``None:`` for a house not read from a folder."""
    from spcopyro.experiments.table import heldout_folds
    from spcopyro.synthetic import HouseSpec, make_house

    spec = HouseSpec(height=24, width=30, num_rooms=2, min_room_size=8, num_trials=1)
    with pytest.raises(ValueError, match="^house 'one': held-out folds need >= 2 trials"):
        next(heldout_folds(make_house(seed=0, spec=spec, name="one")))


_DIGEST_AT_IMPORT = """
import json, sys
from pathlib import Path
from spcopyro.study import cells
package = Path(cells.__file__).resolve().parents[1]
with open(package / "model.py", "a") as edited:  # an edit while the study runs
    edited.write("# edited\\n")
print(json.dumps({"package": str(package), "recorded": cells.source_digest(),
                  "files_now": cells.package_digest(package)}))
"""


def test_the_source_digest_is_of_the_code_imported_not_of_later_edits(tmp_path):
    """A cell's source_digest was read from disk when first asked for (after the first cell),
    so a source file edited while a study ran changed the digest the cells recorded: it is
    read when the study's code is imported."""
    from spcopyro.study.cells import package_digest

    package = Path(__file__).resolve().parents[1] / "spcopyro"
    copy = tmp_path / "spcopyro"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = package_digest(copy)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run([sys.executable, "-c", _DIGEST_AT_IMPORT], capture_output=True,
                          text=True, env=env, cwd=tmp_path, timeout=300, check=True)  # fmt: skip
    record = json.loads(done.stdout.strip().splitlines()[-1])
    assert record["package"] == str(copy.resolve())  # the copy ran, not the checkout
    assert record["files_now"] != before  # the edit changed the files
    assert record["recorded"] == before  # ... not the digest of the code that was imported


def test_sentence_scores_list_no_words_for_a_concept_where_none_was_heard():
    """concept_words lists each large concept's words as fit does (``listed_top_words``): none
    for a concept of 50+ cells where no word was heard (its w row is the prior's, the words
    tied), which filler_top_share then leaves out; they listed its tie-order first words and
    counted it."""
    import math

    import numpy as np

    from spcopyro.config import SpCoConfig

    tied = [("the", 0.1), ("a", 0.1), ("is", 0.1)]  # tie order: fillers first

    class Fitted:
        config = SpCoConfig(num_concepts=3)
        labels = np.repeat([0, 1, 2], evaluate.SENTENCE_MIN_CELLS)  # [N]

        def concepts_in_use(self):
            return np.array([0, 1, 2])

        def heard(self, concept):
            return [4.0, 6.0, 0.0][concept]  # concept 2: no word heard

        def top_words(self, concept, n):
            return [[("the", 0.5), ("kitchen", 0.3)], [("sofa", 0.6), ("the", 0.2)], tied][concept]

    scores = evaluate._sentence_scores(Fitted())
    assert json.loads(scores["concept_words"]) == [["the", "kitchen"], ["sofa", "the"], []]
    assert scores["filler_top_share"] == 0.5  # of the two concepts listing words
    unheard = Fitted()
    unheard.heard = lambda concept: 0.0
    assert math.isnan(evaluate._sentence_scores(unheard)["filler_top_share"])
