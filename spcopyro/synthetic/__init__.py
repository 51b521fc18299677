"""Seeded synthetic houses with known ground truth: the package's embedded default data set.

:func:`make_house` draws a complete :class:`~spcopyro.data.House` from a seed and a
:class:`HouseSpec`: an occupancy grid, a ground-truth spatial category for every free cell, and
what a robot touring the house observed (place-class image histograms and utterances at world
positions). The same seed and spec always give the same house; different seeds give different
houses. :func:`write_synthetic` stores it in the public dataset's on-disk layout (plus
``truth.npy`` and ``categories.json``) so every loader and command can read it.

Modules (the names below are re-exported here, so ``from spcopyro.synthetic import X`` works for
them; not everything public is, see the end):

* :mod:`~spcopyro.synthetic.lexicon`: the words per category (:data:`CATEGORY_LEXICON`,
  :func:`lexicon_for`), sentence templates and :data:`FILLER_WORDS`.
* :mod:`~spcopyro.synthetic.spec`: :class:`HouseSpec` (every knob, validated),
  :class:`HouseSpecError`, sizes and :meth:`HouseSpec.scaled` for benchmarks,
  :meth:`HouseSpec.public_like` (as sparse as the public houses), :meth:`HouseSpec.open_plan`
  (public-like, most of it one open-plan space of three categories).
* :mod:`~spcopyro.synthetic.statistics`: :func:`house_statistics` (free and observed cells,
  density, images, utterances, tour) and :func:`statistics_table`, public and synthetic alike.
* :mod:`~spcopyro.synthetic.floor_plan`: how a house is drawn, steps 1-3: rooms by binary space
  partitioning with doorways, open-plan rooms, ground-truth categories per region.
* :mod:`~spcopyro.synthetic.house`: steps 4-6: the robot's tour, image features and utterances;
  :func:`make_house` and :func:`write_synthetic`.

Not re-exported, among others (import them from their module):
:mod:`~spcopyro.synthetic.floor_plan`'s ``FloorPlan`` and ``floor_plan``,
:mod:`~spcopyro.synthetic.house`'s ``tour_observations`` (what a house simulated on a real map
and the open-plan scores take of a synthetic house).
"""

from spcopyro.synthetic.house import make_house, write_synthetic
from spcopyro.synthetic.lexicon import (
    CATEGORY_LEXICON,
    DEFAULT_CATEGORY_NAMES,
    FILLER_WORDS,
    OPEN_PLAN_CATEGORIES,
    CategoryLexicon,
    lexicon_for,
)
from spcopyro.synthetic.spec import HouseSpec, HouseSpecError
from spcopyro.synthetic.statistics import HouseStatistics, house_statistics, statistics_table

__all__ = [
    "CATEGORY_LEXICON",
    "DEFAULT_CATEGORY_NAMES",
    "FILLER_WORDS",
    "OPEN_PLAN_CATEGORIES",
    "CategoryLexicon",
    "HouseSpec",
    "HouseSpecError",
    "HouseStatistics",
    "house_statistics",
    "lexicon_for",
    "make_house",
    "statistics_table",
    "write_synthetic",
]
