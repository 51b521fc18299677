"""How well a labelling's concepts separate the images: the statistic behind ``fit``'s
refinement (:mod:`spcopyro.fit.refine`) and the two-stage image weight
(:mod:`spcopyro.fit.image_weight`); issue 21, docs/real_houses.md.

Images ``i = 1..n`` with histograms ``f_i`` (``[K]``, summing to 1) taken in cells labelled
``c(i)`` by a fit; ``G`` concepts holding at least one image; ``phi_g`` the mean histogram of
concept ``g``'s images and ``phi`` that of all. The share of the images' variance the concepts
explain, adjusted for the number of groups (so that speck concepts holding one image each
explain nothing by construction)::

    SS_within = sum_i ||f_i - phi_c(i)||^2          SS_total = sum_i ||f_i - phi||^2
    explained = 1 - (SS_within / (n - G)) / (SS_total / (n - 1))

For Dirichlet-distributed histograms ``f ~ Dir(kappa phi)``, ``E ||f - phi||^2 = (1 - ||phi||^2)
/ (kappa + 1)``, so ``explained`` is about ``1 - (kappa_whole + 1) / (kappa_within + 1)``: 0
when the concepts' images are as dispersed as the whole house's, near 1 when the concepts hold
tight image clusters. :class:`ImageSeparation` reports both moment estimates of ``kappa``.

Measured on the regions of a truth (docs/real_houses.md, before any fit was scored): the public
houses' CNN histograms, which follow the view rather than the place, 0.15-0.31; the synthetic
and simulated houses, whose histograms are drawn per place, 0.72-0.80.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from spcopyro.data import House
from spcopyro.data.placement import place_observations
from spcopyro.results.result import SpCoResult

__all__ = ["ImageSeparation", "image_labels", "image_separation"]


@dataclasses.dataclass(frozen=True)
class ImageSeparation:
    """How well a labelling's concepts separate the images (module docstring).

    Attributes:
        explained: share of the images' variance the concepts explain, adjusted for groups.
        kappa_within: moment estimate of the Dirichlet concentration within concepts.
        kappa_whole: the same with the whole house as one group.
        images: images inside a labelled cell (the others are left out).
        concepts: concepts holding at least one of them.
    """

    explained: float
    kappa_within: float
    kappa_whole: float
    images: int
    concepts: int


def _moment_kappa(spread: float, purity_deficit: float) -> float:
    """``kappa`` from ``sum ||f - phi||^2`` and ``sum (1 - ||phi||^2)`` over the same images."""
    return purity_deficit / spread - 1.0 if spread > 0 else math.inf


def image_separation(features: np.ndarray, labels_of_images: np.ndarray) -> ImageSeparation:
    """The statistic of the module docstring for histograms ``features`` ``[T, K]`` and their
    concepts ``labels_of_images`` ``[T]`` (< 0: not labelled, left out)."""
    keep = np.asarray(labels_of_images) >= 0  # [T]
    f = np.asarray(features, dtype=np.float64)[keep]  # [n, K]
    f = f / np.clip(f.sum(axis=1, keepdims=True), 1e-300, None)
    _, group = np.unique(np.asarray(labels_of_images)[keep], return_inverse=True)  # [n]
    n, concepts = f.shape[0], int(group.max()) + 1 if f.shape[0] else 0
    if n < 2 or n <= concepts:
        return ImageSeparation(0.0, math.nan, math.nan, n, concepts)
    sizes = np.bincount(group, minlength=concepts).astype(np.float64)  # [G]
    means = np.zeros((concepts, f.shape[1]))  # [G, K]
    np.add.at(means, group, f)
    means /= sizes[:, None]
    whole = f.mean(axis=0)  # [K]
    ss_within = float(((f - means[group]) ** 2).sum())
    ss_total = float(((f - whole) ** 2).sum())
    explained = 1.0 - (ss_within / (n - concepts)) / (ss_total / (n - 1)) if ss_total > 0 else 0.0
    deficit_within = float((1.0 - (means**2).sum(axis=1))[group].sum())
    deficit_whole = n * (1.0 - float((whole**2).sum()))
    return ImageSeparation(
        explained=explained,
        kappa_within=_moment_kappa(ss_within, deficit_within),
        kappa_whole=_moment_kappa(ss_total, deficit_whole),
        images=n,
        concepts=concepts,
    )


def image_labels(result: SpCoResult, house: House) -> np.ndarray:
    """``[T]`` the concept of the model-grid cell each image of ``house`` was placed in, as the
    fit placed it (eq. 11, an image just off free space snapped to the nearest free cell within
    the fit's snap distance; -1: unplaced or unlabelled). ``result`` is a fit of ``house`` (on
    its model grid)."""
    free_index, _, unplaced = place_observations(
        result.grid, house.observations.image_xy, result.preparation.snap_distance
    )  # [T], [T]
    labels = np.full(free_index.shape[0], -1, dtype=np.int64)  # [T]
    labels[~unplaced] = np.asarray(result.labels)[free_index[~unplaced]]  # labels: [N free]
    return labels
