r""" "Where is X?" from a fitted map, and when its answer deserves care.

Place estimation from a word is the paper's eq. (19):

.. math::

    \hat C = \arg\max_l p(C = l \mid S) = \arg\max_l \; w_{l,S} \, \pi_l ,

taken over the concepts that label at least one cell (a concept that labels no cell has no
region to point at). With the presets' huge alpha (1e7-1e8), pi is nearly uniform, so eq. (19)
weighs a concept of three cells like one of a thousand and can point at a speck whose few
observed cells hold the word. ``prior="area"`` replaces pi_l by the share of the map's cells
labelled l (the probability that a uniformly chosen free cell has concept l), which answers
"which region would a word uttered somewhere on this map come from?":

.. math::

    p(C = l \mid S) \propto w_{l,S} \, \frac{n_l}{N}
    = \frac{1}{N} \sum_{i : C_i = l} w_{C_i, S},

the word's posterior over the cells where it may have been said (uniform over the N free cells)
summed over each concept's n_l cells -- so the area prior *is* the word's posterior over cells,
read per concept. It is the default of :meth:`~spcopyro.results.result.SpCoResult.where` and of
``spcopyro where``.
On the default synthetic house fitted with ``paper-dp`` (5000 sweeps, seed 0) eq. (19) with pi
answers "kitchen" with a concept of one cell in a doorway (p = 0.134, every concept between 0.12
and 0.134), while the area prior answers with the 992-cell region that holds all 510 kitchen
cells (and the living room). The experiments' table keeps both columns (``SpCoSemanticMap``
still defaults to pi); re-measured on 2026-12-05 with word tables that are posterior means
(docs/evaluation.md, five synthetic houses): with the released code's values and gamma 3 both
match 0.995 (with one drawn w, as results reported before, pi matched 0.428); under ``paper-dp``
pi matches 0.785 and the area prior 0.167: beta = 500 leaves every concept's words near
uniform, so the area prior answers every word with the largest region, while pi's near-equal
weights let the word's small lean decide -- the warnings below say the area prior's answer
follows the prior there. ``prior="pi"`` remains the paper's eq. (19). Under the default preset
(5000 sweeps, seed 0, measured 2026-12-05) the two priors answered alike on the five synthetic
houses (matching rate 0.991-1.000) and on three of the five public houses (against the region
truth of docs/real_houses.md); on room1ldk4 and room2ldk4 pi matched more (0.553 and 0.487
against 0.492 and 0.449; mean over the five 0.576 against 0.556; seeds 1 and 2 the same to
0.002). That matching rate is eq. (18)'s precision, which rewards a small region inside the
right room; pi picks smaller regions there, and by recall (0.595 / 0.868 against 0.614 / 0.888)
and IoU (0.420 / 0.395 against 0.406 / 0.403) the two priors are even. So the area prior stays
the default, and ``prior="pi"`` is the choice for a goal inside the place rather than its
extent.

Answers to treat with care carry warnings (:attr:`WhereAnswer.warnings`): the best concept's
posterior odds over the runner-up below :data:`ODDS_WARNING`, the word's Bayes factor for the
best concept (how much hearing it changes that concept's odds from the prior) below
:data:`EVIDENCE_WARNING`, a region that is a speck by the rule of the concept listing and the
map's legend (:func:`~spcopyro.results.concept_words.is_speck`: under 0.5 % of the free cells
and 0.5 m^2, and under 0.1 words heard in it; by size alone, and saying so, where the words
heard in it are not known), or a region strewn over the map in pieces each smaller than
:data:`SMALL_REGION_FRACTION` of the free cells (see :func:`answer_warnings`). The last one is
for a disordered map: room1dk5 fitted with the released code's values (``--preset
original-code``, 1000 sweeps) labels the house with 120 concepts of 120-180 cells each, salt and
pepper; "where is the bedroom?" answered with 144 cells in 128 pieces (the largest 6 cells) over
the whole house, at odds 5.5 and Bayes factor 7.5, and nothing warned (its 0.77% of the free
cells is no speck).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from spcopyro._util.messages import plural, setting, shown_count
from spcopyro.results.concept_words import SPECK_SHARE, SPECK_WORDS, is_speck, speck_sized

__all__ = [
    "DEFAULT_WHERE_PRIOR",
    "EVIDENCE_WARNING",
    "ODDS_WARNING",
    "SMALL_REGION_FRACTION",
    "WHERE_PRIORS",
    "WhereAnswer",
    "answer_warnings",
    "answers_by_concept",
    "bayes_factor",
    "close_to_guess",
    "region_pieces",
    "region_piece_sizes",
    "runner_up_line",
    "SHARED_ANSWER_P",
    "concept_given_words",
    "shared_answers",
    "shared_answer_note",
    "shared_concept_note",
]

WHERE_PRIORS = ("area", "pi")
DEFAULT_WHERE_PRIOR = "area"
"""p(C) of "where is X?" by default: each concept's share of the map (see the module docstring)."""

ODDS_WARNING = 3.0
"""Posterior odds p(best | word) / p(runner-up | word) below which an answer is flagged as not
clearly ahead of the runner-up (:func:`close_odds`). 3 is the bound of Kass and Raftery (1995,
JASA 90:773) under which odds are "not worth more than a bare mention". Measured (original-code,
gamma 3, 1000 sweeps): the six category words of the synthetic house of seed 0 have odds 4-85
with the area prior, 1.02-1.39 with pi (which picks one-cell specks); under paper-dp's
near-uniform words every answer has odds near 1."""


def close_to_guess(odds: float) -> bool:
    """Whether posterior odds of the best concept over the runner-up are below
    :data:`ODDS_WARNING` (:attr:`WhereAnswer.close_to_guess`, :func:`answer_warnings`, and
    ``navigate``'s goals)."""
    return odds < ODDS_WARNING


def close_odds(concept: int, runner_up: int, best: float, second: float) -> str:
    """The words of the close-odds warning, ``"concept C is not clearly more probable than
    concept R (p(concept | word) = B against S, odds B/S < 3)"``: :func:`answer_warnings` and
    ``navigate --strict``'s refusal (:class:`~spcopyro.robot.navigation.goals.AmbiguousGoalError`)
    say it alike. ``best``, ``second``: p(C = concept | word), p(C = runner_up | word) > 0."""
    return (
        f"concept {concept} is not clearly more probable than concept {runner_up} "
        f"(p(concept | word) = {best:.3f} against {second:.3f}, odds {best / second:.2f} < "
        f"{ODDS_WARNING:g})"
    )


EVIDENCE_WARNING = 3.0
"""Bayes factor of the word for the best concept against the others, below which the answer is
flagged as coming from the prior (the region's size, or pi) rather than from the word. Same
bound as :data:`ODDS_WARNING`. On that fit: 15-261 (area prior); under paper-dp about 1."""

SMALL_REGION_FRACTION = SPECK_SHARE
"""The speck share, :data:`~spcopyro.results.concept_words.SPECK_SHARE` (0.5% of the free
cells) under this module's name, the same object so that the two cannot drift apart: a region
strewn over the map in pieces each holding fewer than this is flagged (:func:`answer_warnings`),
and :func:`spcopyro.figures.plotting.plot_semantic_map` writes no label on a region under it (93
cells, 0.23 m^2, in room1dk5; 18 cells in the synthetic house, whose smallest room holds 13%).
Whether the answer's region is a speck is :func:`~spcopyro.results.concept_words.is_speck`'s to
say (under this share of the free cells and under 0.5 m^2, and under 0.1 words heard there)."""


SHARED_ANSWER_P = 0.5
"""Another word of the vocabulary whose own answer is the same concept with p(C | word) above
this (more probable than every other concept together) is listed in
:attr:`WhereAnswer.shared_with`: high p says the concept is the word's, not that its region is
the word's place alone. On room2ldk4 (default fit, seed 0) one concept holds the living room,
shower and toilet: 'toilet' p = 0.984 with 9% of the region in the toilet, and 'living',
'shower' and 'table' are answered with it at p 0.98-0.99."""


def concept_given_words(w: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """[L, V] p(C = l | word) of every word: w_{l,word} p(C = l) normalised over l (eq. 19), a
    column of zeros for a word no concept with prior mass emits.

    Args:
        w: [L, V] p(word | concept).
        prior: [L] p(C = l) over the concepts in use (0 elsewhere).
    """
    score = np.asarray(w, dtype=np.float64) * np.asarray(prior, dtype=np.float64)[:, None]
    total = score.sum(0)  # [V]
    return np.divide(score, total, out=np.zeros_like(score), where=total > 0)  # [L, V]


def answers_by_concept(posterior: np.ndarray) -> dict[int, list[tuple[int, float]]]:
    """Per concept, the words whose answer it is (each word's argmax over ``posterior``'s
    concepts, the first of ties, as ``where``'s), as (word's column, p(C | word)), highest p
    first, ties in vocabulary order; a concept that answers no word is left out.

    Args:
        posterior: [L, V] p(C = l | word) (:func:`concept_given_words`).
    """
    posterior = np.asarray(posterior)
    best = posterior.argmax(axis=0)  # [V] each word's answer
    p = posterior[best, np.arange(posterior.shape[1])]  # [V]
    answers: dict[int, list[tuple[int, float]]] = {}
    for v in np.argsort(-p, kind="stable"):
        answers.setdefault(int(best[v]), []).append((int(v), float(p[v])))
    return answers


def shared_answers(
    w: np.ndarray,
    prior: np.ndarray,
    concept: int,
    vocabulary: list[str] | tuple[str, ...],
    word: str,
    threshold: float = SHARED_ANSWER_P,
    posterior: np.ndarray | None = None,
) -> tuple[tuple[str, float], ...]:
    """The other words whose answer is ``concept`` with p(C = concept | word') > ``threshold``,
    as (word', p), most probable first (ties in vocabulary order).

    Args:
        w: [L, V] p(word | concept).
        prior: [L] p(C = l) over the concepts in use (0 elsewhere), as the answer used.
        concept: the answer's concept.
        vocabulary: [V] the words of ``w``'s columns.
        word: the asked word (left out).
        threshold: :data:`SHARED_ANSWER_P` by default.
        posterior: [L, V] :func:`concept_given_words` of ``w`` and ``prior`` when already
            computed (:meth:`SpCoResult.word_posteriors
            <spcopyro.results.result.SpCoResult.word_posteriors>` keeps it per prior); None:
            computed here.
    """
    if posterior is None:
        posterior = concept_given_words(w, prior)  # [L, V]
    answered = answers_by_concept(posterior).get(concept, [])  # p exact, not rounded
    return tuple(
        (str(vocabulary[v]), p) for v, p in answered if vocabulary[v] != word and p > threshold
    )


def shared_answer_note(answer: WhereAnswer, shown: int = 3) -> str | None:
    """One line saying which other words the answer's concept also answers
    (:attr:`WhereAnswer.shared_with`, at most ``shown`` named), or None when none."""
    return shared_concept_note(answer.concept, answer.shared_with, shown)


def shared_concept_note(
    concept: int, shared_with: Sequence[tuple[str, float]], shown: int = 3
) -> str | None:
    """:func:`shared_answer_note` of an answer's ``concept`` and
    :attr:`~WhereAnswer.shared_with` (``navigate`` keeps these two of each stop's answer).
    One word over ``shown`` is named, not counted (:func:`~spcopyro._util.messages.shown_count`,
    as :func:`~spcopyro._util.messages.listed` lists)."""
    if not shared_with:
        return None
    shown = shown_count(len(shared_with), shown)
    named = ", ".join(f"{w!r} ({_above_text(p, SHARED_ANSWER_P)})" for w, p in shared_with[:shown])
    more = len(shared_with) - shown
    rest = f" and {plural(more, 'more word')}" if more > 0 else ""
    return (  # p named as where's answer line names it (a bare 'p 0.87' before)
        f"concept {concept} is also the answer, at p(concept | word) > {SHARED_ANSWER_P:g}, for "
        f"{named}{rest}: if one of them names another room, this region holds both"
    )


def _above_text(p: float, threshold: float, digits: int = 2) -> str:
    """``p`` (above ``threshold``) to ``digits`` decimals, or as many more as it takes to show
    a value above ``threshold``: 0.5003 over 0.5 is "0.5003", not "0.50"."""
    for places in range(digits, 17):
        text = f"{p:.{places}f}"
        if float(text) > threshold:
            return text
    return repr(p)


@dataclass(frozen=True)
class WhereAnswer:
    """The answer to "where is WORD?"."""

    word: str
    concept: int
    probability: float
    """p(C = concept | word) (eq. 19), normalised over the concepts in use."""
    region: np.ndarray
    """[H, W] bool: the cells labelled with ``concept``."""
    prior: str = DEFAULT_WHERE_PRIOR
    """p(C) used: ``"area"`` (share of the map) or ``"pi"`` (the paper's eq. 19)."""
    runner_up: int | None = None
    """The second most probable concept (None when one concept labels the whole map)."""
    runner_up_probability: float = 0.0
    """p(C = runner_up | word)."""
    evidence: float = float("inf")
    """Bayes factor of the word for ``concept`` against the other concepts in use:
    posterior odds of ``concept`` divided by its prior odds."""
    warnings: tuple[str, ...] = ()
    """Why the answer deserves care, one sentence each (empty for a clear answer)."""
    shared_with: tuple[tuple[str, float], ...] = ()
    """The other words answered by ``concept`` too, each with p(C = concept | word) above
    :data:`SHARED_ANSWER_P`, most probable first (:func:`shared_answers`): a concept answering
    'kitchen' and 'toilet' at p near 1 may cover both rooms."""

    @property
    def odds(self) -> float:
        """Posterior odds of ``concept`` over the runner-up (inf without one)."""
        if self.runner_up is None or self.runner_up_probability <= 0:
            return float("inf")
        return self.probability / self.runner_up_probability

    @property
    def close_to_guess(self) -> bool:
        """The odds over the runner-up are below :data:`ODDS_WARNING` (a warning says so)."""
        return close_to_guess(self.odds)


def answer_warnings(
    posterior: np.ndarray,
    prior: np.ndarray,
    sizes: np.ndarray,
    *,
    word: str = "",
    prior_name: str = DEFAULT_WHERE_PRIOR,
    cell_area: float,
    region: np.ndarray | None = None,
    connectivity: int = 4,
    words_modelled: bool = True,
    heard: float | None = None,
) -> tuple[str, ...]:
    r"""The warnings of the answer argmax ``posterior`` (see :class:`WhereAnswer`).

    Args:
        posterior: [L] p(C = l | word), summing to 1 over the concepts in use, 0 elsewhere.
        prior: [L] p(C = l) over the concepts in use (sums to 1), 0 elsewhere.
        sizes: [L] cells of each concept.
        word: the word (for the messages).
        prior_name: ``"area"`` or ``"pi"`` (for the messages).
        cell_area: square metres of one cell, the labels' grid resolution squared (the area in
            the messages, and a speck's bound :data:`~spcopyro.results.concept_words.SPECK_AREA`);
            required: a default would decide which regions are specks.
        region: [H, W] bool, the best concept's cells (None: its pieces are not checked).
        connectivity: 4 or 8, the neighbourhood that joins the region's cells into pieces
            (the model's, :attr:`~spcopyro.config.SpCoConfig.connectivity`).
        words_modelled: False for a fit that did not model its words (``use_words`` off,
            :func:`~spcopyro.results.concept_words.words_modelled`): every w_l is the prior's,
            so the posterior is the prior whatever the word, which the first warning says.
        heard: the words heard in the best concept's cells (:meth:`SpCoResult.heard
            <spcopyro.results.result.SpCoResult.heard>`: the model's counts over
            ``word_scaling``); None where they are not known (a result without its counts, or
            a caller that does not pass them): the size alone then decides a speck.

    With c the best concept and c' the runner-up, it warns when

    .. math::

        \frac{p(c \mid S)}{p(c' \mid S)} < \text{ODDS\_WARNING}, \qquad
        K = \frac{p(c \mid S) / (1 - p(c \mid S))}{p(c) / (1 - p(c))}
          < \text{EVIDENCE\_WARNING}, \qquad
        n_c < \text{SPECK\_SHARE} \cdot N \;\text{and}\; n_c a < \text{SPECK\_AREA}
        \;\text{and}\; h_c < \text{SPECK\_WORDS},

    the last the rule of :func:`~spcopyro.results.concept_words.is_speck` (h_c the words heard in
    c's cells, a the square metres of one cell, ``cell_area``), by which the concept listing, the
    map's legend and ``concepts.json`` call a concept a speck, so that ``where`` calls the same
    concepts specks they do. Where h_c is not known (``heard`` None) the size alone decides (share
    and area, :func:`~spcopyro.results.concept_words.speck_sized`), and the warning says so. A
    region as small where words were heard gets no warning: it is a small place (a toilet or a
    closet holds under 0.5 % of a large map), the answer line already gives its cells and m^2, and
    "a speck, not a place" told the user asking "where is the toilet?" that the toilet the word was
    heard in was none (a warning is for an answer to treat with care, and the odds and Bayes factor
    warnings still flag it where the word does not single it out). It also warns when the region
    (not small itself) lies in several pieces, each under SMALL_REGION_FRACTION * N cells (specks
    strewn over the map, not a place), and when one concept labels the whole map (every word points
    there); first of all, when the fit did not model its words.
    """
    posterior = np.asarray(posterior, dtype=np.float64)  # [L]
    order = np.argsort(-posterior, kind="stable")
    concept = int(order[0])
    used = int((sizes > 0).sum())
    num_free = int(sizes.sum())
    basis = "its share of the map" if prior_name == "area" else "pi"
    warnings = [] if words_modelled else [
        f"this fit did not model its words (use_words off): every concept's word distribution "
        f"is its prior's, the same for every word, so the answer is the concept the prior "
        f"({basis}) favours whatever the word, and says nothing about where {word!r} is"
    ]  # fmt: skip
    if used < 2:
        return (
            *warnings,
            f"one concept labels the whole map: every word points to concept {concept}",
        )
    best, second = float(posterior[concept]), float(posterior[order[1]])
    if second > 0 and close_to_guess(best / second):
        warnings.append(
            f"{close_odds(concept, int(order[1]), best, second)}: treat the answer with care"
        )
    evidence = bayes_factor(best, float(prior[concept]))
    if evidence < EVIDENCE_WARNING:
        warnings.append(
            f"the word {word!r} says little about concept {concept}: it changes that concept's "
            f"odds by a factor of {evidence:.2f} (< {EVIDENCE_WARNING:g}), so the answer "
            f"follows mostly from the prior ({basis})"
        )
    cells = int(sizes[concept])
    small = cells < SPECK_SHARE * num_free  # a speck or a small place: never "strewn"
    if heard is None:  # judged by its size alone: share and area
        speck = speck_sized(cells, num_free, cell_area)
    else:
        speck = is_speck(cells, heard, num_free, cell_area)
    if speck:
        area = setting("prior='area'", "--prior area", "where")  # a library caller's and where's
        hint = (
            f" (eq. 19 with pi weighs a speck like a room; {area} weighs concepts by their "
            "share of the map)"
            if prior_name == "pi"
            else ""
        )
        if heard is None:
            verdict = (
                f": a speck, not a place{hint}; judged by its size alone: no count of the words "
                "heard in it is known"
            )
        else:
            verdict = f" where {_heard_text(heard)}: a speck, not a place{hint}"
        warnings.append(
            f"the region is {plural(cells, 'cell')} "
            f"({cells * cell_area:.2f} m^2, {cells / num_free:.2%} of the free cells, under "
            f"{SPECK_SHARE:.1%}){verdict}"
        )
    elif not small and region is not None:
        pieces, largest = region_pieces(region, connectivity)
        if pieces > 1 and largest < SMALL_REGION_FRACTION * num_free:
            warnings.append(
                f"the region is strewn over the map: {plural(cells, 'cell')} in {pieces} "
                f"pieces, the largest {plural(largest, 'cell')} ({largest * cell_area:.2f} m^2, "
                f"under {SMALL_REGION_FRACTION:.1%} of the free cells): specks, not a place "
                "(a disordered map; more sweeps or another preset may order it)"
            )
    return tuple(warnings)


def _heard_text(heard: float) -> str:
    """The words heard in a speck, for its warning: ``"no word was heard"`` or ``"0.013 words
    were heard (under 0.1)"`` (:data:`~spcopyro.results.concept_words.SPECK_WORDS`)."""
    if heard <= 0:
        return "no word was heard"
    places = next(n for n in range(2, 18) if float(f"{heard:.{n}g}") < SPECK_WORDS)
    return f"{heard:.{places}g} words were heard (under {SPECK_WORDS:g})"  # 0.0999 not "0.1"


def region_pieces(region: np.ndarray, connectivity: int = 4) -> tuple[int, int]:
    """(number of pieces, cells of the largest) of the ``[H, W]`` bool ``region``, its cells
    joined through the 4- or 8-neighbourhood; (0, 0) for an empty region."""
    sizes = region_piece_sizes(region, connectivity)
    return len(sizes), (sizes[0] if sizes else 0)


def region_piece_sizes(region: np.ndarray, connectivity: int = 4) -> list[int]:
    """The cells of each piece of the ``[H, W]`` bool ``region``, largest first, its cells
    joined through the 4- or 8-neighbourhood (the model's,
    :attr:`~spcopyro.config.SpCoConfig.connectivity`); ``[]`` for an empty region."""
    from scipy import ndimage

    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")
    structure = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    labelled, _ = ndimage.label(np.asarray(region, dtype=bool), structure=structure)
    return sorted(np.bincount(labelled.ravel())[1:].tolist(), reverse=True)  # [pieces]


def runner_up_line(answer: WhereAnswer) -> str:
    """``where``'s line after an answer with a runner-up (its caller checks that there is one):
    the runner-up, and the word's Bayes factor for the answer's concept with what it means. The
    factor, :func:`bayes_factor` of p(concept | word) and p(concept), is also p(word | concept)
    over p(word | not the concept), the other concepts mixed by their prior weights: 60.56 says
    the word is 60.56 times as likely in the concept as in the others (under the area prior: as
    on the rest of the map)."""
    return (f"runner-up: concept {answer.runner_up} (p(concept | word) = "
            f"{answer.runner_up_probability:.3f}); Bayes factor of the word for concept "
            f"{answer.concept}: {answer.evidence:.2f} (how many times as likely the word is in "
            f"this concept as in the others, weighted by the {answer.prior} prior: the concept's "
            f"odds given the word over its prior odds)")  # fmt: skip


def bayes_factor(posterior: float, prior: float) -> float:
    """Posterior odds over prior odds of one concept (inf when either is 0 or 1)."""
    if not 0 < posterior < 1 or not 0 < prior < 1:
        return float("inf")
    return (posterior / (1 - posterior)) / (prior / (1 - prior))
