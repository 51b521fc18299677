"""`spcopyro simulate --map`: a simulated tour on a given floor plan, written in the dataset
layout with the ground truth it used."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spcopyro.baselines.geometry import auto_door_width
from spcopyro.cli.main import main
from spcopyro.data import load_house
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, load_map, save_map
from spcopyro.robot.map_simulation import MapTour, simulate_on_map
from spcopyro.synthetic import lexicon_for


def three_rooms(tmp_path):
    """A 40 x 62 map at 0.1 m, origin (-2, 1): three rooms side by side (walls on columns 21
    and 41, 0.6 m doors), an unknown margin of 1 cell, and a free speck outside the walls."""
    occupancy = np.full((40, 62), UNKNOWN, dtype=np.int8)
    occupancy[1:39, 1:61] = OCCUPIED
    occupancy[2:38, 2:60] = FREE
    for col in (21, 41):
        occupancy[2:38, col] = OCCUPIED
        occupancy[18:24, col] = FREE
    occupancy[0, 0] = FREE  # a speck: not a room
    grid = OccupancyGrid(occupancy, 0.1, (-2.0, 1.0, 0.0))
    return save_map(grid, tmp_path / "plan" / "flat.yaml"), grid


def _check_on_free_cells(house):
    obs = house.observations
    for xy in (obs.image_xy, obs.word_xy):
        rows, cols = house.grid.world_to_cell(xy).T
        assert house.grid.in_bounds(np.stack([rows, cols], -1)).all()
        assert house.grid.free[rows, cols].all()


def test_simulate_on_a_map_written_here(tmp_path, capsys):
    yaml_path, grid = three_rooms(tmp_path)
    out = tmp_path / "data"
    argv = ["simulate", "--map", str(yaml_path), "--out", str(out), "--seed", "3",
            "--categories", "kitchen,bedroom,study,garage"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "3 rooms, 90 images, 27 utterances" in printed
    house = load_house(out / "flat")  # named after the map
    assert house.grid == grid and load_map(out / "map" / "flat.yaml") == grid
    assert house.category_names == ("kitchen", "bedroom", "study")  # 3 rooms: first 3 names
    truth = house.truth  # [H, W]
    rooms = np.load(out / "flat" / "rooms.npy")  # [H, W]
    assert truth.shape == rooms.shape == grid.shape
    assert (truth[~grid.free] == -1).all() and truth[0, 0] == -1 == rooms[0, 0]  # speck
    assert (truth[grid.free] >= 0).sum() == grid.num_free - 1
    record = json.loads((out / "flat" / "rooms.json").read_text())
    assert len(record["rooms"]) == 3 and record["free_cells_in_rooms"] == grid.num_free - 1
    for room in record["rooms"]:  # one category per room, each room one side of the flat
        cells = rooms == room["room"]
        assert cells.sum() == room["cells"]
        assert set(np.unique(truth[cells])) == {house.category_names.index(room["category"])}
    assert sorted(r["category"] for r in record["rooms"]) == ["bedroom", "kitchen", "study"]
    _check_on_free_cells(house)

    # Observations follow their room's category: images were taken in every room in every
    # trial, and the single words mostly come from the room's own lexicon (5% noise).
    obs = house.observations
    cells = grid.world_to_cell(obs.image_xy)  # [T, 2]
    image_room = rooms[cells[:, 0], cells[:, 1]]  # [T]
    assert (image_room >= 0).all() and np.bincount(image_room).tolist() == [30, 30, 30]
    word_cells = grid.world_to_cell(obs.word_xy)
    spoken_in = truth[word_cells[:, 0], word_cells[:, 1]]  # [U] category of the place
    own = [u[0] in lexicon_for(house.category_names[c]).words
           for u, c in zip(obs.utterances, spoken_in, strict=True)]  # fmt: skip
    assert np.mean(own) >= 0.8

    assert main([*argv]) == 2  # exists: needs --overwrite
    assert "pass --overwrite to replace it" in capsys.readouterr().err
    assert main([*argv, "--overwrite"]) == 0


def test_the_simulation_is_seeded():
    grid = OccupancyGrid(np.zeros((20, 30), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    a, b = (simulate_on_map(grid, seed=1) for _ in range(2))
    c = simulate_on_map(grid, seed=2, tour=MapTour(images_per_room=4, utterances_per_room=1))
    assert np.array_equal(a.house.observations.image_xy, b.house.observations.image_xy)
    assert a.house.observations.utterances == b.house.observations.utterances
    assert c.house.observations.num_images == 3 * 4 and a.room_category.size == 1


def test_simulate_on_a_public_house_map(dataset_root, tmp_path, capsys):
    map_yaml = dataset_root / "map" / "room1dk5.yaml"
    argv = ["simulate", "--map", str(map_yaml), "--out", str(tmp_path), "--door-width", "2",
            "--categories", "kitchen,bedroom,bathroom", "--name", "mine"]  # fmt: skip
    assert main(argv) == 0
    assert "3 rooms, 90 images" in capsys.readouterr().out
    house = load_house(tmp_path / "mine")
    assert house.grid == load_map(map_yaml)
    assert house.truth.shape == house.grid.shape and set(np.unique(house.truth)) == {-1, 0, 1, 2}
    _check_on_free_cells(house)


def test_bad_maps_and_options_are_clear_errors(tmp_path, capsys):
    out = str(tmp_path / "out")
    missing = tmp_path / "missing.yaml"
    assert main(["simulate", "--map", str(missing), "--out", out]) == 2
    assert f"{missing}: map yaml not found" in capsys.readouterr().err

    yaml_path, _ = three_rooms(tmp_path)
    text = yaml_path.read_text()
    yaml_path.write_text(text.replace("resolution: 0.1", "resolution: -1"))
    assert main(["simulate", "--map", str(yaml_path), "--out", out]) == 2
    assert "key 'resolution' must be a positive finite number" in capsys.readouterr().err
    yaml_path.write_text(text)

    for extra, message in (
        (["--min-room-area", "100"], "no room of at least 100 m^2"),
        (
            ["--categories", "living room,bed"],
            "categories entries must each be one lower-case word",
        ),
        (["--size", "40", "50"], "--size and --map exclude each other"),
    ):
        assert main(["simulate", "--map", str(yaml_path), "--out", out, *extra]) == 2
        assert message in capsys.readouterr().err, extra
    assert main(["simulate", "--out", out, "--categories", "kitchen"]) == 2
    assert "--categories needs --map" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()

    tiny = OccupancyGrid(np.zeros((4, 4), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="too small"):
        simulate_on_map(tiny)


def test_categories_are_read_as_where_reads_words(tmp_path, capsys):
    """--categories Kitchen,台所 was refused ([a-z0-9_]+ only), though where, navigate and
    export read words in any case and script."""
    import json

    yaml_path, _ = three_rooms(tmp_path)
    out = tmp_path / "out"
    argv = ["simulate", "--map", str(yaml_path), "--out", str(out), "--categories"]
    assert main([*argv, "Kitchen,台所,ＢＥＤＲＯＯＭ"]) == 0
    house = next(p for p in out.iterdir() if (p / "categories.json").is_file())
    assert set(json.loads((house / "categories.json").read_text())) <= {
        "kitchen",
        "台所",
        "bedroom",
    }
    words = (house / "St.csv").read_text()
    assert "台所" in words and "Kitchen" not in words


def test_a_map_saved_as_map_yaml_asks_for_a_name(tmp_path, capsys):
    """Nav2's map_saver writes map.yaml by default; its name would be the house folder ``map``,
    which holds the maps: before, a bare ``House.name='map'`` error that did not say what to do."""
    _, grid = three_rooms(tmp_path)
    yaml_path = save_map(grid, tmp_path / "nav2" / "map.yaml")
    out = tmp_path / "out"
    assert main(["simulate", "--map", str(yaml_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(yaml_path) in err and "--name NAME" in err and not out.exists()
    assert main(["simulate", "--map", str(yaml_path), "--out", str(out), "--name", "home"]) == 0
    assert load_house(out / "home").grid == grid


def test_the_door_width_is_read_from_the_map(tmp_path, capsys, caplog):
    """Issue 21: a fixed 1 m found one room on every public house (a one-category truth, on
    which ARI says nothing) and 2 m one room on room1dk6. ``auto`` takes the width at which
    the room count rises the most (here, as before, the narrowest that separates two rooms)."""
    yaml_path, grid = three_rooms(tmp_path)  # 0.6 m doors
    assert auto_door_width(grid, min_room_area=1.0) == (0.75, 3)
    wide = grid.occupancy.copy()
    for col in (21, 41):
        wide[14:26, col] = FREE  # 1.2 m openings: 0.75 and 1 m no longer cut there
    wide_grid = OccupancyGrid(wide, 0.1, grid.origin)
    assert auto_door_width(wide_grid, min_room_area=1.0) == (1.25, 3)
    simulated = simulate_on_map(wide_grid, seed=0)
    assert simulated.door_width == 1.25 and simulated.room_category.size == 3
    fixed = simulate_on_map(wide_grid, seed=0, tour=MapTour(door_width=1.0))
    assert fixed.door_width == 1.0 and fixed.room_category.size == 1

    out = tmp_path / "data"
    assert main(["simulate", "--map", str(yaml_path), "--out", str(out)]) == 0
    assert "rooms cut at doorways up to 0.75 m wide (read from the map)" in capsys.readouterr().out
    record = json.loads((out / "flat" / "rooms.json").read_text())
    assert record["door_width"] == 0.75 and record["door_width_option"] == "auto"

    open_space = OccupancyGrid(np.zeros((20, 30), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    with caplog.at_level("WARNING", logger="spcopyro"):
        one = simulate_on_map(open_space, seed=0)
    assert one.room_category.size == 1 and one.door_width == 3.0
    assert "one room at every door width up to 3 m" in caplog.text
    for bad in ("0", "wide"):
        with pytest.raises(SystemExit):
            main(["simulate", "--map", str(yaml_path), "--out", str(out), "--door-width", bad])
    with pytest.raises(ValueError, match="door width must be 'auto' or metres > 0"):
        simulate_on_map(grid, tour=MapTour(door_width=-1.0))


@pytest.mark.parametrize("door_width", [True, False, -1.0, 0, float("nan"), "wide"])
def test_a_door_width_that_is_no_length_is_refused_by_name(door_width):
    """A library caller's ``MapTour(door_width=True)`` passed this check, True being an int, and
    failed later in room_segments as "door_width must be a number", not naming the values the
    option takes ('auto' or metres); False and 0 were refused here, True was not. (A study file's
    ``door_width = true`` is refused when the study is read.)"""
    grid = OccupancyGrid(np.zeros((20, 30), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="door width must be 'auto' or metres > 0, got "):
        simulate_on_map(grid, tour=MapTour(door_width=door_width))


def office_block():
    """A 14 x 26 m office floor at 0.1 m: a 2.5 m corridor, four offices above it opening
    through 1.2 m doors, a lobby below it through a 2 m opening and a closet through 0.8 m."""
    occupancy = np.full((140, 260), OCCUPIED, dtype=np.int8)
    occupancy[60:85, 2:258] = FREE  # the corridor
    for left in (2, 66, 130, 194):
        occupancy[2:58, left : left + 62] = FREE  # an office, 0.2 m walls between
        occupancy[58:60, left + 25 : left + 37] = FREE  # its 1.2 m door
    occupancy[87:138, 2:200] = FREE  # the lobby
    occupancy[85:87, 90:110] = FREE  # its 2 m opening
    occupancy[87:138, 202:258] = FREE  # the closet
    occupancy[85:87, 226:234] = FREE  # its 0.8 m door
    return OccupancyGrid(occupancy, 0.1, (0.0, 0.0, 0.0))


def test_auto_reads_the_doors_most_of_the_map_has_not_its_narrowest(tmp_path):
    """QA: on a drawn 100 m office block whose offices open through 1.2 m doors, ``auto``
    chose 1 m and 2 rooms (one 0.8 m door separated the first two), where 1.25 m cuts 26. It
    now takes the width at which the room count rises the most."""
    grid = office_block()
    assert auto_door_width(grid, min_room_area=1.0) == (1.25, 6)  # corridor, offices, closet
    simulated = simulate_on_map(grid, seed=0)
    assert simulated.door_width == 1.25 and simulated.room_category.size == 6


def test_auto_transforms_the_distances_once_and_floods_no_width(monkeypatch):
    """``auto`` segmented the map at each of its 10 widths (a distance transform and about 20
    floods with a breadth-first growth each): 193 s on a 2000 x 2000 map. The room counts need
    one distance transform and a labelling per distinct level, no growth."""
    from scipy import ndimage

    from spcopyro.maps import rooms as geometry  # the segmentation, re-exported by (F)'s

    calls = {"distance": 0, "grow": 0}
    transform, grow = ndimage.distance_transform_edt, geometry.grow_labels

    def counted_transform(*args, **kwargs):
        calls["distance"] += 1
        return transform(*args, **kwargs)

    def counted_grow(*args, **kwargs):
        calls["grow"] += 1
        return grow(*args, **kwargs)

    monkeypatch.setattr(ndimage, "distance_transform_edt", counted_transform)
    monkeypatch.setattr(geometry, "grow_labels", counted_grow)
    assert auto_door_width(office_block(), min_room_area=1.0) == (1.25, 6)
    assert calls == {"distance": 1, "grow": 0}


@pytest.mark.parametrize("min_room_area", [1.0, 0.25, 0.05])
def test_auto_counts_the_rooms_room_segments_cuts(tmp_path, min_room_area):
    """The counts ``auto`` reads without segmenting are those of :func:`room_segments`' segments
    of ``min_room_area`` or more at each width, and the choice is the one made from them."""
    from spcopyro.baselines.geometry import AUTO_DOOR_WIDTHS, room_segments

    _, three = three_rooms(tmp_path)
    wide = three.occupancy.copy()
    wide[14:26, 21] = FREE
    for grid in (office_block(), three, OccupancyGrid(wide, 0.1, three.origin)):
        counts = []
        for width in AUTO_DOOR_WIDTHS:
            segments = room_segments(grid, door_width=width, min_room_area=min_room_area)
            sizes = np.bincount(segments[segments >= 0])
            counts.append(int((sizes * grid.resolution**2 >= min_room_area).sum()))
            alone = auto_door_width(grid, min_room_area=min_room_area, candidates=(width,))
            assert alone == (width, counts[-1])
        rises = np.diff(counts, prepend=1)
        rises[np.asarray(counts) < 2] = 0
        best = int(np.argmax(rises)) if rises.max() > 0 else -1
        chosen = (AUTO_DOOR_WIDTHS[best], counts[best])
        assert auto_door_width(grid, min_room_area=min_room_area) == chosen


def test_room_count_is_room_segments_count(tmp_path, monkeypatch):
    """:func:`room_count` (the one-room warning's count at a given width, and ``auto``'s when the
    rounding guard fails) is the number of :func:`room_segments`' segments that count as rooms:
    from the labellings without growing any room where the guard allows (0.1 m), from the
    segmentation where ``min_room_area / res^2`` lies a hair above an integer (0.45 at 0.3 m)."""
    from spcopyro.baselines.geometry import counts_as_room, room_count, room_segments
    from spcopyro.maps import rooms as geometry  # the segmentation, re-exported by (F)'s

    _, three = three_rooms(tmp_path)
    coarse = OccupancyGrid(office_block().occupancy, 0.3, (0.0, 0.0, 0.0))
    cases = [(office_block(), 1.0, True), (three, 0.25, True), (coarse, 0.45, False)]
    grow, calls = geometry.grow_labels, []
    monkeypatch.setattr(geometry, "grow_labels", lambda *a, **k: calls.append(1) or grow(*a, **k))
    for grid, area, fast in cases:
        assert geometry._counts_are_created(grid.resolution, area) is fast
        for width in (0.5, 0.75, 1.25, 2.0):
            segments = room_segments(grid, door_width=width, min_room_area=area)
            sizes = np.bincount(segments[segments >= 0])
            expected = int((sizes * grid.resolution**2 >= area).sum())
            assert int(counts_as_room(sizes, grid.resolution, area).sum()) == expected
            calls.clear()
            assert room_count(grid, width, area) == expected, (grid.resolution, area, width)
            assert bool(calls) is not fast  # the fast path grows no room
    with pytest.raises(ValueError, match="door_width must be positive"):
        room_count(three, 0.0, 1.0)


def test_auto_and_room_count_take_their_counts_from_one_helper(monkeypatch):
    """``auto_door_width`` and :func:`room_count` each spelt the counts-or-segment branch; both
    ask ``_rooms_at``, and ``auto``'s count at the width it chooses is :func:`room_count`'s there,
    with the rounding guard on (1 m2 at 0.1 m) and off (0.45 m2 at 0.3 m: a segmentation each)."""
    from spcopyro.maps import rooms as geometry  # the segmentation, re-exported by (F)'s

    coarse = OccupancyGrid(office_block().occupancy, 0.3, (0.0, 0.0, 0.0))
    widths, rooms_at, asked = [0.75, 1.25, 2.0], geometry._rooms_at, []

    def recorded(grid, widths, min_room_area, progress=None):
        asked.append((list(widths), min_room_area, progress))
        return rooms_at(grid, widths, min_room_area, progress)

    monkeypatch.setattr(geometry, "_rooms_at", recorded)
    for grid, area in ((office_block(), 1.0), (coarse, 0.45)):
        asked.clear()
        width, count = geometry.auto_door_width(grid, min_room_area=area, candidates=widths)
        singles = [geometry.room_count(grid, w, area) for w in widths]
        assert asked == [(widths, area, None)] + [([w], area, False) for w in widths]
        assert count == singles[widths.index(width)], (grid.resolution, width, singles)


def test_the_public_maps_door_widths(dataset_root):
    """What ``auto`` reads from the five public maps (docs/real_houses.md quotes it)."""
    widths = {}
    for name in ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4"):
        widths[name] = auto_door_width(load_map(dataset_root / "map" / f"{name}.yaml"),
                                       min_room_area=1.0)  # fmt: skip
    assert widths == {"room1dk5": (2.0, 3), "room1dk6": (2.25, 3), "room1ldk4": (1.5, 2),
                      "room1ldk5": (1.5, 2), "room2ldk4": (1.75, 3)}  # fmt: skip


def test_overwriting_a_simulated_map_with_a_drawn_house_removes_its_rooms(tmp_path, capsys):
    """QA: ``simulate --overwrite`` of a drawn house kept the rooms.npy / rooms.json of an
    earlier ``simulate --map`` of the same name, which then described another house."""
    yaml_path, _ = three_rooms(tmp_path)
    out = tmp_path / "data"
    assert main(["simulate", "--map", str(yaml_path), "--out", str(out), "--name", "h"]) == 0
    assert (out / "h" / "rooms.npy").is_file() and (out / "h" / "rooms.json").is_file()
    (out / "h" / "notes.txt").write_text("mine")
    assert main(["simulate", "--out", str(out), "--name", "h", "--overwrite"]) == 0
    capsys.readouterr()
    assert not (out / "h" / "rooms.npy").exists() and not (out / "h" / "rooms.json").exists()
    assert (out / "h" / "notes.txt").read_text() == "mine"  # not the house's: kept
    load_house(out / "h")


def test_options_of_map_and_of_the_drawn_house_are_checked(tmp_path, capsys):
    """QA: --door-width and --min-room-area without --map were ignored (--categories was
    refused); an empty --categories entry was dropped; --size -5 5 and --rooms 0 were reported
    as HouseSpec fields; --size 1000000 1000000 ran for minutes."""
    out = str(tmp_path / "out")
    for extra, message in (
        (["--door-width", "1"], "--door-width needs --map"),
        (["--min-room-area", "5"], "--min-room-area needs --map"),
        (["--size", "1001", "1000"], "1,001,000 cells is over the limit of 1,000,000"),
        (["--size", "5", "5"], "--size 5 5: too small: 5 x 5 leaves a -3 x -3 inside"),
    ):
        assert main(["simulate", "--out", out, *extra]) == 2, extra
        assert message in capsys.readouterr().err, extra
    for extra, message in (
        (["--size", "-5", "5"], "argument --size: must be an integer >= 1, got '-5'"),
        (["--rooms", "0"], "argument --rooms: must be an integer >= 1, got '0'"),
        (
            ["--min-room-area", "-1"],
            "argument --min-room-area: '-1': the area is square metres > 0",
        ),
    ):
        with pytest.raises(SystemExit):
            main(["simulate", "--out", out, *extra])
        assert message in capsys.readouterr().err, extra
    yaml_path, _ = three_rooms(tmp_path)
    assert main(["simulate", "--map", str(yaml_path), "--out", out,
                 "--categories", "kitchen,,bedroom"]) == 2  # fmt: skip
    assert "--categories 'kitchen,,bedroom': an empty name" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_one_room_is_warned_of_at_a_given_width_and_says_why(tmp_path, caplog):
    """QA: a --door-width that left one room gave no warning (only auto warned), and with a
    large --min-room-area auto's warning said the map was one room at every width."""
    open_space = OccupancyGrid(np.zeros((20, 30), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    with caplog.at_level("WARNING", logger="spcopyro"):
        simulate_on_map(open_space, seed=0, tour=MapTour(door_width=1.0))
    assert "one room at door width 1 m" in caplog.text and "ARI" in caplog.text
    caplog.clear()
    _, grid = three_rooms(tmp_path)  # three rooms of 7 m^2 at 0.75 m
    with caplog.at_level("WARNING", logger="spcopyro"):
        assert simulate_on_map(grid, seed=0).room_category.size == 3
        assert not caplog.text
        one = simulate_on_map(grid, seed=0, tour=MapTour(min_room_area=10.0))
    assert one.room_category.size == 1
    assert "one room at every door width" not in caplog.text
    assert "no two rooms of at least 10 m^2 (min_room_area) at any door width up to 3 m" in (
        caplog.text
    )
    assert "with the default 1 m^2 it has 3 rooms at 0.75 m" in caplog.text


def test_messages_name_what_the_user_can_change_where_they_are(tmp_path, caplog, capsys):
    """QA: a study's tour (a [data.NAME] table with map = ...) failed with "lower
    --min-room-area", an option of `simulate --map` the study has not: the library's messages
    name the MapTour field (the study's key, min_room_area), the command its options."""
    yaml_path, grid = three_rooms(tmp_path)
    with pytest.raises(ValueError, match=r"no room of at least 100 m\^2 .*; lower min_room_area$"):
        simulate_on_map(grid, tour=MapTour(min_room_area=100.0))
    out = str(tmp_path / "out")
    assert main(["simulate", "--map", str(yaml_path), "--out", out, "--min-room-area",
                 "100"]) == 2  # fmt: skip
    assert capsys.readouterr().err.rstrip().endswith("; lower --min-room-area")
    with caplog.at_level("WARNING", logger="spcopyro"):
        simulate_on_map(grid, seed=0, tour=MapTour(door_width=0.1))
        simulate_on_map(grid, seed=0, tour=MapTour(categories=("kitchen",)))
    assert "(door_width auto reads from the map" in caplog.text
    assert "give categories two or more names" in caplog.text and "--" not in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="spcopyro"):
        assert main(["simulate", "--map", str(yaml_path), "--out", out, "--categories",
                     "kitchen", "--door-width", "0.1"]) == 0  # fmt: skip
    assert "(--door-width auto reads from the map" in caplog.text


def test_a_map_read_inverted_or_with_no_free_cell_says_why(dataset_root, tmp_path, capsys):
    """simulate --map on room1dk5's map with negate 1 toured its walls, saying only that the
    free space is one room; with free_thresh -0.1, 'the map has no free cell to tour' and its
    free_thresh warning twice (fit, through check_free_cells, said it twice too)."""
    import shutil

    for suffix in (".yaml", ".pgm"):
        shutil.copy(dataset_root / "map" / f"room1dk5{suffix}", tmp_path / f"room1dk5{suffix}")
    map_yaml = tmp_path / "room1dk5.yaml"
    text = map_yaml.read_text()
    map_yaml.write_text(text.replace("negate: 0", "negate: 1"))
    argv = ["simulate", "--map", str(map_yaml), "--out", str(tmp_path / "out")]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert f"is the map read inverted? {map_yaml}:4: negate 1 on a map whose free space " in err
    assert "with negate 0, 18622 cells would be free, not 1864" in err
    map_yaml.write_text(text.replace("free_thresh: 0.196", "free_thresh: -0.1"))
    assert main([*argv, "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert f"no free cell to tour: {map_yaml}:4: negate 0; {map_yaml}:6: free_thresh -0.1" in err
    assert err.count("key 'free_thresh' -0.1 is outside [0, 1]") == 1
