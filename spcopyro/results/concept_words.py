r"""Word lists a person can read: each concept's most probable and most *distinctive* words.

A concept's most probable words under w_l are often the words every concept shares: fillers
("the", "is") or, under a large beta, any word at all (beta = 500 against a few dozen words
makes every w_l nearly uniform: "0.06" for every word). The **lift** of a word v for concept l
sets its probability in the concept against its probability anywhere on the map:

.. math::

    \text{lift}_{lv} = \frac{p(v \mid l)}{p(v)}, \qquad
    p(v) = \sum_{l'} \frac{N_{l'}}{N}\, w_{l'v},

with :math:`N_{l'}` the cells of concept l' in the point estimate: p(v) is the **area-weighted
mixture** of the concepts' word distributions, the probability of hearing v at a free cell drawn
uniformly from the map (not the observed-count marginal, which measures how often v was said in
the data, not where). With this p(v), the lift is exactly the word's Bayes ratio for the concept
in "where is v?" under the area prior (:meth:`spcopyro.results.result.SpCoResult.where`):
:math:`p(C = l \mid v) / p(C = l) = \text{lift}_{lv}`. A distinctive word of a concept is thus one
that points "where is v?" towards it; a lift near 1 says the word says nothing about the place.

A concept whose region holds no observed word gets no word list at all (:data:`NO_WORDS`): its
w_l is its prior (the uniform posterior mean, or a random draw for a sampler's state), not
something learnt. Nor does any concept of a fit that did not model its words (``use_words`` off,
:func:`words_modelled`): every w_l is the prior's, every word tied, and a list of them (in tie
order) was read as what the concept means; the listing, the legend, the map's labels and
``where`` say :data:`WORDS_NOT_MODELLED` once instead.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence

import numpy as np

from spcopyro._util.messages import listed, plural, shown_count
from spcopyro.config import WORDS

__all__ = [
    "MIN_LIFT",
    "NO_WORDS",
    "WORDS_NOT_MODELLED",
    "WORDS_NOT_MODELLED_NOTE",
    "ESTIMATED_WORDS",
    "SPECK_AREA",
    "SPECK_SHARE",
    "SPECK_WORDS",
    "SPECKS_NAMED",
    "is_speck",
    "speck_sized",
    "speck_line",
    "cells_range",
    "distinctive_items",
    "format_concept_words",
    "format_words_heard",
    "heard_words",
    "item_marginal",
    "listed_distinctive_words",
    "listed_top_words",
    "lift",
    "named_specks",
    "near_uniform",
    "prior_share",
    "ranked",
    "shown_words",
    "shown_top_words",
    "words_modelled",
    "words_note",
]

NO_WORDS = "no words heard here"
"""What a concept whose region holds no observed word shows instead of a word list."""

WORDS_NOT_MODELLED = "not modelled (use_words off)"
"""What a fit that did not model its words (:func:`words_modelled`) says once, where the words of
its concepts would be listed: ``fit``'s listing (``words: not modelled (use_words off)``), the
semantic map's legend and labels, ``where`` (which also warns that its answer is the prior's)."""

WORDS_NOT_MODELLED_NOTE = f"words {WORDS_NOT_MODELLED}"
"""The same said of a whole fit's words in one place: a concept's ``words_note``
(:func:`words_note`), the semantic map's legend title and the comparison report's "Concepts
found" line."""


def words_modelled(result: object) -> bool:
    """Whether ``result``'s fit modelled its words: its config's
    :meth:`~spcopyro.config.SpCoConfig.uses` of ``"words"`` (``use_words``; True for a result
    without a config). Where not, every w_l is the prior's (a posterior mean with no counts:
    uniform), every word tied, and no concept has a word list."""
    config = getattr(result, "config", None)
    return config is None or config.uses(WORDS)


def words_note(result: object, heard: float | None) -> str | None:
    """``concepts.json``'s ``words_note`` of a concept of ``result`` where ``heard`` words were
    heard (None: unknown): :data:`NO_WORDS` where none was, ``"words not modelled (use_words
    off)"`` for any other concept of a fit that did not model its words (its ``top_words`` and
    ``distinctive_words`` are empty, as a concept's where no word was heard), else None."""
    if heard == 0:
        return NO_WORDS
    return None if words_modelled(result) else WORDS_NOT_MODELLED_NOTE


def listed_top_words(result, concept: int, n: int) -> list[tuple[str, float]]:
    """The ``n`` most probable words of concept ``concept`` of ``result`` with their
    probabilities (``result.top_words``), as ``concepts()``' ``top_words`` and the place graph
    list them: none where no word was heard in its region (its w_l is its prior) or the fit did
    not model its words (:func:`words_modelled`: every word tied), as :func:`words_note` says."""
    return result.top_words(concept, n) if _words_listed(result, concept) else []


def listed_distinctive_words(result, concept: int, n: int) -> list[tuple[str, float, float]]:
    """The ``n`` words of largest lift above :data:`MIN_LIFT` of concept ``concept`` of
    ``result`` as ``(word, lift, p)`` (:func:`distinctive_items`), of the words heard in its
    region where the result knows them (:func:`heard_words`): none where
    :func:`listed_top_words` lists none (a fit that did not model its words: whatever lifts
    its w holds, they are the prior's, not learnt)."""
    if not _words_listed(result, concept):
        return []
    table, heard = result.emission(WORDS), heard_words(result, concept)  # heard: None if unknown
    row = table.probabilities[concept]  # [V]
    return distinctive_items(row, result.lift()[concept], table.items, n, heard=heard)


def _words_listed(result, concept: int) -> bool:
    """Whether concept ``concept`` of ``result`` lists words: some were heard in its region
    (or ``result`` does not know) and the fit modelled its words."""
    heard = getattr(result, "heard", lambda _: None)(concept)  # None: unknown, listed
    return heard != 0 and words_modelled(result)


ESTIMATED_WORDS = "words as the method estimates them"
"""What a concept's word probabilities are when the fit recorded no ``inference["parameters"]``
(a variational method's E_q, not a posterior mean given labels): ``fit``'s listing and the
semantic map's legend say it."""

MIN_LIFT = 1.1
"""Distinctive words are those whose lift exceeds this: at least 10% more probable in the concept
than on the map as a whole (a display threshold, not a test: a lift of 1.01 under paper-dp's
beta = 500 says nothing a reader could use)."""


RANK_DECIMALS = 9
"""Probabilities and lifts are ranked after rounding to this many decimals, ties by item order.
Two items with the same counts have the same value mathematically, but a sum over concepts
(:func:`item_marginal`'s matrix product) can differ in its last bits between columns and between
CPUs (the vector width decides the order of the additions); unrounded, such a tie would order
the words differently on different machines."""


def ranked(*keys: np.ndarray) -> np.ndarray:
    """Indices that sort by the first key descending, then the next, ..., then by index: each
    key rounded to :data:`RANK_DECIMALS` first, so that last-bit noise cannot reorder ties."""
    rounded = [np.round(np.asarray(key, dtype=np.float64), RANK_DECIMALS) for key in keys]
    index = np.arange(len(rounded[0]))
    return np.lexsort((index, *(-key for key in reversed(rounded))))


def format_words_heard(heard: float) -> str:
    """Words heard in a concept's cells, to one decimal, ``"9"`` rather than ``"9.0"``: with an
    observation footprint an utterance's weight is spread over cells that may lie in two
    concepts, so the count is fractional (8.964 read as noise beside whole utterances). A count
    above 0 that rounds to 0 is ``"<0.1"``: "0 words" beside a word list read as a contradiction
    (a concept with no word heard shows no list)."""
    if 0 < heard < 0.05:
        return "<0.1"
    return f"{heard:.1f}".removesuffix(".0")


def item_marginal(table: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """[K] p(item) = sum_l (N_l / N) table[l] over the concepts in use (``sizes`` ``[L]``: their
    cells): the area-weighted mixture of the rows of ``table`` ``[L, K]``."""
    sizes = np.asarray(sizes, dtype=np.float64)  # [L]
    if sizes.sum() <= 0:
        raise ValueError("no concept labels a cell: the item marginal is undefined")
    return (sizes / sizes.sum()) @ np.asarray(table, dtype=np.float64)  # [K]


def lift(table: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """[L, K] p(item | concept) / p(item) (module docstring; 0 where p(item) is 0)."""
    table = np.asarray(table, dtype=np.float64)  # [L, K]
    marginal = item_marginal(table, sizes)  # [K]
    safe = np.where(marginal > 0, marginal, 1.0)
    return np.where(marginal > 0, table / safe, 0.0)


def distinctive_items(
    row: np.ndarray,
    lift_row: np.ndarray,
    items: Sequence[str],
    n: int = 3,
    min_lift: float = MIN_LIFT,
    heard: Collection[str] | None = None,
) -> list[tuple[str, float, float]]:
    """The ``n`` items of largest lift above ``min_lift`` as ``(item, lift, probability)``,
    largest lift first (ties: the more probable first); fewer when fewer items pass.
    ``heard``: where known (:func:`heard_words`), only those items are candidates: a
    variational E_q[w] gives an unheard word mass, and "door 0.86 | distinctive: entrance x1.3"
    named a word the word list had just left out as not heard there."""
    row, lift_row = np.asarray(row), np.asarray(lift_row)  # [K], [K]
    order = ranked(lift_row, row)  # by lift, then probability, descending
    passes = np.round(lift_row, RANK_DECIMALS) > min_lift  # [K]
    chosen = [k for k in order if passes[k] and (heard is None or items[k] in heard)][:n]
    return [(items[k], float(lift_row[k]), float(row[k])) for k in chosen]


def shown_words(
    top: Sequence[tuple[str, float]], row: np.ndarray | None = None
) -> list[tuple[str, float]]:
    """The ``(word, p)`` of ``top`` worth printing at two decimals, the first always (the
    listing, the map's legend and labels and ``where`` use it). Left out: a word whose
    probability rounds to 0.00 ("bedroom 0.56, bed 0.42, entrance 0.00" read as a third word of
    the place), and, given the concept's whole ``row`` ``[V]``, a word at :func:`prior_share`:
    never heard there ("bathroom 0.57, bathtub 0.29, restroom 0.01", restroom one of 15 words
    at the prior's 0.1 / 10.7, first of them by tie order only). Where the result knows the
    words heard, :func:`shown_top_words` keeps only those before calling it."""
    floor = None if row is None else prior_share(row)

    def unheard(p: float) -> bool:
        return floor is not None and round(p, RANK_DECIMALS) == floor

    return [(w, p) for w, p in top if round(p, 2) > 0 and not unheard(p)] or list(top[:1])


def heard_words(result, concept: int) -> frozenset[str] | None:
    """The words heard in concept ``concept``'s region of ``result`` (an
    :class:`~spcopyro.results.result.SpCoResult`): those of count above 0 in its
    ``word_counts``; None when the result does not keep them (one saved before it did)."""
    counts = getattr(result, "word_counts", None)  # [L, V] or None
    if counts is None:
        return None
    row = np.asarray(counts)[concept]  # [V]
    return frozenset(word for word, n in zip(result.vocabulary, row, strict=True) if n > 0)


def shown_top_words(result, concept: int, n: int) -> list[tuple[str, float]]:
    """:func:`shown_words` of concept ``concept``'s ``n`` most probable words of ``result`` (an
    :class:`~spcopyro.results.result.SpCoResult`): the words fit's listing, the map's legend
    and labels and ``where`` print. Where the result knows the words heard in the concept
    (:func:`heard_words`), they decide: a word among them kept even at the row's minimum (every
    word heard, two of them as often as each other), and a word not among them left out even
    above it (a variational method's E_q[w] has no floor: the default house's svi fit listed
    "door 0.86, entrance 0.01, bathroom 0.01" for a concept where only 'door' was heard). Heard
    means heard under the point labels (``word_counts``): for a variational fit a word whose q
    mass in the concept comes only from cells labelled otherwise is not listed. The ``n`` are
    then the most probable of the heard words (ranked among them first, cut to ``n`` after): a
    variational E_q[w] can rank a heard word below unheard ones, and cutting first listed fewer
    than ``n``, or an unheard word alone where none of the top ``n`` was heard; a posterior mean
    (Gibbs) ranks its heard words first, so it lists the same. Where the result does not know
    them (one saved before it kept ``word_counts``), the ``n`` most probable words less those at
    the floor of its row ``result.w[concept]`` ``[V]`` (:func:`shown_words`). None where the fit
    did not model its words (:func:`words_modelled`): its rows are the prior's, every word tied."""
    if not words_modelled(result):
        return []
    heard = heard_words(result, concept)
    if heard:  # rank among the heard words, then cut (an empty set: as below, never printed)
        everyword = result.top_words(concept, len(result.vocabulary))  # [(word, p)] * V
        return shown_words([(w, p) for w, p in everyword if w in heard])[:n]
    return shown_words(result.top_words(concept, n), result.w[concept])  # row [V]


def prior_share(row: np.ndarray) -> float | None:
    """The probability of a word never heard in a concept whose distribution is ``row`` ``[V]``
    (rounded to :data:`RANK_DECIMALS`), or None when no word need be, read from the row: its
    minimum, when two or more words share it and some word lies above it. Under a posterior
    mean ``(beta + n_lv) / (V beta + n_l)`` every unheard word has that minimum,
    ``beta / (V beta + n_l)``, and a draw's row (no two words equal) has none. Heard words tied
    at the minimum count share it too (every word heard, the rarest twice or more):
    :func:`shown_top_words` keeps them where the result kept its counts (:func:`heard_words`); a
    result saved without them reads them as unheard, as it always did."""
    rounded = np.round(np.asarray(row, dtype=np.float64), RANK_DECIMALS)  # [V]
    if rounded.size < 2:
        return None
    low = rounded.min()
    if np.count_nonzero(rounded == low) < 2 or rounded.max() == low:
        return None
    return float(low)


def format_concept_words(
    top: Sequence[tuple[str, float]],
    distinctive: Sequence[tuple[str, float, float]],
    heard: float | None,
) -> str:
    """One line for a concept: ``NO_WORDS`` when ``heard`` is 0, else its top words with their
    probabilities and its distinctive words (if any) with their lifts, e.g.
    ``"kitchen 0.31, the 0.12 | distinctive: kitchen x4.2, fridge x3.1"``. The top words are
    :func:`shown_words` (given :func:`shown_top_words`, those of a concept's row)."""
    if heard is not None and heard <= 0:
        return f"({NO_WORDS})"
    text = ", ".join(f"{w} {p:.2f}" for w, p in shown_words(top))
    if distinctive:
        text += " | distinctive: " + ", ".join(f"{w} x{r:.1f}" for w, r, _ in distinctive)
    return text


SPECK_SHARE = 0.005
"""A concept where fewer than :data:`SPECK_WORDS` words were heard, on fewer than this
share of the free cells and under :data:`SPECK_AREA` square metres, is a speck
(:func:`is_speck`): a doorway or convex-corner cell the Potts field holds weakly
(docs/real_houses.md, "What is still open"). ``fit``'s listing and the semantic map's legend
put the specks on one line; the figure labels regions from the same 0.5 %."""

SPECK_AREA = 0.5
"""Square metres: a speck (:func:`is_speck`) also covers less than this. The share
:data:`SPECK_SHARE` alone is relative to the map: on a synthetic house of 1.94 million free
cells at 0.05 m (4,850 m^2) its 0.5 % is 24 m^2, and the point estimate ``vi`` joined rooms
where no word was said (79,210 cells, expected VI 0.146 -> 0.228; on 3.87 million cells 438,443,
0.154 -> 0.498, worse than the best single sample's 0.238), erasing rooms learnt from images.
The bound sits between what a speck is and what a room is: a droplet of the Potts field in a
doorway covers about 0.8 m x 0.1-0.3 m (0.08-0.24 m^2; one 0.25 m model cell is 0.0625 m^2),
the smallest rooms, a closet or a toilet, 1-2 m^2. On every public house and the embedded one
the share binds first (0.5 % of the free cells: room2ldk4 0.347 m^2 at 0.05 m and 0.326 m^2 at
0.25 m, room1dk6 0.328 / 0.312, room1ldk5 0.277 / 0.269, room1dk5 0.233 / 0.219, room1ldk4
0.225 / 0.210, the embedded house 0.181 m^2 at 0.1 m and 0.148 m^2 on its 0.3 m model grid), so
their results are those of the share alone; the area binds from about 100 m^2 of free floor."""

SPECK_WORDS = 0.1
"""A concept on fewer than :data:`SPECK_SHARE` of the free cells is a speck where fewer than
this many words were heard in its cells (the words heard, tf-idf weighted if so prepared: the
model's counts divided by ``word_scaling``, as ``result.heard`` gives them; the listing writes
such a count "<0.1" or "0.1"). The rule was "no word heard" (0) until the footprint's reach share
(``footprint_reach_share``, 0.2 under ``coarse`` since 2026-12-06) spread a fifth of each
observation's weight over its geodesic Voronoi cell within its room: nearly every free cell of
a room then hears a small positive count, and a one-cell droplet of the Potts field was listed
as a concept, and answered ``where`` (room1dk5: concept 58, one cell that heard 0.013 of a
word, the runner-up for tv, table and bed under ``where --prior pi``). Under ``coarse``'s
0.75 m footprint a cell where an utterance was said gets about 0.03 of it, so a cluster of a few
cells around the spot of one utterance is a speck, while one where several were said at one
spot (or one holding more of an utterance's footprint) is not."""


def near_uniform(rows: np.ndarray) -> bool:
    """Whether every row of ``rows`` ``[L, V]`` (word distributions of the concepts in use) is
    close to uniform: no word above ``min(2 / V, 1 / V + 0.25)``. Twice uniform alone called
    (0.66, 0.22, 0.11) over three words close to uniform; the second bound keeps small
    vocabularies to what a reader would call flat."""
    rows = np.asarray(rows, dtype=np.float64)
    size = rows.shape[-1]
    if rows.size == 0 or size == 0:
        return False
    return bool(rows.max() < min(2.0 / size, 1.0 / size + 0.25))


def speck_sized(cells: int, num_free: int, cell_area: float) -> bool:
    r"""Whether ``cells`` cells of ``cell_area`` square metres each (the resolution squared of
    the grid they are on) are as small as a speck: fewer than :data:`SPECK_SHARE` of the
    ``num_free`` free cells, and under :data:`SPECK_AREA` square metres,

    .. math::

        n_c < \text{SPECK\_SHARE} \cdot N \quad\text{and}\quad
        n_c \, a < \text{SPECK\_AREA}.

    ValueError unless ``cell_area`` is a finite number > 0."""
    if isinstance(cell_area, bool) or not (np.isfinite(cell_area) and cell_area > 0):
        raise ValueError(
            f"cell_area must be the square metres of one cell (> 0), got {cell_area!r}"
        )
    return cells < SPECK_SHARE * num_free and cells * cell_area < SPECK_AREA


def is_speck(cells: int, heard: float | None, num_free: int, cell_area: float) -> bool:
    """Whether a concept of ``cells`` cells where ``heard`` words were heard is a speck:
    fewer than :data:`SPECK_WORDS` heard on fewer than :data:`SPECK_SHARE` of the ``num_free``
    free cells and under :data:`SPECK_AREA` square metres (:func:`speck_sized`, ``cell_area``
    the square metres of one cell of the grid they are on). ``heard`` counts words (the model's
    counts divided by ``word_scaling``, ``result.heard``); a result that does not know its
    counts (``heard`` None) has none."""
    sized = speck_sized(cells, num_free, cell_area)  # checks cell_area first
    return heard is not None and heard < SPECK_WORDS and sized


SPECKS_NAMED = 8
"""The specks :func:`speck_line` names, the rest counted (one over is named,
:func:`~spcopyro._util.messages.shown_count`): fit's listing named 8 and the map's legend 6 of
the same 8 (room1ldk5, seed 0), each in its own words."""


def speck_line(specks: Sequence[int], sizes: Sequence[int]) -> str:
    """The one line ``fit``'s listing and the semantic map's legend give the specks ``specks``
    (concept ids, largest first) of ``sizes`` cells, the first :data:`SPECKS_NAMED` named and
    the rest counted (:func:`~spcopyro._util.messages.listed`).

    E.g. ``"8 specks of 1 cell where under 0.1 words were heard (concepts 2, 3, 4, 43, 68, 70,
    81, 87; concepts.json lists them)"`` (:data:`SPECK_WORDS`)."""
    which, them = ("concept", "it") if len(specks) == 1 else ("concepts", "them")
    names = listed([str(c) for c in specks], SPECKS_NAMED)
    where = f"({which} {names}; concepts.json lists {them})"
    count = plural(len(sizes), "speck")  # "4 specks"
    heard = f"where under {SPECK_WORDS:g} words were heard"  # is_speck's rule
    return f"{count} of {cells_range(sizes)} {heard} {where}"


def named_specks(specks: Sequence[int]) -> list[int]:
    """The specks of ``specks`` that :func:`speck_line` names by their ids."""
    return list(specks[: shown_count(len(specks), SPECKS_NAMED)])


def cells_range(sizes: Sequence[int]) -> str:
    """``"1 cell"``, ``"5 cells"``, ``"14-18 cells"``: the range of these cell counts."""
    low, high = min(sizes), max(sizes)
    size = f"{low}" if low == high else f"{low}-{high}"
    return f"{size} {'cell' if high == 1 else 'cells'}"
