r"""Concept numbers kept across fits of the same map: a new fit's concepts renumbered to match a
saved fit's on the same cells.

A concept's number is arbitrary (the model is exchangeable in them: a symmetric Dirichlet on pi,
the same prior on every concept's distributions), and a sampler moves a region to another
number whenever a merge or a region move empties one concept and refills another. For an online
update (:func:`spcopyro.robot.online.fit_update`) that made "concept 51 = the toilet" of the saved
fit "concept 56" after the update: the figures' colours, ``show`` and the words table changed
for the user although the place had not (measured on the embedded house, ``spcopyro fit`` of
trials 0-1 then ``--update`` with trial 2, default settings: 4 of its 6 rooms kept their number,
two moved; 2026-12-05).

:func:`matching_permutation` pairs every new concept with the saved concept that shares most
cells with it (one to one, the assignment of largest total overlap), and
:func:`renumbered` gives the new result those numbers. Renumbering changes no answer: the
same cells answer ``where``, and the log joint is the same.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import linear_sum_assignment

from spcopyro.results.result import SpCoResult

__all__ = ["matching_permutation", "moved_numbers", "renumbered"]


def matching_permutation(
    saved_labels: np.ndarray, new_labels: np.ndarray, num_concepts: int
) -> np.ndarray:
    """[L] ``perm``: new concept l is to be numbered ``perm[l]`` (a permutation of 0..L-1).

    The overlap matrix ``O[l, k]`` = the cells labelled l in ``new_labels`` and k in
    ``saved_labels`` (both ``[N]``, the same cells); the one-to-one pairing of largest total
    overlap (:func:`scipy.optimize.linear_sum_assignment`) gives matched new concepts their
    saved numbers; a pair of no overlap is no match; among pairings of equal overlap, the one
    that keeps most concepts' own numbers (a renumbered result is matched again to itself, and
    labels unchanged give the identity). The unmatched new concepts, in ascending
    order, take the numbers left free, in ascending order.
    """
    saved = np.asarray(saved_labels, dtype=np.int64)  # [N]
    new = np.asarray(new_labels, dtype=np.int64)  # [N]
    L = int(num_concepts)
    if saved.shape != new.shape or saved.ndim != 1:
        raise ValueError(f"saved and new labels must be [N] of the same cells, got shapes "
                         f"{saved.shape} and {new.shape}")  # fmt: skip
    for name, labels in (("saved", saved), ("new", new)):
        if labels.size and not 0 <= labels.min() <= labels.max() < L:
            raise ValueError(f"{name} labels must be concepts in 0..{L - 1}, got "
                             f"{labels.min()}..{labels.max()}")  # fmt: skip
    new_used, new_rows = np.unique(new, return_inverse=True)  # [A], [N]
    old_used, old_cols = np.unique(saved, return_inverse=True)  # [B], [N]
    overlap = np.zeros((new_used.size, old_used.size), dtype=np.int64)  # [A, B]
    np.add.at(overlap, (new_rows, old_cols), 1)
    # ties (equal total overlap) keep a concept's own number: a bonus of 1 per such pair,
    # below one cell of overlap (there are < L + 1 pairs), so the total overlap comes first
    same = (new_used[:, None] == old_used[None, :]) & (overlap > 0)  # [A, B]
    rows, cols = linear_sum_assignment(overlap * (L + 1) + same, maximize=True)
    keep = overlap[rows, cols] > 0
    perm = np.full(L, -1, dtype=np.int64)  # [L]
    perm[new_used[rows[keep]]] = old_used[cols[keep]]
    free = np.setdiff1d(np.arange(L), perm[perm >= 0])  # ascending numbers not taken
    perm[perm < 0] = free  # unmatched new concepts, ascending, take them in order
    return perm


def moved_numbers(perm: np.ndarray) -> dict[str, int]:
    """The numbers ``perm`` ([L], as :func:`renumbered` takes it) moved: each concept's new
    number (a string, as a JSON key) -> its number before, for the concepts whose number changed
    (empty for the identity), in ascending new number. An update records it
    (``config.json``'s ``inference.update_of.renumbered``): a raw sample's concept ``k`` is
    ``perm[k]`` in the result, so a result number ``n`` in it was ``moved[str(n)]`` (else ``n``)
    in the sampler's own numbers."""
    perm = np.asarray(perm, dtype=np.int64)  # [L]
    inverse = np.argsort(perm)  # [L] new number -> old
    return {str(n): int(inverse[n]) for n in range(perm.size) if inverse[n] != n}


def renumbered(result: SpCoResult, perm: np.ndarray) -> SpCoResult:
    """``result`` with concept l numbered ``perm[l]`` (a permutation of 0..L-1) in every
    concept-indexed part: ``labels`` and ``labels_final`` ([N] values), ``pi`` ([L]), every
    emission table's rows ([L, K_m]), the columns of ``marginals`` ([N, L]) and the rows of
    ``concept_totals`` ([L, 1 + M]) and ``word_counts`` ([L, V]). Per-cell and per-word parts
    (``agreement``, ``word_totals``) and the trace do not depend on the numbers."""
    perm = np.asarray(perm, dtype=np.int64)  # [L]
    L = len(result.pi)
    if perm.shape != (L,) or not np.array_equal(np.sort(perm), np.arange(L)):
        raise ValueError(f"perm must be a permutation of 0..{L - 1}, got {perm.tolist()}")
    inverse = np.argsort(perm)  # [L] the old number of concept perm[l] = l's new number

    def rows(table: np.ndarray | None) -> np.ndarray | None:
        return None if table is None else np.asarray(table)[inverse]

    def values(labels: np.ndarray | None) -> np.ndarray | None:
        return None if labels is None else perm[np.asarray(labels)].astype(np.asarray(labels).dtype)

    return dataclasses.replace(
        result,
        labels=values(result.labels),
        labels_final=values(result.labels_final),
        pi=rows(result.pi),
        emissions=tuple(
            dataclasses.replace(table, probabilities=rows(table.probabilities))
            for table in result.emissions
        ),
        marginals=None if result.marginals is None else np.asarray(result.marginals)[:, inverse],
        concept_totals=rows(result.concept_totals),
        word_counts=rows(result.word_counts),
    )
