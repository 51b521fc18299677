"""Image histograms turned into counts (``feature_scaling``): what ``floor100`` (the released
code's floor(100 f)) leaves of a histogram over many classes, and that nothing it drops is lost
without a count.

The grid is a 2 x 3 room of free cells at 1 m (origin (0, 0)): every observation inside it
lands on a free cell.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

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
    assert (  # what a library caller sets, then fit's flag (messages.setting)
        "needs feature_scaling='probability' (fit's --feature-scaling probability) or a number; "
        "the refinement of preset coarse counts images so too: refine='never' (fit's --refine "
        "never)"
    ) in warned[0]


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


def test_features_says_what_floor100_would_leave_of_its_rows(tmp_path, capsys):
    """The README's walkthrough writes Ft.csv with ``spcopyro features --weights random``: 1000
    near-flat classes (every value about 0.001). Counted as floor(100 f) (``--preset auto``,
    ``original-code``, the default preset's refinement) every row became zero, and nothing
    said so before the fit; now ``features`` says which rows, and what to fit with."""
    cv2 = pytest.importorskip("cv2")
    pytest.importorskip("torchvision")
    from spcopyro.cli.main import main

    rng = np.random.default_rng(0)
    for number in range(2):
        image = rng.integers(0, 255, (40, 48, 3), dtype=np.uint8)
        cv2.imwrite(str(tmp_path / f"{number:05d}.png"), image)
    out = tmp_path / "Ft.csv"
    assert main(["features", str(tmp_path), "--out", str(out), "--weights", "random"]) == 0
    said = capsys.readouterr().out
    features = np.loadtxt(out, delimiter=",", ndmin=2)  # [2, 1000]
    assert features.shape == (2, 1000) and features.max() < 0.01
    note = [line for line in said.splitlines() if line.startswith("counting")]
    assert len(note) == 1, said
    assert f"leaves nothing of 2 of 2 rows (every value below 0.01: lines 1, 2 of {out})" in note[0]
    assert "--preset auto or original-code add --feature-scaling probability" in note[0]
    assert "The default fit needs nothing" in note[0]  # its refinement is skipped (KEEPS)


def test_the_floor100_note_says_what_the_default_fit_does_with_the_rows():
    """The note said 'fit with --feature-scaling probability' to everyone; the default fit
    reads the rows as probabilities, and its --refine auto does not refine where floor(100 f)
    empties more than half of the images (spcopyro.fit.refine.KEEPS): nothing to do there.
    Where it empties fewer, the refinement, where it runs, counts them so: --refine never."""
    import spcopyro.features.cli as features_cli
    from spcopyro.data.counts import KEEPS
    from spcopyro.features.cli import floor100_note
    from spcopyro.fit import refine

    assert refine.KEEPS is KEEPS  # one share, in the layer below both: no copy to keep in step
    assert not hasattr(features_cli, "REFINEMENT_KEEPS")
    peaked = np.full((3, 1000), 0.2 / 999)
    peaked[:, 0] = 0.8
    flat = np.full((1, 1000), 1e-3)  # every value below 0.01
    most = floor100_note(np.concatenate([peaked[:1], flat, flat]), "Ft.csv")  # 2 of 3 emptied
    assert "leaves nothing of 2 of 3 rows" in most
    assert "The default fit needs nothing" in most and "--refine auto does not refine" in most
    assert "--refine never" not in most
    assert "with --preset auto or original-code add --feature-scaling probability" in most
    few = floor100_note(np.concatenate([peaked, flat]), "Ft.csv")  # 1 of 4: refined where it runs
    assert "leaves nothing of 1 of 4 rows" in few and "needs nothing" not in few
    assert "the refinement counts them as floor(100 f)" in few
    assert "--refine never keeps them as probabilities" in few
    assert "with --preset auto or original-code add --feature-scaling probability" in few
    half = floor100_note(np.concatenate([peaked[:1], flat]), "Ft.csv")  # 1 of 2: not more
    assert "--refine never keeps them as probabilities" in half


def test_the_floor100_note_is_silent_where_floor100_keeps_most_of_the_rows():
    """The public dataset's 205 Places205 classes: floor(100 f) keeps about 73-77 % of a row's
    mass in median and empties none, so ``features`` adds no note; a peaked 1000-class row
    neither."""
    from spcopyro.features.cli import floor100_note

    peaked = np.full((3, 1000), 0.2 / 999)
    peaked[:, 0] = 0.8
    assert floor100_note(peaked, "Ft.csv") is None
    half = np.full((2, 1000), 0.6 / 998)  # 0.4 on two classes of 0.2, the rest below 0.01
    half[:, :2] = 0.2
    note = floor100_note(half, "Ft.csv")
    assert note is not None and "keeps 40% of a row's mass in median" in note
    assert "leaves nothing" not in note
    assert floor100_note(np.zeros((0, 1000)), "Ft.csv") is None
    one = np.concatenate([peaked, np.full((1, 1000), 1e-3)])  # [4, 1000]: the last row flat
    note = floor100_note(one, "Ft.csv")
    assert note is not None and "leaves nothing of 1 of 4 rows" in note
    assert "line 4 of Ft.csv" in note


def test_fit_s_placement_line_says_how_many_images_the_scaling_left_out(tmp_path):
    """``fit``'s printed "placement" line read "images: 4 on free cells" where floor100 had
    left three of them with nothing: the count the placement report carries is on that line.
    The scaling is the preparation's, as the fit's (the summary took it apart from the
    preparation, so a caller could count under one scaling and place under another)."""
    from spcopyro.cli.common import _summary
    from spcopyro.config import DataPreparation
    from spcopyro.data.dataset import House

    house = House("flat", _grid(), _observations(_flat_and_peaked()), source=tmp_path)
    floor100 = DataPreparation(feature_scaling="floor100")  # the auto preset's scaling
    placement = [
        line
        for line in _summary(house, warn=False, preparation=floor100).splitlines()
        if line.startswith("placement")
    ]
    assert len(placement) == 1
    assert "; 3 of 4 images left out" in placement[0]
    kept = _summary(house, warn=False, preparation=DataPreparation(feature_scaling="probability"))
    assert "left out" not in kept


def test_the_counts_the_refinement_and_features_name_the_same_emptied_images(tmp_path):
    """Which images floor(100 f) leaves with nothing is decided in one place
    (spcopyro.data.counts.scaled_away): the counts leave them out, ``fit --refine auto`` counts
    them, ``spcopyro features`` names their lines. An all-zero row has nothing to lose; a row
    with one entry of 0.01 keeps a count."""
    from spcopyro.data.counts import scale_features, scaled_away
    from spcopyro.features.cli import floor100_note
    from spcopyro.fit.refine import _emptied_by_floor100

    features = np.full((6, 1000), 1e-3)  # [6, 1000] rows 0, 2, 5 flat: emptied
    features[1] = 0.0
    features[1, 7] = 1.0
    features[3] = 0.0  # nothing to lose
    features[4, 9] = 0.01  # floor(100 * 0.01) = 1
    emptied = scaled_away(features, scale_features(features, "floor100"))  # [n]
    assert emptied.dtype == np.int64 and emptied.tolist() == [0, 2, 5]
    counts = cell_counts(_grid(), _observations(features), feature_scaling="floor100", warn=False)
    assert counts.placement.scaled_away_images.tolist() == [0, 2, 5]
    assert _emptied_by_floor100(features) == 3
    note = floor100_note(features, tmp_path / "Ft.csv")
    assert (
        f"leaves nothing of 3 of 6 rows (every value below 0.01: lines 1, 3, 6 of {tmp_path}"
        in note
    )
    assert scaled_away(features, features).size == 0  # as probabilities: nothing lost
