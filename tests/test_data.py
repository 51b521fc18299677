"""Tests of spcopyro.data: tokens, tf-idf, placement and snapping, per-cell counts, the loader
(every malformed-file case), save/load round trip, and the public dataset.

The tiny hand-made grid used throughout (resolution 1 m, origin (0, 0), so the cell of a world
point (x, y) is row = 3 - floor(y), col = floor(x)); F free, O occupied, U unknown::

            col 0  1  2  3  4  5
    row 0       O  O  O  O  O  O      y in [3, 4)
    row 1       O  F0 F1 O  O  O      y in [2, 3)
    row 2       O  F2 F3 O  O  U      y in [1, 2)
    row 3       F4 O  O  O  O  O      y in [0, 1)

Fn is the free cell with free_index n (raster order).
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

import numpy as np
import pytest

from spcopyro.data import (
    DEFAULT_SNAP_DISTANCE,
    DataFormatError,
    House,
    Observations,
    cell_counts,
    find_dataset_root,
    list_houses,
    load_house,
    place_observations,
    save_house,
    scale_features,
    tfidf_weights,
    tokenize,
    word_matrix,
)
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, save_map

F, O, U = FREE, OCCUPIED, UNKNOWN
TINY = np.array(
    [
        [O, O, O, O, O, O],
        [O, F, F, O, O, O],
        [O, F, F, O, O, U],
        [F, O, O, O, O, O],
    ],
    dtype=np.int8,
)


@pytest.fixture
def grid() -> OccupancyGrid:
    return OccupancyGrid(occupancy=TINY, resolution=1.0, origin=(0.0, 0.0, 0.0))


def make_obs(**changes) -> Observations:
    """Four images and five utterances on the tiny grid (see the module docstring)."""
    fields = dict(
        image_features=[
            [0.5, 0.25, 0.25],  # i0 at F0
            [0.105, 0.895, 0.0],  # i1 at F0 too
            [0.0, 0.0, 1.0],  # i2 on the wall (1, 3): snapped to F1 at 1 m
            [1.0, 0.0, 0.0],  # i3 far off the map: unplaced
        ],
        image_xy=[[1.5, 2.5], [1.2, 2.9], [3.5, 2.5], [10.0, 10.0]],
        image_trial=[0, 0, 1, 1],
        utterances=[
            ("kitchen",),  # u0 at F3
            ("kitchen", "table"),  # u1 at F0
            ("bed",),  # u2 at (1, 4), 2 m inside the wall: unplaced
            ("kitchen", "kitchen", "bed"),  # u3 just off the map at (3, -1): snapped to F4
            ("table",),  # u4 at F0
        ],
        word_xy=[[2.5, 1.5], [1.5, 2.5], [4.5, 2.5], [-0.5, 0.5], [1.9, 2.1]],
        word_trial=[0, 0, 1, 1, 2],
    )
    fields.update(changes)
    return Observations(**fields)


# ------------------------------------------------------------------------------ tokens, tf-idf


def test_tokenize():
    assert tokenize("Here is the kitchen.") == ("here", "is", "the", "kitchen")
    assert tokenize("  TV ") == ("tv",)
    assert tokenize("It's the living-room!!") == ("it's", "the", "living-room")
    assert tokenize("\u300cBed\u300d, (sofa)") == ("bed", "sofa")
    assert tokenize("... !") == ()
    assert tokenize("") == ()


def test_word_matrix_counts_and_unknown_tokens():
    counts = word_matrix([("a", "b", "a"), ("c",)])
    np.testing.assert_array_equal(counts, [[2, 1, 0], [0, 0, 1]])
    counts = word_matrix([("a",)], vocabulary=("z", "a"))
    np.testing.assert_array_equal(counts, [[0, 1]])
    with pytest.raises(ValueError, match="'q'"):
        word_matrix([("a", "q")], vocabulary=("a",))
    with pytest.raises(ValueError, match="more than once"):
        word_matrix([("a",)], vocabulary=("a", "a"))


@pytest.mark.parametrize("function", [word_matrix, tfidf_weights])
def test_an_empty_word_is_refused_from_python_as_the_command_line_refuses_it(function):
    """ "" (or a blank " ") is no word: Observations and the commands refuse it; word_matrix and
    tfidf_weights counted it as one, in an utterance or a given vocabulary."""
    for blank in ("", " "):
        with pytest.raises(
            ValueError,
            match=re.escape(f"utterance 1 holds the token {blank!r}: a token is non-blank text"),
        ):
            function([("a",), ("b", blank)])
        with pytest.raises(
            ValueError, match=re.escape(f"vocabulary word 1 is {blank!r}: a word is non-blank")
        ):
            function([("a",)], vocabulary=("a", blank))


def test_tfidf_against_hand_computation():
    utterances = [
        ("here", "is", "the", "kitchen"),
        ("the", "kitchen", "kitchen"),
        ("the", "bed"),
        ("the", "bed", "is", "soft"),
    ]
    # D = 4; df: here 1, is 2, the 4, kitchen 2, bed 2, soft 1
    # idf: here ln 4 = 1.3862943611198906, is/kitchen/bed ln 2 = 0.6931471805599453,
    #      the ln 1 = 0 (in every utterance), soft ln 4.
    # columns: here, is, the, kitchen, bed, soft (first appearance)
    expected = np.array(
        [
            [0.34657359027997264, 0.17328679513998632, 0, 0.17328679513998632, 0, 0],
            [0, 0, 0, 0.46209812037329684, 0, 0],  # kitchen: 2/3 ln 2
            [0, 0, 0, 0, 0.34657359027997264, 0],  # bed: 1/2 ln 2
            [0, 0.17328679513998632, 0, 0, 0.17328679513998632, 0.34657359027997264],
        ]
    )
    np.testing.assert_allclose(tfidf_weights(utterances), expected, rtol=1e-15, atol=0)
    # A given vocabulary sets the columns; a token that occurs nowhere gets weight 0.
    vocabulary = ("sofa", "here", "is", "the", "kitchen", "bed", "soft")
    weights = tfidf_weights(utterances, vocabulary=vocabulary)
    np.testing.assert_array_equal(weights[:, 0], 0.0)
    np.testing.assert_allclose(weights[:, 1:], expected, rtol=1e-15, atol=0)
    with pytest.raises(ValueError, match="not in the given vocabulary"):
        tfidf_weights(utterances, vocabulary=("the",))


def test_scale_features():
    f = np.array([[0.105, 0.895, 0.0]])
    np.testing.assert_array_equal(scale_features(f, "probability"), f)
    np.testing.assert_array_equal(scale_features(f, "floor100"), [[10.0, 89.0, 0.0]])
    np.testing.assert_array_equal(scale_features(f, 2.0), [[0.21, 1.79, 0.0]])
    for bad in ("floor", -1.0, 0.0, math.inf, True):
        with pytest.raises(ValueError, match="feature_scaling"):
            scale_features(f, bad)


# ------------------------------------------------------------------------------ Observations


def test_observations_properties_and_validation():
    obs = make_obs()
    assert (obs.num_images, obs.num_utterances, obs.num_feature_classes) == (4, 5, 3)
    assert obs.trials == (0, 1, 2)
    assert obs.vocabulary == ("kitchen", "table", "bed")
    assert obs.image_features.dtype == np.float64 and obs.image_trial.dtype == np.int64
    with pytest.raises(ValueError, match="negative"):
        make_obs(image_features=[[0, -1.0, 0]] * 4)
    with pytest.raises(ValueError, match="not finite"):
        make_obs(image_features=[[0, np.nan, 0]] * 4)
    with pytest.raises(ValueError, match="image_xy has 3 rows but image_features has 4"):
        make_obs(image_xy=[[0, 0]] * 3)
    with pytest.raises(ValueError, match="word_trial"):
        make_obs(word_trial=[0, 0])
    with pytest.raises(ValueError, match="utterance 1 holds no tokens"):
        make_obs(utterances=[("a",), (), ("b",), ("c",), ("d",)])
    with pytest.raises(ValueError, match="image_yaw"):
        make_obs(image_yaw=[0.0])


def test_select_trials():
    obs = make_obs(image_yaw=[0.1, 0.2, 0.3, 0.4], image_paths=["a", "b", "c", "d"])
    sub = obs.select_trials([2, 0])
    np.testing.assert_array_equal(sub.image_features, [[0.5, 0.25, 0.25], [0.105, 0.895, 0.0]])
    np.testing.assert_array_equal(sub.image_xy, [[1.5, 2.5], [1.2, 2.9]])
    np.testing.assert_array_equal(sub.image_trial, [0, 0])
    np.testing.assert_array_equal(sub.image_yaw, [0.1, 0.2])
    assert sub.image_paths == (Path("a"), Path("b"))
    assert sub.utterances == (("kitchen",), ("kitchen", "table"), ("table",))
    np.testing.assert_array_equal(sub.word_xy, [[2.5, 1.5], [1.5, 2.5], [1.9, 2.1]])
    np.testing.assert_array_equal(sub.word_trial, [0, 0, 2])
    assert sub.trials == (0, 2)
    only_words = obs.select_trials([2])
    assert only_words.num_images == 0 and only_words.image_features.shape == (0, 3)
    with pytest.raises(ValueError, match=r"unknown trial ids \[5\]"):
        obs.select_trials([0, 5])


# ------------------------------------------------------------------------------ placement


def test_place_observations_snaps_and_reports(grid):
    xy = [
        [1.5, 2.5],  # (1, 1) F0, on free
        [2.2, 1.7],  # (2, 2) F3, on free
        [3.5, 2.5],  # (1, 3) wall next to F1: snapped (1 cell)
        [4.5, 2.5],  # (1, 4) 2 cells inside the wall: unplaced at 1 m
        [-0.5, 0.5],  # (3, -1) just off the map next to F4: snapped
        [10.0, 10.0],  # (-7, 10) far off the map: unplaced
        [5.5, 1.5],  # (2, 5) unknown, 3 cells from F3: unplaced at 1 m
        [0.5, 3.5],  # (0, 0) wall, 0.71 m from F0's square (its centre 1.41 m away)
        [0.05, 3.95],  # (0, 0) too, 1.34 m from F0's square: unplaced at 1 m
    ]
    index, snapped, unplaced = place_observations(grid, xy, snap_distance=1.0)
    np.testing.assert_array_equal(index, [0, 3, 1, -1, 4, -1, -1, 0, -1])
    np.testing.assert_array_equal(snapped, [0, 0, 1, 0, 1, 0, 0, 1, 0])
    np.testing.assert_array_equal(unplaced, [0, 0, 0, 1, 0, 1, 1, 0, 1])

    # The distance is from the point to the free cell's square, not between centres.
    index, snapped, unplaced = place_observations(grid, xy, snap_distance=0.7)
    np.testing.assert_array_equal(index, [0, 3, 1, -1, 4, -1, -1, -1, -1])
    index, snapped, unplaced = place_observations(grid, xy, snap_distance=1.5)
    np.testing.assert_array_equal(index, [0, 3, 1, 1, 4, -1, -1, 0, 0])
    # 3 m reaches (1, 4) -> F1 (1.5 m to its square; F3's is 1.58 m) and (2, 5) -> F3 (2.5 m).
    index, snapped, unplaced = place_observations(grid, xy, snap_distance=3.0)
    np.testing.assert_array_equal(index, [0, 3, 1, 1, 4, -1, 3, 0, 0])
    np.testing.assert_array_equal(unplaced, [0, 0, 0, 0, 0, 1, 0, 0, 0])
    # No snapping, not even of a point on a wall cell's edge with a free cell (0 m from it).
    index, snapped, unplaced = place_observations(grid, xy, snap_distance=0.0)
    np.testing.assert_array_equal(index, [0, 3, -1, -1, -1, -1, -1, -1, -1])
    assert place_observations(grid, [[3.0, 2.5]], snap_distance=0.0)[2].all()  # (1, 3) | F1
    assert not snapped.any()
    with pytest.raises(ValueError, match="snap_distance"):
        place_observations(grid, xy, snap_distance=-1.0)


@pytest.mark.parametrize("flag", [True, False])
def test_place_observations_refuses_a_bool_for_the_snap_distance(grid, flag):
    """True is an int: ``snap_distance=True`` snapped points up to 1 m away, False none; refused
    now with a bad distance's message (DataPreparation.snap_distance refused bools already)."""
    with pytest.raises(
        ValueError, match=f"snap_distance={flag}: must be a finite number of metres"
    ):
        place_observations(grid, [[0.5, 0.5]], snap_distance=flag)


def test_a_point_just_inside_a_thick_wall_cell_snaps_to_its_own_side():
    # A model grid coarser than the map: 0.3 m cells, the middle one a wall (it holds a thin
    # wall and free map cells on both sides). A position 2 cm into it belongs to the room it
    # was taken in, whatever the cell size; between centres both rooms are 0.3 m away, beyond
    # the default 0.25 m.
    row = OccupancyGrid(np.array([[F, O, F]], dtype=np.int8), 0.3, (0.0, 0.0, 0.0))
    xy = [[0.32, 0.15], [0.58, 0.15], [0.45, 0.6]]  # left side, right side, 0.34 m off both
    index, snapped, unplaced = place_observations(row, xy, snap_distance=DEFAULT_SNAP_DISTANCE)
    np.testing.assert_array_equal(index, [0, 1, -1])
    np.testing.assert_array_equal(snapped, [True, True, False])
    obs = Observations(
        image_features=np.eye(3), image_xy=xy, image_trial=[0, 0, 0],
        utterances=[("kitchen",)], word_xy=[[0.32, 0.15]], word_trial=[0],
    )  # fmt: skip
    report = cell_counts(row, obs, snap_distance=DEFAULT_SNAP_DISTANCE).placement
    assert (report.images_snapped, report.images_unplaced) == (2, 1)
    assert report.words_snapped == 1


def test_snap_limit_is_inclusive_despite_rounding():
    # 0.15 / 0.05 == 2.9999999999999996 in floating point: 3 cells must still be within 0.15 m.
    row = OccupancyGrid(np.array([[F, O, O, O, O]], dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    xy = [[0.175, 0.025], [0.225, 0.025]]  # columns 3 and 4
    index, snapped, unplaced = place_observations(row, xy, snap_distance=0.15)
    np.testing.assert_array_equal(index, [0, -1])
    np.testing.assert_array_equal(unplaced, [False, True])


# ------------------------------------------------------------------------------ cell counts

# With snap 1 m: images i0, i1 -> F0, i2 -> F1 (snapped), i3 unplaced; words u0 -> F3,
# u1 -> F0, u2 unplaced, u3 -> F4 (snapped), u4 -> F0. Observed cells: F0, F1, F3, F4.
EXPECTED_CELLS = [0, 1, 3, 4]
EXPECTED_IMAGES = {
    "probability": [[0.605, 1.145, 0.25], [0, 0, 1], [0, 0, 0], [0, 0, 0]],
    "floor100": [[60, 114, 25], [0, 0, 100], [0, 0, 0], [0, 0, 0]],  # 50+10, 25+89, 25+0
    2.0: [[1.21, 2.29, 0.5], [0, 0, 2], [0, 0, 0], [0, 0, 0]],
}
# vocabulary kitchen, table, bed
EXPECTED_WORD_COUNTS = [[1, 2, 0], [0, 0, 0], [1, 0, 0], [2, 0, 1]]
# tf-idf over all 5 utterances (u2 too): df kitchen 3, table 2, bed 2.
LN53, LN52 = math.log(5 / 3), math.log(5 / 2)
EXPECTED_TFIDF = [
    [0.5 * LN53, 0.5 * LN52 + LN52, 0],  # u1 (kitchen table) + u4 (table)
    [0, 0, 0],
    [LN53, 0, 0],  # u0
    [2 / 3 * LN53, 0, 1 / 3 * LN52],  # u3 (kitchen kitchen bed)
]


@pytest.mark.parametrize("scaling", ["probability", "floor100", 2.0])
@pytest.mark.parametrize("weighting", ["count", "tfidf"])
def test_cell_counts_exact(grid, scaling, weighting, caplog):
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        counts = cell_counts(
            grid,
            make_obs(),
            feature_scaling=scaling,
            word_weighting=weighting,
            snap_distance=1.0,
        )
    np.testing.assert_array_equal(counts.cells, EXPECTED_CELLS)
    assert counts.cells.dtype == np.int64
    np.testing.assert_allclose(counts.image_counts, EXPECTED_IMAGES[scaling], rtol=1e-14)
    expected_words = EXPECTED_WORD_COUNTS if weighting == "count" else EXPECTED_TFIDF
    np.testing.assert_allclose(counts.word_counts, expected_words, rtol=1e-14, atol=1e-15)
    assert counts.vocabulary == ("kitchen", "table", "bed")
    assert counts.num_free == 5

    report = counts.placement
    assert (report.images_on_free, report.images_snapped, report.images_unplaced) == (2, 1, 1)
    assert (report.words_on_free, report.words_snapped, report.words_unplaced) == (3, 1, 1)
    np.testing.assert_array_equal(report.unplaced_images, [3])
    np.testing.assert_array_equal(report.unplaced_words, [2])
    assert report.snap_distance == 1.0
    assert "1 unplaced" in report.summary() and "\n" not in report.summary()
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert "1 image(s) and 1 utterance(s)" in warnings[0].getMessage()


def test_observations_left_out_are_named_by_file_and_line(tmp_path, grid, caplog):
    """The warning named left-out observations by index only ("image indices [3]"); read from
    a house folder it names the position files' lines, with positions and words."""
    house = make_house(tmp_path, grid)
    room = save_house(house, tmp_path / "data")
    loaded = load_house(room, map_yaml=room.parent / "map" / "house1.yaml")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        cell_counts(loaded.grid, loaded.observations, snap_distance=1.0, source=loaded.source)
        cell_counts(loaded.grid, loaded.observations, snap_distance=1.0)
    named, unnamed = (m for r in caplog.records if "left out of the cell" in (m := r.getMessage()))
    assert (room / "Xtx.csv").read_text().splitlines()[3] == "10.0"  # image 3 on line 4
    assert (room / "StXtx.csv").read_text().splitlines()[2] == "4.5"  # 'tv' on line 3
    assert f"images at line(s) 4 (x 10.00, y 10.00) of {room.resolve() / 'Xtx.csv'} and " in named
    assert f"utterances at line(s) 3 ('tv' at x 4.50, y 2.50) of {room.resolve()}" in named
    assert "images of index 3 (x 10.00, y 10.00); utterances of index 2 ('tv' at" in unnamed


def test_cell_counts_nothing_vanishes(grid, caplog):
    obs = make_obs()
    for snap in (0.0, 1.0, 1.5, 3.0, DEFAULT_SNAP_DISTANCE):
        report = cell_counts(grid, obs, snap_distance=snap).placement
        assert report.images_on_free + report.images_snapped + report.images_unplaced == 4
        assert report.words_on_free + report.words_snapped + report.words_unplaced == 5
        assert report.images_unplaced == report.unplaced_images.size
        assert report.words_unplaced == report.unplaced_words.size


def test_cell_counts_vocabulary_options(grid, caplog):
    obs = make_obs()
    counts = cell_counts(
        grid, obs, snap_distance=1.0, vocabulary=("bed", "sofa", "table", "kitchen")
    )
    assert counts.vocabulary == ("bed", "sofa", "table", "kitchen")
    np.testing.assert_array_equal(
        counts.word_counts, [[0, 0, 2, 1], [0, 0, 0, 0], [0, 0, 0, 1], [1, 0, 0, 2]]
    )
    with pytest.raises(ValueError, match="'bed'"):
        cell_counts(grid, obs, vocabulary=("kitchen", "table"))
    for blank in ("", " "):  # no word, as Observations refuses it in an utterance
        for weighting in ("count", "tfidf"):  # word_matrix's one check and message, at column 3
            said = f"vocabulary word 3 is {blank!r}: a word is non-blank text"
            with pytest.raises(ValueError, match=re.escape(said)):
                cell_counts(grid, obs, word_weighting=weighting,
                            vocabulary=("bed", "table", "kitchen", blank))  # fmt: skip
    images_only = obs.select_trials([0, 1]).select_trials([0])
    images_only = Observations(
        image_features=images_only.image_features,
        image_xy=images_only.image_xy,
        image_trial=images_only.image_trial,
        utterances=(),
        word_xy=np.zeros((0, 2)),
        word_trial=[],
    )
    for vocabulary in (None, ()):  # no utterances: V = 0 (a house of images only is fitted)
        counts = cell_counts(grid, images_only, vocabulary=vocabulary)
        assert counts.word_counts.shape == (1, 0)
    np.testing.assert_array_equal(counts.cells, [0])
    with pytest.raises(ValueError, match="word_weighting"):
        cell_counts(grid, obs, word_weighting="bm25")


# ------------------------------------------------------------------------------ loader errors


def write_room(root: Path, grid: OccupancyGrid, name: str = "room") -> Path:
    """A small valid room written by hand: 3 images (2 trials), 3 utterances."""
    save_map(grid, root / "map" / f"{name}.yaml")
    room = root / name
    room.mkdir()
    files = {
        "Ft.csv": "0.5,0.25,0.25\n0.1,0.9,0\n0,0,1\n",
        "Xtx.csv": "1.5\n2.5\n3.5\n",
        "Xty.csv": "2.5\n1.5\n2.5\n",
        "St.csv": "kitchen,Here is the kitchen.,bed",
        "StXtx.csv": "1.5\n2.5\n3.5\n",
        "StXty.csv": "2.5\n1.5\n2.5\n",
        "pose_0.csv": "1.5,2.5,0,1\n2.5,1.5,1,0\n",
        "pose_1.csv": "3.5,2.5,0.7071067811865476,0.7071067811865476\n",
        "word_0.csv": "kitchen\nhere is the kitchen\n",
        "word_1.csv": "bed",
    }
    for file, text in files.items():
        (room / file).write_text(text)
    return room


def test_load_hand_written_room(tmp_path, grid):
    house = load_house(write_room(tmp_path, grid))
    obs = house.observations
    assert house.name == "room" and house.grid == grid
    np.testing.assert_array_equal(obs.image_features, [[0.5, 0.25, 0.25], [0.1, 0.9, 0], [0, 0, 1]])
    np.testing.assert_array_equal(obs.image_xy, [[1.5, 2.5], [2.5, 1.5], [3.5, 2.5]])
    np.testing.assert_array_equal(obs.image_trial, [0, 0, 1])
    assert obs.utterances == (("kitchen",), ("here", "is", "the", "kitchen"), ("bed",))
    np.testing.assert_array_equal(obs.word_trial, [0, 0, 1])
    np.testing.assert_allclose(obs.image_yaw, [0.0, math.pi, math.pi / 2], atol=1e-15)
    assert obs.image_paths is None and house.truth is None


def test_double_spaces_make_no_empty_word(tmp_path, grid):
    """Spaces (several, a tab, a no-break space) part words: none is read as a word ""."""
    room = write_room(tmp_path, grid)
    (room / "St.csv").write_text("kitchen,  Here  is\tthe\u00a0kitchen. ,bed")
    (room / "word_0.csv").write_text("kitchen\nhere   is the  kitchen \n")
    obs = load_house(room).observations
    assert obs.utterances == (("kitchen",), ("here", "is", "the", "kitchen"), ("bed",))
    assert obs.vocabulary == ("kitchen", "here", "is", "the", "bed")


def test_load_without_trial_files_is_one_trial(tmp_path, grid):
    room = write_room(tmp_path, grid)
    for file in ("pose_0.csv", "pose_1.csv", "word_0.csv", "word_1.csv"):
        (room / file).unlink()
    obs = load_house(room).observations
    np.testing.assert_array_equal(obs.image_trial, [0, 0, 0])
    np.testing.assert_array_equal(obs.word_trial, [0, 0, 0])
    assert obs.image_yaw is None


BAD_FILES = [
    # (file, new content, expected fragments of the message)
    ("Ft.csv", "0.5,0.25,0.25\n0.1,abc,0\n0,0,1\n", ["Ft.csv", "line 2", "column 2", "'abc'"]),
    ("Ft.csv", "0.5,0.25,0.25\n0.1,0.9,0\nnan,0,1\n", ["Ft.csv", "line 3", "not finite", "'nan'"]),
    ("Ft.csv", "0.5,0.25,inf\n0.1,0.9,0\n0,0,1\n", ["Ft.csv", "line 1", "not finite", "'inf'"]),
    ("Ft.csv", "0.5,0.25,0.25\n0.1,0.9,0\n0,-0.5,1\n", ["Ft.csv", "line 3", "negative", "-0.5"]),
    ("Ft.csv", "0.5,0.25,0.25\n0.1,0.9\n0,0,1\n", ["Ft.csv", "line 2", "2 values", "'0.1,0.9'"]),
    ("Ft.csv", "0.5,0.25,0.25\n\n0,0,1\n", ["Ft.csv", "line 2", "empty line"]),
    ("Ft.csv", "\n", ["Ft.csv", "empty"]),
    ("Xtx.csv", "1.5\n2.5\n", ["Xtx.csv", "2 values", "Ft.csv holds 3"]),
    ("Xty.csv", "2.5\nabout 1.5\n2.5\n", ["Xty.csv", "line 2", "'about 1.5'"]),
    ("Xty.csv", "2.5\n1.5,1\n2.5\n", ["Xty.csv", "line 2", "'1.5,1'"]),
    ("StXtx.csv", "1.5\n2.5\n3.5\n4.5\n", ["StXtx.csv", "4 values", "St.csv holds 3"]),
    ("StXty.csv", "2.5\n1.5\nx\n", ["StXty.csv", "line 3", "'x'"]),
    ("St.csv", "", ["St.csv", "no words"]),
    ("St.csv", " , ", ["St.csv", "line 1", "utterance 1", "' '"]),
    ("St.csv", "kitchen,,bed", ["St.csv", "line 1", "utterance 2", "''"]),
    ("St.csv", "kitchen,here\nbed", ["St.csv", "line 2", "'bed'"]),
    ("pose_1.csv", "3.5,2.5,0,1\n9,9,0,1\n", ["Ft.csv", "pose_0.csv: 2", "pose_1.csv: 2"]),
    ("pose_1.csv", "3.5,2.5,0\n", ["pose_1.csv", "line 1", "3 values"]),
    ("pose_0.csv", "1.5,2.5,0,1\n2.5,1.6,1,0\n", ["pose_0.csv", "line 2", "Xtx.csv", "1.6"]),
    ("pose_1.csv", "3.5,2.6,0,1\n", ["pose_1.csv", "line 1", "Xtx.csv/Xty.csv line 3", "2.6"]),
    ("pose_1.csv", "3.5,2.5,0,0\n", ["pose_1.csv", "line 1", "quaternion", "0.0"]),
    ("word_1.csv", "sofa\n", ["word_1.csv", "line 1", "St.csv utterance 3", "'sofa'"]),
    ("word_1.csv", "", ["St.csv", "word_0.csv: 2", "word_1.csv: 0"]),
    # an empty first word file: the counts, not word_1.csv line 1 "differs from utterance 1"
    ("word_0.csv", "", ["St.csv", "word_0.csv: 0", "word_1.csv: 1"]),
    # a blank line is an utterance of no words, not an empty word
    ("word_0.csv", "kitchen\n \nhere is the kitchen\n", ["word_0.csv", "line 2", "no words"]),
]


@pytest.mark.parametrize(("file", "text", "fragments"), BAD_FILES)
def test_loader_errors_name_file_line_value(tmp_path, grid, file, text, fragments):
    room = write_room(tmp_path, grid)
    (room / file).write_text(text)
    with pytest.raises(DataFormatError) as error:
        load_house(room)
    message = str(error.value)
    for fragment in fragments:
        assert fragment in message, (fragment, message)


@pytest.mark.parametrize("file", ["Ft.csv", "Xtx.csv", "St.csv", "StXty.csv"])
def test_loader_missing_required_file(tmp_path, grid, file):
    room = write_room(tmp_path, grid)
    (room / file).unlink()
    with pytest.raises(FileNotFoundError, match=file):
        load_house(room)


def test_loader_given_a_file_names_it_as_a_file(tmp_path, grid):
    room = write_room(tmp_path, grid)
    with pytest.raises(NotADirectoryError, match="Ft.csv is a file, not a room folder"):
        load_house(room / "Ft.csv")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_house(room / "nothing")


def test_loader_missing_map_and_unpaired_trial_files(tmp_path, grid):
    room = write_room(tmp_path, grid)
    (room / "word_1.csv").unlink()
    with pytest.raises(DataFormatError, match="word_1.csv") as error:
        load_house(room)
    assert "trial 1 has a pose file but no word file" in str(error.value)  # not every trial
    (tmp_path / "map" / "room.yaml").unlink()
    with pytest.raises(FileNotFoundError, match="room.yaml") as error:
        load_house(room)
    assert f"(no map in {tmp_path / 'map'})" in str(error.value)


def test_a_copied_house_without_its_map_names_the_maps_there(tmp_path, grid):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(write_room(tmp_path, grid), copy)  # its map is still map/room.yaml
    with pytest.raises(
        FileNotFoundError,
        match=r"map/copy.yaml: map of house 'copy' not found"
        r".*NAME the folder's name \(the maps there: room.yaml\); a copied",
    ):
        load_house(copy)
    shutil.rmtree(tmp_path / "map")
    with pytest.raises(FileNotFoundError, match=r"\(there is no folder .*map\)"):
        load_house(copy)


def test_loader_truth_errors(tmp_path, grid):
    room = write_room(tmp_path, grid)
    np.save(room / "truth.npy", np.full((3, 6), -1, dtype=np.int64))
    with pytest.raises(DataFormatError, match=r"truth.npy.*\(3, 6\)"):
        load_house(room)
    labels = np.full(TINY.shape, -1)
    labels[0, 0] = 1  # an occupied cell
    np.save(room / "truth.npy", labels)
    with pytest.raises(DataFormatError, match=r"truth.npy.*row 0, col 0"):
        load_house(room)
    (room / "categories.json").write_text('{"a": 1}')
    with pytest.raises(DataFormatError, match="categories.json"):
        load_house(room)


def test_loader_image_folder_mismatch_warns(tmp_path, grid, caplog):
    room = write_room(tmp_path, grid)
    for k, n in ((0, 2), (1, 1)):
        (room / f"img_{k}").mkdir()
        for i in range(n):
            (room / f"img_{k}" / f"{i + 1:05d}.jpg").write_bytes(b"jpg")
    paths = load_house(room).observations.image_paths
    assert [p.relative_to(room).as_posix() for p in paths] == [
        "img_0/00001.jpg",
        "img_0/00002.jpg",
        "img_1/00001.jpg",
    ]
    (room / "img_0" / "00002.jpg").unlink()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        house = load_house(room)
    assert house.observations.image_paths is None
    # the count is pose_0.csv's (it splits Ft.csv's rows into trials): it was 'trial 0 has 2
    # rows in Ft.csv', of a file that holds 3 rows
    (message,) = [r.getMessage() for r in caplog.records if "img_0" in r.getMessage()]
    assert message.startswith(
        f"{room / 'img_0'} holds 1 images but pose_0.csv holds 2 poses, one per image of trial 0"
    )
    for name in ("pose_0.csv", "pose_1.csv", "word_0.csv", "word_1.csv", "img_1/00001.jpg"):
        (room / name).unlink()
    (room / "img_1").rmdir()
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_house(room)  # without pose files, one trial: Ft.csv's rows are the count
    (message,) = [r.getMessage() for r in caplog.records if "img_0" in r.getMessage()]
    assert message.startswith(f"{room / 'img_0'} holds 1 images but Ft.csv holds 3 rows")


def test_an_image_folder_of_no_trial_names_the_trials_and_the_missing_pose_file(
    tmp_path, grid, caplog
):
    """'img_5 has no trial' said neither which trials the house has nor what was missing."""
    room = write_room(tmp_path, grid)
    for k, n in ((0, 2), (1, 1), (5, 1)):
        (room / f"img_{k}").mkdir()
        for i in range(n):
            (room / f"img_{k}" / f"{i + 1:05d}.jpg").write_bytes(b"jpg")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        assert load_house(room).observations.image_paths is None
    (message,) = [r.getMessage() for r in caplog.records if "img_5" in r.getMessage()]
    assert "img_5 belongs to no trial of the house (its trials: 0, 1; there is no pose_5.csv)" in (
        message
    )


# ------------------------------------------------------------------------------ round trip


def make_house(tmp_path: Path, grid: OccupancyGrid) -> House:
    image_dir = tmp_path / "camera"
    image_dir.mkdir()
    paths = []
    for i in range(4):
        paths.append(image_dir / f"shot{i}.jpg")
        paths[-1].write_bytes(bytes([i]) * 10)
    obs = make_obs(
        image_features=[[1 / 3, 2 / 3, 0.0], [0.1, 0.2, 0.7], [1e-17, 0.0, 1.0], [0.0, 0.0, 0.0]],
        image_xy=[[1.5, 2.5], [1 / 7, -2 / 3], [3.5, 2.5], [10.0, 10.0]],
        image_trial=[0, 0, 2, 2],
        utterances=[("here", "is", "the", "kitchen"), ("bed",), ("tv",), ("the", "table")],
        word_xy=[[2.5, 1.5], [1.5, 2.5], [4.5, 2.5], [-0.5, 0.5]],
        word_trial=[0, 2, 2, 3],  # trial 3 has words but no images
        image_yaw=[0.0, 1.0, -2.5, 3.0],
        image_paths=paths,
    )
    truth = np.full(TINY.shape, -1, dtype=np.int64)
    truth[1:3, 1:3] = [[0, 0], [1, -1]]
    truth[3, 0] = 1
    return House("house1", grid, obs, truth=truth, category_names=("kitchen", "bedroom"))


def test_save_load_round_trip(tmp_path, grid):
    house = make_house(tmp_path, grid)
    room = save_house(house, tmp_path / "data")
    assert room == tmp_path / "data" / "house1"
    assert (room / "St.csv").read_text() == "here is the kitchen,bed,tv,the table"
    assert sorted(p.name for p in room.iterdir() if p.name.startswith(("pose", "word"))) == [
        "pose_0.csv",
        "pose_2.csv",
        "pose_3.csv",
        "word_0.csv",
        "word_2.csv",
        "word_3.csv",
    ]
    assert list_houses(tmp_path / "data") == ["house1"]

    back = load_house(room)
    a, b = house.observations, back.observations
    assert back.name == "house1" and back.grid == grid and back.source == room.resolve()
    for name in ("image_features", "image_xy", "image_trial", "word_xy", "word_trial"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
    assert b.utterances == a.utterances
    np.testing.assert_allclose(b.image_yaw, a.image_yaw, rtol=0, atol=1e-14)
    assert [p.read_bytes() for p in b.image_paths] == [p.read_bytes() for p in a.image_paths]
    np.testing.assert_array_equal(back.truth, house.truth)
    assert back.category_names == ("kitchen", "bedroom")

    with pytest.raises(FileExistsError):
        save_house(house, tmp_path / "data")
    smaller = House("house1", grid, a.select_trials([0]))  # stale trials 2, 3 must go
    save_house(smaller, tmp_path / "data", overwrite=True)
    again = load_house(room)
    assert again.observations.trials == (0,) and again.truth is None
    assert again.observations.image_paths is not None and len(again.observations.image_paths) == 2


def test_save_rejects_unrepresentable_houses(tmp_path, grid):
    for utterances, fragment in (
        ([("a,b",), ("c",), ("d",), ("e",), ("f",)], "comma"),
        ([("Kitchen",), ("c",), ("d",), ("e",), ("f",)], "read back"),
        ([("two words",), ("c",), ("d",), ("e",), ("f",)], "read back"),
    ):
        house = House("h", grid, make_obs(utterances=utterances))
        with pytest.raises(ValueError, match=fragment):
            save_house(house, tmp_path)
    unsorted = House("h", grid, make_obs(image_trial=[1, 0, 0, 0]))
    with pytest.raises(ValueError, match="ascending"):
        save_house(unsorted, tmp_path)
    with pytest.raises(ValueError, match="truth"):
        House("h", grid, make_obs(), truth=np.zeros((2, 2), dtype=np.int64))


def test_find_dataset_root_and_list_houses(tmp_path, monkeypatch):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        find_dataset_root(tmp_path / "nowhere")
    with pytest.raises(FileNotFoundError, match="no map/"):
        find_dataset_root(tmp_path)
    (tmp_path / "map").mkdir()
    for name in ("b", "a", "c"):
        (tmp_path / name).mkdir()
    (tmp_path / "map" / "a.yaml").write_text("")
    (tmp_path / "map" / "b.yaml").write_text("")
    assert find_dataset_root(tmp_path) == tmp_path.resolve()
    monkeypatch.setenv("SPCOPYRO_DATA", str(tmp_path))
    assert find_dataset_root() == tmp_path.resolve()
    assert list_houses(tmp_path) == ["a", "b"]


# ------------------------------------------------------------------------------ public dataset

# Off-free observations with the default snap distance (0.25 m), measured on the public data.
SNAPPED = {"room1dk5": (10, 2), "room1ldk4": (17, 6)}


def count_lines(path: Path) -> int:
    return len([line for line in path.read_text().splitlines() if line.strip()])


@pytest.mark.dataset
def test_public_houses(dataset_root, capsys):
    houses = list_houses(dataset_root)
    assert houses == ["room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4"]
    for name in houses:
        room = dataset_root / name
        house = load_house(room)
        obs = house.observations
        assert obs.num_images == count_lines(room / "Ft.csv")
        assert obs.num_utterances == count_lines(room / "StXtx.csv")
        assert obs.num_feature_classes == 205
        assert obs.trials == (0, 1, 2)
        for k in range(3):
            assert (obs.image_trial == k).sum() == count_lines(room / f"pose_{k}.csv")
            assert (obs.word_trial == k).sum() == count_lines(room / f"word_{k}.csv")
            assert len(list((room / f"img_{k}").glob("*.jpg"))) == (obs.image_trial == k).sum()
        assert obs.image_paths is not None and obs.image_yaw is not None
        assert "kitchen" in obs.vocabulary

        counts = cell_counts(house.grid, obs)
        report = counts.placement
        assert report.images_on_free + report.images_snapped + report.images_unplaced == (
            obs.num_images
        )
        assert report.words_on_free + report.words_snapped + report.words_unplaced == (
            obs.num_utterances
        )
        assert (report.images_unplaced, report.words_unplaced) == (0, 0)
        assert (report.images_snapped, report.words_snapped) == SNAPPED.get(name, (0, 0))
        np.testing.assert_allclose(counts.image_counts.sum(), obs.num_images, rtol=1e-6)
        assert counts.word_counts.sum() == obs.num_utterances
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""


def test_save_house_overwrites_the_room_its_images_are_read_from(tmp_path, grid):
    """A house loaded from ROOM, written over ROOM (overwrite): its images are copied into the
    staging folder before the swap, so the new ROOM holds them, byte for byte (save_house
    refused this, saying the images were read from ROOM)."""
    house = make_house(tmp_path, grid)
    room = save_house(house, tmp_path / "data")
    back = load_house(room)
    originals = {k: [p.read_bytes() for p in house.observations.select_trials([k]).image_paths]
                 for k in (0, 2)}  # fmt: skip
    save_house(House("house1", grid, back.observations.select_trials([0, 2])), room.parent,
               overwrite=True)  # fmt: skip
    again = load_house(room).observations
    assert again.trials == (0, 2)
    for k in (0, 2):
        assert [p.read_bytes() for p in again.select_trials([k]).image_paths] == originals[k]
        assert len(originals[k]) == 2
    assert sorted(p.name for p in room.iterdir() if p.name.startswith("img_")) == ["img_0", "img_2"]
