"""A saved fit's vocabulary read as the tokenizer reads words now.

A fit saved by an older spcopyro may hold words that :func:`~spcopyro.data.text.tokenize` now
folds or strips (``TV``, ``stove.``, a byte-order mark in front): a word typed today (``stove``)
or the data's words never equal them. :func:`renormalise_vocabulary` reads such a vocabulary as
the tokenizer would now, and :func:`renormalised_result` gives a result whose word columns are
read so (saved words that become one word share a column, their probabilities and counts
added): ``fit --update`` (:mod:`spcopyro.robot.online`) and the questions on a saved fit
(``where``, ``export --word``, ``navigate``) read a saved vocabulary this way. Imports neither
torch nor the samplers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from spcopyro._util.messages import echo, listed
from spcopyro.config import WORDS
from spcopyro.data.text import fold_word, tokenize

if TYPE_CHECKING:
    from spcopyro.results.result import SpCoResult

__all__ = ["SavedVocabulary", "renormalise_vocabulary", "renormalised_result"]

RENAMED_SHOWN = 10
"""Renamed words a warning names (then '... (N more)')."""


@dataclass(frozen=True)
class SavedVocabulary:
    """A saved vocabulary as the tokenizer reads words now (:func:`renormalise_vocabulary`)."""

    vocabulary: tuple[str, ...]
    """[V*] the saved words re-normalised, in order of first appearance."""
    columns: np.ndarray
    """[V] the column in :attr:`vocabulary` of each saved word."""
    renamed: tuple[tuple[str, str], ...]
    """(saved word, the word it is now) for each saved word the tokenizer writes otherwise."""
    unmatchable: tuple[str, ...]
    """Saved words that are no single word now (punctuation alone): kept, matching nothing."""

    def fold(self, probabilities: np.ndarray) -> np.ndarray:
        """[L, V*] each row of ``probabilities`` [L, V] over the re-normalised vocabulary (the
        probabilities of saved words that became one word added)."""
        folded = np.zeros((probabilities.shape[0], len(self.vocabulary)))  # [L, V*]
        np.add.at(folded.T, self.columns, np.asarray(probabilities, dtype=np.float64).T)
        return folded

    def renamed_as(self, asked: str) -> str | None:
        """The word a saved word that ``asked`` spells (but for case, surrounding spaces and
        Unicode form: ``stove.`` for a saved ``stove.``) is read as now; None when ``asked``
        spells no saved word that was renamed."""
        key = fold_word(asked.strip())
        return next((new for old, new in self.renamed if fold_word(old) == key), None)

    def renamed_note(self, asked: Sequence[str] = ()) -> str | None:
        """The sentence that names the saved words read as other words (None: none were).
        ``asked``: the words a command was asked about; those that spell a renamed saved word
        (:meth:`renamed_as`) are named first and said to be answered for as the word they are
        now (``where OUT stove.`` on a fit that saved ``stove.`` said so in a second warning
        that called ``stove.`` no word of the vocabulary)."""
        if not self.renamed:
            return None
        spelt = {fold_word(word.strip()) for word in asked if self.renamed_as(word) is not None}
        renamed = sorted(self.renamed, key=lambda pair: fold_word(pair[0]) not in spelt)
        pairs = listed([f"{echo(old)} -> {echo(new)}" for old, new in renamed], RENAMED_SHOWN)
        answered = "".join(
            f"; {echo(word)} is answered for as {echo(self.renamed_as(word))}"
            for word in dict.fromkeys(asked)
            if self.renamed_as(word) is not None
        )
        return (f"{len(self.renamed)} word(s) of its vocabulary are not words the tokenizer "
                f"makes now (a fit saved by an older spcopyro), read as it reads them: "
                f"{pairs}{answered}")  # fmt: skip


def renormalise_vocabulary(saved: Sequence[str]) -> SavedVocabulary:
    """``saved`` (a saved fit's vocabulary) as :func:`~spcopyro.data.text.tokenize` reads
    words now: a word it makes one other word of (``TV`` -> ``tv``, ``stove.`` -> ``stove``)
    is renamed, and saved words that become one word share its column; a word it makes no word
    or several of keeps its column unchanged (listed in ``unmatchable``). Words that the
    tokenizer leaves as they are keep their order: a vocabulary of them is returned as it is."""
    index: dict[str, int] = {}
    columns, renamed, unmatchable = [], [], []
    for word in saved:
        tokens = tokenize(word)
        target = tokens[0] if len(tokens) == 1 else word
        if target != word:
            renamed.append((word, target))
        elif tokens != (word,):
            unmatchable.append(word)
        columns.append(index.setdefault(target, len(index)))
    return SavedVocabulary(
        tuple(index), np.asarray(columns, dtype=np.int64), tuple(renamed), tuple(unmatchable)
    )


def renormalised_result(result: SpCoResult) -> tuple[SpCoResult, SavedVocabulary]:
    """``result`` with its vocabulary read as :func:`renormalise_vocabulary` reads it: the word
    distributions, ``word_totals`` and ``word_counts`` over the re-normalised words (saved words
    that became one word added), and what was read so. ``result`` itself when no word was
    renamed, or when it has no words."""
    if not any(table.name == WORDS for table in result.emissions):
        return result, renormalise_vocabulary(())
    saved = renormalise_vocabulary(result.vocabulary)
    if not saved.renamed:
        return result, saved
    tables = tuple(
        dataclasses.replace(table, items=saved.vocabulary,
                            probabilities=saved.fold(table.probabilities))
        if table.name == WORDS else table
        for table in result.emissions
    )  # fmt: skip
    totals, counts = result.word_totals, result.word_counts
    if totals is not None:
        totals = saved.fold(np.asarray(totals, dtype=np.float64)[None, :])[0]  # [V*]
    if counts is not None:
        counts = saved.fold(counts)  # [L, V*]
    return dataclasses.replace(result, emissions=tables, word_totals=totals,
                               word_counts=counts), saved  # fmt: skip
