"""Baseline (E): every free cell takes the word of the nearest utterance.

The nearest-neighbour comparison method of the SpCoMapping paper (Katsumata et al. 2019,
"Semantic Mapping Based on Spatial Concepts for Grounding Words Related to Places in Daily
Environments", Frontiers in Robotics and AI 6:31, Table 4, method E): no learning at all, the
map is the Voronoi diagram of the utterance positions, each cell labelled with a word.

* Utterances are placed as in fitting (:func:`spcopyro.data.place_observations`); those farther
  than ``snap_distance`` from free space take no part and are counted in ``notes``. The others
  keep their exact world positions.
* An utterance's word is its **last** token. Single-word utterances (the public dataset) are
  unaffected; in sentences the place is usually named last ("here is the kitchen", "this is
  the bedroom"), while the first token is a filler ("here", "this", "there").
* Each free cell's centre takes the word of the nearest utterance position (Euclidean distance,
  through walls; ``scipy.spatial.cKDTree``). Several utterances at exactly the same position:
  the later one counts.
* Labels are vocabulary indices (the vocabulary is every token of the observations, fillers
  included, so any held-out token the fitted trials contain can be ranked).
* ``region(word)`` = the cells labelled with that word (empty if it labels none);
  ``p(word | cell)`` is one-hot at the cell's word with epsilon smoothing,
  ``(1[word = label] + eps) / (1 + V eps)`` (the identity table of
  :class:`~spcopyro.results.semantic_map.TabularSemanticMap`), so every word has a rank.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spcopyro.data import DEFAULT_SNAP_DISTANCE, Observations, place_observations
from spcopyro.maps import OccupancyGrid
from spcopyro.results.semantic_map import TabularSemanticMap

__all__ = ["nearest_word_map"]


def nearest_word_map(
    grid: OccupancyGrid,
    observations: Observations,
    *,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    smoothing: float = 1e-3,
) -> TabularSemanticMap:
    """Baseline (E): the word of the nearest utterance in every free cell (module docstring).

    Raises:
        ValueError: no utterance lies on (or within ``snap_distance`` of) free space, or the map
            has no free cell.
    """
    if grid.num_free == 0:
        raise ValueError(f"nearest_word_map: map {grid.source or grid!r} has no free cell")
    vocabulary = observations.vocabulary  # [V]
    index = {word: v for v, word in enumerate(vocabulary)}
    _, _, unplaced = place_observations(grid, observations.word_xy, snap_distance)  # [U]
    keep = np.flatnonzero(~unplaced)  # [U']
    if keep.size == 0:
        raise ValueError(
            f"nearest_word_map: none of the {observations.num_utterances} utterances lies within "
            f"{snap_distance} m of free space on map {grid.source or grid!r}"
        )
    last_word = np.array(
        [index[tokens[-1]] for tokens in observations.utterances], dtype=np.int64
    )  # [U]
    positions = observations.word_xy[keep]  # [U', 2]
    words = last_word[keep]  # [U']
    # One utterance per distinct position, the latest: np.unique on the reversed order keeps
    # each position's first occurrence there, i.e. its last one here.
    _, first_reversed = np.unique(positions[::-1], axis=0, return_index=True)
    latest = keep.size - 1 - first_reversed  # [P]
    tree = cKDTree(positions[latest])
    _, nearest = tree.query(grid.cell_to_world(grid.free_cells))  # [N]
    labels = np.full(grid.shape, -1, dtype=np.int64)  # [H, W]
    labels[grid.free] = words[latest][nearest]
    return TabularSemanticMap(
        grid=grid,
        vocabulary=vocabulary,
        labels=labels,
        word_counts=np.eye(len(vocabulary)),
        smoothing=smoothing,
        name="nearest",
        notes=(
            f"{keep.size} of {observations.num_utterances} utterances used; "
            f"{int(unplaced.sum())} farther than {snap_distance:g} m from free space left out",
        ),
    )
