"""Gibbs against variational inference (issue #10) as a study (issue 26 item 1):
``spcopyro compare-inference`` runs the study engine on the grid of its settings and draws
``comparison.md``, ``comparison.json`` and the quality-against-time figures from the study's
``results.csv``.

The comparison's grid is its variants (:data:`~spcopyro.experiments.inference_comparison.VARIANTS`
whose method the registry holds, each with the preset and gamma of the settings and its own
budget) x the synthetic houses (seeds 0 .. seeds - 1, house and fit) and the public houses
(one cell per held-out trial: seeds 0 .. folds - 1). Its cells are scored as the comparison
scores a fit (``scoring = "comparison"``, :mod:`spcopyro.study.comparison_cell`). The shipped
``compare_inference.toml`` (``compare_inference_quick.toml``) holds the same cells, key for key,
as the command's defaults (``--quick``) on the public dataset.

* :func:`comparison_study`: the study of a :class:`ComparisonSettings`;
* :func:`records_of_rows`: the comparison's per-fit records from ``results.csv`` rows;
* :func:`run_comparison`: run the study (cached and resumable in ``out``) and write the
  comparison's report from its table.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from spcopyro._util.messages import plural
from spcopyro.data import list_houses, load_house
from spcopyro.experiments.ablation_variants import make_variant
from spcopyro.experiments.comparison_report import iteration_unit, summarise, write_report
from spcopyro.experiments.inference_comparison import (
    PUBLIC,
    QUICK_SPEC,
    SYNTHETIC,
    VARIANTS,
    ComparisonSettings,
    available_variants,
    budget,
    current_record,
)
from spcopyro.experiments.table import failed_cells, heldout_folds, report_nothing
from spcopyro.results.map_checks import is_degenerate_map_warning
from spcopyro.study.ablation import spec_options
from spcopyro.study.cell_warnings import read_warnings
from spcopyro.study.comparison_cell import COMPARISON
from spcopyro.study.evaluate import WARNINGS
from spcopyro.study.maps import remove_stale
from spcopyro.study.order import duration, run_seconds
from spcopyro.study.report import with_warnings
from spcopyro.study.run import StudyPlan, run_study
from spcopyro.study.spec import DataSource, Study
from spcopyro.study.table import TABLE, read_table
from spcopyro.synthetic import HouseSpec

__all__ = [
    "comparison_study", "one_concept_maps", "plan_lines", "records_of_rows", "run_comparison",
]  # fmt: skip

LONG_SECONDS = 600.0
"""A run predicted longer than this is told how to run a shorter comparison."""


def _folds(root: Path, house: str, folds: int | None) -> int:
    count = len(load_house(root / house).observations.trials)
    if count < 2:
        list(heldout_folds(load_house(root / house)))  # raises, naming the house
    if folds is not None and folds > count:  # it was cut to count without a word
        raise ValueError(f"--folds {folds}: public house {house} has {count} trials, so at most "
                         f"{count} held-out folds")  # fmt: skip
    return count if folds is None else folds


def comparison_study(
    settings: ComparisonSettings, keys: Sequence[str] | None = None, name: str = "compare-inference"
) -> Study:
    """The study of ``settings`` (module docstring); ``keys``: the variants to run (default:
    ``settings.variants``; every one's method must be in the registry)."""
    keys = tuple(settings.variants if keys is None else keys)
    variants = []
    for key in keys:
        line = VARIANTS[key]
        overrides = {"preset": settings.preset, **settings.overrides, "method": line.method}
        variants.append(make_variant(key, {**overrides, **line.options_for(settings.quick)}))
    data = []
    if SYNTHETIC in settings.house_types and settings.seeds >= 1:
        spec = settings.synthetic_spec or (QUICK_SPEC if settings.quick else HouseSpec())
        seeds = tuple(range(settings.seeds))
        data.append(DataSource(SYNTHETIC, "synthetic", "default", spec_options(spec), seeds=seeds))
    root = settings.dataset_root
    if PUBLIC in settings.house_types and root is not None:
        for house in settings.public_houses or tuple(list_houses(root)):
            seeds = tuple(range(_folds(Path(root), house, settings.folds)))
            if seeds:
                target = str(Path(root) / house)
                data.append(DataSource(house, "public", target, heldout=True, seeds=seeds))
    return Study(
        name=name, variants=tuple(variants), data=tuple(data),
        sweeps=tuple((key, budget(VARIANTS[key], settings)) for key in keys),
        scoring=COMPARISON, description=settings.command,
    )  # fmt: skip


def plan_lines(study: Study, plan: StudyPlan, where: str) -> list[str]:
    """What a run of ``study`` (``plan``: :func:`~spcopyro.study.run.plan_study`'s, as
    :func:`~spcopyro.study.run.run_study` is about to run it, with fits to run; ``where`` they
    run) does, said before its first fit in the place of the study engine's "N of M cells to
    run" (``describe``): how many fits (per method: the synthetic houses and the public
    houses' held-out trials), at which budgets, their predicted time
    (:func:`spcopyro.study.order.run_seconds`), and, for a run predicted over
    :data:`LONG_SECONDS`, shorter invocations. The default study is 140 fits
    (7 methods x 5 synthetic houses and 15 held-out trials), predicted at 1.8 h of fits on the
    2-core machine its rates were measured on; it showed only "140 of 140 cells to run" and a
    progress bar, whose first minutes predicted 4 to 17 hours. The first line ends in "cells
    run: ``where``"; run_study calls it only when fits are to run."""
    per_method = {}
    for cell in plan.cells:
        per_method[cell.row] = per_method.get(cell.row, 0) + 1
    synthetic = sum(len(d.seeds) for d in study.data if d.kind == "synthetic")
    public = [d for d in study.data if d.kind != "synthetic"]
    trials = sum(len(d.seeds) for d in public)
    houses = [plural(synthetic, "synthetic house")] if synthetic else []
    if public:
        houses.append(
            f"{plural(trials, 'held-out trial')} of {plural(len(public), 'public house')}"
        )
    each = max(per_method.values())
    budgets = ", ".join(f"{key} {n} {iteration_unit(key)}" for key, n in study.sweeps)
    seconds = run_seconds(plan.predicted.get(c.key, 0.0) for c in plan.pending)
    before = f" ({plan.cached} finished before)" if plan.cached else ""  # a run resumed
    lines = [
        f"compare-inference: {len(plan.pending)} of {len(plan.cells)} fits to run{before}: "
        f"{plural(len(per_method), 'method')} x {plural(each, 'fit')} each "
        f"({'; '.join(houses)}), at these budgets: {budgets}; predicted {duration(seconds)} "
        "of fits one after another (times of a 2-core machine: a guide, not a promise); cells "
        f"run: {where}"
    ]  # fmt: skip
    if seconds > LONG_SECONDS:
        tenth = " ".join(f"{key}={n // 10}" for key, n in study.sweeps if n >= 1000)
        smaller = f", or a tenth of the longest budgets (--iterations {tenth})" if tenth else ""
        lines.append(
            "a shorter comparison: --quick (a smoke run: a tiny house, a few iterations), "
            f"--houses synthetic --seeds 2 (2 synthetic houses a method){smaller}; Ctrl-C "
            "stops the run, and the same command continues where it stopped"
        )
    return lines


def records_of_rows(rows: Sequence[dict[str, object]]) -> dict[str, dict[str, list[dict]]]:
    """house type -> variant -> the comparison's records (finished cells, table order)."""
    records: dict[str, dict[str, list[dict]]] = {}
    for row in rows:
        if row.get("status") != "ok" or not row.get("details"):
            continue
        house_type = SYNTHETIC if row["data_kind"] == "synthetic" else PUBLIC
        by_variant = records.setdefault(house_type, {})
        record = current_record(json.loads(str(row["details"])))  # an earlier run's too
        by_variant.setdefault(str(row["variant"]), []).append(record)
    return records


def one_concept_maps(rows: Sequence[dict[str, object]]) -> dict[str, dict[str, int]]:
    """house type -> line -> its finished cells whose map was warned of as one concept
    (:func:`~spcopyro.results.map_checks.is_degenerate_map_warning`), for comparison.md's
    summary: the warnings' section lists each message, not which lines collapsed."""
    collapsed: dict[str, dict[str, int]] = {}
    for row in rows:
        if row.get("status") != "ok" or not any(map(is_degenerate_map_warning,
                                                    read_warnings(row.get(WARNINGS)))):  # fmt: skip
            continue
        house_type = SYNTHETIC if row["data_kind"] == "synthetic" else PUBLIC
        by_line = collapsed.setdefault(house_type, {})
        by_line[str(row["variant"])] = by_line.get(str(row["variant"]), 0) + 1
    return collapsed


def run_comparison(
    out: str | os.PathLike[str],
    settings: ComparisonSettings,
    report: Callable[[str], None] = report_nothing,
    *,
    workers: int = 1,
    retry_failed: bool = False,
    rerun_stale: bool = False,
) -> dict[str, object]:
    """Run the cells of :func:`comparison_study` that ``out`` does not hold yet (``workers``
    > 1: on a Dask LocalCluster; times are then measured beside other fits), then write
    ``comparison.json``, ``comparison.md`` and one figure per house type
    (``comparison_{synthetic,public}.png``) from ``out/results.csv``. Returns the summary
    written to the JSON, with ``failed``: the cells that failed (left out of it).
    ``rerun_stale``: also run the finished cells other spcopyro source computed."""
    out = Path(out)
    keys, notes = available_variants(settings.variants, report)
    study = comparison_study(settings, keys)
    kinds = {d.kind for d in study.data}
    if SYNTHETIC in settings.house_types and "synthetic" not in kinds:
        notes.append(f"{SYNTHETIC} houses skipped: no seeds")
    if PUBLIC in settings.house_types and "public" not in kinds:
        notes.append(f"{PUBLIC} houses skipped: the public dataset was not found")
    run = run_study(
        study, out, workers=workers, retry_failed=retry_failed, rerun_stale=rerun_stale,
        report=report, root=settings.dataset_root,
        describe=plan_lines,  # before the first fit: the scale
    )  # fmt: skip
    rows = read_table(out / TABLE)
    records = records_of_rows(rows)
    for house_type, by_variant in records.items():  # every available variant, as before
        records[house_type] = {key: by_variant.get(key, []) for key in keys}
    notes += failed_cells(rows)  # comparison.md named no failed fit
    summary = summarise(records, settings, notes, run.seconds, run.cached)
    summary["workers"] = workers
    summary["load_average_at_end"] = list(os.getloadavg())
    summary["cpus"] = os.cpu_count()  # the load reads against it
    summary["one_concept_maps"] = one_concept_maps(rows)
    # comparison.md, written once with the cells' warnings (listed as report.md lists them)
    written = write_report(out, summary, finish=lambda text: with_warnings(text, rows))
    figures = [p for p in written if p.suffix == ".png"]
    remove_stale(out, [f"comparison_{kind}.png" for kind in (SYNTHETIC, PUBLIC)], figures)
    summary["failed"] = sum(1 for r in rows if r.get("status") != "ok")
    return summary
