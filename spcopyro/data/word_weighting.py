"""The word weighting ``"auto"``: tf-idf when the utterances are sentences, counts otherwise.

Words are never pre-listed: any token becomes vocabulary. Single words (the public dataset's
"kitchen", "bedroom") are counted as they are; sentences ("here is the kitchen") carry filler
words said everywhere, which tf-idf (paper eq. 20, Section 5's Table 5 setting) weighs down.

**The rule** (:func:`auto_word_weighting`): an utterance is a *sentence* when it holds more
than one token (:func:`spcopyro.data.tokenize`'s tokens: ``"living room"`` is a sentence of
two). ``"auto"`` is ``"tfidf"`` when at least :data:`TFIDF_SENTENCE_SHARE` (30%) of the
utterances are sentences, ``"count"`` otherwise (single words, a few multi-word names among
them, or no utterance). It is resolved once, when the data are known
(:func:`resolved_preparation`), and a fit records the resolved value (``config.json``'s
``data.word_weighting``); an online update keeps the weighting of the fit it updates
(:func:`keeping_word_weighting`). The decision carries its reason (:class:`AutoWeighting`:
the sentences and utterances it counted), which the fit's data line gives.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

from spcopyro._util.messages import one_of
from spcopyro.config import RESOLVED_WORD_WEIGHTINGS, WORD_WEIGHTINGS, WordWeighting

if TYPE_CHECKING:
    from spcopyro.config import DataPreparation, SpCoSettings
    from spcopyro.data.observations import Observations

__all__ = [
    "TFIDF_SENTENCE_SHARE",
    "AutoWeighting",
    "auto_word_weighting",
    "keeping_word_weighting",
    "resolve_word_weighting",
    "resolved_preparation",
    "resolved_settings",
    "sentence_count",
]


def sentence_count(observations: Observations) -> int:
    """How many utterances of ``observations`` are sentences (more than one token)."""
    return sum(len(tokens) > 1 for tokens in observations.utterances)


TFIDF_SENTENCE_SHARE = 0.3
"""The share of utterances that are sentences from which ``"auto"`` weighs words by tf-idf.

Measured 2026-12-05 on ``spcopyro simulate`` houses (6 rooms, 54 utterances; ``--sentences``
0, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0 on seeds 0-5 and 0.1, 0.15, 0.2, 0.3 on seeds 6-11), each fitted
with ``fit``'s defaults, 300 sweeps, once counting words, once by tf-idf; grouped by the share
of sentences the house actually holds (ARI against the ground truth, mean; regions not specks;
"filler": a region named after "is", "here", "the", ...):

=================================  ======  =========  =========  ============  ============
houses (share of sentences)        houses  ARI count  ARI tfidf  filler count  filler tfidf
=================================  ======  =========  =========  ============  ============
single words (0%)                  6       0.970      0.970      0             0
single words, 1-2 "living room"    12      0.988      0.956      0             0
0 < share < 30%                    38      0.975      0.964      2 houses      1 house
share >= 30% (31-98%)              20      0.967      0.967      16 houses     0
=================================  ======  =========  =========  ============  ============

Below 30% tf-idf cost ARI (0.011 on the 38 houses, 0.032 with 1-2 "living room", none on
single words) and split rooms (regions for 6 rooms a house: 243 for 228, counts 230; with
"living room" 83 for 72, counts 72; single words 41 for 36, counts 36): on single words it
weighs down the place words said most often. From 30% up, counted words named a region after a
filler on 16 of the 20 houses (26 regions; on 2 of the 38 below), tf-idf on none, at the same
ARI. The share of the simulated ``--sentences 0.3`` houses ran 19-43%, of ``0.5`` 43-57%.
"""


@dataclass(frozen=True)
class AutoWeighting:
    """What ``"auto"`` chose for a house's utterances and why (:func:`auto_word_weighting`):
    the rule and the note the fit's data line gives come from the same counts."""

    weighting: WordWeighting
    sentences: int  # utterances of more than one token
    total: int  # utterances

    @property
    def reason(self) -> str:
        """The counts behind the choice: ``"27 of 54 utterances are sentences (50%; tf-idf
        from 30%)"``, ``"none of 36 utterances is a sentence"``, ``"no words"``."""
        sentences, total = self.sentences, self.total
        if not sentences:
            return f"none of {total} utterances is a sentence" if total else "no words"
        verb = "is a sentence" if sentences == 1 else "are sentences"
        share = 100 * sentences // total  # floored: 29.6% reads 29%, below the 30%
        threshold = f"{100 * TFIDF_SENTENCE_SHARE:g}%"
        return f"{sentences} of {total} utterances {verb} ({share}%; tf-idf from {threshold})"

    @property
    def note(self) -> str | None:
        """Why a fit's ``"auto"`` is this weighting, as its data line says it: ``"auto: "`` and
        the :attr:`reason`; None for a house without sentences (counted, as always: nothing to
        explain)."""
        return f"auto: {self.reason}" if self.sentences else None

    def kept_note(self, kept: str, where: str) -> str | None:
        """Why an update's ``"auto"`` is ``kept``, the weighting of the fit in ``where`` it
        updates, where that says something: ``"auto: as the fit in OUT"`` for tf-idf, and what
        this data alone would choose where it differs (``"...; this data alone would be tfidf:
        18 of 36 utterances are sentences (50%; tf-idf from 30%)"``); None where both count."""
        if kept == self.weighting == "count":
            return None
        note = f"auto: as the fit in {where}"
        if kept != self.weighting:
            note += f"; this data alone would be {self.weighting}: {self.reason}"
        return note


def auto_word_weighting(observations: Observations) -> AutoWeighting:
    """``"tfidf"`` when at least :data:`TFIDF_SENTENCE_SHARE` of the utterances are sentences
    (more than one token), else ``"count"`` (and ``"count"`` with no utterance), with the
    counts it decided by."""
    sentences, total = sentence_count(observations), observations.num_utterances
    tfidf = bool(total) and sentences / total >= TFIDF_SENTENCE_SHARE
    return AutoWeighting("tfidf" if tfidf else "count", sentences, total)


def resolve_word_weighting(weighting: str, observations: Observations) -> WordWeighting:
    """``weighting`` (``"count"``, ``"tfidf"`` or ``"auto"``) as it applies to
    ``observations``: ``"auto"`` by :func:`auto_word_weighting`, the others as they are.
    ValueError for any other value."""
    if weighting not in WORD_WEIGHTINGS:
        raise ValueError(f"word_weighting={weighting!r}: must be {one_of(WORD_WEIGHTINGS)}")
    if weighting == "auto":
        return auto_word_weighting(observations).weighting
    return weighting  # type: ignore[return-value]


def resolved_preparation(
    preparation: DataPreparation, observations: Observations
) -> DataPreparation:
    """``preparation`` with its word weighting resolved for ``observations``
    (:func:`resolve_word_weighting`); the same object when it needs no change."""
    weighting = resolve_word_weighting(preparation.word_weighting, observations)
    if weighting == preparation.word_weighting:
        return preparation
    return dataclasses.replace(preparation, word_weighting=weighting)


def resolved_settings(settings: SpCoSettings, observations: Observations) -> SpCoSettings:
    """``settings`` with the data preparation's word weighting resolved for ``observations``
    (:func:`resolved_preparation`; the preset name and the fields chosen kept)."""
    data = resolved_preparation(settings.data, observations)
    return settings if data is settings.data else dataclasses.replace(settings, data=data)


def keeping_word_weighting(
    saved: object, settings: SpCoSettings, where: str = "the saved fit"
) -> SpCoSettings:
    """``settings`` with a word weighting ``"auto"`` set to ``saved``, the weighting the fit in
    ``where`` records (``config.json``'s ``data.word_weighting``): an update keeps the weighting
    of the fit it updates, whatever its new utterances are. ValueError where that fit records
    no resolved weighting (``"auto"``, or none): which one its words were weighted by is not
    known, and resolving it for the update's data could change it. The message says to edit
    the record, most likely to ``"count"`` (a result built without a preparation counted its
    words, and recorded ``"auto"`` before :class:`~spcopyro.results.result.SpCoResult` recorded
    ``"count"``); asking the update for a weighting does not get around it, as
    :func:`~spcopyro.robot.online.check_compatible` compares it with the record."""
    if settings.data.word_weighting != "auto":
        return settings
    if saved not in RESOLVED_WORD_WEIGHTINGS:
        raise ValueError(
            f"{where} records word_weighting {saved!r}, not the weighting its words were "
            f"counted with ({one_of(RESOLVED_WORD_WEIGHTINGS)}), so an update cannot keep it: "
            "record the one it was fitted with in its preparation.word_weighting (config.json's "
            "data.word_weighting for a saved fit), most likely 'count' (a result built without "
            "a preparation counted its words); asking the update for a weighting "
            "(--word-weighting, the settings' word_weighting) does not get around it, as the "
            "update's preparation must be the one recorded"
        )
    data = settings.data.replace(word_weighting=saved)
    return dataclasses.replace(settings, data=data)
