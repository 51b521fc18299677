"""The ablation (issue #14) as a study (issue 26 item 1): ``spcopyro ablation`` runs the study
engine on the shipped ``ablation.toml`` (``ablation_quick.toml`` with ``--quick``).

The ablation's grid is its variants and baselines x its synthetic settings (seeds
0 .. seeds - 1, house and fit) and public houses (seeds 0 .. public_seeds - 1, seed s holding
out trial s mod 3) -- a study whose sources carry their own ``seeds`` and which fits every
variant a second time with the observations off (``observations_off = true``). The command's
options are those of :class:`~spcopyro.experiments.ablation.AblationSettings`:

* :func:`ablation_settings` reads them from a study (the shipped file gives the defaults);
* :func:`ablation_study` is the study of a settings object (the same cells, by key, as the file
  it came from: ``tests/test_ablation.py`` checks it);
* :func:`run_ablation` runs that study (cached and resumable in ``out``: ``cells/``,
  ``results.csv``, ``report.md``) and draws ``ablation.md``, ``ablation.json`` and
  ``ablation.png`` from ``results.csv`` alone (:func:`records_of_rows`,
  :func:`spcopyro.experiments.ablation_report.write_report`).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from spcopyro.data import list_houses
from spcopyro.experiments.ablation import AblationSettings
from spcopyro.experiments.ablation_report import SCORES, write_report
from spcopyro.experiments.table import failed_cells
from spcopyro.study import STUDIES
from spcopyro.study.cells import BASELINE_METHOD
from spcopyro.study.report import with_warnings
from spcopyro.study.run import run_study
from spcopyro.study.spec import DataSource, Study
from spcopyro.study.table import TABLE, read_table
from spcopyro.synthetic import HouseSpec

__all__ = [
    "ABLATION",
    "ABLATION_QUICK",
    "ablation_settings",
    "ablation_study",
    "records_of_rows",
    "run_ablation",
    "spec_options",
]

ABLATION = STUDIES / "ablation.toml"
"""The ablation's default grid (``spcopyro ablation``)."""
ABLATION_QUICK = STUDIES / "ablation_quick.toml"
"""Its smoke run (``spcopyro ablation --quick``)."""

PUBLIC_ONLY = frozenset(("ari", "matching_rate", "ari_off"))
"""Scores the ablation does not report on a public house (its region truth is the study's)."""


def _count(seeds: tuple[int, ...] | None, study: Study, what: str) -> int:
    seeds = study.seeds if seeds is None else seeds
    if tuple(seeds) != tuple(range(len(seeds))):
        raise ValueError(f"{study.source}: the ablation's {what} seeds are 0 .. n-1, got {seeds}")
    return len(seeds)


def ablation_settings(
    study: Study, dataset_root: str | os.PathLike[str] | None = None, **changes: object
) -> AblationSettings:
    """The ablation's settings of ``study`` (variants, baselines, sources, seeds, sweeps) with
    ``changes``; its public houses are read under ``dataset_root`` (None: none run)."""
    sweeps = dict(study.sweeps)
    if set(sweeps) != {"*"} or study.methods:
        raise ValueError(f"{study.source}: the ablation gives every fit the same sweeps and "
                         "each variant its own method")  # fmt: skip
    synthetic = [d for d in study.data if d.kind == "synthetic"]
    public = [d for d in study.data if d.kind == "public"]
    other = [d.name for d in study.data if d.kind not in ("synthetic", "public") or d.house_seed]
    if other:
        raise ValueError(f"{study.source}: the ablation takes synthetic houses drawn with the "
                         f"cell's seed and public houses, not {other}")  # fmt: skip
    values: dict[str, object] = dict(
        variants=study.variants, baselines=study.baselines,
        houses={d.name: d.house_spec() for d in synthetic},
        synthetic=tuple(d.name for d in synthetic),
        seeds=max((_count(d.seeds, study, "synthetic") for d in synthetic), default=0),
        public_seeds=max((_count(d.seeds, study, "public") for d in public), default=0),
        public_houses=tuple(d.target for d in public),
        dataset_root=None if dataset_root is None else Path(dataset_root),
        sweeps=sweeps["*"], spcoa_iterations=study.spcoa_iterations,
        observations_off=study.observations_off,
    )  # fmt: skip
    values.update(changes)
    return AblationSettings(**values)  # type: ignore[arg-type]


def spec_options(spec: HouseSpec) -> tuple[tuple[str, object], ...]:
    """The fields of ``spec`` that differ from ``HouseSpec()`` (``HouseSpec(**them) == spec``)."""
    default = HouseSpec()
    return tuple(
        (f.name, getattr(spec, f.name))
        for f in dataclasses.fields(spec)
        if getattr(spec, f.name) != getattr(default, f.name)
    )


def ablation_study(settings: AblationSettings, name: str = "ablation") -> Study:
    """The study of ``settings``: every row on each synthetic setting (seeds
    0 .. ``seeds`` - 1) and each public house under ``dataset_root`` (all of them when
    ``public_houses`` is None; seeds 0 .. ``public_seeds`` - 1, held out)."""
    data = []
    for house in settings.synthetic:
        if house not in settings.houses:
            raise ValueError(
                f"unknown synthetic house {house!r}; choose from {list(settings.houses)}"
            )
        if settings.seeds >= 1:
            spec = spec_options(settings.houses[house])
            seeds = tuple(range(settings.seeds))
            data.append(DataSource(house, "synthetic", "default", spec, seeds=seeds))
    root = settings.dataset_root
    if root is not None and settings.public_seeds >= 1:
        seeds = tuple(range(settings.public_seeds))
        for house in settings.public_houses or tuple(list_houses(root)):
            target = str(Path(root) / house)
            data.append(DataSource(house, "public", target, heldout=True, seeds=seeds))
    return Study(
        name=name, variants=tuple(settings.variants), data=tuple(data),
        sweeps=(("*", settings.sweeps),), baselines=tuple(settings.baselines),
        spcoa_iterations=settings.spcoa_iterations, observations_off=settings.observations_off,
        description=settings.command,
    )  # fmt: skip


def records_of_rows(rows: Sequence[dict[str, object]]) -> list[dict[str, object]]:
    """The ablation's per-job records (as ``ablation.json`` holds them) from ``results.csv``
    rows: the finished cells, their scores of :data:`~.ablation_report.SCORES` that apply."""
    records = []
    for row in rows:
        if row.get("status") != "ok":
            continue
        public = row["data_kind"] == "public"
        record: dict[str, object] = {
            "row": row["variant"], "house": row["data"], "public": public, "seed": row["seed"],
            "baseline": row["method"] == BASELINE_METHOD, "free_cells": row["free_cells"],
        }  # fmt: skip
        if public:
            record["held_out_trial"] = row["held_out_trial"]
        if row.get("top_words"):
            record["top_words"] = json.loads(str(row["top_words"]))
        for score in SCORES:
            if row.get(score) is not None and not (public and score in PUBLIC_ONLY):
                record[score] = row[score]
        records.append(record)
    return records


def run_ablation(
    out: str | os.PathLike[str],
    settings: AblationSettings,
    report: Callable[[str], None] = lambda message: None,
    *,
    retry_failed: bool = False,
    rerun_stale: bool = False,
    name: str = "ablation",
) -> dict[str, object]:
    """Run the cells of :func:`ablation_study` that ``out`` does not hold yet (``settings.workers``
    > 1: on a Dask LocalCluster), then write ``ablation.md``, ``ablation.json`` and
    ``ablation.png`` from ``out/results.csv``; returns the summary written to ``ablation.json``.
    A failed cell is reported and left out of the summary (``failed`` in the returned dict);
    ``name``: the study's (in ``report.md``); ``rerun_stale``: also run the finished cells other
    spcopyro source computed."""
    study = ablation_study(settings, name)
    run = run_study(
        study, out, workers=settings.workers, retry_failed=retry_failed,
        rerun_stale=rerun_stale, report=report, root=settings.dataset_root,
    )  # fmt: skip
    rows = read_table(Path(out) / TABLE)
    # ablation.md, written once with the cells' warnings (listed as report.md lists them)
    summary = write_report(
        Path(out), settings, records_of_rows(rows), run.seconds, run.cached, failed_cells(rows),
        finish=lambda text: with_warnings(text, rows),
    )  # fmt: skip
    summary["failed"] = sum(1 for r in rows if r.get("status") != "ok")
    return summary
