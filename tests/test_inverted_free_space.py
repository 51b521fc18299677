"""A map whose free space reads as occupied (``negate: 1`` on a map drawn with free space white,
thresholds or an inverted image) is refused before a fit, not only when no observation at all
lands on free space (:meth:`spcopyro.data.PlacementReport.free_space_inverted`): with
``negate: 1`` a house's walls read free, a few observations snap onto them and the fit went
ahead on them with warnings only."""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
import pytest

from spcopyro.config import SpCoSettings
from spcopyro.data import Observations, cell_counts, load_house, save_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from spcopyro.synthetic import make_house

HOUSES = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


def _negated(tmp_path: Path, negate: str = "1") -> Path:
    """The embedded house saved under ``tmp_path``, three of its images moved onto walls (which
    the negated map reads free, as a robot's tour passes close to them), its yaml's negate set
    to ``negate``."""
    house = make_house(seed=0, name="flat")
    obs = house.observations
    walls = house.grid.cell_to_world(np.argwhere(house.grid.occupancy == OCCUPIED)[:3])  # [3, 2]
    image_xy = np.concatenate([walls, obs.image_xy[3:]])  # [T, 2]
    save_house(dataclasses.replace(house, observations=dataclasses.replace(obs, image_xy=image_xy)),
               tmp_path)  # fmt: skip
    yaml_path = tmp_path / "map" / "flat.yaml"
    text = yaml_path.read_text()
    assert "negate: 0" in text
    yaml_path.write_text(text.replace("negate: 0", f"negate: {negate}"))
    for truth in ("truth.npy", "categories.json"):  # its labels lie on cells no longer free
        (tmp_path / "flat" / truth).unlink(missing_ok=True)
    return yaml_path


def test_a_negated_map_is_refused_naming_its_yaml_and_negate_line(tmp_path, caplog):
    yaml_path = _negated(tmp_path)
    line = next(i for i, t in enumerate(yaml_path.read_text().splitlines(), 1) if "negate" in t)
    house = load_house(tmp_path / "flat")
    assert house.grid.num_free  # its walls read free: check_free_cells lets it through
    report = cell_counts(house.grid, house.observations).placement
    assert report.num_on_free == 3  # on the walls: not "no observation lands on free space"
    with caplog.at_level(logging.ERROR), pytest.raises(ValueError) as error:
        prepare_model_data(house, SpCoSettings())
    message = str(error.value)
    assert f"on occupied cells on map {yaml_path}" in message
    assert "negate inverts it" in message and "image is inverted" in message
    assert f"{yaml_path}:{line}: negate 1: with negate 0, " in message


def test_the_public_houses_and_the_embedded_one_are_not_refused(dataset_root):
    for name in HOUSES:
        house = load_house(dataset_root / name)
        report = cell_counts(house.grid, house.observations).placement
        assert not report.free_space_inverted(), name
        assert report.unplaced_on_occupied == 0, name
    house = make_house(seed=0)
    report = cell_counts(house.grid, house.observations).placement
    assert not report.free_space_inverted() and report.num_unplaced == 0


def _observations(xy: np.ndarray) -> Observations:
    """One image and one utterance at each point ``[n, 2]``."""
    n = len(xy)
    return Observations(
        image_features=np.full((n, 2), 0.5), image_xy=xy, image_trial=np.zeros(n, dtype=int),
        utterances=[("kitchen",)] * n, word_xy=xy, word_trial=np.zeros(n, dtype=int),
    )  # fmt: skip


@pytest.mark.parametrize(
    ("cols", "refused"),
    [
        ([0, 3, 3, 3], True),  # 6 of 8 left out, all on occupied cells
        ([0, 0, 3, 3], False),  # 4 of 8 left out: half, not more
        ([0, 4, 4, 4], False),  # 6 of 8 left out on unknown cells: a map of part of the tour
        ([0, 9, 9, 9], False),  # 6 of 8 off the map
        ([0, 3, 4, 4], False),  # 6 of 8 left out, 2 on occupied cells: not more than half
        ([0, 3, 3, 4], True),  # 4 of the 6 on occupied cells
    ],
)
def test_the_rule_more_than_half_left_out_mostly_on_occupied_cells(cols, refused):
    occupancy = np.array([[FREE, UNKNOWN, UNKNOWN, OCCUPIED, UNKNOWN]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 1.0, (0.0, 0.0, 0.0))
    xy = np.array([[c + 0.5, 0.5] for c in cols])  # [4, 2] cell centres
    report = cell_counts(grid, _observations(xy), snap_distance=0.0, warn=False).placement
    assert report.free_space_inverted() == refused
    if refused:
        with pytest.raises(ValueError, match="free space most likely reads as occupied"):
            report.check_on_free()
    else:
        report.check_on_free()
