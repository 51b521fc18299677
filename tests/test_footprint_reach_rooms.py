"""The reach share's Voronoi cells within rooms (DataPreparation.footprint_reach_door_width,
spcopyro.data.footprint, "Voronoi cells within rooms"): the free-cell graph cut at the room
segments of spcopyro.maps.rooms.room_segments before the Voronoi cells are drawn.

Checked: on two rooms joined by a doorway, with one observation in the first, the uncut Voronoi
cell reaches into the second room and the cut one does not, every placed row still summing to
one; a room no doorway cuts keeps its weights byte for byte; the option is refused without a
share and for bad values, naming the field and value; it is saved only where set and loads back;
the refinement replaces it; ``spcopyro fit --footprint-reach-door-width`` reaches config.json
and the summary's data line; the segmentation is done once for every modality of a fit.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from gibbs_problems import tiny_grid

from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, preset
from spcopyro.data import Observations, place_observations
from spcopyro.data.counts import prepared_cell_counts
from spcopyro.data.footprint import (
    footprint_weights,
    room_of_free_cells,
    shared_footprints,
    voronoi_weights,
)
from spcopyro.fit.refine import refined_settings, replaced_preparation

WALL = 14  # the column of the wall between the rooms (0.1 m cells)
TWO_ROOMS = [
    "." * WALL + ("." if 5 <= row <= 8 else "#") + "." * WALL for row in range(14)
]  # 1.4 x 1.4 m rooms either side of a wall, joined by a 0.4 m doorway (rows 5-8)


def two_rooms():
    """The two-room grid, its [N] bool mask of the second room's free cells, and one cell in
    the first room."""
    grid = tiny_grid(TWO_ROOMS)
    free_cells = np.asarray(grid.free_cells)  # [N, 2]
    second = free_cells[:, 1] > WALL  # [N]
    return grid, second, int(grid.free_index[6, 3])


def observed_at(grid, cells: list[tuple[int, int]], words: int) -> Observations:
    """An image at each (row, col) of ``cells`` (features one-hot), an utterance "kitchen" at
    each of the first ``words``."""
    xy = np.asarray(grid.cell_to_world(np.array(cells)), dtype=np.float64)  # [T, 2]
    return Observations(image_features=np.eye(len(cells)), image_xy=xy,
                        image_trial=np.zeros(len(cells), dtype=np.int64),
                        utterances=(("kitchen",),) * words, word_xy=xy[:words],
                        word_trial=np.zeros(words, dtype=np.int64))  # fmt: skip


def test_one_rooms_observation_reaches_the_next_room_uncut_and_not_within_rooms():
    grid, second, inside = two_rooms()
    rooms = room_of_free_cells(grid, 1.0)  # [N]
    assert rooms.min() >= 0 and np.unique(rooms).size == 2
    assert np.unique(rooms[second]).size == 1 and rooms[second][0] not in rooms[~second]
    cells = np.array([inside, -1])  # one placed observation, one unplaced
    uncut = voronoi_weights(grid, cells).toarray()  # [2, N]
    assert uncut[0, second].sum() > 0.4  # its Voronoi cell is every free cell
    cut = voronoi_weights(grid, cells, door_width=1.0).toarray()  # [2, N]
    assert not cut[0, second].any() and not cut[1].any()
    np.testing.assert_allclose(cut[0, ~second], 1.0 / (~second).sum(), rtol=1e-12)
    share = 0.25
    mixed = footprint_weights(grid, cells, 0.2, reach_share=share, reach_door_width=1.0)
    np.testing.assert_allclose(mixed.toarray()[0].sum(), 1.0, rtol=1e-12)
    assert not mixed.toarray()[0, second].any()  # the 0.2 m footprint stays in the room too
    disc = footprint_weights(grid, cells, 0.2).toarray()
    np.testing.assert_allclose(mixed.toarray() - (1 - share) * disc, share * cut, atol=1e-15)


def test_two_rooms_each_with_an_observation_split_at_the_door():
    """With a spot in each room, the uncut cells split the rooms where the spots are equally
    far (the first room's spot near the doorway takes part of the second room); within rooms
    each spot's cell is its own room."""
    grid, second, _ = two_rooms()
    near_door = int(grid.free_index[6, 12])  # 0.2 m from the doorway
    far = int(grid.free_index[6, 27])  # the second room's far side
    cells = np.array([near_door, far])
    uncut = voronoi_weights(grid, cells).toarray()
    assert uncut[0, second].any()  # through the doorway into the second room
    cut = voronoi_weights(grid, cells, door_width=1.0).toarray()
    np.testing.assert_allclose(cut[0], np.where(~second, 1.0 / (~second).sum(), 0.0), rtol=1e-12)
    np.testing.assert_allclose(cut[1], np.where(second, 1.0 / second.sum(), 0.0), rtol=1e-12)


def test_an_open_room_is_unchanged_by_the_cut():
    grid = tiny_grid(["." * 20] * 14)  # one walled space: one segment
    assert np.unique(room_of_free_cells(grid, 1.0)).size == 1
    cells = np.array([int(grid.free_index[3, 3]), int(grid.free_index[10, 15]), -1])
    plain = footprint_weights(grid, cells, 0.2, reach_share=0.25)
    within = footprint_weights(grid, cells, 0.2, reach_share=0.25, reach_door_width=1.0)
    for a, b in ((plain.indptr, within.indptr), (plain.indices, within.indices),
                 (plain.data, within.data)):  # fmt: skip
        assert a.tobytes() == b.tobytes()


def test_counts_within_rooms_reach_only_the_observed_room():
    grid, second, inside = two_rooms()
    obs = observed_at(grid, [(6, 3)], words=1)
    assert place_observations(grid, obs.image_xy, 0.0)[0][0] == inside
    prep = DataPreparation(footprint_radius=0.2, footprint_reach_share=0.25)
    uncut = prepared_cell_counts(grid, obs, prep, warn=False)
    cut = prepared_cell_counts(grid, obs, prep.replace(footprint_reach_door_width=1.0),
                               warn=False)  # fmt: skip
    assert second[uncut.cells].any() and not second[cut.cells].any()
    np.testing.assert_allclose(cut.image_counts.sum(), 1.0, rtol=1e-12)
    np.testing.assert_allclose(cut.word_counts.sum(), 1.0, rtol=1e-12)


def test_the_rooms_are_segmented_once_for_every_modality_of_a_fit(monkeypatch):
    import spcopyro.maps.rooms as rooms

    grid, _, _ = two_rooms()
    obs = observed_at(grid, [(6, 3), (6, 20)], words=1)
    calls, segment = [], rooms.room_segments
    monkeypatch.setattr(rooms, "room_segments", lambda *a, **k: calls.append(1) or segment(*a, **k))
    prep = DataPreparation(footprint_reach_share=0.25, footprint_reach_door_width=1.0)
    with shared_footprints():
        prepared_cell_counts(grid, obs, prep, warn=False)
    assert len(calls) == 1  # images and words, one segmentation


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "1"])
def test_a_bad_door_width_is_refused_naming_the_field_and_value(bad):
    with pytest.raises(ValueError) as caught:
        DataPreparation(footprint_reach_share=0.25, footprint_reach_door_width=bad)
    assert f"DataPreparation.footprint_reach_door_width={bad!r}: must be None (no cut)" in str(
        caught.value
    )
    grid = tiny_grid(["..."])
    with pytest.raises(ValueError, match=r"footprint_reach_door_width=.*must be None \(no cut\)"):
        footprint_weights(grid, np.array([0]), 0.0, reach_share=0.5, reach_door_width=bad)


def test_a_door_width_without_a_share_is_refused(tmp_path, capsys):
    with pytest.raises(ValueError, match=r"footprint_reach_door_width=1\.0: cuts the Voronoi"):
        DataPreparation(footprint_reach_door_width=1.0)
    # the default preset's share is 0.2 since 2026-12-06: the share of 0 given explicitly
    code = main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint-reach-door-width",
                 "1", "--footprint-reach-share", "0", "--out", str(tmp_path / "fit")])  # fmt: skip
    assert code != 0
    assert "footprint_reach_share, which is 0" in capsys.readouterr().err
    assert not (tmp_path / "fit" / "config.json").exists()


def test_the_door_width_is_saved_only_where_set_and_loads_back():
    prep = DataPreparation(footprint_reach_share=0.25)
    assert "footprint_reach_door_width" not in prep.to_json()
    within = prep.replace(footprint_reach_door_width=1.0)
    saved = json.loads(json.dumps(within.to_json()))
    assert saved["footprint_reach_door_width"] == 1.0
    assert DataPreparation(**saved) == within
    assert DataPreparation(**json.loads(json.dumps(prep.to_json()))) == prep


def test_the_refinement_replaces_the_door_width():
    settings = preset("coarse", footprint_reach_share=0.25, footprint_reach_door_width=1.0)
    refined = refined_settings(settings, 100, 2500)
    assert refined.data.footprint_reach_door_width is None
    assert replaced_preparation(settings, refined.data)["footprint_reach_door_width"] == {
        "given": 1.0, "refinement": None}  # fmt: skip


def test_the_summary_says_the_cut():
    from spcopyro.cli.fit_summary import data_line, reach_cut_text

    assert reach_cut_text(None, 1.0) == "Voronoi cells within rooms at 1 m doors"
    assert reach_cut_text(2.0, 1.0) == "Voronoi cells within 2 m, within rooms at 1 m doors"
    data = DataPreparation(footprint_reach_share=0.25, footprint_reach_door_width=1.0)
    assert "reach share 0.25 (Voronoi cells within rooms at 1 m doors)" in data_line(data)


def test_fit_door_width_option_reaches_config_json(tmp_path):
    from spcopyro.results.result import SpCoResult

    out = tmp_path / "fit"
    code = main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint-reach-share", "0.25",
                 "--footprint-reach-door-width", "1", "--no-figures",
                 "--out", str(out)])  # fmt: skip
    assert code == 0
    settings = json.loads((out / "config.json").read_text())
    assert settings["data"]["footprint_reach_door_width"] == 1.0
    assert settings["data"]["footprint_reach_share"] == 0.25
    assert SpCoResult.load(out).preparation.footprint_reach_door_width == 1.0
