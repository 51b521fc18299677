r"""A point estimate without speck clusters: each speck's cells joined to other clusters.

The greedy search of :mod:`spcopyro.results.point_estimate` minimises the expected loss over
all partitions. Under the model every kept sample holds many one-cell droplets of labels that
form and dissolve in corners and doorways, and the minimiser keeps a cell apart where its
co-clustering probability with every neighbouring cluster is below about one half: a speck
(:func:`~spcopyro.results.concept_words.is_speck`, a cluster on fewer than
:data:`~spcopyro.results.concept_words.SPECK_SHARE` of the cells and under
:data:`~spcopyro.results.concept_words.SPECK_AREA` square metres where fewer than
:data:`~spcopyro.results.concept_words.SPECK_WORDS` words were heard) that is no place,
only droplets whose labels differ from sample to sample reported as a cluster of their own.
:func:`join_specks` moves every cell of a speck to the cluster that is no speck where the move
lowers the expected loss most (or raises it least), one cell at a time, each by the exact change
of the module doc of :mod:`~spcopyro.results.point_estimate`,

.. math::

    \Delta_i(k') = \big[f(a_{k'} + 1) - f(a_{k'}) + f(a_k - 1) - f(a_k)\big]
        - \frac{2}{S} \sum_s \big[f(n^s_{k' j_s} + 1) - f(n^s_{k' j_s})
        + f(n^s_{k j_s} - 1) - f(n^s_{k j_s})\big]

(divided by Z), read off the S contingency tables and updated after each move. The cells go
in order of their best change at the start (the cheapest first, so that the clearest joins
shape the tables the others are read from), each read again when its turn comes. A cluster
that is no speck only gains cells, so it stays one, and every speck empties. Each join is the
cheapest for its cell when it is made and the other clusters' cells are not moved again: a
greedy approximation of the minimiser among the partitions without specks, not its proof (on
the README's fit every joined cell went to a concept one of its neighbours holds). A cluster
where 0.1 words or more were heard is never a speck, however small; one that heard less
(the footprint's reach share gives nearly every cell of a room a little) is, if small, as the
listing and the legend call it: the words at each cell are counted as words (the model's counts
divided by ``word_scaling``, :func:`~spcopyro.results.posterior_means.words_per_cell`), the
units of ``result.heard``. A cluster of 0.5 m^2 or more is never a speck, whatever share of the
map it holds: on a big house the share alone called whole rooms where no word was said specks,
and joined them (:data:`~spcopyro.results.concept_words.SPECK_AREA`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from spcopyro.results.concept_words import is_speck
from spcopyro.results.estimate_tables import _f, _pairs, _sample_tables, _Samples

__all__ = ["Joined", "check_cell_words", "join_specks", "speck_clusters"]

CHUNK = 1_000_000
"""At most this many table entries (cells x samples x clusters) read at once for the cells'
first changes."""


class Joined(NamedTuple):
    """What :func:`join_specks` did."""

    estimate: np.ndarray
    """[N] int64 the clusters after the joins (the input's codes; emptied clusters unused)."""
    cells: int
    """How many cells of specks were moved."""
    specks: int
    """How many speck clusters they emptied."""
    change: float
    """The sum of the moves' exact changes of the expected loss (divided by Z)."""


def check_cell_words(cell_words: np.ndarray, cells: int) -> np.ndarray:
    """``cell_words`` as a float64 ``[N]`` array of non-negative counts (words heard at
    each cell), else ValueError."""
    words = np.asarray(cell_words, dtype=np.float64)
    if words.shape != (cells,) or not np.all(np.isfinite(words)) or np.any(words < 0):
        raise ValueError(
            f"cell_words must be [{cells}] finite counts >= 0 (the words heard at each cell), "
            f"got shape {words.shape}"
        )
    return words


def speck_clusters(
    estimate: np.ndarray, k: int, cell_words: np.ndarray, cell_area: float
) -> np.ndarray:
    """[k] bool: whether each cluster of ``estimate`` [N] (codes 0..k-1) is a speck, by
    :func:`~spcopyro.results.concept_words.is_speck` of its cells, their area (``cell_area``
    square metres each: the resolution squared of the grid the estimate is on) and the words
    heard on them (``cell_words`` [N], in words: the model's counts divided by
    ``word_scaling``; the result's ``heard`` sums the same counts in the same units)."""
    sizes = np.bincount(estimate, minlength=k)  # [k]
    heard = np.bincount(estimate, weights=cell_words, minlength=k)  # [k]
    n = estimate.shape[0]
    return np.array(
        [is_speck(int(sizes[c]), float(heard[c]), n, cell_area) for c in range(k)], dtype=bool
    )


def _changes(
    place: np.ndarray,
    own: np.ndarray,
    sizes: np.ndarray,
    targets: np.ndarray,
    flat: np.ndarray,
    widths: np.ndarray,
    loss: str,
) -> np.ndarray:
    """[m, T] Delta_i(k') of the module doc (times Z) for m cells of the clusters ``own`` [m]
    and the clusters ``targets`` [T]; ``flat`` the tables one after another, ``place`` [m, S]
    each cell's column's place in its sample's table (its offset + j_s), ``widths`` [S] J_s,
    ``sizes`` [k] float64 the clusters' sizes."""
    here = flat[place + own[:, None] * widths[None, :]]  # [m, S] n^s_{k j_s}
    there = flat[place[:, :, None] + targets[None, None, :] * widths[None, :, None]]  # [m, S, T]
    shared = (_f(there + 1, loss) - _f(there, loss)).sum(1)  # [m, T]
    shared += (_f(here - 1, loss) - _f(here, loss)).sum(1)[:, None]  # [m, T]
    change = (_f(sizes[targets] + 1, loss) - _f(sizes[targets], loss))[None, :]  # [1, T]
    change = change + (_f(sizes[own] - 1, loss) - _f(sizes[own], loss))[:, None]  # [m, T]
    return change - 2.0 * shared / widths.shape[0]


def join_specks(
    estimate: np.ndarray,
    k: int,
    prepared: _Samples,
    loss: str,
    cell_words: np.ndarray,
    cell_area: float,
) -> Joined:
    """``estimate`` [N] (codes 0..k-1) with every speck's cells moved to clusters that are no
    specks (module doc); unchanged where it has no speck, or nothing but specks.
    ``prepared``: the samples of :func:`~spcopyro.results.point_estimate.point_estimate`,
    ``cell_words`` [N] the words heard at each cell (:func:`check_cell_words`), ``cell_area``
    the square metres of one cell (:func:`speck_clusters`)."""
    speck = speck_clusters(estimate, k, cell_words, cell_area)  # [k]
    targets = np.flatnonzero(~speck)  # [T]
    cells = np.flatnonzero(speck[estimate])  # [M]
    estimate = estimate.copy()
    if cells.size == 0 or targets.size == 0:
        return Joined(estimate, 0, 0, 0.0)
    tables = _sample_tables(_pairs(estimate, prepared), k, prepared)  # S x [k, J_s]
    flat = tables.flat  # the tables' entries, updated in place as cells move
    widths = np.asarray(prepared.sizes, dtype=np.int64)  # [S]
    place = (prepared.codes[:, cells] + tables.offsets[:-1, None]).T  # [M, S]
    sizes = np.bincount(estimate, minlength=k).astype(np.float64)  # [k]
    step = max(1, CHUNK // (widths.shape[0] * targets.shape[0]))
    first = np.concatenate([  # [M] each cell's best change at the start
        _changes(place[a : a + step], estimate[cells[a : a + step]], sizes, targets, flat,
                 widths, loss).min(1)
        for a in range(0, cells.shape[0], step)
    ])  # fmt: skip
    total = 0.0
    for m in np.argsort(first, kind="stable"):  # the cheapest first
        cell, source = cells[m], estimate[cells[m : m + 1]]  # [1] its cluster
        change = _changes(place[m : m + 1], source, sizes, targets, flat, widths, loss)[0]  # [T]
        best = int(np.argmin(change))
        target = int(targets[best])
        flat[place[m] + int(source[0]) * widths] -= 1.0  # the cell leaves its entries ...
        flat[place[m] + target * widths] += 1.0  # ... and joins the target's
        sizes[source[0]] -= 1.0
        sizes[target] += 1.0
        estimate[cell] = target
        total += float(change[best])
    n = estimate.shape[0]
    scale = float(n * n if loss == "binder" else n)
    return Joined(estimate, int(cells.shape[0]), int(speck.sum()), total / scale)
