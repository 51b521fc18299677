r"""The ablation of issue #14 ("Evidence required"): every variant on dense, sparse and other
synthetic houses and on the public houses, beside the baselines (C) SpCoA and (F) geometry.

This module holds what the ablation *is*: its synthetic settings (:data:`SYNTHETIC_HOUSES`),
default rows, options (:class:`AblationSettings`) and the scorers only it uses
(:func:`concepts_over`, :func:`largest_share`, :func:`top_words`). It runs as a study (issue 26):
:func:`spcopyro.study.ablation.run_ablation` fits each row x house x seed as a cell of the
study engine (shipped as ``spcopyro/study/studies/ablation.toml``), scored by
:func:`spcopyro.study.evaluate.run_cell`:

* **synthetic houses** (house seed = fit seed): the ARI of the map against the truth
  (:func:`~spcopyro.metrics.adjusted_rand_index`), the matching rate (eq. 18, places by eq. 19
  with p(C) = pi, and with the area prior), the ARI of the same fit with the observations
  switched off (``use_images = use_words = False``, same seed: what the map would be from the
  MRF alone) and the ARI between the two maps (how much the data moved the map);
* **public houses** (no drawn truth): the fit on two trials, the third held out (trial
  ``seed mod 3``): held-out word prediction (top-1 / top-3 / mean rank,
  :func:`~spcopyro.metrics.heldout_word_prediction`) and localisation (mean distance to the
  named region, :func:`~spcopyro.metrics.heldout_localisation`), the ARI between that map and
  the map fitted with the observations off;
* everywhere: the concepts holding >= 1 % of the free cells (public houses: next to the
  paper's Table 2 counts, :data:`TABLE2_CATEGORIES`), the top words of the largest concepts
  that hold an utterance and whether the top word is a place word, the fit's seconds (wall
  clock and CPU time of the process: on a shared machine the CPU time is what to plan with).

:mod:`spcopyro.experiments.ablation_report` aggregates the records (mean +- sd over seeds) into
``ablation.md``, ``ablation.json`` and ``ablation.png``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from spcopyro.data import House, place_observations
from spcopyro.experiments.ablation_report import TABLE2_CATEGORIES, settings_json
from spcopyro.experiments.ablation_variants import Variant, parse_variant
from spcopyro.results.concept_words import listed_top_words
from spcopyro.synthetic import HouseSpec, lexicon_for

__all__ = [
    "BASELINES",
    "DEFAULT_VARIANTS",
    "PAPER_PLACE_WORDS",
    "QUICK_HOUSES",
    "SYNTHETIC_HOUSES",
    "TABLE2_CATEGORIES",
    "AblationSettings",
    "concepts_over",
    "largest_share",
    "settings_json",
    "top_words",
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

    def __post_init__(self) -> None:
        """Every row's name is its own: a variant named like a baseline of the run (``--variant
        C-spcoa:gamma=3``) ran both and then failed drawing the tables (KeyError), the two
        rows' records pooled under one name."""
        names = [v.name for v in self.variants]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"variant names must differ: {', '.join(twice)} given twice")
        clash = [n for n in names if n in self.baselines]
        if clash:
            rows = ", ".join(self.baselines)
            raise ValueError(f"variant {clash[0]!r}: the name of a baseline row of the run "
                             f"({rows}); give the variant another name")  # fmt: skip

    @classmethod
    def quick(cls, **changes: object) -> AblationSettings:
        """A smoke run: two small houses, 2 seeds, 30 sweeps, 1 public house and seed."""
        values: dict[str, object] = dict(
            houses=dict(QUICK_HOUSES), synthetic=tuple(QUICK_HOUSES), seeds=2, public_seeds=1,
            sweeps=30, spcoa_iterations=5,
        )  # fmt: skip
        values.update(changes)
        return cls(**values)  # type: ignore[arg-type]


def concepts_over(labels: np.ndarray, share: float = MIN_SHARE) -> int:
    """The number of labels holding at least ``share`` of the cells ``labels`` ([N])."""
    sizes = np.bincount(labels[labels >= 0])
    return int((sizes >= share * labels.size).sum())


def largest_share(labels: np.ndarray) -> float:
    """The largest label's share of the labelled cells of ``labels`` ([N], -1: none); nan
    when no cell is labelled."""
    sizes = np.bincount(labels[labels >= 0])
    return float(sizes.max() / sizes.sum()) if sizes.sum() else float("nan")


def _place_words(house: House) -> frozenset[str]:
    if house.category_names is None:
        return PAPER_PLACE_WORDS
    return frozenset(lexicon_for(name).name_word for name in house.category_names)


def top_words(result: object, house: House) -> tuple[list[list[tuple[str, float]]], float]:
    """The top words of the largest concepts holding an utterance, as ``fit`` lists them
    (:func:`~spcopyro.results.concept_words.listed_top_words`: none for a concept of a fit that
    did not model its words, whose words are all tied at the prior's), and the share of those
    listing words whose top word is a place word (nan when none holds an utterance or none lists
    words).
    ``house`` on the model's grid (:func:`spcopyro.data.model_grid.model_house`), as the fit
    saw it."""
    cells, _, unplaced = place_observations(
        house.grid,
        house.observations.word_xy,
        result.preparation.snap_distance,  # type: ignore[attr-defined]
    )
    labels = result.labels  # type: ignore[attr-defined]
    heard = np.unique(labels[cells[~unplaced]])
    sizes = np.bincount(labels, minlength=int(labels.max()) + 1)
    largest = heard[np.argsort(-sizes[heard], kind="stable")][:TOP_CONCEPTS]
    words = [listed_top_words(result, int(c), 3) for c in largest]
    places = _place_words(house)
    listed = [w for w in words if w]
    share = float(np.mean([w[0][0] in places for w in listed])) if listed else np.nan
    return [[(str(k), round(float(p), 3)) for k, p in w] for w in words], share
