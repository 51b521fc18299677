"""The chain's starting state: initial labels with globals drawn given them.

The labels come from :mod:`spcopyro.initialisation` (random labels, a given label map, or
per-concept Gaussians, the paper's pre-learning initialisation); its helpers are re-exported here.
"""

from __future__ import annotations

import torch

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.state import GibbsState
from spcopyro.gibbs.sweep import sample_globals
from spcopyro.initialisation import (
    check_labels,
    kmeans_gaussians,
    labels_from_gaussians,
    random_labels,
)
from spcopyro.model import ModelData

__all__ = [
    "check_labels",
    "initial_state",
    "kmeans_gaussians",
    "labels_from_gaussians",
    "random_labels",
]


def initial_state(
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    labels: torch.Tensor | None = None,
) -> GibbsState:
    """A state from initial labels (random if None), with globals drawn given those labels."""
    if labels is None:
        labels = random_labels(data.num_free, config, generator)
    labels = check_labels(labels, data.num_free, config).clone()
    return GibbsState(labels, *sample_globals(labels, data, config, generator))
