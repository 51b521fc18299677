"""A roboticist's own house files written by hand: mistakes that were read silently or refused
without saying what to do (Ft.csv rows that are not histograms summing to 1, a St.csv ending
with a comma or holding an empty utterance, a header line, one utterance a line).

The house: a 2 x 3 room of free cells at 1 m (origin (0, 0)), three images and three
utterances, written by :func:`spcopyro.data.save_house` and then edited as a user would.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from spcopyro.data import DataFormatError, House, Observations, load_house, save_house
from spcopyro.data.dataset_files import read_features
from spcopyro.maps import FREE, OccupancyGrid


def _room(root, features=((0.5, 0.5), (0.25, 0.75), (1.0, 0.0))):
    """The house folder; one trial, without its pose_0.csv / word_0.csv (optional files)."""
    grid = OccupancyGrid(
        occupancy=np.full((2, 3), FREE, dtype=np.int8), resolution=1.0, origin=(0.0, 0.0, 0.0)
    )
    obs = Observations(
        image_features=np.asarray(features, dtype=np.float64),  # [3, 2]
        image_xy=[[0.5, 0.5], [2.5, 1.5], [1.5, 0.5]],
        image_trial=[0, 0, 0],
        utterances=[("here", "is", "the", "kitchen"), ("bed",), ("kitchen",)],
        word_xy=[[0.5, 0.5], [2.5, 1.5], [1.5, 0.5]],
        word_trial=[0, 0, 0],
    )
    room = save_house(House(name="home", grid=grid, observations=obs), root)
    for name in ("pose_0.csv", "word_0.csv"):
        (room / name).unlink()
    return room


def _st_csv_refused(tmp_path, text: str, match: str) -> None:
    """The house with St.csv written as ``text`` is refused with a message matching ``match``."""
    room = _room(tmp_path)
    (room / "St.csv").write_text(text, encoding="utf-8")
    with pytest.raises(DataFormatError, match=match):
        load_house(room)


def _warnings(caplog, room):
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        house = load_house(room)
    return house, [r.getMessage() for r in caplog.records]


@pytest.mark.parametrize(
    ("features", "said"),
    [
        (  # one row scaled by mistake: it weighed 3 images
            ((0.5, 0.5), (0.75, 2.25), (1.0, 0.0)),
            "1 of 3 image feature rows do not sum to 1 (line 2: 3)",
        ),
        (  # percentages: every image weighed 100
            ((50.0, 50.0), (25.0, 75.0), (100.0, 0.0)),
            "percentages? divide every value by 100",
        ),
    ],
)
def test_ft_rows_that_do_not_sum_to_one_are_warned_of(tmp_path, caplog, features, said):
    """Ft.csv rows are histograms summing to 1, and a row summing to s weighs as much as s
    images (feature scaling 'probability' takes them as they are; the refinement's floor(100 f)
    too): percentages or a row scaled by mistake were read silently."""
    room = _room(tmp_path, features)
    house, messages = _warnings(caplog, room)
    np.testing.assert_array_equal(house.observations.image_features, features)  # kept as read
    told = [m for m in messages if "do not sum to 1" in m]
    assert len(told) == 1, messages
    assert str(room / "Ft.csv") in told[0] and said in told[0], told[0]


def test_ft_rows_that_sum_to_one_or_zero_are_not_warned_of(tmp_path, caplog):
    """Rows summing to 1 within rounding pass unsaid; an all-zero row has its own warning."""
    room = _room(tmp_path, ((0.5, 0.5000004), (0.25, 0.7), (0.0, 0.0)))
    _, messages = _warnings(caplog, room)
    assert not [m for m in messages if "do not sum to 1" in m], messages
    assert any("1 of 3 image feature rows are all zero" in m for m in messages), messages


def test_st_csv_ending_with_a_comma_says_so(tmp_path):
    """``for w in words: f.write(w + ',')``: 'utterance 4 holds no words' said nothing of the
    comma at the end of the line."""
    _st_csv_refused(
        tmp_path,
        "here is the kitchen,bed,kitchen,",
        r"St\.csv, line 1: utterance 4 holds no words "
        r"\(the line ends with a comma: .*none after the last\): ''",
    )


def test_an_empty_utterance_names_its_position_lines(tmp_path):
    """An empty entry in the middle (two commas in a row): the fix is to remove it and its
    position, line 2 of StXtx.csv and StXty.csv, or to write what was said."""
    _st_csv_refused(
        tmp_path,
        "here is the kitchen, ,kitchen",
        r"utterance 2 holds no words \(an utterance is "
        r"placed by line 2 of StXtx\.csv and StXty\.csv: ",
    )


@pytest.mark.parametrize(
    ("name", "header", "value"),
    [("Xtx.csv", "x", "x"), ("Ft.csv", "class_0,class_1", "class_0"), ("StXty.csv", "y", "y")],
)
def test_a_header_line_is_named_as_one(tmp_path, name, header, value):
    """A spreadsheet's or pandas' header line: 'not a number: 'x'' said the value, not that
    these files have no header."""
    room = _room(tmp_path)
    path = room / name
    path.write_text(f"{header}\n" + path.read_text(encoding="utf-8"), encoding="utf-8")
    with pytest.raises(DataFormatError, match=rf"{name}, line 1, column 1: not a number \(a "
                       rf"header line\? these files have none.*\): '{value}'"):  # fmt: skip
        load_house(room)


def test_a_bad_first_value_is_not_called_a_header(tmp_path):
    """A line of numbers with one that does not read is a bad value, not a header."""
    room = _room(tmp_path)
    (room / "Ft.csv").write_text("abc,0.5\n0.25,0.75\n1.0,0.0\n", encoding="utf-8")
    with pytest.raises(DataFormatError, match=r"Ft\.csv, line 1, column 1: not a number: 'abc'"):
        load_house(room)


def test_st_csv_of_one_utterance_a_line_says_to_join_them(tmp_path):
    """St.csv written in word_K.csv's layout, one utterance a line."""
    _st_csv_refused(
        tmp_path,
        "here is the kitchen\nbed\nkitchen\n",
        r"line 2: must be one line of comma-separated "
        r"utterances \(.*join the lines with commas\): 'bed'",
    )


def test_a_rotated_map_says_how_to_use_it(tmp_path):
    """An origin yaw of 0.5: 'rotated maps are not supported (yaw must be 0)' said what is not
    done, not how a user with such a map gets on: rotate the positions into the image's axes."""
    from spcopyro.maps import load_map
    from spcopyro.maps.map_yaml import MapFormatError

    room = _room(tmp_path)
    yaml = room.parent / "map" / "home.yaml"
    text = yaml.read_text(encoding="utf-8")
    origin = next(line for line in text.splitlines() if line.startswith("origin:"))
    yaml.write_text(text.replace(origin, "origin: [0.0, 0.0, 0.5]"), encoding="utf-8")
    with pytest.raises(MapFormatError, match=r"yaw 0\.5; rotated maps are not supported \(yaw "
                       r"must be 0\): rotate the observations' positions by -yaw about the "
                       r"origin's x, y into the image's axes and write yaw 0"):  # fmt: skip
        load_map(yaml)


def test_ft_zero_rows_past_the_fifth_are_counted(tmp_path, caplog):
    """The all-zero rows' warning lists five lines, then how many more (``listed``), as the
    other warnings do: it ended with a bare ", ..." that said nothing of how many."""
    path = tmp_path / "Ft.csv"
    path.write_text("0,0\n" * 7 + "0.5,0.5\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        read_features(path)
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}: 7 of 8 image feature rows are all zero (lines 1, 2, 3, 4, 5, ... (2 more)): "
        "those images carry no information"
    ]


def test_ft_row_sum_warning_says_what_it_means_plainly(tmp_path, caplog):
    """The whole warning, for someone writing their own house files: it named "floor(100 f),
    the refinement's count", the fit's internals, which told them nothing they could act on."""
    path = tmp_path / "Ft.csv"
    path.write_text("0.5,0.5\n0.75,2.25\n1,0\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        read_features(path)
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}: 1 of 3 image feature rows do not sum to 1 (line 2: 3): a row is a histogram of "
        "class probabilities, and one that sums to s weighs as much as s images against the "
        "words; scale each row to sum to 1 (f / f.sum(axis=1, keepdims=True)) unless that "
        "weight is meant"
    ]
