r"""The ablation of issue #14 ("Evidence required"): every variant on dense, sparse and other
synthetic houses and on the public houses, beside the baselines (C) SpCoA and (F) geometry.

For each row (a :class:`~spcopyro.experiments.ablation_variants.Variant` of SpCoMapping, or a
baseline of :mod:`spcopyro.experiments.methods`) x house x seed, one job (:func:`run_job`):

* **synthetic houses** (:data:`SYNTHETIC_HOUSES`; house seed = fit seed): the ARI of the map
  against the truth (:func:`~spcopyro.metrics.adjusted_rand_index`), the matching rate (eq. 18,
  places by eq. 19 with p(C) = pi, and with the area prior), the ARI of the same fit with the
  observations switched off (``use_images = use_words = False``, same seed: what the map would
  be from the MRF alone) and the ARI between the two maps (how much the data moved the map);
* **public houses** (no drawn truth): the fit on two trials, the third held out (trial
  ``seed mod 3``): held-out word prediction (top-1 / top-3 / mean rank,
  :func:`~spcopyro.metrics.heldout_word_prediction`) and localisation (mean distance to the
  named region, :func:`~spcopyro.metrics.heldout_localisation`), the ARI between that map and
  the map fitted with the observations off;
* everywhere: the concepts holding >= 1 % of the free cells (public houses: next to the
  paper's Table 2 counts, :data:`TABLE2_CATEGORIES`), the top words of the largest concepts
  that hold an utterance and whether the top word is a place word, the fit's seconds (wall
  clock and CPU time of the process: on a shared machine the CPU time is what to plan with).

:func:`run_ablation` runs the jobs (in a process pool with ``workers`` > 1, each process with
one torch thread), then :mod:`spcopyro.experiments.ablation_report` aggregates them (mean +- sd
over seeds) into ``ablation.md``, ``ablation.json`` and ``ablation.png``.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from spcopyro.data import House, list_houses, load_house, place_observations
from spcopyro.data.model_grid import model_house
from spcopyro.experiments.ablation_report import TABLE2_CATEGORIES, settings_json, write_report
from spcopyro.experiments.ablation_variants import Variant, parse_variant
from spcopyro.experiments.methods import RunSettings, fit_method
from spcopyro.experiments.table import heldout_folds
from spcopyro.fit.house import fit_house
from spcopyro.metrics import (
    SpCoSemanticMap,
    adjusted_rand_index,
    heldout_localisation,
    heldout_word_prediction,
    matching_rate,
)
from spcopyro.synthetic import HouseSpec, lexicon_for, make_house

__all__ = [
    "BASELINES",
    "DEFAULT_VARIANTS",
    "PAPER_PLACE_WORDS",
    "QUICK_HOUSES",
    "SYNTHETIC_HOUSES",
    "TABLE2_CATEGORIES",
    "AblationSettings",
    "Job",
    "jobs_of",
    "run_ablation",
    "run_job",
    "settings_json",
]

SYNTHETIC_HOUSES: dict[str, HouseSpec] = {
    "dense": HouseSpec(),
    "sparse": HouseSpec.public_like(),
    "dense-large": HouseSpec.scaled(90, 120),
    "sparse-small": HouseSpec.public_like(height=120, width=125, num_rooms=3),
    "open-plan": HouseSpec.open_plan(),
}
"""The synthetic settings: ``dense`` is the default house (60 x 80 cells at 0.1 m, 6 regions,
4.9 % of the free cells observed); ``sparse`` is :meth:`HouseSpec.public_like` (as sparse as the
public houses: 0.05 m cells, ~23,500 free, ~70 observed, 7 regions); ``dense-large`` is
:meth:`HouseSpec.scaled` (90 x 120: 10 rooms, 12 regions, 12 categories, ~9,000 free cells);
``sparse-small`` a public-like house of 3 rooms (4 regions, ~13,000 free cells, ~40 observed);
``open-plan`` is :meth:`HouseSpec.open_plan` (public-like, 65 % of it one walled space holding
living, dining and kitchen side by side, plus 3 small walled rooms: 6 regions, ~23,650 free
cells, ~60 observed), where cutting at doors, (F), scores ARI 0.43 (seeds 0-4)."""

QUICK_HOUSES: dict[str, HouseSpec] = {
    "dense": HouseSpec.scaled(45, 60),
    "sparse": HouseSpec.public_like(height=70, width=70, num_rooms=2),
}
"""Small houses for ``--quick`` (smoke runs and tests)."""

PAPER_PLACE_WORDS = frozenset(
    ("bedroom", "shower", "kitchen", "entrance", "living", "dining", "closet", "corridor", "parlor")
)
"""The place names of the paper's Table 3 (its words that are Places205 classes); the others
(window, tree, shelf, ..., door) name objects."""

BASELINES = ("C-spcoa", "F-geometry")
"""Baseline rows (keys of :data:`spcopyro.experiments.methods.REGISTRY`)."""

DEFAULT_VARIANTS: tuple[str, ...] = (
    "paper-dp:preset=paper-dp",
    "orig-g3:preset=original-code,gamma=3",
    "paper-dp+sw:preset=paper-dp,cluster_moves=0.2",
)
"""Variants that exist today (the coordinator adds those of hyper, merge, words, footprint)."""

MIN_SHARE = 0.01
"""A concept counts when it holds at least this share of the free cells."""
TOP_CONCEPTS = 3
"""Top words are listed for this many of the largest concepts that hold an utterance."""


@dataclass(frozen=True)
class AblationSettings:
    """What :func:`run_ablation` runs."""

    variants: tuple[Variant, ...] = field(
        default_factory=lambda: tuple(parse_variant(text) for text in DEFAULT_VARIANTS)
    )
    baselines: tuple[str, ...] = BASELINES
    synthetic: tuple[str, ...] = tuple(SYNTHETIC_HOUSES)
    """Keys of :attr:`houses` to run."""
    houses: dict[str, HouseSpec] = field(default_factory=lambda: dict(SYNTHETIC_HOUSES))
    seeds: int = 10
    """Synthetic seeds 0 .. seeds - 1 (house and fit)."""
    public_seeds: int = 3
    """Seeds per public house; seed s holds out trial s mod (number of trials)."""
    dataset_root: Path | None = None
    public_houses: tuple[str, ...] | None = None
    """None: every house of the dataset."""
    sweeps: int = 1000
    spcoa_iterations: int = 100
    observations_off: bool = True
    """Also fit every variant with the observations switched off."""
    workers: int = 1
    command: str = ""

    @classmethod
    def quick(cls, **changes: object) -> AblationSettings:
        """A smoke run: two small houses, 2 seeds, 30 sweeps, 1 public house and seed."""
        values: dict[str, object] = dict(
            houses=dict(QUICK_HOUSES), synthetic=tuple(QUICK_HOUSES), seeds=2, public_seeds=1,
            sweeps=30, spcoa_iterations=5,
        )  # fmt: skip
        values.update(changes)
        return cls(**values)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Job:
    """One row x house x seed."""

    row: str
    variant: Variant | None  # None: a baseline
    house: str  # a synthetic setting or a public house's name
    public: bool
    seed: int
    spec: HouseSpec | None = None  # synthetic only
    house_path: str | None = None  # public only
    sweeps: int = 1000
    spcoa_iterations: int = 100
    observations_off: bool = True


def jobs_of(settings: AblationSettings) -> list[Job]:
    """Every job of a run, synthetic first, in row order within each house and seed."""
    jobs = []
    rows: list[tuple[str, Variant | None]] = [(v.name, v) for v in settings.variants]
    rows += [(b, None) for b in settings.baselines]
    common = dict(
        sweeps=settings.sweeps, spcoa_iterations=settings.spcoa_iterations,
        observations_off=settings.observations_off,
    )  # fmt: skip
    for name in settings.synthetic:
        if name not in settings.houses:
            raise ValueError(
                f"unknown synthetic house {name!r}; choose from {list(settings.houses)}"
            )
        for seed in range(settings.seeds):
            for row, variant in rows:
                jobs.append(
                    Job(row, variant, name, False, seed, spec=settings.houses[name], **common)
                )
    root = settings.dataset_root
    if root is not None:
        names = settings.public_houses or tuple(list_houses(root))
        for name in names:
            for seed in range(settings.public_seeds):
                for row, variant in rows:
                    path = str(Path(root) / name)
                    jobs.append(Job(row, variant, name, True, seed, house_path=path, **common))
    return jobs


def _free_labels(model: object, house: House) -> np.ndarray:
    """[N] the label of every free cell (free-index order)."""
    return model.label_image()[house.grid.free]  # type: ignore[attr-defined]


def concepts_over(labels: np.ndarray, share: float = MIN_SHARE) -> int:
    """The number of labels holding at least ``share`` of the cells ``labels`` ([N])."""
    sizes = np.bincount(labels[labels >= 0])
    return int((sizes >= share * labels.size).sum())


def _place_words(house: House) -> frozenset[str]:
    if house.category_names is None:
        return PAPER_PLACE_WORDS
    return frozenset(lexicon_for(name).name_word for name in house.category_names)


def _top_words(result: object, house: House) -> tuple[list[list[tuple[str, float]]], float]:
    """The top words of the largest concepts holding an utterance, and the share of them whose
    top word is a place word (nan when none holds an utterance)."""
    cells, _, unplaced = place_observations(
        house.grid,
        house.observations.word_xy,
        result.preparation.snap_distance,  # type: ignore[attr-defined]
    )
    labels = result.labels  # type: ignore[attr-defined]
    heard = np.unique(labels[cells[~unplaced]])
    sizes = np.bincount(labels, minlength=int(labels.max()) + 1)
    largest = heard[np.argsort(-sizes[heard], kind="stable")][:TOP_CONCEPTS]
    words = [result.top_words(int(c), 3) for c in largest]  # type: ignore[attr-defined]
    places = _place_words(house)
    share = float(np.mean([bool(w) and w[0][0] in places for w in words])) if words else np.nan
    return [[(str(k), round(float(p), 3)) for k, p in w] for w in words], share


def _fit_variant(job: Job, house: House, num_categories: int | None, **extra: object):
    assert job.variant is not None
    variant = job.variant
    settings = variant.spco_settings(num_categories, **extra)
    start, cpu = time.perf_counter(), time.process_time()
    result = fit_house(
        house, settings, method=variant.method, options=variant.method_options(),
        sweeps=job.sweeps, seed=job.seed, progress=False, threads=1, **variant.fit_kwargs(),
    )  # fmt: skip
    return result, time.perf_counter() - start, time.process_time() - cpu


def _load(job: Job) -> House:
    if job.public:
        assert job.house_path is not None
        return load_house(job.house_path)
    return make_house(seed=job.seed, spec=job.spec, name=job.house)


def run_job(job: Job) -> dict[str, object]:
    """Fit one row to one house with one seed; the record of its scores (module docstring)."""
    torch.set_num_threads(1)
    house = _load(job)
    record: dict[str, object] = {
        "row": job.row, "house": job.house, "public": job.public, "seed": job.seed,
        "baseline": job.variant is None, "free_cells": int(house.grid.num_free),
    }  # fmt: skip
    test = None
    if job.public:
        num_categories = TABLE2_CATEGORIES.get(job.house)
        folds = list(heldout_folds(house))
        _, held, house, test = folds[job.seed % len(folds)]
        record["held_out_trial"] = held
    else:
        assert house.category_names is not None
        num_categories = len(house.category_names)
    result = None
    if job.variant is None:
        start, cpu = time.perf_counter(), time.process_time()
        fitted = fit_method(
            job.row, house, RunSettings(sweeps=job.sweeps, spcoa_iterations=job.spcoa_iterations),
            seed=job.seed, num_categories=num_categories, public=job.public,
        )  # fmt: skip
        model = fitted.model
        record["seconds"] = time.perf_counter() - start
        record["cpu_seconds"] = time.process_time() - cpu
    else:
        # A variant with a model grid (cell_size) is scored on that grid: its result lives there.
        cell_size = job.variant.spco_settings(num_categories).data.cell_size
        house = model_house(house, cell_size)
        result, record["seconds"], record["cpu_seconds"] = _fit_variant(job, house, num_categories)
        model = SpCoSemanticMap(result)
        record["concepts"] = int(len(result.concepts_in_use()))
        record["top_words"], record["place_top_share"] = _top_words(result, house)
    labels = _free_labels(model, house)  # [N]
    record["concepts_1pct"] = concepts_over(labels)
    if job.public:
        assert test is not None
        words = heldout_word_prediction(model, test)
        places = heldout_localisation(model, test)
        record.update(top1=words.top1, top3=words.top3, mean_rank=words.mean_rank,
                      distance_m=places.mean_distance, inside_rate=places.inside_rate)  # fmt: skip
    else:
        truth = house.truth
        assert truth is not None and house.category_names is not None
        record["ari"] = adjusted_rand_index(model.label_image(), truth)
        record["matching_rate"] = matching_rate(model, truth, house.category_names).value
        if result is not None:
            area = SpCoSemanticMap(result, prior="area")
            record["matching_rate_area"] = matching_rate(area, truth, house.category_names).value
    if result is not None and job.observations_off:
        off, record["seconds_off"], record["cpu_seconds_off"] = _fit_variant(
            job, house, num_categories, use_images=False, use_words=False
        )
        off_image = off.label_image()
        record["ari_on_off"] = adjusted_rand_index(model.label_image(), off_image)
        record["concepts_1pct_off"] = concepts_over(off_image[house.grid.free])
        if not job.public:
            record["ari_off"] = adjusted_rand_index(off_image, house.truth)
    return record


def _run_jobs(
    jobs: list[Job], workers: int, report: Callable[[str], None]
) -> Iterator[dict[str, object]]:
    def line(record: dict[str, object], done: int) -> str:
        score = record.get("ari", record.get("top1"))
        name = "ARI" if "ari" in record else "top-1"
        return (
            f"[{done}/{len(jobs)}] {record['house']} seed {record['seed']} {record['row']}: "
            f"{name} {score:.3f}, concepts >= 1% {record['concepts_1pct']} "
            f"({record['seconds']:.1f} s)"
        )

    if workers <= 1:
        for done, job in enumerate(jobs, 1):
            record = run_job(job)
            report(line(record, done))
            yield record
        return
    context = multiprocessing.get_context("spawn")  # no forked torch / numba thread pools
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context) as pool:
        futures = [pool.submit(run_job, job) for job in jobs]
        for done, future in enumerate(concurrent.futures.as_completed(futures), 1):
            record = future.result()
            report(line(record, done))
            yield record


def run_ablation(
    out: str | os.PathLike[str],
    settings: AblationSettings,
    report: Callable[[str], None] = lambda message: None,
) -> dict[str, object]:
    """Run every job, write ``ablation.md``, ``ablation.json`` and ``ablation.png`` into
    ``out``; returns the summary written to ``ablation.json``."""
    jobs = jobs_of(settings)
    start = time.perf_counter()
    order = {(j.row, j.house, j.seed): k for k, j in enumerate(jobs)}
    records = sorted(
        _run_jobs(jobs, settings.workers, report),
        key=lambda r: order[(r["row"], r["house"], r["seed"])],  # type: ignore[index]
    )
    seconds = time.perf_counter() - start
    return write_report(Path(out), settings, records, seconds)
