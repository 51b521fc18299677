"""Scores of a semantic map against ground truth."""

from __future__ import annotations

import numpy as np
from sklearn.metrics import adjusted_rand_score


def adjusted_rand_index(labels: np.ndarray, truth: np.ndarray) -> float:
    """ARI between two [H, W] label images over the cells where the truth is defined (>= 0).

    Invariant to how the concepts are numbered (scikit-learn's implementation).
    """
    if labels.shape != truth.shape:
        raise ValueError(f"label image {labels.shape} and truth {truth.shape} differ in shape")
    mask = truth >= 0
    return float(adjusted_rand_score(truth[mask], labels[mask]))
