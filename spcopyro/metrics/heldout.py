r"""Scores on a held-out trial: predicting its words, and finding the places they name.

These need no drawn ground truth (the public dataset has none): each held-out utterance is
placed on a free cell as in fitting, then

* :func:`heldout_word_prediction` ranks the vocabulary by the model's p(word | cell) and records
  the true token's rank (:func:`rank_of_truth`) and top-1 / top-3 hits
  (:class:`WordPredictionScores`);
* :func:`heldout_localisation` measures how far each word was said from the region the model
  answers "where is it?" with (:class:`LocalisationScores`).

A "cell" passed to :meth:`~spcopyro.results.semantic_map.SemanticMapModel.word_distribution` is a
free-cell index (``grid.free_index``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from spcopyro.data import DEFAULT_SNAP_DISTANCE, Observations, place_observations
from spcopyro.results.semantic_map import SemanticMapModel, SpCoResultLike, as_semantic_map

__all__ = [
    "TIE_RTOL",
    "LocalisationScores",
    "WordPredictionScores",
    "heldout_localisation",
    "heldout_word_prediction",
    "rank_of_truth",
]

# ---------------------------------------------------------------------------------------------
# Held-out trials
# ---------------------------------------------------------------------------------------------


def _heldout_tokens(
    model: SemanticMapModel, observations: Observations, snap_distance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...], int, int]:
    """Known token occurrences of the placed held-out utterances.

    Returns utterance index ``[n]``, free cell ``[n]``, vocabulary index ``[n]`` of every known
    token occurrence, the sorted distinct unknown tokens, the number of unknown token
    occurrences (of placed utterances) and the number of unplaced utterances.
    """
    cells, _, unplaced = place_observations(model.grid, observations.word_xy, snap_distance)
    vocab_index = {word: v for v, word in enumerate(model.vocabulary)}
    utterance, cell, token, unknown_words = [], [], [], set()
    num_unknown = 0
    for u, tokens in enumerate(observations.utterances):
        if unplaced[u]:
            continue
        for word in tokens:
            v = vocab_index.get(word)
            if v is None:
                unknown_words.add(word)
                num_unknown += 1
            else:
                utterance.append(u)
                cell.append(cells[u])
                token.append(v)
    as_int = lambda values: np.asarray(values, dtype=np.int64)  # noqa: E731
    return (
        as_int(utterance),
        as_int(cell),
        as_int(token),
        tuple(sorted(unknown_words)),
        num_unknown,
        int(unplaced.sum()),
    )


@dataclass(frozen=True, eq=False)
class WordPredictionScores:
    """:func:`heldout_word_prediction`'s answer, one entry per scored token occurrence.

    Ranks are 1-based; ties count at their expected position under random tie breaking.
    """

    ranks: np.ndarray  # [n] float64 expected rank of the true word
    top1_hits: np.ndarray  # [n] float64 P(true word ranked first)
    top3_hits: np.ndarray  # [n] float64 P(true word among the first three)
    vocabulary_size: int
    unknown_tokens: int
    """Token occurrences (of placed utterances) not in the model's vocabulary: not scored."""
    unknown_words: tuple[str, ...]
    unplaced_utterances: int
    """Held-out utterances farther than the snap distance from free space: not scored."""

    @property
    def num_scored(self) -> int:
        return int(self.ranks.size)

    @property
    def mean_rank(self) -> float:
        return float(self.ranks.mean()) if self.ranks.size else float("nan")

    @property
    def top1(self) -> float:
        return float(self.top1_hits.mean()) if self.ranks.size else float("nan")

    @property
    def top3(self) -> float:
        return float(self.top3_hits.mean()) if self.ranks.size else float("nan")

    @classmethod
    def pooled(cls, folds: Sequence[WordPredictionScores]) -> WordPredictionScores:
        """All folds' token occurrences together (a micro average over folds)."""
        if not folds:
            raise ValueError("pooled needs at least one fold")
        return cls(
            ranks=np.concatenate([f.ranks for f in folds]),
            top1_hits=np.concatenate([f.top1_hits for f in folds]),
            top3_hits=np.concatenate([f.top3_hits for f in folds]),
            vocabulary_size=max(f.vocabulary_size for f in folds),
            unknown_tokens=sum(f.unknown_tokens for f in folds),
            unknown_words=tuple(sorted({w for f in folds for w in f.unknown_words})),
            unplaced_utterances=sum(f.unplaced_utterances for f in folds),
        )


TIE_RTOL = 1e-9
"""Scores within this relative difference rank as ties (:func:`rank_of_truth`)."""


def rank_of_truth(
    probabilities: np.ndarray, truth: np.ndarray, ks: Sequence[int] = (1, 3)
) -> tuple[np.ndarray, list[np.ndarray]]:
    r"""Expected rank of the true class and top-k hit probabilities under random tie breaking.

    With g the number of classes more probable than the true one and t the number of other
    classes as probable (equal to a relative :data:`TIE_RTOL`: classes equal in exact
    arithmetic, e.g. words heard nowhere, come out of a vectorised sum a few last bits apart in
    a way that depends on the CPU, so exact comparison made a held-out score differ between
    machines), the true class is equally likely at positions g+1 .. g+t+1:

    .. math::

        \text{rank} = g + 1 + t/2, \qquad P(\text{top-}k) = \min(1, \max(0, (k - g)/(t + 1))).

    Args:
        probabilities: ``[n, V]`` scores (any monotone scale).
        truth: ``[n]`` int index of the true class.

    Returns:
        ``rank [n]`` float64 and a list of ``[n]`` float64 hit probabilities, one per k.
    """
    p = np.asarray(probabilities, dtype=np.float64)  # [n, V]
    t_idx = np.asarray(truth, dtype=np.int64)  # [n]
    true_p = p[np.arange(p.shape[0]), t_idx][:, None]  # [n, 1]
    close = np.isclose(p, true_p, rtol=TIE_RTOL, atol=0.0)  # [n, V]
    greater = ((p > true_p) & ~close).sum(axis=1)  # [n] g
    ties = close.sum(axis=1) - 1  # [n] t
    rank = greater + 1 + ties / 2.0
    hits = [np.clip((k - greater) / (ties + 1.0), 0.0, 1.0) for k in ks]
    return rank.astype(np.float64), hits


def heldout_word_prediction(
    model: SemanticMapModel | SpCoResultLike,
    observations: Observations,
    *,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
) -> WordPredictionScores:
    r"""Predict each held-out word from where it was said.

    Every utterance of ``observations`` (the held-out trial) is placed on a free cell as in
    fitting (:func:`~spcopyro.data.place_observations`, snapping within ``snap_distance``); for
    each of its tokens that the model knows, the model's

    .. math::

        p(\text{word} \mid \text{cell}) = \sum_l p(C_{\text{cell}} = l)\, w_{l,\text{word}}

    (:meth:`~spcopyro.results.semantic_map.SemanticMapModel.word_distribution`) ranks the
    vocabulary,
    and the true token's rank (:func:`rank_of_truth`: 1 = best, ties at their expected position)
    and top-1 / top-3 hits are recorded. Tokens the model does not know and utterances off free
    space are counted in the answer, not scored. A sentence's filler words are tokens like any
    other.
    """
    sem = as_semantic_map(model)
    _, cells, token, unknown_words, num_unknown, num_unplaced = _heldout_tokens(
        sem, observations, snap_distance
    )
    vocabulary_size = len(sem.vocabulary)
    if token.size:
        probabilities = sem.word_distribution(cells)  # [n, V]
        if probabilities.shape != (token.size, vocabulary_size):
            raise ValueError(
                f"word_distribution returned shape {probabilities.shape}, expected "
                f"({token.size}, {vocabulary_size})"
            )
        ranks, (top1, top3) = rank_of_truth(probabilities, token, ks=(1, 3))
    else:
        ranks, top1, top3 = np.empty(0), np.empty(0), np.empty(0)
    return WordPredictionScores(
        ranks=ranks,
        top1_hits=top1,
        top3_hits=top3,
        vocabulary_size=vocabulary_size,
        unknown_tokens=num_unknown,
        unknown_words=unknown_words,
        unplaced_utterances=num_unplaced,
    )


@dataclass(frozen=True, eq=False)
class LocalisationScores:
    """:func:`heldout_localisation`'s answer, one entry per scored token occurrence."""

    distances: np.ndarray  # [n] float64 metres; inf where the word's region is empty
    words: tuple[str, ...]  # [n] the token of each entry
    unknown_tokens: int
    unknown_words: tuple[str, ...]
    unplaced_utterances: int
    # [n] float64: share of the free cells in the region each entry's word names (0 when empty);
    # a distance is read against it, since a region of the whole map is 0 m from everywhere
    region_shares: np.ndarray | None = None

    @property
    def num_scored(self) -> int:
        return int(self.distances.size)

    @property
    def mean_region_share(self) -> float:
        """Mean share of the free cells in the named regions (nan when not recorded or none).

        A small :attr:`mean_distance` says something only when this is small: a map of one
        region names the whole map for every word, and every distance is 0 m.
        """
        if self.region_shares is None or not self.region_shares.size:
            return float("nan")
        return float(self.region_shares.mean())

    @property
    def empty_regions(self) -> int:
        """Entries whose word has an empty region (distance inf; left out of the means)."""
        return int(np.isinf(self.distances).sum())

    @property
    def mean_distance(self) -> float:
        """Mean distance in metres over entries with a non-empty region."""
        finite = self.distances[np.isfinite(self.distances)]
        return float(finite.mean()) if finite.size else float("nan")

    @property
    def median_distance(self) -> float:
        """Median over all entries (an empty region counts as infinitely far)."""
        return float(np.median(self.distances)) if self.distances.size else float("nan")

    @property
    def inside_rate(self) -> float:
        """Share of entries said inside the region their word names (distance 0)."""
        return float((self.distances == 0).mean()) if self.distances.size else float("nan")

    @classmethod
    def pooled(cls, folds: Sequence[LocalisationScores]) -> LocalisationScores:
        """All folds' entries together."""
        if not folds:
            raise ValueError("pooled needs at least one fold")
        return cls(
            distances=np.concatenate([f.distances for f in folds]),
            words=tuple(w for f in folds for w in f.words),
            unknown_tokens=sum(f.unknown_tokens for f in folds),
            unknown_words=tuple(sorted({w for f in folds for w in f.unknown_words})),
            unplaced_utterances=sum(f.unplaced_utterances for f in folds),
            region_shares=(
                None
                if any(f.region_shares is None for f in folds)
                else np.concatenate([f.region_shares for f in folds])  # type: ignore[misc]
            ),
        )


def heldout_localisation(
    model: SemanticMapModel | SpCoResultLike,
    observations: Observations,
    *,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
) -> LocalisationScores:
    """How far each held-out word was said from the region the model answers "where is it?" with.

    Each utterance is placed on a free cell as in :func:`heldout_word_prediction`; for each of its
    known tokens the distance is the Euclidean distance in metres from that cell's centre to the
    centre of the nearest cell of ``region(token)``: 0 when the cell lies in the region, inf
    when the region is empty. Unknown tokens and unplaced utterances are counted, not scored.
    Each entry also records its region's share of the free cells (``region_shares``): a map of
    one region answers every word with the whole map and scores 0 m everywhere, which is not a
    good localisation (the geometry baseline on room1dk6 does that).
    """
    sem = as_semantic_map(model)
    _, cells, token, unknown_words, num_unknown, num_unplaced = _heldout_tokens(
        sem, observations, snap_distance
    )
    grid = sem.grid
    rows, cols = grid.free_cells[cells, 0], grid.free_cells[cells, 1]  # [n]
    distances = np.empty(token.size, dtype=np.float64)  # [n]
    shares = np.zeros(token.size, dtype=np.float64)  # [n]
    for v in np.unique(token):
        word = sem.vocabulary[int(v)]
        region = np.asarray(sem.region(word), dtype=bool)  # [H, W]
        if region.shape != grid.shape:
            raise ValueError(f"region of {word!r} has shape {region.shape}, grid {grid.shape}")
        at = token == v
        shares[at] = np.count_nonzero(region & grid.free) / max(grid.num_free, 1)
        if not region.any():
            distances[at] = np.inf
            continue
        to_region = ndimage.distance_transform_edt(~region, sampling=grid.resolution)  # [H, W]
        distances[at] = to_region[rows[at], cols[at]]
    return LocalisationScores(
        distances=distances,
        words=tuple(sem.vocabulary[int(v)] for v in token),
        unknown_tokens=num_unknown,
        unknown_words=unknown_words,
        unplaced_utterances=num_unplaced,
        region_shares=shares,
    )
