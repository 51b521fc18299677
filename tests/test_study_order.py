"""The order a study's cells start in on a cluster (spcopyro.study.order): longest first."""

from __future__ import annotations

import pytest
from study_setup import (
    counting_start,
    fake_cluster,
    on_a_cluster,
    one_variant_study,
    small_house,
    small_house_toml,
)

from spcopyro.study import run as study_run
from spcopyro.study.cells import cells_of
from spcopyro.study.order import (
    CELL_SECONDS,
    WARMUP_SECONDS,
    cluster_pays,
    duration,
    longest_first,
    predicted_seconds,
    run_seconds,
)
from spcopyro.study.run import run_study
from spcopyro.study.spec import study_from_dict

SMALL = small_house()


def _methods_study(**data):
    return study_from_dict({
        "study": {"name": "order", "seeds": 2, "methods": ["cavi", "gibbs", "svi"],
                  "sweeps": {"gibbs": 2000, "cavi": 100, "svi": 300}},
        "variants": {"dp": {"preset": "paper-dp"}},
        "data": data or {"small": SMALL},
    })  # fmt: skip


def test_without_history_slow_methods_and_big_houses_start_first():
    """On one house, 300 SVI steps before 2000 Gibbs sweeps before 100 CAVI iterations (the
    full-budget study's times per iteration); of one method, the bigger house first; the seeds
    of a group, predicted alike, keep their order."""
    big = {**SMALL, "synthetic": "scaled", "height": 48, "width": 60}
    cells = cells_of(_methods_study(small=SMALL, big=big))
    order = [
        (c.method, c.data.name, c.seed) for c in longest_first(cells, predicted_seconds(cells))
    ]
    for data in ("small", "big"):
        methods = [m for m, d, _ in order if d == data]
        assert methods == ["svi"] * 2 + ["gibbs"] * 2 + ["cavi"] * 2
    for method in ("svi", "gibbs", "cavi"):
        assert [(d, s) for m, d, s in order if m == method] == [
            ("big", 0), ("big", 1), ("small", 0), ("small", 1)
        ]  # fmt: skip


def test_finished_cells_predict_their_group_then_their_kind():
    """A resumed study that has seen its Gibbs cells take a minute each starts the missing
    Gibbs cell first; its cells of the same method on other synthetic data follow that rate."""
    study = _methods_study(small=SMALL, other={**SMALL, "num_trials": 3})
    cells = cells_of(study)
    done = [c for c in cells if c.method == "gibbs" and c.data.name == "small" and c.seed == 0]
    finished = {c.key: {"status": "ok", "seconds": 60.0} for c in done}
    finished["not-a-cell"] = {"status": "ok", "seconds": 1e9}  # another study's: ignored
    pending = [c for c in cells if c.key not in finished]
    predicted = predicted_seconds(pending, cells, finished)
    by_cell = {(c.method, c.data.name, c.seed): predicted[c.key] for c in pending}
    assert by_cell[("gibbs", "small", 1)] == pytest.approx(60.0)
    assert by_cell[("gibbs", "other", 0)] == pytest.approx(60.0)  # same method and kind
    assert by_cell[("svi", "small", 0)] < 60.0
    assert longest_first(pending, predicted)[0].method == "gibbs"
    failed = {c.key: {"status": "error", "seconds": 60.0} for c in done}
    assert predicted_seconds(pending, cells, failed) == predicted_seconds(pending)


def test_without_history_baselines_and_smoke_budgets_are_predicted_at_their_measured_cost():
    """Without history, the nearest-utterance and geometry baselines (a few ms a cell on a small
    house) are predicted under 0.1 s, not at a flat second each (which predicted ablation_small's
    16 cells at 4 s for 0.7 s of fits); SpCoA by its iterations; a method's fixed cost counts
    at a smoke budget (4 VI-Gibbs sweeps: ~0.4 s measured, not 4 x 1.2 ms)."""
    study = study_from_dict({
        "study": {"name": "baselines", "seeds": 1, "methods": ["vi-gibbs"], "sweeps": 4,
                  "baselines": ["C-spcoa", "D-cnn", "E-nearest", "F-geometry"],
                  "spcoa_iterations": 100},
        "variants": {"dp": {"preset": "paper-dp"}},
        "data": {"small": SMALL},
    })  # fmt: skip
    cells = cells_of(study)
    predicted = {c.row: seconds for c in cells for k, seconds in
                 predicted_seconds(cells).items() if k == c.key}  # fmt: skip
    for row in ("D-cnn", "E-nearest", "F-geometry"):
        assert 0 < predicted[row] < 0.1, (row, predicted[row])
    assert predicted["C-spcoa"] > 10 * predicted["F-geometry"]
    assert predicted["dp"] > 0.1


def test_finished_baselines_predict_the_same_baseline_on_other_data():
    """A geometry cell on new data takes the geometry cells' rate (ms), not the median of every
    baseline's (SpCoA's 100 iterations of a minute pulled it to 0.3 s)."""
    study = study_from_dict({
        "study": {"name": "b", "seeds": 1, "sweeps": 2, "baselines": ["C-spcoa", "F-geometry"],
                  "spcoa_iterations": 100},
        "variants": {"dp": {"preset": "paper-dp"}},
        "data": {"small": SMALL, "other": {**SMALL, "num_trials": 3}},
    })  # fmt: skip
    cells = cells_of(study)
    done = [c for c in cells if c.data.name == "small" and c.variant is None]
    finished = {c.key: {"status": "ok", "seconds": 60.0 if c.row == "C-spcoa" else 0.003}
                for c in done}  # fmt: skip
    pending = [c for c in cells if c.key not in finished]
    predicted = predicted_seconds(pending, cells, finished)
    by_row = {c.row: predicted[c.key] for c in pending if c.variant is None}
    assert by_row["F-geometry"] == pytest.approx(0.003)
    assert by_row["C-spcoa"] == pytest.approx(60.0)


class _FakeFuture:
    def __init__(self, cell):
        self.cell = cell

    def result(self):
        return REAL_RUN_CELL(self.cell)

    def release(self):
        pass


class _FakeClient:
    def __init__(self):
        self.submitted = []

    def submit(self, function, cell, key, priority):
        self.submitted.append((cell, priority))
        return _FakeFuture(cell)


REAL_RUN_CELL = study_run.evaluate.run_cell


def _run_on_fake_cluster(tmp_path, monkeypatch, ready_at_once: bool):
    """The two-sweep-length study through run_study's Dask path, with a cluster that is up at
    once (every cell submitted) or never (every cell run here): the cells as they were
    submitted with their priorities, the cells run here, and the study's cells."""
    distributed = pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    client = _FakeClient()
    ran_here = []

    class FakeStart:
        def __init__(self, workers, on_ready=None):
            if ready_at_once:
                on_ready(client)

        def wait(self):
            return client

        def close(self):
            pass

    def run_cell(cell):  # in this process (the fake workers call REAL_RUN_CELL)
        ran_here.append(cell)
        return REAL_RUN_CELL(cell)

    monkeypatch.setattr(study_run, "ClusterStart", FakeStart)
    on_a_cluster(monkeypatch)  # 4 short cells: the cluster path all the same
    monkeypatch.setattr(distributed, "as_completed", iter)
    monkeypatch.setattr(study_run.evaluate, "run_cell", run_cell)
    study = study_from_dict({
        "study": {"name": "lengths", "seeds": 2, "sweeps": {"short": 2, "long": 6}},
        "variants": {"short": {"preset": "paper-dp"}, "long": {"preset": "paper-dp"}},
        "data": {"small": SMALL},
    })  # fmt: skip
    run = run_study(study, tmp_path / "out", workers=2, progress=False)
    assert run.ran == 4 and run.failed == 0
    return client.submitted, ran_here, cells_of(study)


def test_cluster_gets_the_longest_cells_first_with_falling_priority(tmp_path, monkeypatch):
    submitted, ran_here, cells = _run_on_fake_cluster(tmp_path, monkeypatch, ready_at_once=True)
    assert ran_here == []  # every cell went to the (fake) workers
    assert [(c.row, c.seed) for c, _ in submitted] == [
        ("long", 0), ("long", 1), ("short", 0), ("short", 1)
    ]  # fmt: skip
    priorities = [priority for _, priority in submitted]
    assert priorities == sorted(priorities, reverse=True) and len(set(priorities)) == 4


def test_this_process_runs_the_shortest_cells_while_the_cluster_starts(tmp_path, monkeypatch):
    submitted, ran_here, _ = _run_on_fake_cluster(tmp_path, monkeypatch, ready_at_once=False)
    assert submitted == []
    assert [(c.row, c.seed) for c in ran_here] == [
        ("short", 1), ("short", 0), ("long", 1), ("long", 0)
    ]  # fmt: skip


def test_dry_run_predicts_each_group_and_the_whole_run(tmp_path, capsys, monkeypatch):
    """``--dry-run`` gives each group's predicted time and the run's, on the workers asked for:
    SVI's 300 steps on the small house cost more than Gibbs' 2000 sweeps, as the full-budget
    study measured."""
    from spcopyro.cli.main import main
    from spcopyro.study.run import plan_study

    study = _methods_study()
    plan = plan_study(study, tmp_path / "none")
    by_method = {c.method: plan.predicted[c.key] for c in plan.pending}
    assert by_method["svi"] > by_method["gibbs"] > by_method["cavi"] > 0
    path = tmp_path / "order.toml"
    path.write_text(
        '[study]\nname = "order"\nseeds = 2\nmethods = ["gibbs", "svi"]\n'
        "sweeps = { gibbs = 2000, svi = 3000 }\n"  # 18 s: long enough for a LocalCluster
        '[variants.dp]\npreset = "paper-dp"\n' + small_house_toml()
    )
    assert main(["study", str(path), "--out", str(tmp_path / "dry"), "--dry-run",
                 "--workers", "2"]) == 0  # fmt: skip
    planned = capsys.readouterr().out
    assert "| iterations | cells | predicted |" in planned
    assert "| small | dp | svi | 3000 | 2 |" in planned
    assert "of fits one after another; on 2 workers at least" in planned
    assert not (tmp_path / "dry").exists()


@pytest.mark.parametrize(
    ("predicted", "workers", "pays"),
    [
        ([0.02, 0.02], 2, False),  # two 30-sweep cells: 3-6.5 s on the cluster, 2 s here
        ([0.04] * 16, 2, False),  # ablation_small: 1.7 s here, 2.5 s and more with a cluster
        ([4.0 - CELL_SECONDS] * 2, 2, False),  # 8 s of cells: the cluster's break-even
        ([4.05 - CELL_SECONDS] * 2, 2, False),  # 8.1 s: the workers' warm-ups tip it
        ([4.2] * 2, 2, True),
        ([1.66] * 20, 2, True),  # benchmarks/study_dask.py: 30 s here, 0.6-0.7 of it there
        ([300.0, 1.0, 1.0], 2, False),  # one cell decides the wall either way
        ([300.0, 300.0], 2, True),
        ([1.66] * 20, 1, False),
        ([600.0], 8, False),  # a single cell: this process runs it while the cluster starts
        ([], 2, False),
    ],
)  # fmt: skip
def test_a_cluster_is_started_only_where_it_is_predicted_to_pay(predicted, workers, pays):
    assert cluster_pays(predicted, workers) is pays


def test_shipped_small_study_runs_here_and_a_long_one_on_the_cluster(tmp_path):
    """The shipped ``ablation_small`` (16 cells of 30 sweeps, predicted at 4 s) started a
    LocalCluster by default (``--workers`` = the machine's cores) for nothing; 20 cells of
    2000 sweeps (the benchmark's study) still go to the cluster."""
    from spcopyro.study import STUDIES
    from spcopyro.study.run import plan_study
    from spcopyro.study.spec import load_study

    small = plan_study(load_study(STUDIES / "ablation_small.toml"), tmp_path / "a")
    assert not cluster_pays(small.predicted.values(), 2)
    long = study_from_dict({
        "study": {"name": "long", "seeds": 5, "sweeps": 2000},
        "variants": {"a": {"preset": "paper-dp"}, "b": {"preset": "original-code"}},
        "data": {"d": {"synthetic": "default"}, "e": {"synthetic": "default", "num_rooms": 3}},
    })  # fmt: skip
    assert cluster_pays(plan_study(long, tmp_path / "b").predicted.values(), 2)


def test_a_short_study_asked_for_workers_starts_no_cluster(tmp_path, monkeypatch):
    """Two cells of 30 sweeps with ``--workers 2`` started a LocalCluster: 6.5 s against 3.3 s
    in one process (2-core machine); its first line now says why none was started."""
    started: list[int] = []
    fake_cluster(monkeypatch, counting_start(started))
    study = one_variant_study("two", seeds=2, sweeps=30)
    lines: list[str] = []
    done = run_study(study, tmp_path / "out", workers=2, progress=False, report=lines.append)
    assert started == []
    assert (done.ran, done.ran_here, done.failed) == (2, 2, 0)
    assert done.where.startswith("in-process (2 cells predicted at 0.4 s of fits, too short for "
                                 "a LocalCluster of 2 workers"), done.where  # fmt: skip
    assert lines[0].endswith(done.where), lines
    assert not any("while the LocalCluster started" in line for line in lines), lines
    planned = study_run.plan_markdown(study_run.plan_study(study, tmp_path / "dry"), study, 2)
    assert "with --workers 2 run in this process all the same" in planned, planned


@pytest.mark.parametrize(
    "seconds, text",
    [(0.4, "0.4 s"), (8.23, "8.2 s"), (9.96, "10 s"), (42, "42 s"), (600, "10 min"),
     (7380, "2.0 h")],
)  # fmt: skip
def test_duration_reads_as_a_person_would(seconds, text):
    """Below 10 s a tenth: a smoke study's 0.4 s of fits read "0 s", as if it ran nothing."""
    assert duration(seconds) == text


def test_a_run_is_predicted_with_each_process_warm_up_once():
    """Each process's first cell takes about 0.35 s more (WARMUP_SECONDS), whatever its method;
    the cells' own predictions leave it out, a run's holds it once per process: once in one
    process, once on the workers side by side (each pays it at the same time)."""
    assert run_seconds([]) == 0.0
    assert run_seconds([0.02, 0.02]) == pytest.approx(0.04 + WARMUP_SECONDS)
    assert run_seconds([1.0, 1.0, 2.0], 2) == pytest.approx(2.0 + WARMUP_SECONDS)
    assert run_seconds([6.0, 1.0, 1.0], 2) == pytest.approx(6.0 + WARMUP_SECONDS)


def test_dry_run_total_holds_the_warm_up(tmp_path):
    """Two cells of 30 sweeps on the small house: about 0.01 s of fits predicted, 0.4 s with
    this process's first cell; ``--dry-run`` said "0 s"."""
    study = one_variant_study("two", seeds=2, sweeps=30)
    plan = study_run.plan_study(study, tmp_path / "dry")
    fits = sum(plan.predicted.values())
    assert fits < 0.05, plan.predicted
    planned = study_run.plan_markdown(plan, study, 1)
    assert f"predicted: {duration(fits + WARMUP_SECONDS)} of fits one after another" in planned
    assert "predicted: 0.4 s of fits" in planned, planned


def test_progress_bar_advances_by_predicted_seconds_and_counts_cells(tmp_path, capsys):
    """The bar's share is of the cells' predicted seconds (so its remaining time holds for
    cells of different lengths), with the count of cells beside it."""
    study = _methods_study()
    plan = study_run.plan_study(study, tmp_path / "none")
    bar = study_run._bar(plan.pending, plan.predicted, progress=True)
    svi = next(c for c in plan.pending if c.method == "svi")
    bar.advance(svi)
    bar.close()
    shown = capsys.readouterr().err
    share = plan.predicted[svi.key] / sum(plan.predicted.values())
    assert f"cells 1/6: {100 * share:3.0f}% of the predicted time|" in shown  # not of cells
    bar = study_run._bar(plan.pending, plan.predicted, progress=True)
    for cell in plan.pending:
        bar.advance(cell)
    bar.close()
    assert "cells 6/6: 100% of the predicted time|" in capsys.readouterr().err
    assert study_run._bar(plan.pending, plan.predicted, progress=False) is None
