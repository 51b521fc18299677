"""Regions of an ``[H, W]`` label image (-1: no label): which labels touch, and the connected
regions of each label.

* :func:`region_contacts` -- every pair of labels that are 4-neighbours somewhere, with how many
  neighbouring cell pairs they share (a border's length in cells);
* :func:`concept_regions` -- the 4-connected regions of every label, numbered label by label.

The semantic map's colours (:func:`spcopyro.maps.palette.concept_colours`), its region labels
(:func:`spcopyro.figures.plotting.region_label_spots`) and the place graph
(:mod:`spcopyro.robot.navigation.places`) read their regions from here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["concept_regions", "region_contacts"]


def region_contacts(labels: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(a, b, cells)``, ``[P]`` each: the pairs ``a < b`` of labels >= 0 that touch across a
    4-neighbour edge of the ``[H, W]`` label image (-1 cells touch nothing), sorted, and how
    many neighbouring cell pairs each shares."""
    lab = np.asarray(labels)
    if lab.ndim != 2:
        raise ValueError(f"labels must be a 2-D [H, W] array, got shape {lab.shape}")
    pairs = []
    for first, second in ((lab[:, :-1], lab[:, 1:]), (lab[:-1, :], lab[1:, :])):  # -, |
        touch = (first >= 0) & (second >= 0) & (first != second)
        u, v = first[touch], second[touch]
        pairs.append(np.stack([np.minimum(u, v), np.maximum(u, v)], axis=1))  # [P, 2]
    both = np.concatenate(pairs).astype(np.int64)
    if not len(both):
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty
    unique, counts = np.unique(both, axis=0, return_counts=True)
    return unique[:, 0], unique[:, 1], counts


def concept_regions(image: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(regions [H, W], concept_of [R])``: the 4-connected regions of every label of the
    ``[H, W]`` image, numbered concept by concept in ascending order and, within a concept, in
    the raster order of their first cell (-1 off every region); ``concept_of[r]`` is region r's
    label. Each concept is labelled inside its bounding box only (one pass over the image finds
    the boxes), which numbers the same regions in the same order as over the whole image."""
    from scipy import ndimage  # here, not on every import of spcopyro.maps (start-up)

    image = np.asarray(image)
    regions = np.full(image.shape, -1, dtype=np.int64)  # [H, W]
    concept_of: list[int] = []
    crops = ndimage.find_objects(np.where(image >= 0, image + 1, 0))  # [max label + 1] boxes
    for concept in np.unique(image[image >= 0]):
        crop = crops[concept]
        labelled, count = ndimage.label(image[crop] == concept)  # [h, w], 0 = not this concept
        if count:
            view = regions[crop]
            view[labelled > 0] = labelled[labelled > 0] - 1 + len(concept_of)
            concept_of += [int(concept)] * count
    return regions, np.asarray(concept_of, dtype=np.int64)
