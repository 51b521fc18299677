"""`spcopyro simulate` warns of a drawn house of one room, as `simulate --map` warns of a map
that stays one room: its truth has one category, so ARI against it says nothing."""

from __future__ import annotations

import logging

import pytest

from spcopyro.cli.main import main


@pytest.mark.parametrize(
    ("argv", "how"),
    [(["--rooms", "1"], "--rooms 1"), (["--size", "20", "20"], "--size 20 20"), ([], None)],
)
def test_a_house_of_one_room_is_warned_of(tmp_path, caplog, argv, how):
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        assert main(["simulate", "--out", str(tmp_path), *argv]) == 0
    if how is None:  # the default house: 5 rooms
        assert "one room" not in caplog.text
    else:
        assert f"one room ({how}): the simulated truth has one category" in caplog.text


def test_rooms_of_one_category_given_are_warned_of(tmp_path, caplog):
    """simulate --map --categories kitchen: every room a kitchen, said nothing of."""
    from test_map_simulation import three_rooms

    from spcopyro.robot.map_simulation import MapTour, simulate_on_map

    _, grid = three_rooms(tmp_path)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        two = simulate_on_map(grid, seed=0, tour=MapTour(categories=("kitchen", "living")))
    assert len(set(two.room_category.tolist())) == 2 and not caplog.text
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        one = simulate_on_map(grid, seed=0, tour=MapTour(categories=("kitchen",)))
    assert set(one.room_category.tolist()) == {0}
    assert "3 rooms, all kitchen (one category given): the simulated truth has one" in caplog.text


def test_an_open_plan_too_small_for_its_size_names_the_option(tmp_path, capsys):
    """--density open-plan --size 60 60 failed with "HouseSpec.open_plan_share 0.65 cuts ...
    min_room_size (24)": fields the user never gave."""
    out = str(tmp_path / "out")
    assert main(["simulate", "--out", out, "--density", "open-plan", "--size", "60", "60"])
    error = capsys.readouterr().err
    assert "--size 60 60: too small for --density open-plan" in error
    assert "HouseSpec" not in error and "min_room_size" not in error
    assert "enlarge --size" in error
