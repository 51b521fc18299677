"""Hand-made fitted results whose answers can be worked out by hand (shared by the tests of
"where is X?" and of the figures)."""

from __future__ import annotations

import numpy as np

from spcopyro.config import SpCoConfig
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.results.result import EmissionTable, SpCoResult, Trace

WORDS = ("kitchen", "bed", "sofa")


def two_rooms() -> SpCoResult:
    """A 10 x 31 map split by a wall (column 15): concept 0 fills the left room (150 cells),
    concept 1 the right one (150 cells) but for one cell of concept 2 (a speck). pi is uniform;
    "kitchen" is most probable under the speck, then under the left room."""
    occupancy = np.full((10, 31), FREE, dtype=np.int8)
    occupancy[:, 15] = OCCUPIED
    grid = OccupancyGrid(occupancy=occupancy, resolution=0.1, origin=(0.0, 0.0, 0.0))
    image = np.full(grid.shape, -1)
    image[:, :15] = 0
    image[:, 16:] = 1
    image[5, 22] = 2
    w = np.array([[0.6, 0.2, 0.2], [0.1, 0.6, 0.3], [0.7, 0.15, 0.15]])  # [L, V]
    return SpCoResult(
        grid=grid,
        config=SpCoConfig(num_concepts=3, prior="dirichlet"),
        labels=image[grid.free],  # [N]
        pi=np.full(3, 1 / 3),  # [L]
        emissions=(
            EmissionTable("images", ("0", "1"), np.full((3, 2), 0.5)),  # [L, K]
            EmissionTable("words", WORDS, w),
        ),
        trace=Trace(objective=np.zeros(1), num_concepts=np.array([3]), seconds=np.zeros(1)),
        best_iteration=0,
    )


def one_word_per_concept(grid: OccupancyGrid, labels: np.ndarray, words: tuple[str, ...],
                         num_concepts: int = 4) -> SpCoResult:  # fmt: skip
    """A result on ``grid`` with ``labels`` [N] in which concept l's most probable word is
    ``words[l]`` (0.9 against 0.02 for every other word, renormalised), pi uniform, images
    uninformative: the navigation tests' hand-built houses."""
    w = np.full((num_concepts, len(words)), 0.02)  # [L, V]
    w[np.arange(num_concepts), np.arange(num_concepts)] = 0.9
    w /= w.sum(1, keepdims=True)
    return SpCoResult(
        grid=grid,
        config=SpCoConfig(num_concepts=num_concepts, prior="dirichlet"),
        labels=labels,  # [N]
        pi=np.full(num_concepts, 1 / num_concepts),  # [L]
        emissions=(
            EmissionTable("images", ("0", "1"), np.full((num_concepts, 2), 0.5)),  # [L, K]
            EmissionTable("words", words, w),
        ),
        trace=Trace(
            objective=np.zeros(1), num_concepts=np.array([num_concepts]), seconds=np.zeros(1)
        ),  # fmt: skip
        best_iteration=0,
    )
