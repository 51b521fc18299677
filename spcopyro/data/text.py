"""Words: tokenisation, the utterance-by-token count matrix and tf-idf weights (paper eq. 20).

Utterances are tokenised by :func:`tokenize` (case-folded, NFKC, edge punctuation stripped);
:func:`word_matrix` counts each vocabulary token in each utterance and :func:`tfidf_weights`
weights them by tf-idf, the two word weightings (:data:`WordWeighting`) of
:func:`spcopyro.data.cell_counts`.
"""

from __future__ import annotations

import os
import string
import unicodedata
from collections.abc import Iterable, Sequence

import numpy as np

from spcopyro._util.messages import listed
from spcopyro.config import WordWeighting

__all__ = [
    "WordWeighting",
    "fold_word",
    "format_characters",
    "hidden_characters_note",
    "hidden_word_entries",
    "hidden_match",
    "hidden_words_warning",
    "tfidf_weights",
    "tokenize",
    "unsegmented",
    "word_matrix",
]


_PUNCTUATION = set(string.punctuation)


def fold_word(word: str) -> str:
    """``word`` in Unicode's compatibility composition (NFKC), case-folded: one spelling for
    the ways a keyboard or a file may encode the same word (a decomposed ``"ダ"``, full-width
    ``"ＴＶ"``, ``"STRASSE"`` for ``"straße"``), as ``where`` compares words and
    :func:`tokenize` reads the data's."""
    return unicodedata.normalize("NFKC", word).casefold()


def _is_punctuation(char: str) -> bool:
    """Punctuation, or an invisible format or control character (a zero-width space, a
    byte-order mark left where two files were joined): what a token's ends lose."""
    category = unicodedata.category(char)
    return char in _PUNCTUATION or category[0] == "P" or category in _EDGE_CATEGORIES


_EDGE_CATEGORIES = ("Cf", "Cc")  # format (U+200B, U+FEFF, ...) and control characters


def tokenize(utterance: str) -> tuple[str, ...]:
    """Tokens of an utterance: folded (:func:`fold_word`: case-folded, NFKC), split on
    whitespace, punctuation stripped from both ends of each token (inner punctuation, as in
    ``living-room``, stays), and invisible characters (a zero-width space, a byte-order mark)
    too; empty tokens vanish.

    ``tokenize("Here is the kitchen.") == ("here", "is", "the", "kitchen")``; ``"ＴＶ"`` (full
    width) and ``"TV"`` are one word, ``"tv"``, as are a decomposed and a composed ``"ダ"``.
    """
    tokens = []
    for raw in fold_word(utterance).split():
        start, end = 0, len(raw)
        while start < end and _is_punctuation(raw[start]):
            start += 1
        while end > start and _is_punctuation(raw[end - 1]):
            end -= 1
        if start < end:
            tokens.append(raw[start:end])
    return tuple(tokens)


def format_characters(token: str) -> tuple[str, ...]:
    """The invisible format characters (Unicode category Cf) inside ``token``, each once, as
    ``"U+200B ZERO WIDTH SPACE"``.

    :func:`tokenize` strips them from a token's ends only: inside one, a zero-width space,
    (non-)joiner, soft hyphen or byte-order mark stays, so ``"kit\u200bchen"`` is a word apart
    from ``"kitchen"`` that prints the same. They are not removed, since some spell words (a
    Persian word's zero-width non-joiner) or separate them (a zero-width space in Thai); the
    data's reader warns of them (:mod:`spcopyro.data.dataset_files`).
    """
    found = (char for char in token if unicodedata.category(char) == "Cf")
    return tuple(dict.fromkeys(f"U+{ord(c):04X} {unicodedata.name(c, 'unnamed')}" for c in found))


def hidden_word_entries(utterances: Iterable[Sequence[str]], first_number: int = 0) -> list[str]:
    """Each token of ``utterances`` that holds invisible format characters
    (:func:`format_characters`), once, in order of first use, as ``"'kit\u200bchen' (utterance
    3: U+200B ZERO WIDTH SPACE)"``; utterances numbered from ``first_number`` (the St.csv
    reader's 1, :class:`~spcopyro.data.observations.Observations`' 0)."""
    hidden: dict[str, str] = {}
    for number, tokens in enumerate(utterances, start=first_number):
        for token in tokens:
            if token not in hidden and (chars := format_characters(token)):
                hidden[token] = f"{token!r} (utterance {number}: {', '.join(chars)})"
    return list(hidden.values())


HIDDEN_WORDS_SHOWN = 3
"""Words :func:`hidden_words_warning` names (then '... (N more)')."""


def hidden_words_warning(
    utterances: Iterable[Sequence[str]], source: str | os.PathLike[str] | None = None
) -> str | None:
    """The warning that words of ``utterances`` hold invisible format characters
    (:func:`hidden_word_entries`: ``'kit\u200bchen'`` prints as ``'kitchen'`` but is a word
    apart from it); None when none does. ``source``: the St.csv the utterances were read from
    (named with its line, the utterances numbered from 1 as its entries are); None: given as
    tokens to :class:`~spcopyro.data.observations.Observations` (numbered from 0, its
    indices). The one wording of both, which the St.csv reader and ``Observations`` log."""
    hidden = hidden_word_entries(utterances, first_number=0 if source is None else 1)
    if not hidden:
        return None
    shown = listed(hidden, HIDDEN_WORDS_SHOWN)
    if source is None:
        where, whose, read, kept = "Observations", " of the utterances", "", ""
    else:
        where, whose, read = f"{os.fspath(source)}, line 1", "", "read as "
        kept = ", as Persian needs its zero-width non-joiner"
    return (
        f"{where}: {len(hidden)} word(s){whose} hold invisible format characters (Unicode "
        f"category Cf), each {read}a word apart from its letters without them: {shown} (kept: "
        f"remove them where the language does not need them{kept})"
    )


def hidden_characters_note(word: str, vocabulary: Sequence[str]) -> str | None:
    """Why ``word`` (asked of ``where`` or ``navigate``) is not the vocabulary's word it prints
    as: the invisible format characters inside it (:func:`format_characters`) and the
    vocabulary's word it is without them (``'kit\u200bchen'``: ``'kitchen'``), or the
    vocabulary's word that is it with such characters inside (the data's ``'kit\u200bchen'``
    for a typed ``'kitchen'``); None when neither holds any."""
    chars, same = format_characters(word.strip()), hidden_match(word, vocabulary)
    if chars:
        found = f"; without them it is {same!r}, a word of the vocabulary" if same else ""
        return f"{word!r} holds invisible format characters (Unicode category Cf): " + (
            ", ".join(chars) + found
        )
    if same is None:
        return None
    return (
        f"the vocabulary's {same!r} is {word!r} with invisible format characters (Unicode "
        f"category Cf) inside, as the data spell it: {', '.join(format_characters(same))}"
    )


def hidden_match(word: str, vocabulary: Sequence[str]) -> str | None:
    """The word of ``vocabulary`` that is ``word`` but for the invisible format characters
    (Unicode Cf) either holds, folded (:func:`fold_word`); None when there is none or neither
    holds any (then ``word`` is looked up as it is)."""
    bare = _without_format_characters(word.strip())
    hidden = bool(format_characters(word))
    return next((known for known in vocabulary if (hidden or format_characters(known))
                 and _without_format_characters(known) == bare), None)  # fmt: skip


def _without_format_characters(word: str) -> str:
    """``word`` folded (:func:`fold_word`) without its format characters (Unicode Cf)."""
    return fold_word("".join(c for c in word if unicodedata.category(c) != "Cf"))


_UNSPACED_SCRIPTS = {"CJK": 6, "HIRAGANA": 6, "KATAKANA": 6, "THAI": 10, "LAO": 10, "KHMER": 10,
                     "MYANMAR": 10}  # fmt: skip
"""Scripts written without spaces between words (Unicode character names' first word), and the
letters a word of theirs may hold before :func:`unsegmented` takes it for a sentence: Japanese
and Chinese words are short (台所, 冷蔵庫, お手洗い), Thai ones longer (ห้องครัว, 6 letters)."""


def unsegmented(token: str) -> bool:
    """Whether ``token`` (one of :func:`tokenize`'s) looks like a sentence of a script written
    without spaces, read as one word: at least 6 letters of Han and kana (``ここは台所です``;
    katakana alone is a loanword, ``ダイニングキッチン``, and not counted) or 10 of Thai, Lao,
    Khmer or Myanmar, and no other letter. Nothing here splits it: a segmenter (MeCab's
    ``-Owakati`` for Japanese) writes such text with spaces between its words."""
    scripts = []
    for char in token:
        category = unicodedata.category(char)
        if category == "Lo":
            scripts.append(unicodedata.name(char, "").split(" ")[0])
        elif category[0] == "L" and category != "Lm":  # Lm: ー, 々, of no script by name
            return False  # a letter of a spaced script (Latin, Cyrillic, ...)
    if not scripts or any(script not in _UNSPACED_SCRIPTS for script in scripts):
        return False
    if set(scripts) == {"KATAKANA"}:
        return False
    return len(scripts) >= min(_UNSPACED_SCRIPTS[script] for script in scripts)


def _check_tokens(tokens: Iterable[object], utterance: int) -> None:
    """Raise ValueError naming ``utterance`` (its index) at its first token that is not non-blank
    text: ``""`` or ``" "`` is no word, and no data's words hold one (:func:`tokenize` drops
    them). Observations and :func:`word_matrix` both check with it."""
    for token in tokens:
        if not isinstance(token, str) or not token.strip():
            raise ValueError(
                f"utterance {utterance} holds the token {token!r}: a token is non-blank text "
                "(spcopyro.data.tokenize drops blank ones)"
            )


def _vocabulary_index(vocabulary: Sequence[str]) -> dict[str, int]:
    """``{word: column}`` of a vocabulary; ValueError at a blank word or one listed twice."""
    for v, token in enumerate(vocabulary):
        if not isinstance(token, str) or not token.strip():
            raise ValueError(f"vocabulary word {v} is {token!r}: a word is non-blank text")
    index = {token: v for v, token in enumerate(vocabulary)}
    if len(index) != len(vocabulary):
        seen: set[str] = set()
        dup = next(t for t in vocabulary if t in seen or seen.add(t))
        raise ValueError(f"vocabulary lists {dup!r} more than once")
    return index


def word_matrix(
    utterances: Sequence[Sequence[str]], vocabulary: Sequence[str] | None = None
) -> np.ndarray:
    """``[U, V]`` float64 counts n(t, d) of each vocabulary token t in each utterance d.

    ``vocabulary`` defaults to the distinct tokens in order of first appearance. A token that is
    not in a given vocabulary raises ValueError (naming it): nothing is dropped silently; so does
    an empty (or blank) token or vocabulary word, ``""``, which no data's words hold.
    """
    for d, tokens in enumerate(utterances):  # as Observations refuses them: no word at all
        _check_tokens(tokens, d)
    if vocabulary is None:
        vocabulary = tuple(dict.fromkeys(t for u in utterances for t in u))
    index = _vocabulary_index(vocabulary)
    rows, cols, unknown = [], [], {}
    for d, tokens in enumerate(utterances):
        for token in tokens:
            v = index.get(token)
            if v is None:
                unknown.setdefault(token, d)
            else:
                rows.append(d)
                cols.append(v)
    if unknown:
        listed = ", ".join(f"{t!r} (utterance {d})" for t, d in list(unknown.items())[:10])
        raise ValueError(
            f"{len(unknown)} token(s) not in the given vocabulary of {len(index)}: {listed}"
        )
    counts = np.zeros((len(utterances), len(index)), dtype=np.float64)  # [U, V]
    np.add.at(counts, (np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)), 1.0)
    return counts


def tfidf_weights(
    utterances: Sequence[Sequence[str]], vocabulary: Sequence[str] | None = None
) -> np.ndarray:
    """tf-idf weight of every vocabulary token in every utterance (paper eq. 20).

    Each utterance is a document d; D is the number of utterances::

        tf(t, d)     = n(t, d) / |d|            n(t, d): occurrences of t in d, |d|: tokens in d
        idf(t)       = log(D / df(t))           df(t): number of utterances containing t
        tfidf(t, d)  = tf(t, d) * idf(t)

    (natural log). A token present in *every* utterance gets weight 0 everywhere -- that is the
    point of idf: it carries no information about where it was said. A vocabulary token that
    occurs in no utterance (df = 0) gets weight 0. Each row sums to at most log(D).

    Args:
        utterances: ``[U]`` token sequences (each non-empty).
        vocabulary: ``[V]`` columns; defaults to distinct tokens in order of first appearance.
            A token not in a given vocabulary, or an empty one (``""``), raises ValueError.

    Returns:
        ``[U, V]`` float64 matrix; row d holds tfidf(t, d) for every vocabulary token t
        (0 for tokens not in d).
    """
    counts = word_matrix(utterances, vocabulary)  # [U, V]
    num_docs = counts.shape[0]
    length = counts.sum(axis=1, keepdims=True)  # [U, 1] |d|
    if (length == 0).any():
        raise ValueError(f"utterance {int(np.flatnonzero(length == 0)[0])} holds no tokens")
    doc_freq = (counts > 0).sum(axis=0)  # [V] df(t)
    idf = np.zeros(counts.shape[1], dtype=np.float64)  # [V]
    seen = doc_freq > 0
    idf[seen] = np.log(num_docs / doc_freq[seen])
    return counts / length * idf  # [U, V]
