"""Checks of a fitted map against the observations: is the map degenerate? (issue 21, item 5)

A map is *degenerate* when one concept holds most of the free cells while words said at
different places lie inside it: the fit has not separated the places those words name (too
strong a Potts coupling for the data, emissions that the data cannot move, or a chain that
coarsened into one region). :func:`degenerate_map_warning` says so, naming the words;
:func:`house_map_warning` places a house's utterances on the map's cells first, as the fit does.
:func:`spcopyro.fit.house.fit_house` and ``spcopyro fit`` log it (logger ``"spcopyro"``).

The rule (numpy only)::

    share = (cells of the largest concept c) / (free cells)
    warn  if share > DEGENERATE_SHARE
          and, over the utterances placed on c's cells, the mean positions of at least two
              distinct words are at least DEGENERATE_SEPARATION metres apart

Every token of an utterance counts as a word (the word preparation drops none: see
:mod:`spcopyro.data.text`); a word's count is the number of c's utterances that hold it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from spcopyro.config import DEFAULT_PRESET

if TYPE_CHECKING:
    from spcopyro.data import House

__all__ = [
    "MIN_COVERAGE",
    "coverage_warning",
    "DEGENERATE_SEPARATION",
    "DEGENERATE_SHARE",
    "NAMED_WORDS",
    "degenerate_map_warning",
    "house_map_warning",
]

DEGENERATE_SHARE = 0.6
"""Share of the free cells above which the largest concept may be a degenerate map: a house
with rooms of distinct names rarely has one room over 60% of its floor."""
DEGENERATE_SEPARATION = 1.5
"""Metres: two words whose utterances inside the largest concept have mean positions at least
this far apart were said at different places (a room's length; utterances of one spot, rounded
onto a 5 cm grid or snapped 0.25 m, stay well within it)."""
NAMED_WORDS = 8
"""The warning names at most this many words, most heard first."""


def degenerate_map_warning(
    labels: np.ndarray,
    utterance_cells: np.ndarray,
    utterance_xy: np.ndarray,
    utterances: Sequence[Sequence[str]],
    sampled: bool = True,
) -> str | None:
    """A warning when the map is degenerate (see the module docstring), else None.

    Args:
        labels: ``[N]`` int, the concept of every free cell (free-index order).
        utterance_cells: ``[U]`` int, the free cell each utterance was placed on (-1: unplaced;
            :func:`~spcopyro.data.place_observations`).
        utterance_xy: ``[U, 2]`` world positions (metres) of the utterances.
        utterances: ``[U]`` each utterance's tokens.
        sampled: the fit ran the Gibbs sampler (``gibbs``, ``vi-gibbs``), whose split-merge
            moves (``--merge-moves``) it names; else it names ``--method gibbs`` with them
            (``fit`` refuses ``--merge-moves`` with a variational method).

    The message names the concept, its share of the free cells and the words heard inside it
    (most heard first, at most :data:`NAMED_WORDS`, with their counts).
    """
    labels = np.asarray(labels).reshape(-1)  # [N]
    cells = np.asarray(utterance_cells, dtype=np.int64).reshape(-1)  # [U]
    xy = np.asarray(utterance_xy, dtype=np.float64).reshape(-1, 2)  # [U, 2]
    if not (len(cells) == len(xy) == len(utterances)):
        raise ValueError(
            f"utterance_cells ({len(cells)}), utterance_xy ({len(xy)}) and utterances "
            f"({len(utterances)}) must describe the same utterances"
        )
    if labels.size == 0 or len(cells) == 0:
        return None
    if (cells >= labels.size).any():
        raise ValueError(f"utterance_cells must be free indices below {labels.size} (or -1)")
    concepts, sizes = np.unique(labels, return_counts=True)
    largest = int(np.argmax(sizes))
    concept, share = concepts[largest], sizes[largest] / labels.size
    if share <= DEGENERATE_SHARE:
        return None
    inside = np.flatnonzero((cells >= 0) & (labels[np.maximum(cells, 0)] == concept))  # [U_c]
    heard: dict[str, list[int]] = {}  # word -> its utterances inside the concept
    for u in inside:
        for word in dict.fromkeys(utterances[u]):
            heard.setdefault(word, []).append(int(u))
    if len(heard) < 2:
        return None
    means = np.stack([xy[us].mean(axis=0) for us in heard.values()])  # [W, 2]
    apart = np.linalg.norm(means[:, None, :] - means[None, :, :], axis=-1).max()
    if apart < DEGENERATE_SEPARATION:
        return None
    moves = "--merge-moves 0.2" if sampled else "--method gibbs --merge-moves 0.2"
    ranked = sorted(heard.items(), key=lambda item: -len(item[1]))  # stable: first heard first
    named = ", ".join(f"{word} ({len(us)})" for word, us in ranked[:NAMED_WORDS])
    more = len(ranked) - NAMED_WORDS
    if more > 0:
        named += f", and {more} more"
    return (
        f"one concept ({concept}) holds {share:.0%} of the free cells while words said at "
        f"different places (up to {apart:.1f} m apart) lie inside it: {named}; the map does not "
        f"separate the places these words name (try a lower --gamma, {moves} so that regions "
        f"can split, or the default --preset {DEFAULT_PRESET} if the fit used another)"
    )


def house_map_warning(
    labels: np.ndarray, house: House, snap_distance: float, sampled: bool = True
) -> str | None:
    """:func:`degenerate_map_warning` of ``labels`` ``[N]`` on ``house``'s map, its utterances
    placed on free cells as the fit places them (:func:`~spcopyro.data.place_observations`
    with the fit's ``snap_distance``, metres); ``sampled``: as there."""
    from spcopyro.data import place_observations

    observations = house.observations
    if len(observations.utterances) == 0:
        return None
    cells, _, _ = place_observations(house.grid, observations.word_xy, snap_distance)
    return degenerate_map_warning(
        labels, cells, observations.word_xy, observations.utterances, sampled
    )


MIN_COVERAGE = 0.55
"""Share of the free space's extent (per axis) below which the observations' extent makes a
wrong map resolution likely: a tour of the house covers 0.66-0.96 of it on every public and
synthetic house; a map whose resolution is twice too large shrinks the tour to about half."""


def coverage_warning(house: House) -> str | None:
    """A warning when the observations span less than :data:`MIN_COVERAGE` of the free space's
    extent along both axes (issue 22 item 4: a map whose yaml resolution was off by 2x fitted
    without a word): the map's resolution or origin may be wrong, or the robot saw only part of
    the map. None otherwise."""
    grid, obs = house.grid, house.observations
    positions = np.concatenate([obs.image_xy, obs.word_xy])  # [T + U, 2]
    if grid.num_free < 2 or positions.shape[0] < 2:
        return None
    free_xy = grid.cell_to_world(grid.free_cells)  # [N, 2]
    span = np.ptp(free_xy, axis=0)  # [2]
    if not (span > 0).all():
        return None
    covered = np.ptp(positions, axis=0) / span  # [2]
    if (covered >= MIN_COVERAGE).any():
        return None
    return (
        f"the observations span only {covered[0]:.0%} x {covered[1]:.0%} of the free space of "
        f"map {grid.source or ''} (x x y): if the robot toured the whole map, its resolution "
        f"({grid.resolution:g} m) or origin may be wrong"
    )
