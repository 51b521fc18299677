r"""Scores of a semantic map against a ground truth: label images and places named by words.

* :func:`adjusted_rand_index`: ARI of a label image against the ground truth over the cells
  where the truth is defined.
* :func:`matching_rate`: the paper's matching rate for place estimation (eq. 18), the place
  estimated from a word as in eq. (19); :class:`MatchingRate` is its answer, the category words
  (``category_words``) say which word names which ground-truth category. See its docstring for
  the exact definition used.

Label images are ``[H, W]`` integer arrays in map-image row order with -1 off free space.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from spcopyro.metrics.rand import adjusted_rand_score
from spcopyro.results.semantic_map import SemanticMapModel, SpCoResultLike, as_semantic_map

__all__ = ["MATCHING_KINDS", "MatchingRate", "adjusted_rand_index", "matching_rate"]


MATCHING_KINDS = ("precision", "recall", "iou")


def _grid_hint(shape: tuple[int, ...], truth_shape: tuple[int, ...]) -> str:
    """What to do when a fit's labels are on a coarser grid than the truth (the default preset
    fits on 0.25 m model cells): nothing when the shapes do not look like that."""
    if (
        len(shape) != 2
        or len(truth_shape) != 2
        or not all(0 < s < t for s, t in zip(shape, truth_shape, strict=True))
    ):
        return ""
    return (
        ": the labels look like a fit on a coarser model grid (the default preset's 0.25 m "
        "cells); score them against spcopyro.data.model_grid.model_house(house, "
        "cell_size).truth, or take them to the map's cells with "
        "spcopyro.maps.coarse.refine_labels(labels, house.grid, factor)"
    )


def adjusted_rand_index(labels: np.ndarray, truth: np.ndarray) -> float:
    """ARI between two [H, W] label images over the cells where the truth is defined (>= 0).

    Invariant to how the concepts are numbered (scikit-learn's implementation).
    """
    if labels.shape != truth.shape:
        raise ValueError(
            f"label image {labels.shape} and truth {truth.shape} differ in shape"
            + _grid_hint(labels.shape, truth.shape)
        )
    mask = truth >= 0
    return float(adjusted_rand_score(truth[mask], labels[mask]))


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
    model: SemanticMapModel | SpCoResultLike | Callable[[str], np.ndarray],
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
        model: a :class:`~spcopyro.results.semantic_map.SemanticMapModel`, a
            :class:`~spcopyro.results.result.SpCoResult` (eq. 19 with prior pi), or any
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
            raise ValueError(
                f"region of {word!r} has shape {region.shape}, truth {truth.shape}"
                + _grid_hint(region.shape, truth.shape)
            )
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
