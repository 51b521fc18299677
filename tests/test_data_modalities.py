"""Tests of further modalities in spcopyro.data: ModalityObservations and its validation, trial
selection, placement and per-cell sums in cell_counts, the ``modality_<name>.csv`` files (round
trip and every malformed-file case), and that nothing changes without further modalities.

The tiny hand-made grid (as in test_data.py; resolution 1 m, origin (0, 0), so the cell of a
world point (x, y) is row = 3 - floor(y), col = floor(x)); F free, O occupied, U unknown::

            col 0  1  2  3  4  5
    row 0       O  O  O  O  O  O      y in [3, 4)
    row 1       O  F0 F1 O  O  O      y in [2, 3)
    row 2       O  F2 F3 O  O  U      y in [1, 2)
    row 3       F4 O  O  O  O  O      y in [0, 1)

Fn is the free cell with free_index n (raster order).
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from spcopyro.data import (
    CellModalityCounts,
    DataFormatError,
    House,
    ModalityObservations,
    ModalityPlacement,
    Observations,
    cell_counts,
    load_house,
    save_house,
)
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

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


def wifi(**changes) -> ModalityObservations:
    """Five observations of three access points."""
    fields = dict(
        name="wifi",
        items=("ap1", "ap2", "ap3"),
        positions=[
            [1.5, 2.5],  # o0 at F0 (with images i0, i1 and word u1, u4)
            [1.1, 2.2],  # o1 at F0 too
            [1.5, 1.5],  # o2 at F2: a cell with no image and no word
            [3.5, 2.5],  # o3 on the wall (1, 3): snapped to F1 at 1 m
            [10.0, 10.0],  # o4 far off the map: unplaced
        ],
        trials=[0, 0, 1, 1, 7],  # trial 7 has neither images nor words
        counts=[
            [1.0, 0.0, 2.0],
            [0.5, 3.0, 0.0],
            [0.0, 0.0, 4.0],
            [2.0, 2.0, 2.0],
            [9.0, 9.0, 9.0],
        ],
    )
    fields.update(changes)
    return ModalityObservations(**fields)


def objects(**changes) -> ModalityObservations:
    """Two observations of detected objects, both on cells with images or words."""
    fields = dict(
        name="objects",
        items=("sofa", "fridge"),
        positions=[[2.5, 1.5], [1.2, 2.9]],  # F3, F0
        trials=[0, 1],
        counts=[[1, 0], [0, 2]],
    )
    fields.update(changes)
    return ModalityObservations(**fields)


def make_obs(**changes) -> Observations:
    """Four images and five utterances on the tiny grid (those of test_data.py)."""
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


# ------------------------------------------------------------------------------ validation


def test_modality_observations_converts_and_counts():
    raw_counts = np.array([[1, 0, 2]] * 5)  # int: converted (copied) to float64
    m = wifi(counts=raw_counts, items=["ap1", "ap2", "ap3"])
    assert m.items == ("ap1", "ap2", "ap3")
    assert (m.num_observations, m.num_items) == (5, 3)
    assert m.counts.dtype == np.float64 and m.positions.dtype == np.float64
    assert m.trials.dtype == np.int64
    raw_counts[0, 0] = 100
    assert m.counts[0, 0] == 1.0
    empty = ModalityObservations("radio", ("a",), positions=[], trials=[], counts=[])
    assert empty.counts.shape == (0, 1) and empty.positions.shape == (0, 2)
    assert empty.trials.shape == (0,)


@pytest.mark.parametrize(
    ("changes", "error", "fragment"),
    [
        (dict(name="WiFi"), ValueError, "lower-case identifier"),
        (dict(name="2g"), ValueError, "lower-case identifier"),
        (dict(name=""), ValueError, "lower-case identifier"),
        (dict(name="wi-fi"), ValueError, "lower-case identifier"),
        (dict(name="images"), ValueError, "must not be one of"),
        (dict(name="words"), ValueError, "must not be one of"),
        (dict(name="theta"), ValueError, "would take the name of a model site"),
        (dict(name="log_joint"), ValueError, "or of a sampler diagnostic"),  # mcmc.get_samples()
        (dict(name="wifi_probs"), ValueError, "end in _probs"),  # modality wifi's parameters
        (dict(items=(), counts=np.zeros((5, 0))), ValueError, "at least one"),
        (dict(items="ap1"), ValueError, "sequence of names"),
        (dict(items=("ap1", "ap2", "ap1")), ValueError, "'ap1' more than once"),
        (dict(items=("ap1", "a,b", "ap3")), ValueError, "item 1"),
        (dict(items=("ap1", " ap2", "ap3")), ValueError, "item 1"),
        (dict(items=("ap1", "", "ap3")), ValueError, "item 1"),
        (dict(items=("ap1", "a\nb", "ap3")), ValueError, "item 1"),
        (dict(items=("ap1", 2, "ap3")), ValueError, "item 1"),
        (dict(counts=np.ones((5, 2))), ValueError, r"counts must have shape \[T, 3\]"),
        (dict(counts=np.ones(5)), ValueError, r"counts must have shape \[T, 3\]"),
        (dict(counts=[[1, 0, 2]] * 4 + [[1, -0.5, 0]]), ValueError, r"counts\[4, 1\] is negative"),
        (dict(counts=[[1, 0, 2]] * 4 + [[1, 0, np.inf]]), ValueError, r"counts\[4, 2\] is not fin"),
        (dict(positions=[[0, 0]] * 4), ValueError, "positions has 4 rows but counts has 5"),
        (dict(positions=[[0, 0, 0]] * 5), ValueError, r"positions must have shape \[N, 2\]"),
        (dict(positions=[[0, 0]] * 4 + [[np.nan, 0]]), ValueError, "positions row 4 is not fin"),
        (dict(trials=[0, 0, 1]), ValueError, r"trials must have shape \[5\]"),
        (dict(trials=[0, 0, 1, 1, -1]), ValueError, "negative trial id"),
        (dict(trials=[0.0, 0, 1, 1, 2]), ValueError, "must hold integers"),
    ],
)
def test_modality_observations_validation(changes, error, fragment):
    with pytest.raises(error, match=fragment) as info:
        wifi(**changes)
    if "name" not in changes:
        assert "modality 'wifi'" in str(info.value)


def test_observations_with_modalities():
    obs = make_obs(modalities=[wifi(), objects()])
    assert isinstance(obs.modalities, tuple)
    assert [m.name for m in obs.modalities] == ["wifi", "objects"]
    assert obs.modality("objects") is obs.modalities[1]
    with pytest.raises(KeyError, match="no modality 'radio'"):
        obs.modality("radio")
    assert obs.trials == (0, 1, 2, 7)  # trial 7: only wifi
    assert make_obs().modalities == () and make_obs().trials == (0, 1, 2)
    with pytest.raises(ValueError, match="'wifi' is used more than once"):
        make_obs(modalities=(wifi(), objects(), wifi(trials=[1] * 5)))
    with pytest.raises(TypeError, match=r"modalities\[1\] must be a ModalityObservations"):
        make_obs(modalities=(wifi(), "objects"))
    with pytest.raises(TypeError, match="not one"):
        make_obs(modalities=wifi())


def test_select_trials_filters_modalities():
    obs = make_obs(modalities=(wifi(), objects()))
    sub = obs.select_trials([0, 7])
    w, o = sub.modalities
    assert (w.name, w.items) == ("wifi", ("ap1", "ap2", "ap3"))
    np.testing.assert_array_equal(w.trials, [0, 0, 7])
    np.testing.assert_array_equal(w.positions, [[1.5, 2.5], [1.1, 2.2], [10.0, 10.0]])
    np.testing.assert_array_equal(w.counts, [[1, 0, 2], [0.5, 3, 0], [9, 9, 9]])
    np.testing.assert_array_equal(o.trials, [0])
    assert sub.trials == (0, 7) and sub.num_images == 2
    only_words = obs.select_trials([2])  # a modality with no observation left stays, T = 0
    assert [m.num_observations for m in only_words.modalities] == [0, 0]
    assert only_words.modalities[1].counts.shape == (0, 2)
    with pytest.raises(ValueError, match=r"unknown trial ids \[5\]"):
        obs.select_trials([5])


# ------------------------------------------------------------------------------ cell counts


def test_cell_counts_places_and_sums_modalities(grid, caplog):
    plain = cell_counts(grid, make_obs(), snap_distance=1.0)
    with caplog.at_level(logging.INFO, logger="spcopyro"):
        counts = cell_counts(
            grid,
            make_obs(modalities=(wifi(), objects())),
            snap_distance=1.0,
            feature_scaling="floor100",  # not applied to further modalities
        )
    # Images and words occupy F0, F1, F3, F4; wifi adds F2, where nothing else was observed.
    np.testing.assert_array_equal(plain.cells, [0, 1, 3, 4])
    np.testing.assert_array_equal(counts.cells, [0, 1, 2, 3, 4])
    assert counts.cells.dtype == np.int64
    w, o = counts.modalities
    assert isinstance(w, CellModalityCounts)
    assert (w.name, w.items, o.name, o.items) == (
        "wifi",
        ("ap1", "ap2", "ap3"),
        "objects",
        ("sofa", "fridge"),
    )
    np.testing.assert_array_equal(
        w.counts,
        [
            [1.5, 3.0, 2.0],  # F0: o0 + o1
            [2.0, 2.0, 2.0],  # F1: o3, snapped
            [0.0, 0.0, 4.0],  # F2: o2
            [0.0, 0.0, 0.0],  # F3
            [0.0, 0.0, 0.0],  # F4
        ],
    )
    np.testing.assert_array_equal(o.counts, [[0, 2], [0, 0], [0, 0], [1, 0], [0, 0]])
    assert w.counts.dtype == np.float64
    # The image and word rows follow the new cells: F2's rows are zero, the others unchanged.
    floor100 = cell_counts(grid, make_obs(), snap_distance=1.0, feature_scaling="floor100")
    keep = [0, 1, 3, 4]
    np.testing.assert_array_equal(counts.image_counts[keep], floor100.image_counts)
    np.testing.assert_array_equal(counts.word_counts[keep], floor100.word_counts)
    np.testing.assert_array_equal(counts.image_counts[2], 0.0)
    np.testing.assert_array_equal(counts.word_counts[2], 0.0)
    assert counts.vocabulary == plain.vocabulary

    report = counts.placement
    assert report.images_unplaced == plain.placement.images_unplaced == 1
    wp, op = report.modalities
    assert isinstance(wp, ModalityPlacement)
    assert (wp.name, wp.on_free, wp.snapped, wp.unplaced) == ("wifi", 3, 1, 1)
    np.testing.assert_array_equal(wp.unplaced_indices, [4])
    assert (op.name, op.on_free, op.snapped, op.unplaced) == ("objects", 2, 0, 0)
    summary = report.summary()
    assert summary.startswith(plain.placement.summary().removesuffix(" (snap distance 1 m)"))
    assert "; wifi: 3 on free cells, 1 snapped, 1 unplaced" in summary
    assert "; objects: 2 on free cells, 0 snapped, 0 unplaced (snap distance 1 m)" in summary
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any(
        "1 observation(s) of modality 'wifi'" in m and "observations of index 4 (" in m
        for m in warnings
    )
    infos = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
    assert any("1 observation(s) of modality 'wifi' snapped" in m for m in infos)


def test_cell_holding_only_a_further_modality(grid):
    # No image or word lands on a free cell; one wifi observation does (F2).
    obs = Observations(
        image_features=np.zeros((0, 3)),
        image_xy=np.zeros((0, 2)),
        image_trial=[],
        utterances=(),
        word_xy=np.zeros((0, 2)),
        word_trial=[],
        modalities=(wifi(positions=[[1.5, 1.5]], trials=[0], counts=[[0, 1, 0]]),),
    )
    counts = cell_counts(grid, obs, vocabulary=())
    np.testing.assert_array_equal(counts.cells, [2])
    assert counts.image_counts.shape == (1, 3) and counts.word_counts.shape == (1, 0)
    np.testing.assert_array_equal(counts.image_counts, 0.0)
    np.testing.assert_array_equal(counts.modalities[0].counts, [[0, 1, 0]])


def test_cell_counts_without_further_modalities_is_unchanged(grid):
    obs = make_obs()
    for options in (
        dict(snap_distance=1.0),
        dict(snap_distance=0.0, feature_scaling="floor100", word_weighting="tfidf"),
    ):
        plain = cell_counts(grid, obs, **options)
        assert plain.modalities == () and plain.placement.modalities == ()
        for modalities in (
            (wifi(positions=[], trials=[], counts=np.zeros((0, 3))),),  # T = 0
            (objects(),),  # only on cells that already hold images or words
        ):
            other = cell_counts(grid, make_obs(modalities=modalities), **options)
            for name in ("cells", "image_counts", "word_counts"):
                a, b = getattr(plain, name), getattr(other, name)
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
    assert plain.placement.summary() == (
        "images: 2 on free cells, 0 snapped, 2 unplaced; words: 3 on free cells, 0 snapped, "
        "2 unplaced (snap distance 0 m)"
    )


# ------------------------------------------------------------------------------ files


def make_house(grid: OccupancyGrid, modalities=None) -> House:
    if modalities is None:
        modalities = (objects(), wifi())
    return House("house1", grid, make_obs(modalities=modalities))


def test_modality_files_round_trip(tmp_path, grid):
    house = make_house(grid)
    room = save_house(house, tmp_path / "data")
    assert (room / "modality_wifi.csv").read_text().splitlines() == [
        "trial,x,y,ap1,ap2,ap3",
        "0,1.5,2.5,1.0,0.0,2.0",
        "0,1.1,2.2,0.5,3.0,0.0",
        "1,1.5,1.5,0.0,0.0,4.0",
        "1,3.5,2.5,2.0,2.0,2.0",
        "7,10.0,10.0,9.0,9.0,9.0",
    ]
    assert (room / "modality_objects.csv").is_file()
    assert not (room / "pose_7.csv").exists()  # trial 7 holds only wifi observations
    back = load_house(room).observations
    assert [m.name for m in back.modalities] == ["objects", "wifi"]  # sorted by name
    for a, b in zip(house.observations.modalities, back.modalities, strict=True):
        assert (a.name, a.items) == (b.name, b.items)
        for name in ("positions", "trials", "counts"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), name
    assert back.trials == (0, 1, 2, 7)
    plain_back = load_house(save_house(House("plain", grid, make_obs()), tmp_path / "data"))
    assert plain_back.observations.modalities == ()

    # Awkward floats read back exactly; an overwrite removes stale modality files.
    odd = wifi(
        positions=[[1 / 3, -2 / 3], [1e-300, 2.5], [0, 0], [1, 1], [5e17, 3]],
        counts=np.array([[1 / 7, 0, 1e-17]] * 5),
    )
    save_house(make_house(grid, (odd,)), tmp_path / "data", overwrite=True)
    assert not (room / "modality_objects.csv").exists()
    (again,) = load_house(room).observations.modalities
    assert again.positions.tobytes() == odd.positions.tobytes()
    assert again.counts.tobytes() == odd.counts.tobytes()


def test_hand_written_modality_file(tmp_path, grid):
    room = save_house(make_house(grid, ()), tmp_path / "data")
    (room / "modality_sound.csv").write_bytes(
        b"\xef\xbb\xbftrial, x ,y,speech,music\r\n3,1.5,2.5,2,0\r\n0, 2.5 ,1.5,0, 1e-1\r\n\r\n"
    )
    (sound,) = load_house(room).observations.modalities
    assert sound.name == "sound" and sound.items == ("speech", "music")
    np.testing.assert_array_equal(sound.trials, [3, 0])
    np.testing.assert_array_equal(sound.positions, [[1.5, 2.5], [2.5, 1.5]])
    np.testing.assert_array_equal(sound.counts, [[2, 0], [0, 0.1]])
    (room / "modality_sound.csv").write_text("trial,x,y,speech\n")  # no observation: T = 0
    (sound,) = load_house(room).observations.modalities
    assert sound.counts.shape == (0, 1)


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("", ["line 1", "no header line"]),
        ("trial,x,z,ap1\n", ["line 1, column 3", "header column 3 must be 'y'", "'z'"]),
        ("trial,x\n", ["line 1, column 3", "must be 'y'", "''"]),
        ("trial,x,y\n", ["line 1", "names no item", "'trial,x,y'"]),
        ("trial,x,y,a,b,a\n", ["line 1, column 6", "item named twice", "column 4", "'a'"]),
        ("trial,x,y,a,,b\n", ["line 1, column 5", "empty item name", "''"]),
        ("trial,x,y,a\n0,1,1,1\n0,1,1\n", ["line 3", "row has 3 values, expected 4", "'0,1,1'"]),
        ("trial,x,y,a\n0,1,1,1\n\n0,1,1,1\n", ["line 3", "empty line"]),
        ("trial,x,y,a\n0,abc,1,1\n", ["line 2, column 2", "not a number", "'abc'"]),
        ("trial,x,y,a\n0,1,inf,1\n", ["line 2, column 3", "not finite", "'inf'"]),
        ("trial,x,y,a,b\n0,1,1,1,-2\n", ["line 2, column 5", "negative count of item 'b'", "'-2'"]),
        ("trial,x,y,a\n0,1,1,nan\n", ["line 2, column 4", "not finite", "'nan'"]),
        ("trial,x,y,a\n1.5,1,1,1\n", ["line 2, column 1", "trial id", "'1.5'"]),
        ("trial,x,y,a\n-1,1,1,1\n", ["line 2, column 1", "trial id", "'-1'"]),
    ],
)
def test_malformed_modality_file_names_file_line_value(tmp_path, grid, text, fragments):
    room = save_house(make_house(grid, ()), tmp_path / "data")
    path = room / "modality_wifi.csv"
    path.write_text(text)
    with pytest.raises(DataFormatError) as info:
        load_house(room)
    message = str(info.value)
    assert message.startswith(str(path))
    assert info.value.path == path
    for fragment in fragments:
        assert fragment in message, (fragment, message)


@pytest.mark.parametrize("name", ["WiFi", "images", "words", "2g", "wi-fi", ""])
def test_modality_file_with_a_bad_name(tmp_path, grid, name):
    room = save_house(make_house(grid, ()), tmp_path / "data")
    path = room / f"modality_{name}.csv"
    path.write_text("trial,x,y,a\n0,1,1,1\n")
    with pytest.raises(DataFormatError, match="modality name") as info:
        load_house(room)
    assert str(info.value).startswith(str(path)) and repr(name) in str(info.value)
