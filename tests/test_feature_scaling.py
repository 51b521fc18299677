"""Image histograms turned into counts (``feature_scaling``): what ``floor100`` (the released
code's floor(100 f)) leaves of a histogram over many classes, and that nothing it drops is lost
without a count.

The grid is a 2 x 3 room of free cells at 1 m (origin (0, 0)): every observation inside it
lands on a free cell.
"""

from __future__ import annotations

import logging

import numpy as np

from spcopyro.data import Observations, cell_counts
from spcopyro.maps import FREE, OccupancyGrid


def _grid() -> OccupancyGrid:
    return OccupancyGrid(
        occupancy=np.full((2, 3), FREE, dtype=np.int8), resolution=1.0, origin=(0.0, 0.0, 0.0)
    )


def _observations(features: np.ndarray) -> Observations:
    num_images = features.shape[0]
    return Observations(
        image_features=features,
        image_xy=np.full((num_images, 2), 0.5),
        image_trial=np.zeros(num_images, dtype=np.int64),
        utterances=[("kitchen",)],
        word_xy=np.full((1, 2), 1.5),
        word_trial=np.zeros(1, dtype=np.int64),
    )


def _flat_and_peaked() -> np.ndarray:
    """[4, 1000]: three flat histograms over 1000 classes (every entry 0.001, an ImageNet head
    that cannot tell) and one peaked on class 7."""
    features = np.full((4, 1000), 1e-3)
    features[3] = 0.0
    features[3, 7] = 1.0
    return features


def test_the_placement_summary_counts_images_floor100_leaves_with_nothing(tmp_path, caplog):
    """floor(100 * 0.001) = 0: the three flat images add nothing to the counts. The warning
    said so, but the counts' report (its ``summary()``, which the semantic map's notes carry)
    still read "4 on free cells", as if every image had been counted."""
    obs = _observations(_flat_and_peaked())
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        counts = cell_counts(_grid(), obs, feature_scaling="floor100", source=tmp_path)
    assert counts.image_counts.sum() == 100.0  # the peaked image alone
    report = counts.placement
    assert report.images_scaled_away == 3
    assert report.scaled_away_images.tolist() == [0, 1, 2]
    assert report.images_on_free == 4  # placed they were; counted they are not
    summary = report.summary()
    assert "3 of 4 images left out" in summary
    assert "feature_scaling='floor100'" in summary
    warned = [r.getMessage() for r in caplog.records if "carry no information" in r.getMessage()]
    assert len(warned) == 1
    assert "3 of 4 image(s)" in warned[0]
    assert f"lines 1, 2, 3 of {tmp_path / 'Ft.csv'}" in warned[0]


def test_the_count_of_images_left_with_nothing_survives_a_footprint():
    """With a footprint the report is the plain counts' (the spread counts are built on them):
    the images floor100 empties are counted there too."""
    obs = _observations(_flat_and_peaked())
    counts = cell_counts(_grid(), obs, feature_scaling="floor100", footprint_radius=1.0)
    assert counts.placement.images_scaled_away == 3
    assert "3 of 4 images left out" in counts.placement.summary()


def test_no_image_is_counted_as_left_out_when_the_scaling_keeps_it():
    """As probabilities or s * f a flat histogram keeps its mass: nothing is reported, and the
    summary line is what it was."""
    obs = _observations(_flat_and_peaked())
    for scaling in ("probability", 100.0):
        counts = cell_counts(_grid(), obs, feature_scaling=scaling)
        assert counts.placement.images_scaled_away == 0
        assert counts.placement.scaled_away_images.size == 0
        assert "left out" not in counts.placement.summary()
        assert counts.image_counts.sum() > 0
    # An all-zero row has nothing to lose: load_house warns about it, this count does not.
    zero = np.zeros((2, 1000))
    zero[1, 3] = 1.0
    counts = cell_counts(_grid(), _observations(zero), feature_scaling="floor100")
    assert counts.placement.images_scaled_away == 0
