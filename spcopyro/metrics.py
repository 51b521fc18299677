r"""Scores of a semantic map: against ground truth, on held-out trials, and across samples.

Every score here takes any method's output through one small interface,
:class:`SemanticMapModel` (a label image, ``p(word | cell)`` over a vocabulary, and the region a
word names), so SpCoMapping (:class:`SpCoSemanticMap` wraps a
:class:`~spcopyro.results.SpCoResult`) and the baselines of :mod:`spcopyro.baselines`
(:class:`TabularSemanticMap`) are scored by the same code.

Scores
------
* :func:`adjusted_rand_index`: ARI of a label image against the ground truth over free cells.
* :func:`matching_rate`: the paper's matching rate for place estimation (eq. 18), the place
  estimated from a word as in eq. (19). See its docstring for the exact definition used.
* :func:`heldout_word_prediction` and :func:`heldout_localisation`: scores on a trial that was
  not fitted, needing no drawn ground truth (the public dataset has none).
* :func:`num_concepts`, :func:`co_assignment`, :func:`chain_ari`, :func:`pairwise_chain_ari`:
  posterior summaries that do not depend on how concepts are numbered (label switching).

Conventions: label images are ``[H, W]`` integer arrays in map-image row order with -1 off free
space (:meth:`spcopyro.results.SpCoResult.label_image`); a "cell" passed to
:meth:`SemanticMapModel.word_distribution` is a free-cell index (``grid.free_index``), the
order every per-free-cell array of the package uses.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from scipy import ndimage
from sklearn.metrics import adjusted_rand_score

from spcopyro.data import DEFAULT_SNAP_DISTANCE, CellCounts, Observations, place_observations
from spcopyro.maps import OccupancyGrid
from spcopyro.results import SpCoResult, UnknownWordError

__all__ = [
    "CoAssignment",
    "LocalisationScores",
    "MatchingRate",
    "SemanticMapModel",
    "SpCoSemanticMap",
    "TabularSemanticMap",
    "WordPredictionScores",
    "adjusted_rand_index",
    "as_semantic_map",
    "chain_ari",
    "co_assignment",
    "heldout_localisation",
    "heldout_word_prediction",
    "matching_rate",
    "num_concepts",
    "pairwise_chain_ari",
    "rank_of_truth",
]

MATCHING_KINDS = ("precision", "recall", "iou")


def adjusted_rand_index(labels: np.ndarray, truth: np.ndarray) -> float:
    """ARI between two [H, W] label images over the cells where the truth is defined (>= 0).

    Invariant to how the concepts are numbered (scikit-learn's implementation).
    """
    if labels.shape != truth.shape:
        raise ValueError(f"label image {labels.shape} and truth {truth.shape} differ in shape")
    mask = truth >= 0
    return float(adjusted_rand_score(truth[mask], labels[mask]))


# ---------------------------------------------------------------------------------------------
# The interface every method is scored through
# ---------------------------------------------------------------------------------------------


@runtime_checkable
class SemanticMapModel(Protocol):
    """What a semantic-mapping method gives the scores of this module.

    Attributes:
        grid: the occupancy grid the map is drawn on.
        vocabulary: the ``V`` words the method knows, in the column order of
            :meth:`word_distribution`.
    """

    @property
    def grid(self) -> OccupancyGrid: ...

    @property
    def vocabulary(self) -> tuple[str, ...]: ...

    def label_image(self) -> np.ndarray:
        """``[H, W]`` int64 label of every free cell (any numbering), -1 off free space."""
        ...

    def word_distribution(self, cells: np.ndarray) -> np.ndarray:
        """``[n] int64`` free-cell indices -> ``[n, V]`` float64 p(word | cell), rows sum to 1."""
        ...

    def region(self, word: str) -> np.ndarray:
        """``[H, W]`` bool cells the method answers "where is ``word``?" with (may be empty).

        Raises :class:`~spcopyro.results.UnknownWordError` (a ``KeyError``) for a word outside
        :attr:`vocabulary`.
        """
        ...


def _check_cells(cells: np.ndarray, num_free: int) -> np.ndarray:
    """``[n]`` int64 free-cell indices, validated."""
    idx = np.asarray(cells)
    if idx.ndim != 1 or (idx.size and idx.dtype.kind not in "iu"):
        raise ValueError(f"cells must be a 1-D integer array of free-cell indices, got {idx!r}")
    idx = idx.astype(np.int64, copy=False)
    bad = (idx < 0) | (idx >= num_free)
    if bad.any():
        raise ValueError(
            f"cells[{int(np.flatnonzero(bad)[0])}] = {int(idx[bad][0])} is not a free-cell index "
            f"(the grid has {num_free} free cells)"
        )
    return idx


@dataclass(frozen=True, eq=False)
class TabularSemanticMap:
    r"""A label image plus a table of word counts per label: the baselines' semantic map.

    With ``n_{l,v}`` the (possibly real-valued) count of word v heard in cells labelled l and
    ``epsilon`` = ``smoothing``:

    .. math::

        p(v \mid \text{cell}) = \frac{n_{l,v} + \epsilon}{\sum_{v'} n_{l,v'} + V\epsilon},
        \qquad l = \text{label of the cell},

    and "where is v?" is answered with the cells labelled :math:`\arg\max_l n_{l,v}` (the label
    under which v was heard most often; ties go to the label with more cells, then the smaller
    id). This is eq. (19) with p(C = l) proportional to the number of words heard under l. A
    word never heard under any label (all counts 0) gets an empty region.

    Attributes:
        grid: the occupancy grid.
        vocabulary: ``[V]`` words.
        labels: ``[H, W]`` int64, labels ``0 .. n_labels - 1`` on every free cell, -1 elsewhere.
        word_counts: ``[n_labels, V]`` float64 >= 0.
        smoothing: epsilon > 0 (so that every word has a rank).
        name: the method, for tables.
        notes: what the method did with its input (e.g. unplaced observations), for reports.
    """

    grid: OccupancyGrid
    vocabulary: tuple[str, ...]
    labels: np.ndarray  # [H, W] int64
    word_counts: np.ndarray  # [n_labels, V] float64
    smoothing: float = 1e-3
    name: str = ""
    notes: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        labels = np.array(self.labels, dtype=np.int64)  # [H, W]
        if labels.shape != self.grid.shape:
            raise ValueError(f"labels {labels.shape} and grid {self.grid.shape} differ in shape")
        free = self.grid.free  # [H, W] bool
        if (labels[~free] != -1).any():
            raise ValueError("labels must be -1 on every non-free cell")
        counts = np.array(self.word_counts, dtype=np.float64)  # [n_labels, V]
        vocabulary = tuple(self.vocabulary)
        if counts.ndim != 2 or counts.shape[1] != len(vocabulary):
            raise ValueError(
                f"word_counts must have shape [n_labels, {len(vocabulary)}], got {counts.shape}"
            )
        on_free = labels[free]  # [N]
        if on_free.size and (on_free.min() < 0 or on_free.max() >= counts.shape[0]):
            bad = on_free[(on_free < 0) | (on_free >= counts.shape[0])][0]
            raise ValueError(
                f"every free cell needs a label in 0..{counts.shape[0] - 1}; found {int(bad)}"
            )
        if not np.isfinite(counts).all() or (counts < 0).any():
            raise ValueError("word_counts must be finite and >= 0")
        if not (np.isfinite(self.smoothing) and self.smoothing > 0):
            raise ValueError(f"smoothing must be positive and finite, got {self.smoothing!r}")
        labels.setflags(write=False)
        counts.setflags(write=False)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "word_counts", counts)
        object.__setattr__(self, "vocabulary", vocabulary)
        object.__setattr__(self, "notes", tuple(self.notes))

    @classmethod
    def from_cell_counts(
        cls,
        grid: OccupancyGrid,
        labels: np.ndarray,
        counts: CellCounts,
        *,
        num_labels: int | None = None,
        smoothing: float = 1e-3,
        name: str = "",
        notes: Sequence[str] = (),
    ) -> TabularSemanticMap:
        """The map of ``labels`` (``[H, W]``) with the words of ``counts`` summed per label.

        ``n_{l,v} = sum over observed cells m labelled l of counts.word_counts[m, v]``;
        ``num_labels`` defaults to the largest label + 1. The placement summary of ``counts``
        is added to ``notes``.
        """
        labels = np.asarray(labels, dtype=np.int64)  # [H, W]
        if labels.shape != grid.shape:
            raise ValueError(f"labels {labels.shape} and grid {grid.shape} differ in shape")
        if counts.num_free != grid.num_free:
            raise ValueError(
                f"counts were made on a grid of {counts.num_free} free cells, not {grid.num_free}"
            )
        cell_labels = labels[grid.free]  # [N]
        if num_labels is None:
            num_labels = int(cell_labels.max()) + 1 if cell_labels.size else 0
        table = np.zeros((num_labels, len(counts.vocabulary)), dtype=np.float64)  # [n_l, V]
        observed = cell_labels[counts.cells]  # [M]
        if observed.size and (observed.min() < 0 or observed.max() >= num_labels):
            raise ValueError(f"an observed cell has a label outside 0..{num_labels - 1}")
        np.add.at(table, observed, counts.word_counts)
        return cls(
            grid=grid,
            vocabulary=counts.vocabulary,
            labels=labels,
            word_counts=table,
            smoothing=smoothing,
            name=name,
            notes=(*notes, counts.placement.summary()),
        )

    @property
    def num_labels(self) -> int:
        return int(self.word_counts.shape[0])

    def label_image(self) -> np.ndarray:
        """``[H, W]`` int64 labels, -1 off free space (a copy)."""
        return self.labels.copy()

    def word_table(self) -> np.ndarray:
        """``[n_labels, V]`` float64 smoothed p(word | label)."""
        v = len(self.vocabulary)
        totals = self.word_counts.sum(axis=1, keepdims=True)  # [n_labels, 1]
        return (self.word_counts + self.smoothing) / (totals + v * self.smoothing)

    def word_distribution(self, cells: np.ndarray) -> np.ndarray:
        """``[n]`` free-cell indices -> ``[n, V]`` p(word | cell) (see the class docstring)."""
        idx = _check_cells(cells, self.grid.num_free)
        cell_labels = self.labels[self.grid.free][idx]  # [n]
        return self.word_table()[cell_labels]

    def _word_index(self, word: str) -> int:
        try:
            return self.vocabulary.index(word)
        except ValueError:
            raise UnknownWordError(
                f"word {word!r} is not in the vocabulary of {len(self.vocabulary)} words"
                + (f" of {self.name}" if self.name else "")
            ) from None

    def region_label(self, word: str) -> int | None:
        """The label :meth:`region` answers with, or None when the word was never heard."""
        column = self.word_counts[:, self._word_index(word)]  # [n_labels]
        if not (column > 0).any():
            return None
        sizes = np.bincount(self.labels[self.grid.free], minlength=self.num_labels)
        best = np.flatnonzero(column == column.max())
        return int(best[np.argmax(sizes[best])])  # first of the largest: the smallest id

    def region(self, word: str) -> np.ndarray:
        """``[H, W]`` bool cells labelled :meth:`region_label` (empty if never heard)."""
        label = self.region_label(word)
        if label is None:
            return np.zeros(self.grid.shape, dtype=bool)
        return self.labels == label


@dataclass(frozen=True, eq=False)
class SpCoSemanticMap:
    r"""A fitted :class:`~spcopyro.results.SpCoResult` seen through :class:`SemanticMapModel`.

    ``p(word | cell) = sum_l p(C_cell = l) w_l`` with w of the MAP-visited state. Without
    ``label_samples``, ``p(C_cell = l)`` is 1 for the MAP-visited label (a point estimate);
    with ``label_samples`` (``[S, N]``, e.g. :attr:`~spcopyro.gibbs.api.GibbsRun.label_samples`)
    it is the fraction of samples in which the cell has label l. The samples should come from
    the same chain near the MAP-visited state: w belongs to one state, and concept ids are only
    comparable within a chain (label switching). ``region(word)`` is
    :meth:`~spcopyro.results.SpCoResult.where` (eq. 19) with ``prior`` ("pi" or "area").
    """

    result: SpCoResult
    prior: str = "pi"
    label_samples: np.ndarray | None = None  # [S, N] int

    def __post_init__(self) -> None:
        if self.prior not in ("pi", "area"):
            raise ValueError(f"prior must be 'pi' or 'area', got {self.prior!r}")
        if self.label_samples is not None:
            samples = np.asarray(self.label_samples)
            n = self.result.grid.num_free
            if samples.ndim != 2 or samples.shape[1] != n or samples.shape[0] == 0:
                raise ValueError(
                    f"label_samples must have shape [S >= 1, {n}], got {samples.shape}"
                )
            num_l = self.result.w.shape[0]
            if samples.min() < 0 or samples.max() >= num_l:
                raise ValueError(f"label_samples must hold concepts in 0..{num_l - 1}")
            object.__setattr__(self, "label_samples", samples.astype(np.int64))

    @property
    def grid(self) -> OccupancyGrid:
        return self.result.grid

    @property
    def vocabulary(self) -> tuple[str, ...]:
        return self.result.vocabulary

    def label_image(self) -> np.ndarray:
        return self.result.label_image()

    def word_distribution(self, cells: np.ndarray) -> np.ndarray:
        """``[n]`` free-cell indices -> ``[n, V]`` p(word | cell) (see the class docstring)."""
        idx = _check_cells(cells, self.grid.num_free)
        w = np.asarray(self.result.w, dtype=np.float64)  # [L, V]
        if self.label_samples is None:
            return w[self.result.labels_best[idx]]
        return w[self.label_samples[:, idx]].mean(axis=0)  # [S, n, V] -> [n, V]

    def region(self, word: str) -> np.ndarray:
        return self.result.where(word, prior=self.prior).region


def as_semantic_map(model: SemanticMapModel | SpCoResult) -> SemanticMapModel:
    """A :class:`SpCoResult` wrapped in :class:`SpCoSemanticMap`; a model as it is."""
    if isinstance(model, SpCoResult):
        return SpCoSemanticMap(model)
    if isinstance(model, SemanticMapModel):
        return model
    raise TypeError(
        f"expected a SemanticMapModel or SpCoResult, got {type(model).__name__} (needs grid, "
        "vocabulary, label_image(), word_distribution(cells), region(word))"
    )


# ---------------------------------------------------------------------------------------------
# Matching rate (eqs. 18-19)
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MatchingRate:
    """:func:`matching_rate`'s answer.

    ``per_word[word] = (category, precision, recall, iou)``; words the method does not know score
    0 on all three and are listed in ``unknown_words``; words whose region is empty (or lies off
    the truth's cells) score 0 and are listed in ``empty_regions``.
    """

    value: float
    kind: str
    per_word: dict[str, tuple[int, float, float, float]]
    unknown_words: tuple[str, ...]
    empty_regions: tuple[str, ...]


def _category_words(
    category_words: Mapping[str, int] | Sequence[str], num_categories: int
) -> dict[str, int]:
    if isinstance(category_words, Mapping):
        pairs = {str(word): int(c) for word, c in category_words.items()}
    elif isinstance(category_words, str):
        raise ValueError("category_words must be a sequence of names or a word -> id mapping")
    else:
        pairs = {}
        for c, word in enumerate(category_words):
            if word in pairs:
                raise ValueError(f"category_words lists {word!r} twice")
            pairs[str(word)] = c
    if not pairs:
        raise ValueError("category_words is empty: no word names a category")
    for word, c in pairs.items():
        if not 0 <= c < num_categories:
            raise ValueError(
                f"category_words[{word!r}] = {c} is not a category of the truth "
                f"(0..{num_categories - 1})"
            )
    return pairs


def matching_rate(
    model: SemanticMapModel | SpCoResult | Callable[[str], np.ndarray],
    truth: np.ndarray,
    category_words: Mapping[str, int] | Sequence[str],
    *,
    kind: str = "precision",
) -> MatchingRate:
    r"""The matching rate of place estimation from words (paper eq. 18, places by eq. 19).

    For every word w that names a ground-truth category c(w) (``category_words``), the method
    estimates a place R_w, the cells it answers "where is w?" with (SpCoMapping: the cells of
    :math:`\hat C = \arg\max_C p(C \mid w)`, eq. 19; a baseline: its own ``region``). With
    T_c the cells of category c, both restricted to the cells where the truth is defined
    (``truth >= 0``):

    .. math::

        \mathrm{MR} = \frac{1}{|W|} \sum_{w \in W} \frac{|R_w \cap T_{c(w)}|}{|R_w|}
        \qquad (\text{kind} = \text{"precision"}, \text{the default})

    i.e. the share of the estimated place that lies in the named category, averaged over the
    category words. This is the reading of eq. (18) we use: a robot sent to the estimated place
    succeeds in proportion to how much of it is the right place. It rewards a small correct
    region as much as a complete one, so ``kind="recall"`` (:math:`|R_w \cap T|/|T|`, how much of
    the place is found) and ``kind="iou"`` (:math:`|R_w \cap T|/|R_w \cup T|`) are offered, and
    all three are returned per word. An empty R_w (or a word the method does not know) scores 0;
    such words stay in the average and are listed in the answer.

    Args:
        model: a :class:`SemanticMapModel`, a :class:`SpCoResult` (eq. 19 with prior pi), or any
            function ``word -> [H, W] bool``; it may raise ``KeyError`` for an unknown word.
        truth: ``[H, W]`` int ground-truth category per cell, -1 where undefined.
        category_words: the word naming each category: a sequence (entry c names category c,
            e.g. ``house.category_names``) or a mapping word -> category id.
        kind: ``"precision"``, ``"recall"`` or ``"iou"``.
    """
    if kind not in MATCHING_KINDS:
        raise ValueError(f"kind must be one of {MATCHING_KINDS}, got {kind!r}")
    truth = np.asarray(truth)
    if truth.ndim != 2 or truth.dtype.kind not in "iu":
        raise ValueError(f"truth must be an [H, W] integer array, got {truth.dtype} {truth.shape}")
    defined = truth >= 0  # [H, W] bool
    num_categories = int(truth.max()) + 1 if defined.any() else 0
    words = _category_words(category_words, num_categories)
    region_of = model if callable(model) and not hasattr(model, "region") else None
    if region_of is None:
        region_of = as_semantic_map(model).region  # type: ignore[arg-type]

    per_word: dict[str, tuple[int, float, float, float]] = {}
    unknown: list[str] = []
    empty: list[str] = []
    for word, c in words.items():
        target = truth == c  # [H, W] bool
        if not target.any():
            raise ValueError(f"category {c} (word {word!r}) has no cells in the truth")
        try:
            region = np.asarray(region_of(word), dtype=bool)  # [H, W]
        except KeyError:
            unknown.append(word)
            per_word[word] = (c, 0.0, 0.0, 0.0)
            continue
        if region.shape != truth.shape:
            raise ValueError(f"region of {word!r} has shape {region.shape}, truth {truth.shape}")
        region = region & defined
        hit = int(np.count_nonzero(region & target))
        size = int(np.count_nonzero(region))
        if size == 0:
            empty.append(word)
        precision = hit / size if size else 0.0
        recall = hit / int(np.count_nonzero(target))
        iou = hit / int(np.count_nonzero(region | target))
        per_word[word] = (c, precision, recall, iou)
    column = MATCHING_KINDS.index(kind) + 1
    value = float(np.mean([scores[column] for scores in per_word.values()]))
    return MatchingRate(value, kind, per_word, tuple(unknown), tuple(empty))


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


def rank_of_truth(
    probabilities: np.ndarray, truth: np.ndarray, ks: Sequence[int] = (1, 3)
) -> tuple[np.ndarray, list[np.ndarray]]:
    r"""Expected rank of the true class and top-k hit probabilities under random tie breaking.

    With g the number of classes more probable than the true one and t the number of other
    classes exactly as probable, the true class is equally likely at positions g+1 .. g+t+1:

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
    greater = (p > true_p).sum(axis=1)  # [n] g
    ties = (p == true_p).sum(axis=1) - 1  # [n] t
    rank = greater + 1 + ties / 2.0
    hits = [np.clip((k - greater) / (ties + 1.0), 0.0, 1.0) for k in ks]
    return rank.astype(np.float64), hits


def heldout_word_prediction(
    model: SemanticMapModel | SpCoResult,
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

    (:meth:`SemanticMapModel.word_distribution`) ranks the vocabulary, and the true token's rank
    (:func:`rank_of_truth`: 1 = best, ties at their expected position) and top-1 / top-3 hits
    are recorded. Tokens the model does not know and utterances off free space are counted in
    the answer, not scored. A sentence's filler words are tokens like any other.
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

    @property
    def num_scored(self) -> int:
        return int(self.distances.size)

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
        )


def heldout_localisation(
    model: SemanticMapModel | SpCoResult,
    observations: Observations,
    *,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
) -> LocalisationScores:
    """How far each held-out word was said from the region the model answers "where is it?" with.

    Each utterance is placed on a free cell as in :func:`heldout_word_prediction`; for each of its
    known tokens the distance is the Euclidean distance in metres from that cell's centre to the
    centre of the nearest cell of ``region(token)``: 0 when the cell lies in the region, inf
    when the region is empty. Unknown tokens and unplaced utterances are counted, not scored.
    """
    sem = as_semantic_map(model)
    _, cells, token, unknown_words, num_unknown, num_unplaced = _heldout_tokens(
        sem, observations, snap_distance
    )
    grid = sem.grid
    rows, cols = grid.free_cells[cells, 0], grid.free_cells[cells, 1]  # [n]
    distances = np.empty(token.size, dtype=np.float64)  # [n]
    for v in np.unique(token):
        word = sem.vocabulary[int(v)]
        region = np.asarray(sem.region(word), dtype=bool)  # [H, W]
        if region.shape != grid.shape:
            raise ValueError(f"region of {word!r} has shape {region.shape}, grid {grid.shape}")
        at = token == v
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
    )


# ---------------------------------------------------------------------------------------------
# Label-switching-free posterior summaries
# ---------------------------------------------------------------------------------------------


def num_concepts(labels: np.ndarray) -> int:
    """Number of distinct labels >= 0 in a label image ``[H, W]`` or label vector ``[N]``."""
    values = np.asarray(labels)
    return int(np.unique(values[values >= 0]).size)


def chain_ari(labels_a: np.ndarray, labels_b: np.ndarray) -> float:
    """ARI between two chains' maps: a stability measure invariant to label numbering.

    Takes two ``[H, W]`` label images (compared over the cells where both are >= 0; the free
    cells must agree) or two ``[N]`` label vectors in the same free-cell order.
    """
    a, b = np.asarray(labels_a), np.asarray(labels_b)
    if a.shape != b.shape:
        raise ValueError(f"the two maps differ in shape: {a.shape} and {b.shape}")
    if a.ndim == 2:
        if not np.array_equal(a >= 0, b >= 0):
            raise ValueError("the two label images label different cells (their -1 differ)")
        return float(adjusted_rand_score(a[a >= 0], b[b >= 0]))
    if a.ndim != 1:
        raise ValueError(f"maps must be [H, W] images or [N] vectors, got shape {a.shape}")
    return float(adjusted_rand_score(a, b))


def pairwise_chain_ari(maps: Sequence[np.ndarray]) -> np.ndarray:
    """``[C, C]`` ARI between every two of C chains' maps (1 on the diagonal)."""
    count = len(maps)
    table = np.eye(count)  # [C, C]
    for i in range(count):
        for j in range(i + 1, count):
            table[i, j] = table[j, i] = chain_ari(maps[i], maps[j])
    return table


@dataclass(frozen=True, eq=False)
class CoAssignment:
    """:func:`co_assignment`'s answer. P cell pairs, S samples."""

    pairs: np.ndarray  # [P, 2] int64 free-cell indices (i != j)
    similarity: np.ndarray  # [P] float64 share of samples in which the pair shares a label
    consecutive_ari: np.ndarray  # [S - 1] ARI between sample s and s + 1
    num_concepts: np.ndarray  # [S] int64 labels in use per sample

    @property
    def mean_similarity(self) -> float:
        """Estimate of the posterior probability that two random cells share a concept."""
        return float(self.similarity.mean())

    @property
    def uncertainty(self) -> float:
        r"""Mean of :math:`4 s (1 - s)` over pairs: 0 when every pair is decided in every sample
        (always together or always apart), 1 when every pair is together half the time."""
        s = self.similarity
        return float((4.0 * s * (1.0 - s)).mean())


def co_assignment(
    label_samples: np.ndarray,
    *,
    num_pairs: int = 10_000,
    seed: int = 0,
    pairs: np.ndarray | None = None,
) -> CoAssignment:
    """Posterior co-assignment (similarity) summary of sampled maps, free of label switching.

    For cell pairs (i, j) -- ``pairs`` if given, else ``num_pairs`` pairs of distinct cells
    drawn uniformly with ``numpy.random.default_rng(seed)`` -- the share of samples with
    ``label[s, i] == label[s, j]``, an estimate of p(C_i = C_j | data); also the ARI between
    consecutive samples (how much the map moves per thinning interval) and the number of concepts
    per sample.

    Args:
        label_samples: ``[S, N]`` int labels of N free cells in S samples (e.g. thinned
            :attr:`~spcopyro.gibbs.api.GibbsRun.label_samples`), S >= 1, N >= 2.
    """
    samples = np.asarray(label_samples)
    if samples.ndim != 2 or samples.shape[0] < 1 or samples.shape[1] < 2:
        raise ValueError(f"label_samples must have shape [S >= 1, N >= 2], got {samples.shape}")
    if samples.dtype.kind not in "iu":
        raise ValueError(f"label_samples must be integers, got dtype {samples.dtype}")
    num_samples, n = samples.shape
    if pairs is None:
        if num_pairs < 1:
            raise ValueError(f"num_pairs must be >= 1, got {num_pairs}")
        rng = np.random.default_rng(seed)
        first = rng.integers(0, n, size=num_pairs)  # [P]
        second = rng.integers(0, n - 1, size=num_pairs)  # [P]
        second = second + (second >= first)  # distinct from first, uniform over the rest
        chosen = np.stack([first, second], axis=1).astype(np.int64)  # [P, 2]
    else:
        chosen = np.asarray(pairs)
        if chosen.ndim != 2 or chosen.shape[1] != 2 or chosen.dtype.kind not in "iu":
            raise ValueError(f"pairs must be a [P, 2] integer array, got {chosen.shape}")
        chosen = chosen.astype(np.int64)
        if chosen.size and (chosen.min() < 0 or chosen.max() >= n):
            raise ValueError(f"pairs must index the {n} cells of label_samples")
    together = samples[:, chosen[:, 0]] == samples[:, chosen[:, 1]]  # [S, P] bool
    consecutive = np.array(
        [adjusted_rand_score(samples[s], samples[s + 1]) for s in range(num_samples - 1)],
        dtype=np.float64,
    )  # [S - 1]
    concepts = np.array([np.unique(row).size for row in samples], dtype=np.int64)  # [S]
    return CoAssignment(
        pairs=chosen,
        similarity=together.mean(axis=0),
        consecutive_ari=consecutive,
        num_concepts=concepts,
    )
