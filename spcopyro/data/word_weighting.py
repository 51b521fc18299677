"""The word weighting ``"auto"``: tf-idf when the utterances are sentences, counts otherwise.

Words are never pre-listed: any token becomes vocabulary. Single words (the public dataset's
"kitchen", "bedroom") are counted as they are; sentences ("here is the kitchen") carry filler
words said everywhere, which tf-idf (paper eq. 20, Section 5's Table 5 setting) weighs down.

**The rule** (:func:`auto_word_weighting`): an utterance is a *sentence* when it holds more
than one token (:func:`spcopyro.data.tokenize`'s tokens: ``"living room"`` is a sentence of
two). ``"auto"`` is ``"tfidf"`` when at least one utterance is a sentence, ``"count"`` when
every utterance is a single word (or there are none). It is resolved once, when the data are
known (:func:`resolved_preparation`), and a fit records the resolved value (``config.json``'s
``preparation.word_weighting``); an online update keeps the weighting of the fit it updates.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from spcopyro.config import WORD_WEIGHTINGS, WordWeighting

if TYPE_CHECKING:
    from spcopyro.config import DataPreparation, SpCoSettings
    from spcopyro.data.observations import Observations

__all__ = [
    "auto_word_weighting",
    "auto_word_weighting_note",
    "resolve_word_weighting",
    "resolved_preparation",
    "resolved_settings",
    "sentence_count",
]


def sentence_count(observations: Observations) -> int:
    """How many utterances of ``observations`` are sentences (more than one token)."""
    return sum(len(tokens) > 1 for tokens in observations.utterances)


def auto_word_weighting(observations: Observations) -> WordWeighting:
    """``"tfidf"`` when any utterance is a sentence (more than one token), else ``"count"``."""
    return "tfidf" if sentence_count(observations) else "count"


def auto_word_weighting_note(observations: Observations) -> str:
    """Why ``"auto"`` chose its weighting, as the fit's data line says it:
    ``"auto: 27 of 54 utterances are sentences"``."""
    sentences, total = sentence_count(observations), observations.num_utterances
    if not sentences:
        return f"auto: none of {total} utterances is a sentence" if total else "auto: no words"
    verb = "is" if sentences == 1 else "are"
    return f"auto: {sentences} of {total} utterances {verb} sentences"


def resolve_word_weighting(weighting: str, observations: Observations) -> WordWeighting:
    """``weighting`` (``"count"``, ``"tfidf"`` or ``"auto"``) as it applies to
    ``observations``: ``"auto"`` by :func:`auto_word_weighting`, the others as they are.
    ValueError for any other value."""
    if weighting not in WORD_WEIGHTINGS:
        raise ValueError(
            f"word_weighting={weighting!r}: must be one of {', '.join(map(repr, WORD_WEIGHTINGS))}"
        )
    if weighting == "auto":
        return auto_word_weighting(observations)
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
