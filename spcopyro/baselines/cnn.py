"""Baseline (D): CNN-based semantic mapping, after Suenderhauf et al. (2016).

N. Suenderhauf, F. Dayoub, S. McMahon, B. Talbot, R. Schulz, P. Corke, G. Wyeth, B. Upcroft,
M. Milford: "Place categorization and semantic mapping on a mobile robot", ICRA 2016. A CNN
classifies every camera image into a place class, and the map takes the classes of the images
taken in it. SpCoMapping's paper (Katsumata et al. 2019, Table 4, method D) compares with this
idea; here it runs on the same data structures as SpCoMapping:

1. Every image is placed on a free cell as in fitting (:func:`spcopyro.data.cell_counts`:
   eq. 11, snapping points within ``snap_distance`` of free space; farther ones are reported in
   ``notes``). A cell holding images is labelled with the most probable place class of the
   summed histograms of its images, ``argmax_k sum_i f_ik`` (ties: the smallest class id).
2. Every other free cell takes the label of the nearest image cell (Euclidean distance between
   cell centres, through walls: ``scipy.ndimage.distance_transform_edt`` with
   ``return_indices``; ties broken by the EDT).

Labels are place-class ids (``0 .. K-1``, Places205 classes for the public dataset).

Words. The method itself has none; to answer "where is WORD?" and to predict words, each
utterance is assigned the class of its cell in the map, i.e. the class of the nearest image
cell (utterances are made where images are taken, so this is the class of the co-located
image). Counting these gives ``n_{k,v}``, the times word v was heard in class k:
``region(v)`` is the map's cells of the class under which v was heard most often, and
``p(v | cell) = (n_{k,v} + eps) / (n_k + V eps)`` for the cell's class k
(:class:`~spcopyro.results.semantic_map.TabularSemanticMap`).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from spcopyro.data import DEFAULT_SNAP_DISTANCE, Observations, cell_counts
from spcopyro.maps import OccupancyGrid
from spcopyro.results.semantic_map import TabularSemanticMap

__all__ = ["cnn_label_image", "cnn_semantic_map"]


def _fill_nearest(grid: OccupancyGrid, seeds: np.ndarray) -> np.ndarray:
    """``[H, W]`` seeds (>= 0 labelled, -1 not) -> every free cell takes its nearest seed."""
    _, (near_row, near_col) = ndimage.distance_transform_edt(seeds < 0, return_indices=True)
    filled = seeds[near_row, near_col]  # [H, W]
    return np.where(grid.free, filled, -1).astype(np.int64)


def cnn_semantic_map(
    grid: OccupancyGrid,
    observations: Observations,
    *,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    smoothing: float = 1e-3,
) -> TabularSemanticMap:
    """Baseline (D): the map of the images' most probable place classes (module docstring).

    Raises:
        ValueError: no image lies on (or within ``snap_distance`` of) free space.
    """
    vocabulary = None if observations.num_utterances else ()
    counts = cell_counts(
        grid,
        observations,
        feature_scaling="probability",
        snap_distance=snap_distance,
        vocabulary=vocabulary,
    )
    has_image = counts.image_counts.sum(axis=1) > 0  # [M] bool
    if not has_image.any():
        raise ValueError(
            f"cnn_semantic_map: none of the {observations.num_images} images lies within "
            f"{snap_distance} m of free space on map {grid.source or grid!r}"
        )
    image_cells = grid.free_cells[counts.cells[has_image]]  # [M', 2] (row, col)
    seeds = np.full(grid.shape, -1, dtype=np.int64)  # [H, W]
    seeds[image_cells[:, 0], image_cells[:, 1]] = np.argmax(
        counts.image_counts[has_image], axis=1
    )  # first maximum: the smallest class id
    labels = _fill_nearest(grid, seeds)  # [H, W]
    return TabularSemanticMap.from_cell_counts(
        grid,
        labels,
        counts,
        num_labels=observations.num_feature_classes,
        smoothing=smoothing,
        name="cnn",
        notes=(f"{int(has_image.sum())} image cells labelled by their most probable class",),
    )


def cnn_label_image(
    grid: OccupancyGrid,
    observations: Observations,
    *,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
) -> np.ndarray:
    """``[H, W]`` int64 place class of every free cell (-1 elsewhere) of baseline (D)."""
    return cnn_semantic_map(grid, observations, snap_distance=snap_distance).label_image()
