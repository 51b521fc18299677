r"""The semantic-map protocol: what any fitted method offers to be scored and queried.

A *semantic map* is a method's answer to the paper's two questions about a map: "what is said
where?" and "where is WORD?". Every fitted method -- SpCoMapping fitted by Gibbs sampling or by
variational inference, or one of the baselines of :mod:`spcopyro.baselines` -- is scored and
queried through one small interface, :class:`SemanticMapModel`:

* ``grid``: the :class:`~spcopyro.maps.OccupancyGrid` the map is drawn on;
* ``vocabulary``: the ``V`` words the method knows, in the column order of
  ``word_distribution``;
* ``label_image()``: an ``[H, W]`` int64 label of every free cell (any numbering: scores that
  compare label images are invariant to it), -1 off free space;
* ``word_distribution(cells)``: ``[n]`` int64 free-cell indices (``grid.free_index`` order, the
  order every per-free-cell array of the package uses) -> ``[n, V]`` float64 p(word | cell),
  rows summing to 1;
* ``region(word)``: the ``[H, W]`` bool cells the method answers "where is ``word``?" with
  (possibly empty), raising :class:`UnknownWordError` (a ``KeyError``) for a word outside
  ``vocabulary``.

Nothing else is required: a method that offers these five members *is* a semantic map
(:class:`SemanticMapModel` is a runtime-checkable :class:`~typing.Protocol`) and every score of
:mod:`spcopyro.metrics` applies to it.

Two implementations live here:

* :class:`TabularSemanticMap`: a label image plus a table of word counts per label, the form
  the baselines (D)-(F) give their answer in;
* :class:`SpCoSemanticMap`: a fitted SpCoMapping result
  (:class:`~spcopyro.results.result.SpCoResult` or anything offering the same members,
  :class:`SpCoResultLike`) seen through the protocol.
  :func:`as_semantic_map` wraps such a result and passes a semantic map through unchanged.

Also here: :func:`word_index`, :func:`word_key`, :func:`close_words`, :func:`did_you_mean` and
:class:`UnknownWordError`, how a word is looked up in a fitted vocabulary. This module imports
neither the samplers nor the result module, so a baseline or a score can depend on it without
pulling in inference.
"""

from __future__ import annotations

import difflib
import re
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from spcopyro._util.messages import KNOWN_WORDS_SHOWN, listed
from spcopyro.data import CellCounts
from spcopyro.data.text import fold_word, hidden_characters_note, hidden_match, tokenize
from spcopyro.maps import OccupancyGrid

__all__ = [
    "SemanticMapModel",
    "SpCoResultLike",
    "SpCoSemanticMap",
    "TabularSemanticMap",
    "UnknownWordError",
    "CLOSE_WORD_CUTOFF",
    "KNOWN_WORDS_SHOWN",
    "as_semantic_map",
    "close_words",
    "did_you_mean",
    "word_index",
    "word_key",
]


class UnknownWordError(KeyError):
    """A word that is not in the fitted vocabulary."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0])


def word_key(vocabulary: Sequence[str], word: str) -> str:
    """How ``word`` is looked up in ``vocabulary``: lower-cased, surrounding spaces dropped,
    and, when that is not a known word, the one token :func:`~spcopyro.data.text.tokenize` makes
    of it (punctuation stripped from its ends, as from every word the data's utterances hold:
    ``"Kitchen?"`` and ``"台所。"`` are ``"kitchen"`` and ``"台所"``); when that is not known
    either, the vocabulary's word that is the same text in another Unicode form (NFKC,
    case-folded: ``"ＴＶ"`` is ``"tv"``, a decomposed ``"ダイニング"`` the composed one).
    TypeError for a word that is not a ``str`` (bytes, a list of words, None)."""
    if not isinstance(word, str):
        raise TypeError(f"a word must be a str, got {type(word).__name__} {word!r}")
    key = word.strip().lower()
    if key in vocabulary:
        return key
    tokens = tokenize(word)
    key = tokens[0] if len(tokens) == 1 else key
    if key not in vocabulary:
        folded = fold_word(key)
        key = next((known for known in vocabulary if fold_word(known) == folded), key)
    return key


CLOSE_WORD_CUTOFF = 0.8
"""The least ``difflib.SequenceMatcher`` ratio (``2 M / (len(a) + len(b))``, ``M`` the
matching characters, of the two words decomposed, NFKD, and case-folded) at which a known word
is offered for an unknown one (:func:`close_words`): every "did you mean" of ``where``,
``export`` and ``navigate``. Measured on the 23 words of the five public houses: of their 6748
one-edit typos (a letter dropped, swapped with the next, changed or added), 91% get the
word first at 0.8 (5555 of the 5558 of the words of five letters or more: "kitchn",
"bedrom" 0.923, "toliet" 0.833, "tabel" and "chiar" 0.8, "refridgerator" 0.96; "diving"
offers "living" before "dining"), 99% at 0.75 or 0.6; a changed letter of a four-letter word
is 0.75 ("sofe"), as far as two distinct words are ("hall" from "wall" 0.75). Other places
and the houses' own words at their closest: "bathroom"/"washroom" 0.75, "bathroom"/"bedroom"
0.667 (difflib's default cutoff, 0.6, offered "bedroom" for "bathroom"), "bathroom"/"bath"
0.667, "restroom"/"bedroom" 0.667, "living"/"dining" 0.667, "floor"/"door" 0.667,
"terrace"/"entrance" 0.667, "bedroom"/"bed" 0.6: the ratio offers none of them (the glued
"room" of :func:`close_words` does offer "bath" for "bathroom", room1ldk5's word for its
bathroom, and "bed" for "bedroom", "rest" for "restroom"). Offered a
different room, a user may send the robot there; the typo of a short word is given up
instead (the error lists the known words)."""

_ROOM_SUFFIX = re.compile(r"[-_]?room$")


def _compared(word: str) -> str:
    """``word`` as :func:`close_words` compares it: decomposed (NFKD, so an accent is one more
    character: "cafe" is 0.889 from "café", not 0.75) and case-folded."""
    return unicodedata.normalize("NFKD", word).casefold()


def close_words(word: str, candidates: Sequence[str], n: int = 3) -> list[str]:
    """At most ``n`` of ``candidates`` that ``word`` (not one of them) may be a misspelling
    of, closest first: a candidate that ``word`` is glued to "room" ("livingroom",
    "dining-room", "bath_room": ``navigate`` reads "living room" as "living", the "room" a
    filler word; 0.75 by ratio), then those at a ``difflib.SequenceMatcher`` ratio of at
    least :data:`CLOSE_WORD_CUTOFF` (its docstring lists the pairs measured). Empty when none
    is close: a different room ("bathroom" for a house with "bedroom" and "washroom") is no
    suggestion, nor is a blank candidate ("" or spaces: no word, which "room" alone, its stem
    empty, was glued to). ``where``'s and ``export``'s :func:`word_index` and ``navigate``'s
    :func:`~spcopyro.robot.navigation.goals.parse_instruction` all suggest through this."""
    words = [c for c in reversed(candidates) if c.strip()]  # the data's readers make no blank
    by_form = {_compared(c): c for c in words}  # form -> its first candidate
    form = _compared(word)
    stem = _ROOM_SUFFIX.sub("", form)
    glued = [by_form[stem]] if stem != form and stem in by_form else []
    ratio = difflib.get_close_matches(form, by_form, n=n, cutoff=CLOSE_WORD_CUTOFF)
    close = glued + [by_form[f] for f in ratio if by_form[f] not in glued]
    return close[:n]


def did_you_mean(key: str, known: Sequence[str], prefix: str = "") -> str:
    """``"; did you mean settings.gamma?"``: the known keys ``key`` may be a misspelling of
    (:func:`close_words`, the one rule), each after ``prefix``; empty where none is close.
    :func:`word_index`, ``navigate``'s instructions
    (:func:`~spcopyro.robot.navigation.goals.parse_instruction`), a study variant's keys
    (:mod:`spcopyro.experiments.ablation_variants`) and a study file's
    (:mod:`spcopyro.study.spec`) suggest through this."""
    close = close_words(key, known)
    return f"; did you mean {', '.join(prefix + c for c in close)}?" if close else ""


def word_index(vocabulary: tuple[str, ...], word: str) -> int:
    """The column of ``word`` (as :func:`word_key` reads it) in ``vocabulary``;
    :class:`UnknownWordError` with the closest known words when it is not there."""
    key = word_key(vocabulary, word)
    try:
        return vocabulary.index(key)
    except ValueError:
        tokens = tokenize(word)
        if len(tokens) > 1:  # "the kitchen": one word is looked up, not a phrase
            known = [t for t in tokens if t in vocabulary]
            example = (
                f" (of these, {', '.join(known)} {'is' if len(known) == 1 else 'are'} known)"
                if known
                else ""
            )
            raise UnknownWordError(
                f"{word!r} holds {len(tokens)} words; give one word of the vocabulary{example}"
            ) from None
        hint = did_you_mean(key, vocabulary)
        if not hint and vocabulary:  # nothing close: say which words there are
            hint = f"; known words: {listed(sorted(vocabulary))}"
        if not vocabulary:  # a house of images only: nothing was heard, no word names a place
            hint = (
                ": the fit heard no words (its house holds no utterances), so it can locate none; "
                "fit it again once words are heard there"
            )
        hidden = hidden_characters_note(word, vocabulary)  # 'kit\u200bchen' prints as kitchen
        if hidden:
            hint = f": {hidden}" + ("" if hidden_match(word, vocabulary) else hint)
        raise UnknownWordError(
            f"word {word!r} is not in the vocabulary of {len(vocabulary)} words{hint}"
        ) from None


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

        Raises :class:`UnknownWordError` (a ``KeyError``) for a word outside
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
        # Not :func:`word_index`: a baseline's vocabulary is matched exactly (no lower-casing)
        # and its message names the method instead of suggesting close words.
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


@runtime_checkable
class SpCoResultLike(Protocol):
    """What :class:`SpCoSemanticMap` reads from a fitted SpCoMapping result.

    :class:`~spcopyro.results.result.SpCoResult` offers it, whatever inference method fitted it; it
    is checked by duck typing (this module does not import the result module).

    Attributes:
        grid: the occupancy grid of the fit.
        vocabulary: ``[V]`` words, the columns of ``w``.
        w: ``[L, V]`` p(word | concept): a point estimate or posterior mean.
        labels: ``[N]`` int point estimate of every free cell's concept (``grid.free_index``
            order).
        marginals: ``[N, L]`` p(C_i = l) where the method has it (variational), else None.
    """

    @property
    def grid(self) -> OccupancyGrid: ...

    @property
    def vocabulary(self) -> tuple[str, ...]: ...

    @property
    def w(self) -> np.ndarray: ...

    @property
    def labels(self) -> np.ndarray: ...

    @property
    def marginals(self) -> np.ndarray | None: ...

    def label_image(self) -> np.ndarray:
        """``[H, W]`` int64 concepts of the point estimate, -1 off free space."""
        ...

    def where(self, word: str, prior: str = "area") -> Any:
        """Eq. (19)'s answer for ``word``; its ``.region`` is the ``[H, W]`` bool place."""
        ...


@dataclass(frozen=True, eq=False)
class SpCoSemanticMap:
    r"""A fitted :class:`~spcopyro.results.result.SpCoResult` seen through
    :class:`SemanticMapModel`.

    ``p(word | cell) = sum_l p(C_cell = l) w_l`` with the result's w. ``p(C_cell = l)`` is: with
    ``label_samples`` (``[S, N]``, e.g. :attr:`~spcopyro.gibbs.run.GibbsRun.label_samples`) the
    fraction of samples in which the cell has label l; else the result's per-cell ``marginals``
    where it has them (a variational q(C)); else 1 for the point estimate's label. Samples
    should come from the same chain near the point estimate: w belongs to one state, and concept
    ids are only comparable within a chain (label switching). ``region(word)`` is
    :meth:`~spcopyro.results.result.SpCoResult.where` (eq. 19) with ``prior`` ("pi" or "area").
    """

    result: SpCoResultLike
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
        if self.label_samples is not None:
            return w[self.label_samples[:, idx]].mean(axis=0)  # [S, n, V] -> [n, V]
        marginals = getattr(self.result, "marginals", None)
        if marginals is not None:
            return np.asarray(marginals, dtype=np.float64)[idx] @ w  # [n, L] @ [L, V]
        return w[self.result.labels[idx]]

    def region(self, word: str) -> np.ndarray:
        return self.result.where(word, prior=self.prior).region


def as_semantic_map(model: SemanticMapModel | SpCoResultLike) -> SemanticMapModel:
    """A :class:`~spcopyro.results.result.SpCoResult` (anything :class:`SpCoResultLike`) wrapped in
    :class:`SpCoSemanticMap`; a model as it is."""
    if isinstance(model, SpCoResultLike):
        return SpCoSemanticMap(model)
    if isinstance(model, SemanticMapModel):
        return model
    raise TypeError(
        f"expected a SemanticMapModel or SpCoResult, got {type(model).__name__} (needs grid, "
        "vocabulary, label_image(), word_distribution(cells), region(word))"
    )
