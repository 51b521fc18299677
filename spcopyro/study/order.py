"""The order a study's cells start in on a cluster: longest first.

Workers take cells in the order they were submitted. A study mixes cells whose cost differs by
two orders of magnitude (an SVI fit of a public house: 5-12 min; 100 CAVI iterations on a
synthetic one: half a second), and whichever cell starts last decides how long the cluster
runs after the others are done: in the table's order (data, seed, variant, method) a slow cell
near the end runs alone while the other workers wait. Started longest first (the "longest
processing time" rule), the short cells fill the workers' gaps at the end instead; with the
cells' costs known, its makespan is at most 4/3 of the best possible (Graham 1969).

A cell's cost is predicted, in seconds on the 2-core machine the defaults were measured on (only
the order matters), as its iterations times a time per iteration (plus, without history, its
method's fixed cost):

* from the study's own finished cells where it has some: the median seconds per iteration of
  the finished cells of the same variant (or baseline), data source and method (a study that is
  resumed or gains seeds), else of the same method (or baseline) on the same kind of data;
* otherwise :data:`SECONDS_PER_ITERATION`, the medians of the full-budget Gibbs-versus-VI study
  (docs/studies.md) by method and kind of data, a synthetic house's scaled by its map's area
  against the default house's, plus :data:`SETUP_SECONDS` (a baseline's cell:
  :data:`BASELINE_SECONDS`, scaled alike).

The same prediction decides whether a study asked to run on a LocalCluster starts one at all
(:func:`cluster_pays`): a study whose cells are predicted to take less than the cluster's
start-up saves runs in this process. A whole run's prediction (:func:`run_seconds`) adds
:data:`WARMUP_SECONDS` once per process that runs cells (the first cell's warm-up), which no
cell's own prediction holds.
"""

from __future__ import annotations

import statistics
from collections.abc import Iterable, Mapping

from spcopyro.study.cells import BASELINE_METHOD, Cell
from spcopyro.study.spec import SYNTHETIC_FACTORIES

__all__ = [
    "BASELINE_SECONDS", "CELL_SECONDS", "CLUSTER_START_SECONDS", "SECONDS_PER_ITERATION",
    "SETUP_SECONDS", "WARMUP_SECONDS", "WORKER_SLOWDOWN", "cluster_pays", "duration",
    "longest_first", "predicted_seconds", "run_seconds",
]  # fmt: skip

SECONDS_PER_ITERATION: dict[str, tuple[float, float]] = {
    "gibbs": (0.83e-3, 0.96e-3),
    "vi-gibbs": (1.22e-3, 1.38e-3),
    "cavi": (4.34e-3, 24.0e-3),
    "stochastic-vi": (8.96e-3, 57.6e-3),
    "svi": (19.8e-3, 167.4e-3),
    "lbp": (23.2e-3, 475.4e-3),
}
"""Seconds per iteration (synthetic house, public house or simulated map) of each method at
the study's budgets: medians of the full-budget Gibbs-versus-VI study, 2026-12-03, 2 cores.
A method missing here costs what Gibbs does."""
SETUP_SECONDS: dict[str, float] = {
    "gibbs": 0.02,
    "vi-gibbs": 0.3,
    "cavi": 0.08,
    "stochastic-vi": 0.04,
    "svi": 0.15,
    "lbp": 0.4,
}
"""A fit's seconds beside its iterations (each method's setup), added to a prediction from
:data:`SECONDS_PER_ITERATION`: what a cell of 4 iterations takes beyond 4 of 40 (default
synthetic house, 2 seeds, 2 cores at load 2-5, 2026-12-05). It matters at smoke budgets only
(30 Gibbs sweeps: 0.03 s, not the 0.01 s of 30 x 0.83 ms; 4 VI-Gibbs sweeps: 0.4 s, not
0.005 s); the full-budget medians hold it already, a few % of their cells' seconds.
A method missing here costs what Gibbs does."""
BASELINE_SECONDS: dict[str, tuple[float, float]] = {
    "C-spcoa": (5e-3, 10e-3),
    "D-cnn": (2e-3, 0.02),
    "E-nearest": (2e-3, 0.015),
    "F-geometry": (4e-3, 0.2),
}
"""Seconds of a baseline row's cell (default synthetic house, public house or simulated map;
C-spcoa, the one that iterates: of an iteration), without history: 2 seeds of each on the
default house, room1dk5, room1ldk4 and a tour on room1dk5's map, 2 cores at load 2-5,
2026-12-05 (nearest utterance 1-14 ms, geometry 2-3 ms and 0.10-0.23 s, SpCoA 0.6 s and 1.2 s
for 100 iterations). A baseline missing here costs a second."""


def _group(cell: Cell) -> tuple[str, str, str]:
    return cell.row, cell.data.name, cell.method


def _kind(cell: Cell) -> tuple[str, str]:
    """The method (a baseline: its row, since baselines' costs differ 100-fold) and the kind of
    data."""
    method = cell.row if cell.method == BASELINE_METHOD else cell.method
    return method, "synthetic" if cell.data.kind == "synthetic" else "measured"


def _per_iteration(
    cells: Iterable[Cell], finished: Mapping[str, Mapping[str, object]]
) -> tuple[dict[tuple[str, str, str], float], dict[tuple[str, str], float]]:
    """Median seconds per iteration of the finished cells among ``cells``, by group and kind."""
    by_group: dict[tuple[str, str, str], list[float]] = {}
    by_kind: dict[tuple[str, str], list[float]] = {}
    for cell in {c.key: c for c in cells}.values():
        record = finished.get(cell.key)
        if record is None or record.get("status") != "ok":
            continue
        seconds = record.get("seconds")
        if not isinstance(seconds, (int, float)) or seconds <= 0:
            continue
        rate = float(seconds) / max(cell.sweeps, 1)
        by_group.setdefault(_group(cell), []).append(rate)
        by_kind.setdefault(_kind(cell), []).append(rate)
    return (
        {k: statistics.median(v) for k, v in by_group.items()},
        {k: statistics.median(v) for k, v in by_kind.items()},
    )


def _static_rate(cell: Cell) -> float:
    """Predicted seconds per iteration of ``cell`` without history (its fixed cost spread
    over its iterations)."""
    if cell.method == BASELINE_METHOD:
        synthetic, measured = BASELINE_SECONDS.get(cell.row, (1.0, 1.0))
        setup = 0.0
    else:
        synthetic, measured = SECONDS_PER_ITERATION.get(cell.method, SECONDS_PER_ITERATION["gibbs"])
        setup = SETUP_SECONDS.get(cell.method, SETUP_SECONDS["gibbs"])
    iterations = max(cell.sweeps, 1)
    if cell.data.kind != "synthetic":
        return measured + setup / iterations
    spec, default = cell.data.house_spec(), SYNTHETIC_FACTORIES["default"]()
    return synthetic * (spec.height * spec.width) / (default.height * default.width) + (
        setup / iterations
    )


def predicted_seconds(
    cells: Iterable[Cell],
    history: Iterable[Cell] = (),
    finished: Mapping[str, Mapping[str, object]] | None = None,
) -> dict[str, float]:
    """Each cell's predicted seconds, by key (module docstring). ``history``: the cells whose
    records ``finished`` (by key, as :meth:`spcopyro.study.table.CellStore.finished` gives
    them) may hold."""
    by_group, by_kind = _per_iteration(history, finished or {})
    predicted = {}
    static: dict[tuple[int, str, str, int], float] = {}  # per source, row, method, iterations
    for cell in cells:
        rate = by_group.get(_group(cell)) or by_kind.get(_kind(cell))
        if not rate:
            known = (id(cell.data), cell.row if cell.method == BASELINE_METHOD else "",
                     cell.method, cell.sweeps)  # fmt: skip
            if known not in static:
                static[known] = _static_rate(cell)
            rate = static[known]
        predicted[cell.key] = rate * max(cell.sweeps, 1)
    return predicted


def longest_first(cells: Iterable[Cell], predicted: Mapping[str, float]) -> list[Cell]:
    """``cells`` by ``predicted`` seconds (by key, :func:`predicted_seconds`), longest first;
    cells predicted alike keep their order."""
    return sorted(cells, key=lambda cell: -predicted[cell.key])


CELL_SECONDS = 0.1
"""A cell's wall seconds beside its fit's own (drawing or loading its house, scoring, storing):
16 cells of ``ablation_small`` took 1.6-1.7 s in one process for 0.7 s of fits (2026-12-05)."""
WARMUP_SECONDS = 0.35
"""What a process's first cell takes beyond the same cell run again, for any method (numba's
cached kernels loaded, the fit's lazy imports), in the fit's own seconds: paid once by each
process that runs cells, so it belongs to a run's prediction (:func:`run_seconds`,
:func:`cluster_pays`), not to a cell's. Measured 2026-12-05 in fresh processes that had
imported what a worker imports (:mod:`spcopyro.study.worker_imports`), default synthetic house,
2 cores at load 1.3-1.8: the first of 3-4 cells 0.24-0.38 s longer (30 Gibbs sweeps 0.28-0.38 s
against 0.04 s; 4 of them 0.37 against 0.014-0.021 s; 4 CAVI iterations 0.33-0.45 against
0.06-0.08 s), whichever method came first; the later cells of another method 0.02 s at most.
:data:`SETUP_SECONDS` leaves it out (measured on warm processes' cells)."""
CLUSTER_START_SECONDS = 3.0
"""What a LocalCluster adds to its run beyond its workers' share of the cells, on an idle
2-core machine (docs/studies.md, "The LocalCluster's speed"): its workers ready 2.9 s after the
start (cells run in this process meanwhile), each worker's first result about 1 s later than
its fit's own seconds (beyond :data:`WARMUP_SECONDS`, which those seconds hold), the last
cells' imbalance; 5-8 s to the workers' start alone on the same machine under a load of 4."""
WORKER_SLOWDOWN = 1.25
"""A cell's seconds on a worker over its seconds in one process (1.23-1.30 measured, two
workers on 2 cores: docs/studies.md)."""


def run_seconds(predicted: Iterable[float], workers: int = 1) -> float:
    r"""A run's predicted seconds of fits for cells of ``predicted`` seconds
    (:func:`predicted_seconds`): one process, :math:`\sum_i p_i + w`; ``workers`` side by side
    at least :math:`\max(\sum_i p_i / N, \max_i p_i) + w`, where :math:`w` =
    :data:`WARMUP_SECONDS` is each process's first-cell warm-up (paid by every worker at once);
    0 for no cells."""
    seconds = [max(float(p), 0.0) for p in predicted]
    if not seconds:
        return 0.0
    return max(sum(seconds) / max(workers, 1), max(seconds)) + WARMUP_SECONDS


def cluster_pays(predicted: Iterable[float], workers: int) -> bool:
    r"""Whether a LocalCluster of ``workers`` is predicted to end the cells of ``predicted``
    seconds (:func:`predicted_seconds`) sooner than this process alone.

    With :math:`t_i` = predicted_i + :data:`CELL_SECONDS`, :math:`W = \sum_i t_i` and
    :math:`w` = :data:`WARMUP_SECONDS` (each process's first cell), one process takes
    :math:`W + w`; the cluster, each of whose workers pays the warm-up too, about
    :math:`s (\max(W / N, \max_i t_i) + w) + c` (:math:`s` = :data:`WORKER_SLOWDOWN`,
    :math:`c` = :data:`CLUSTER_START_SECONDS`, :math:`N` = ``workers``): it pays where that is
    less than :math:`W + w`. Never for one cell (:math:`W = \max_i t_i`), nor for one worker;
    on 2 workers from :math:`W > 8.2` s of cells none of which dominates.
    """
    seconds = [max(float(p), 0.0) + CELL_SECONDS for p in predicted]
    if workers <= 1 or len(seconds) <= 1:
        return False
    here, spread = sum(seconds) + WARMUP_SECONDS, run_seconds(seconds, workers)
    return here > WORKER_SLOWDOWN * spread + CLUSTER_START_SECONDS


def duration(seconds: float) -> str:
    """``seconds`` as a person reads a prediction: 0.4 s, 8.2 s, 40 s, 12 min, 2.3 h (a
    tenth below 10 s, where a smoke study's whole run lies: not "0 s" for 0.4 s of fits)."""
    if seconds < 9.95:
        return f"{seconds:.1f} s"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
