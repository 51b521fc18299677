"""The name of a concept's region, one rule for every output that names one.

A region is named by the concept's most probable word (highest p(word | concept), its row of the
word table) among the words whose ``where`` answer (eq. 19 under the default area prior,
argmax_C p(C | word)) is the concept and that were heard on the map's free space: the top-word
rule, restricted to the words that answer the concept, so that a name always agrees with
``where``. A concept's most probable word may be another concept's answer, and ``show OUT
--graph`` named places after top words (room2ldk4: two places named "bedroom", only one of them
where ``spcopyro where OUT bedroom`` is). Ranking the answering words by p(C | word) instead
picked the word most exclusive to the concept, not the one most said there: on room2ldk4 (200
sweeps, seed 0) the 31.8 m^2 place whose answering words are bedroom, entrance, kitchen and
refrigerator read "entrance" and the one answering parlor, shelf, tv and closet "shelf" (now
"bedroom" and "parlor", their top words); on the seeded default demo every place's top word
answers it, and its names are the same under both rules ("sink" for the kitchen). Where no
word's answer is the concept, the region is named by its most probable word heard there (under
the point labels, where the result keeps ``word_counts``:
:func:`~spcopyro.results.concept_words.shown_top_words`, as the word lists), else by its top
word; a variational E_q[w] gives unheard words mass, and its top word named a region after a
word never heard in it. A posterior mean (Gibbs) ranks its heard words first: the same name. A
fit that did not model its words (``use_words`` off,
:func:`~spcopyro.results.concept_words.words_modelled`: w the prior's, every word tied) names
every concept ``concept N``: its top word was a word in tie order (the embedded house's five
concepts were all "restroom"), and no word's ``where`` answer is learnt. A region where no word
was heard is named ``concept N`` too (even where a word's answer is it: that answer is the
prior's alone).
Place words and object words are not told apart (a fit does not know which is which).

Used by the place graph (:attr:`~spcopyro.robot.navigation.places.Place.name`: ``show
--graph``, ``navigate``'s routes), ``concepts.json``'s ``name`` and the semantic map's label of
a concept's further regions (of a fit that modelled its words). numpy only: ``spcopyro show``
imports it.
"""

from __future__ import annotations

import numpy as np

from spcopyro.config import WORDS
from spcopyro.results.concept_words import ranked, shown_top_words, words_modelled

__all__ = ["answered_words", "concept_name", "concept_names"]


def answered_words(result: object, heard_only: bool = False) -> dict[int, tuple[str, ...]]:
    """Per concept, the words whose ``where`` answer (eq. 19, the default area prior) it is,
    most probable in the concept first (its row of the word table, p(word | concept), ranked
    after rounding to :data:`~spcopyro.results.concept_words.RANK_DECIMALS`, ties in vocabulary
    order); ``heard_only``: only the words heard on the map's free space and the concepts whose
    region holds a heard word (an answer without either is the prior's alone). Empty for a fit
    without words."""
    table = next((t for t in getattr(result, "emissions", ()) if t.name == WORDS), None)
    vocabulary = result.vocabulary  # type: ignore[attr-defined]
    if table is None or not vocabulary or not words_modelled(result):  # the prior's answers
        return {}
    posterior = np.asarray(result.word_posteriors())  # type: ignore[attr-defined]  # [L, V]
    w = np.asarray(table.probabilities)  # [L, V] p(word | concept)
    totals = getattr(result, "word_totals", None)  # [V] or None (an old result: all heard)
    heard = getattr(result, "heard", lambda _: None)
    best = posterior.argmax(axis=0)  # [V] each word's where answer (the first of ties)
    keep = np.ones(best.size, dtype=bool)  # [V] the words that may answer
    if heard_only and totals is not None:
        keep = np.asarray(totals) != 0
    answers: dict[int, tuple[str, ...]] = {}
    for c in np.unique(best[keep]).tolist():
        if heard_only and heard(c) == 0:
            continue
        columns = np.flatnonzero((best == c) & keep)  # [n] vocabulary order
        answers[c] = tuple(vocabulary[v] for v in columns[ranked(w[c, columns])])
    return answers


def concept_name(
    result: object, concept: int, answers: dict[int, tuple[str, ...]] | None = None
) -> str:
    """The name of ``concept``'s region (module docstring): its most probable answered word, else
    its most probable heard word (its top word where the result does not keep ``word_counts``
    or they hold none for it), else ``concept N`` (always, where the fit did not model its
    words). ``answers``:
    :func:`answered_words` with ``heard_only``, when already computed (naming many concepts)."""
    if answers is None:
        answers = answered_words(result, heard_only=True)
    if answers.get(concept):
        return answers[concept][0]
    heard = getattr(result, "heard", lambda _: None)(concept)
    emissions = getattr(result, "emissions", ())
    if heard != 0 and any(table.name == WORDS for table in emissions):
        top = shown_top_words(result, concept, 1)  # none where the words were not modelled
        if top:
            return top[0][0]
    return f"concept {concept}"


def concept_names(result: object) -> dict[int, str]:
    """:func:`concept_name` of every concept in use."""
    answers = answered_words(result, heard_only=True)
    return {
        int(c): concept_name(result, int(c), answers)
        for c in result.concepts_in_use()  # type: ignore[attr-defined]
    }
