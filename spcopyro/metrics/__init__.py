r"""Scores of a semantic map: against ground truth, on held-out trials, and across samples.

Every score here takes any method's output through one small interface,
:class:`~spcopyro.results.semantic_map.SemanticMapModel` (a label image, ``p(word | cell)`` over a
vocabulary, and the region a word names), so SpCoMapping
(:class:`~spcopyro.results.semantic_map.SpCoSemanticMap` wraps a
:class:`~spcopyro.results.result.SpCoResult`) and the baselines of :mod:`spcopyro.baselines`
(:class:`~spcopyro.results.semantic_map.TabularSemanticMap`) are scored by the same code. The
interface lives in :mod:`spcopyro.results.semantic_map`; its names are re-exported here.

Scores
------
* :mod:`spcopyro.metrics.truth`: :func:`adjusted_rand_index` (ARI of a label image against the
  ground truth over free cells) and :func:`matching_rate` (the paper's matching rate for place
  estimation, eq. 18, the place estimated from a word as in eq. 19; see its docstring for the
  exact definition used).
* :mod:`spcopyro.metrics.heldout`: :func:`heldout_word_prediction` and
  :func:`heldout_localisation`, scores on a trial that was not fitted, needing no drawn ground
  truth (the public dataset has none).
* :mod:`spcopyro.metrics.posterior`: :func:`num_concepts`, :func:`co_assignment`,
  :func:`chain_ari`, :func:`pairwise_chain_ari`, posterior summaries that do not depend on how
  concepts are numbered (label switching).

Conventions: label images are ``[H, W]`` integer arrays in map-image row order with -1 off free
space (:meth:`spcopyro.results.result.SpCoResult.label_image`); a "cell" passed to
:meth:`~spcopyro.results.semantic_map.SemanticMapModel.word_distribution` is a free-cell index
(``grid.free_index``), the order every per-free-cell array of the package uses.
"""

from spcopyro.metrics.heldout import (
    LocalisationScores,
    WordPredictionScores,
    heldout_localisation,
    heldout_word_prediction,
    rank_of_truth,
)
from spcopyro.metrics.posterior import (
    CoAssignment,
    chain_ari,
    co_assignment,
    num_concepts,
    pairwise_chain_ari,
)
from spcopyro.metrics.truth import (
    MATCHING_KINDS,
    MatchingRate,
    adjusted_rand_index,
    matching_rate,
)
from spcopyro.results.semantic_map import (
    SemanticMapModel,
    SpCoResultLike,
    SpCoSemanticMap,
    TabularSemanticMap,
    UnknownWordError,
    as_semantic_map,
    word_index,
)

__all__ = [
    "MATCHING_KINDS",
    "CoAssignment",
    "LocalisationScores",
    "MatchingRate",
    "SemanticMapModel",
    "SpCoResultLike",
    "SpCoSemanticMap",
    "TabularSemanticMap",
    "UnknownWordError",
    "WordPredictionScores",
    "adjusted_rand_index",
    "as_semantic_map",
    "chain_ari",
    "co_assignment",
    "heldout_localisation",
    "heldout_word_prediction",
    "matching_rate",
    "num_concepts",
    "pairwise_chain_ari",
    "rank_of_truth",
    "word_index",
]
