"""Observation events of the SpCoA baseline: images, with the utterances paired to them.

Every image is one event t with its world position x_t, its place-class histogram f_t ([K], scaled
by :func:`spcopyro.data.scale_features`) and the words s_t ([V]) heard there. Each utterance is
paired with the *nearest image of the same trial* when that image is at most ``pair_distance``
metres away (in the public dataset and the synthetic houses every utterance is spoken exactly at
an image position), its word counts (or tf-idf weights, paper eq. 20) added to that event's s_t;
an utterance with no image that near becomes an event of its own, with its position, its words
and no image (f_t = 0). Nothing is dropped. The events live in continuous world coordinates: the
map is used only to label its cells afterwards.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from spcopyro._util.number_checks import is_finite_number
from spcopyro.config import WordWeightingSetting
from spcopyro.data import (
    FeatureScaling,
    Observations,
    scale_features,
    tfidf_weights,
    word_matrix,
)
from spcopyro.data.word_weighting import resolve_word_weighting

__all__ = ["DEFAULT_PAIR_DISTANCE", "SpCoAData", "spcoa_data"]

DEFAULT_PAIR_DISTANCE = 0.5  # metres: an utterance joins the nearest image of its trial this near
_PAIR_EPS = 1e-9  # metres: tolerance on pair_distance


@dataclass(frozen=True, eq=False)
class SpCoAData:
    """The observation events the mixture clusters (see the module docstring).

    T events (the images first, in image order, then the utterances that no image was near,
    in utterance order), K image classes, V words.
    """

    xy: np.ndarray  # [T, 2] float64 world metres
    features: np.ndarray  # [T, K] float64 scaled image counts (0 for word-only events)
    words: np.ndarray  # [T, V] float64 word counts or tf-idf weights
    vocabulary: tuple[str, ...]  # [V]
    image_event: np.ndarray  # [num_images] int64 event of each image (= its index)
    utterance_event: np.ndarray  # [U] int64 event each utterance was added to

    @property
    def num_events(self) -> int:
        """T."""
        return int(self.xy.shape[0])


def spcoa_data(
    observations: Observations,
    *,
    feature_scaling: FeatureScaling = "probability",
    word_weighting: WordWeightingSetting = "count",
    pair_distance: float = DEFAULT_PAIR_DISTANCE,
) -> SpCoAData:
    """The events of ``observations``: images, with each utterance paired to the nearest image of
    its trial within ``pair_distance`` metres, and word-only events for the rest.
    ``word_weighting``: ``"count"``, ``"tfidf"`` or ``"auto"`` (tf-idf when at least 30% of the
    utterances are sentences, as SpCoMapping's fit and
    :func:`~spcopyro.baselines.spcoa.fit_spcoa` by default: :mod:`spcopyro.data.word_weighting`).

    Raises ValueError when there is nothing to cluster (no images and no utterances) or
    ``pair_distance`` is not a finite number >= 0.
    """
    if not (is_finite_number(pair_distance) and pair_distance >= 0):
        raise ValueError(f"pair_distance={pair_distance!r}: must be a finite number >= 0 metres")
    word_weighting = resolve_word_weighting(word_weighting, observations)  # ValueError if bad
    num_images, num_utterances = observations.num_images, observations.num_utterances
    if num_images + num_utterances == 0:
        raise ValueError("spcoa: the observations hold no images and no utterances")
    features = scale_features(observations.image_features, feature_scaling)  # [I, K]
    vocabulary = observations.vocabulary
    if num_utterances == 0:
        utterance_words = np.zeros((0, 0), dtype=np.float64)  # [0, 0]
    elif word_weighting == "count":
        utterance_words = word_matrix(observations.utterances, vocabulary)  # [U, V]
    else:
        utterance_words = tfidf_weights(observations.utterances, vocabulary)  # [U, V]

    # Pair each utterance with the nearest image of its trial (a k-d tree per trial).
    utterance_event = np.full(num_utterances, -1, dtype=np.int64)  # [U]
    for trial in observations.trials:
        images = np.flatnonzero(observations.image_trial == trial)  # [I_k]
        spoken = np.flatnonzero(observations.word_trial == trial)  # [U_k]
        if images.size == 0 or spoken.size == 0:
            continue
        distance, nearest = cKDTree(observations.image_xy[images]).query(
            observations.word_xy[spoken]
        )  # [U_k] x2
        near = distance <= pair_distance + _PAIR_EPS  # [U_k] bool
        utterance_event[spoken[near]] = images[nearest[near]]
    alone = np.flatnonzero(utterance_event < 0)  # [U_0] utterances that become events
    utterance_event[alone] = num_images + np.arange(alone.size)

    num_events = num_images + alone.size
    xy = np.concatenate([observations.image_xy, observations.word_xy[alone]])  # [T, 2]
    event_features = np.zeros((num_events, features.shape[1]), dtype=np.float64)  # [T, K]
    event_features[:num_images] = features
    words = np.zeros((num_events, len(vocabulary)), dtype=np.float64)  # [T, V]
    np.add.at(words, utterance_event, utterance_words)
    return SpCoAData(
        xy=xy,
        features=event_features,
        words=words,
        vocabulary=vocabulary,
        image_event=np.arange(num_images, dtype=np.int64),
        utterance_event=utterance_event,
    )
