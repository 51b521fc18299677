r"""Posterior summaries that do not depend on how concepts are numbered (label switching).

* :func:`num_concepts`: labels in use in a map.
* :func:`chain_ari`, :func:`pairwise_chain_ari`: agreement between chains' maps (ARI).
* :func:`co_assignment` (:class:`CoAssignment`): how often pairs of cells share a concept
  across sampled maps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from spcopyro.metrics.rand import adjusted_rand_score

__all__ = ["CoAssignment", "chain_ari", "co_assignment", "num_concepts", "pairwise_chain_ari"]


def num_concepts(labels: np.ndarray) -> int:
    """Number of distinct labels >= 0 in a label image ``[H, W]`` or label vector ``[N]``."""
    values = np.asarray(labels)
    return int(np.unique(values[values >= 0]).size)


def chain_ari(labels_a: np.ndarray, labels_b: np.ndarray) -> float:
    """ARI between two chains' maps: a stability measure invariant to label numbering.

    Takes two ``[H, W]`` label images (compared over the cells where both are >= 0; the free
    cells must agree) or two ``[N]`` label vectors in the same free-cell order.
    """
    a, b = np.asarray(labels_a), np.asarray(labels_b)
    if a.shape != b.shape:
        raise ValueError(f"the two maps differ in shape: {a.shape} and {b.shape}")
    if a.ndim == 2:
        if not np.array_equal(a >= 0, b >= 0):
            raise ValueError("the two label images label different cells (their -1 differ)")
        return float(adjusted_rand_score(a[a >= 0], b[b >= 0]))
    if a.ndim != 1:
        raise ValueError(f"maps must be [H, W] images or [N] vectors, got shape {a.shape}")
    return float(adjusted_rand_score(a, b))


def pairwise_chain_ari(maps: Sequence[np.ndarray]) -> np.ndarray:
    """``[C, C]`` ARI between every two of C chains' maps (1 on the diagonal)."""
    count = len(maps)
    table = np.eye(count)  # [C, C]
    for i in range(count):
        for j in range(i + 1, count):
            table[i, j] = table[j, i] = chain_ari(maps[i], maps[j])
    return table


@dataclass(frozen=True, eq=False)
class CoAssignment:
    """:func:`co_assignment`'s answer. P cell pairs, S samples."""

    pairs: np.ndarray  # [P, 2] int64 free-cell indices (i != j)
    similarity: np.ndarray  # [P] float64 share of samples in which the pair shares a label
    consecutive_ari: np.ndarray  # [S - 1] ARI between sample s and s + 1
    num_concepts: np.ndarray  # [S] int64 labels in use per sample

    @property
    def mean_similarity(self) -> float:
        """Estimate of the posterior probability that two random cells share a concept."""
        return float(self.similarity.mean())

    @property
    def uncertainty(self) -> float:
        r"""Mean of :math:`4 s (1 - s)` over pairs: 0 when every pair is decided in every sample
        (always together or always apart), 1 when every pair is together half the time."""
        s = self.similarity
        return float((4.0 * s * (1.0 - s)).mean())


def co_assignment(
    label_samples: np.ndarray,
    *,
    num_pairs: int = 10_000,
    seed: int = 0,
    pairs: np.ndarray | None = None,
) -> CoAssignment:
    """Posterior co-assignment (similarity) summary of sampled maps, free of label switching.

    For cell pairs (i, j) -- ``pairs`` if given, else ``num_pairs`` pairs of distinct cells
    drawn uniformly with ``numpy.random.default_rng(seed)`` -- the share of samples with
    ``label[s, i] == label[s, j]``, an estimate of p(C_i = C_j | data); also the ARI between
    consecutive samples (how much the map moves per thinning interval) and the number of concepts
    per sample.

    Args:
        label_samples: ``[S, N]`` int labels of N free cells in S samples (e.g. thinned
            :attr:`~spcopyro.gibbs.run.GibbsRun.label_samples`), S >= 1, N >= 2.
    """
    samples = np.asarray(label_samples)
    if samples.ndim != 2 or samples.shape[0] < 1 or samples.shape[1] < 2:
        raise ValueError(f"label_samples must have shape [S >= 1, N >= 2], got {samples.shape}")
    if samples.dtype.kind not in "iu":
        raise ValueError(f"label_samples must be integers, got dtype {samples.dtype}")
    num_samples, n = samples.shape
    if pairs is None:
        if num_pairs < 1:
            raise ValueError(f"num_pairs must be >= 1, got {num_pairs}")
        rng = np.random.default_rng(seed)
        first = rng.integers(0, n, size=num_pairs)  # [P]
        second = rng.integers(0, n - 1, size=num_pairs)  # [P]
        second = second + (second >= first)  # distinct from first, uniform over the rest
        chosen = np.stack([first, second], axis=1).astype(np.int64)  # [P, 2]
    else:
        chosen = np.asarray(pairs)
        if chosen.ndim != 2 or chosen.shape[1] != 2 or chosen.dtype.kind not in "iu":
            raise ValueError(f"pairs must be a [P, 2] integer array, got {chosen.shape}")
        chosen = chosen.astype(np.int64)
        if chosen.size and (chosen.min() < 0 or chosen.max() >= n):
            raise ValueError(f"pairs must index the {n} cells of label_samples")
    together = samples[:, chosen[:, 0]] == samples[:, chosen[:, 1]]  # [S, P] bool
    consecutive = np.array(
        [adjusted_rand_score(samples[s], samples[s + 1]) for s in range(num_samples - 1)],
        dtype=np.float64,
    )  # [S - 1]
    concepts = np.array([np.unique(row).size for row in samples], dtype=np.int64)  # [S]
    return CoAssignment(
        pairs=chosen,
        similarity=together.mean(axis=0),
        consecutive_ari=consecutive,
        num_concepts=concepts,
    )
