"""Maps as ROS users write them (map_saver, Nav2's map_saver_cli, image editors): what load_map
warns about and refuses, naming the yaml, the line, the key and the value."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from spcopyro.cli.main import main
from spcopyro.data import dataset
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, MapFormatError, load_map
from spcopyro.maps.map_server import MAX_MAP_COORDINATE

# a walled room (row 0 = top) with unexplored space (map_saver's grey 205) around it
PIXELS = np.full((12, 16), 205, dtype=np.uint8)
PIXELS[2:10, 2:14] = 0
PIXELS[3:9, 3:13] = 254
KEYS = {
    "image": "room.pgm",
    "resolution": "0.05",
    "origin": "[-2.5, -1.25, 0.0]",
    "negate": "0",
    "occupied_thresh": "0.65",
    "free_thresh": "0.196",
}


def write_map(tmp_path: Path, pixels: np.ndarray = PIXELS, **keys: str | None) -> Path:
    """``room.yaml`` (one ``key: value`` a line, in KEYS' order, then new keys; a None drops a
    key) beside ``room.pgm`` (or the image ``keys['image']`` names, written by OpenCV)."""
    lines = {**KEYS, **keys}
    cv2.imwrite(str(tmp_path / str(lines["image"])), pixels)
    text = "".join(f"{key}: {value}\n" for key, value in lines.items() if value is not None)
    (tmp_path / "room.yaml").write_text(text)
    return tmp_path / "room.yaml"


def warnings_of(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


def test_a_map_as_map_saver_writes_it_loads_without_a_warning(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path))
    assert warnings_of(caplog) == []
    assert (grid.occupancy[PIXELS == 205] == UNKNOWN).all()


def test_unknown_grey_read_as_free_under_nav2s_free_thresh_is_warned(tmp_path, caplog):
    """Nav2's map_saver writes unexplored space as 205 and ``free_thresh: 0.25``: map_server
    (and load_map) read those cells as free, which was said nowhere."""
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path, free_thresh="0.25"))
    assert (grid.occupancy[PIXELS == 205] == FREE).all()  # as map_server reads them
    (message,) = warnings_of(caplog)
    count = int((PIXELS == 205).sum())
    assert message.startswith(f"{tmp_path / 'room.yaml'}:6: {count} cells of grey 205")
    assert "free_thresh 0.25" in message and "set free_thresh: 0.196" in message


def test_unknown_grey_read_as_free_through_an_alpha_channel_is_warned(tmp_path, caplog):
    """map_server's trinary mode averages the alpha channel in: an opaque 205 reads as 217.5."""
    rgba = np.dstack([PIXELS, PIXELS, PIXELS, np.full_like(PIXELS, 255)])
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path, rgba, image="room.png"))
    assert (grid.occupancy[PIXELS == 205] == FREE).all()
    (message,) = warnings_of(caplog)
    assert message.startswith(f"{tmp_path / 'room.yaml'}:1: ") and "alpha channel" in message


@pytest.mark.parametrize("image", ["room.pgm", "room.png"])
@pytest.mark.parametrize(
    ("grey", "free_thresh", "line"),
    [(205 * 257, "0.25", 6), (205 * 256, "0.25", 6), (205 * 256 + 255, "0.196", 1)],
)
def test_unknown_grey_read_as_free_in_a_16_bit_map_is_warned(
    tmp_path, caplog, image, grey, free_thresh, line
):
    """The warning about map_saver's unknown grey was given for 8-bit images only: a 16-bit
    pgm or png (205 scaled up by 257 or by 256: 52685 or 52480; or just lighter, 52735, which
    reads as free under map_saver's own free_thresh) read its unexplored space as free without
    a word."""
    pixels = PIXELS.astype(np.uint16) * 257  # [H, W]
    pixels[PIXELS == 205] = grey
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path, pixels, image=image, free_thresh=free_thresh))
    assert (grid.occupancy[PIXELS == 205] == FREE).all()  # as map_server reads them
    (message,) = warnings_of(caplog)
    count = int((PIXELS == 205).sum())
    assert message.startswith(
        f"{tmp_path / 'room.yaml'}:{line}: {count} cells of grey 205 read at 8 bits "
        "(52480..52735 of 65535), map_saver's unknown, read as free space"
    )
    assert ("set free_thresh: 0.196" if line == 6 else "write unexplored space as 52685") in message


def test_a_16_bit_map_as_map_saver_would_write_it_loads_without_a_warning(tmp_path, caplog):
    pixels = PIXELS.astype(np.uint16) * 257  # [H, W]
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path, pixels))
    assert warnings_of(caplog) == []
    assert (grid.occupancy[PIXELS == 205] == UNKNOWN).all()


@pytest.mark.parametrize(
    ("resolution", "hint"),
    [("1e4", "wider than 2 m"), ("5", "millimetres or centimetres"), ("5e-5", "kilometres")],
)
def test_an_absurd_resolution_is_warned_naming_its_line(tmp_path, caplog, resolution, hint):
    """A resolution of 10 km a cell (or 5: 0.05 m written in centimetres) was read without a
    word; the positions then fall in one cell or off the map."""
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_map(write_map(tmp_path, resolution=resolution))
    (message,) = warnings_of(caplog)
    assert message.startswith(f"{tmp_path / 'room.yaml'}:2: key 'resolution' ")
    assert f"cells of {float(resolution):g} m" in message and hint in message
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_map(write_map(tmp_path, resolution="2.0"))  # a fit's coarse cells may be 2 m
    assert warnings_of(caplog) == []


@pytest.mark.parametrize(
    ("keys", "line", "typo", "meant"),
    [
        ({"mdoe": "scale"}, 7, "mdoe", "mode"),
        ({"Mode": "trinary"}, 7, "Mode", "mode"),
        ({"occupied_tresh": "0.5"}, 7, "occupied_tresh", "occupied_thresh"),
    ],
)
def test_a_misspelt_key_is_warned_not_dropped_silently(tmp_path, caplog, keys, line, typo, meant):
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_map(write_map(tmp_path, **keys))
    (message,) = warnings_of(caplog)
    assert message == (
        f"{tmp_path / 'room.yaml'}:{line}: unknown key {typo!r} ignored, as map_server ignores "
        f"it: did you mean {meant!r}?"
    )


def test_other_unknown_keys_are_ignored_quietly(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_map(write_map(tmp_path, map_name="kitchen_floor", frame_id="map"))
    assert warnings_of(caplog) == []


def test_a_required_key_missing_names_its_misspelling(tmp_path):
    path = write_map(tmp_path, resolution=None, resoluton="0.05")
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    assert str(err.value) == (
        f"{path}: missing required key 'resolution', metres per cell (image pixel), e.g. 0.05 "
        f"({path}:6 has 'resoluton': misspelt?)"
    )


def test_a_mode_load_map_does_not_read_names_its_line(tmp_path):
    path = write_map(tmp_path, mode="scale")
    with pytest.raises(MapFormatError, match=rf"^{path}:7: key 'mode': 'scale' is not supported"):
        load_map(path)
    with pytest.raises(MapFormatError, match="a robot's map saved in scale mode .* is an "
                       "occupancy map: write 'mode: trinary'"):  # fmt: skip
        load_map(path)  # what a user of the commands, not of load_filter_mask, can do
    with pytest.raises(MapFormatError) as err:  # raw pixels are cell values: no such reading
        load_map(write_map(tmp_path, mode="raw"))
    assert "'raw' is not supported" in str(err.value) and "robot's map" not in str(err.value)


def test_a_map_beyond_the_datas_coordinate_limit_is_refused_at_load(tmp_path, capsys):
    """A map whose origin is in UTM coordinates loaded, and `simulate --map` wrote a house on
    it that `fit` then refused ("a unit or parsing error?") without naming the map."""
    assert MAX_MAP_COORDINATE == dataset.MAX_COORDINATE
    path = write_map(tmp_path, origin="[500000.0, 4100000.0, 0.0]")
    with pytest.raises(MapFormatError, match=rf"^{path}:3: key 'origin' \[500000.0, 4100000.0"):
        load_map(path)
    out = tmp_path / "out"
    assert main(["simulate", "--map", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}:3: key 'origin'") and "Traceback" not in err
    assert not out.exists()
    # a map reaching into the limit, or lying across the frame's origin, loads
    load_map(write_map(tmp_path, origin="[999999.5, -0.3, 0.0]"))
    load_map(write_map(tmp_path, origin="[-2.5, -1000000.3, 0.0]"))


def test_a_fit_on_its_maps_own_cells_is_exported_and_planned_on_its_own_grid(tmp_path, capsys):
    """A fit of a map whose cells are not finer than --cell-size (0.2 m cells: coarsening factor
    1) writes no robot_map.yaml; `export` and `navigate` took its data folder's map (the
    fallback for fits older than robot_map.yaml) as "the map the fit's cells were coarsened
    from", and exported that file, edited since the fit, as Nav2's main map."""
    import dataclasses

    from test_nav2 import top_and_bottom

    from spcopyro.config import DataPreparation
    from spcopyro.maps import OCCUPIED, save_map

    result = top_and_bottom()
    source = {"data": str(tmp_path / "data" / "flat"), "house": "flat"}
    fit = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.25),
                              provenance={"source": source}).save(tmp_path / "fit")  # fmt: skip
    edited = np.array(result.grid.occupancy)
    edited[2, 1:] = OCCUPIED  # the data folder's map, edited since the fit
    save_map(result.grid.with_occupancy(edited), tmp_path / "data" / "map" / "flat.yaml")

    assert main(["export", str(fit), "--nav2", str(tmp_path / "nav2"), "--word", "kitchen"]) == 0
    assert "coarsened from" not in capsys.readouterr().out
    assert load_map(tmp_path / "nav2" / "map.yaml") == result.grid
    assert main(["navigate", str(fit), "go to the kitchen", "--start=2.0,-1.5", "--radius", "0",
                 "--no-figure"]) == 0  # fmt: skip
    assert "coarsened from" not in capsys.readouterr().out


@pytest.mark.parametrize("image", ["/home/robot/maps/room.pgm", "maps/room.pgm"])
def test_an_image_path_map_saver_wrote_names_the_image_beside_the_yaml(tmp_path, image):
    """map_saver writes the path it was given (ROS 1 `-f /abs/path`, Nav2 `map_url:
    maps/room`, Nav2 issue #3078): moved, or saved into a folder, the map's image is beside its
    yaml under another path; the error said only 'not found'."""
    from spcopyro.maps import MapFileNotFoundError

    path = write_map(tmp_path)
    path.write_text(path.read_text().replace("image: room.pgm", f"image: {image}"))
    with pytest.raises(MapFileNotFoundError) as err:
        load_map(path)
    message = str(err.value)
    assert message.startswith(f"{path}:1: key 'image': image file ")
    assert message.endswith(f"{str(tmp_path / 'room.pgm')!r}, beside the yaml, has its name: "
                            "map_saver writes the path it was given (-f, map_url), which breaks "
                            "when the map moves or that path has a folder (map_server fails "
                            "too): write image: room.pgm")  # fmt: skip
    (tmp_path / "room.pgm").unlink()
    with pytest.raises(MapFileNotFoundError, match=r"not found$"):
        load_map(path)


NO_INFORMATION, LETHAL_OBSTACLE = 255, 254  # nav2_costmap_2d cost values


def _costmap_of(values: np.ndarray) -> np.ndarray:
    """[H, W] costs of an OccupancyGrid's data as nav2_costmap_2d's Costmap2D(msg) makes them:
    -1 -> NO_INFORMATION, else round(v * 254 / 100)."""
    costs = np.rint(values.astype(float) * LETHAL_OBSTACLE / 100.0)
    return np.where(values == -1, NO_INFORMATION, costs).astype(np.int64)


def test_a_keepout_mask_leaves_the_costmaps_unknown_cells_unknown(tmp_path):
    """Nav2's KeepoutFilter (keepout_filter.cpp) skips a mask cell with no information and
    otherwise writes it where ``data > old_data || old_data == NO_INFORMATION``: the mask's 0
    around the place turned every unknown cell of the map into free space."""
    from test_nav2 import top_and_bottom

    from spcopyro.maps import load_filter_mask
    from spcopyro.robot.nav2 import export_nav2

    result = top_and_bottom()  # column 0 unknown; the kitchen the top room
    export = export_nav2(result, tmp_path / "nav2", ["kitchen"])
    master = _costmap_of(load_map(export.map_yaml).occupancy)  # the static layer
    data = _costmap_of(load_filter_mask(export.masks[0].mask_yaml).values)
    write = (data != NO_INFORMATION) & ((data > master) | (master == NO_INFORMATION))
    filtered = np.where(write, data, master)  # [H, W] the costmap after the filter
    unknown = result.grid.occupancy == UNKNOWN
    assert unknown.any() and (filtered[unknown] == NO_INFORMATION).all()
    place = result.where("kitchen").region
    assert (filtered[place] == LETHAL_OBSTACLE).all()
    assert np.array_equal(filtered[~place], master[~place])  # nothing else changed


@pytest.mark.parametrize("yaw", ["-nan", "nan", ".NaN"])
def test_a_nan_yaw_says_where_it_comes_from(tmp_path, yaw):
    """ROS 1's map_saver writes `origin: [x, y, -nan]` for a map published with a zero
    quaternion (ros-planning/navigation#993): refused, as map_server does, saying what to do."""
    path = write_map(tmp_path, origin=f"[-15.400000, -30.900000, {yaw}]")
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    message = str(err.value)
    assert message.startswith(f"{path}:3: key 'origin' must be a list of 3 finite numbers")
    assert message.endswith(
        "invalid (zero) orientation quaternion, as some mapping packages "
        "do; map_server refuses it too: the map is not rotated, write 0"
    )
    with pytest.raises(MapFormatError, match=r"got \[0, 0\]$"):  # no hint without a nan yaw
        load_map(write_map(tmp_path, origin="[0, 0]"))


@pytest.mark.parametrize("yaw", ["8.881784197001252e-16", "-1e-9", "-0.0"])
def test_a_yaw_of_float_noise_reads_as_zero(tmp_path, yaw):
    """A yaw of a quaternion's float noise was refused as a rotated map ("yaw must be 0"):
    within MAX_YAW_NOISE it turns nothing by a cell, and reads as 0; a real yaw is refused."""
    grid = load_map(write_map(tmp_path, origin=f"[-15.4, -30.9, {yaw}]"))
    assert grid.origin == (-15.4, -30.9, 0.0)
    with pytest.raises(MapFormatError, match="rotated maps are not supported"):
        load_map(write_map(tmp_path, origin="[-15.4, -30.9, 1e-3]"))


def test_tabs_between_a_key_and_its_value_read_as_map_server_reads_them(tmp_path):
    """yaml-cpp (map_server) reads a tab after `key:` as a space; PyYAML refused the file
    ("found character '\\t' that cannot start any token")."""
    path = write_map(tmp_path)
    tabbed = (
        "image:\troom.pgm\nresolution:\t\t0.05\norigin:\t[-2.5,\t-1.25, 0.0]\t# lower left\n"
        "negate: 0\t\noccupied_thresh:\t0.65\nfree_thresh: \t0.196\n"
    )
    expected = load_map(path)
    path.write_text(tabbed)
    assert load_map(path) == expected
    path.write_text(tabbed.replace("negate: 0", "\tnegate: 0"))  # a tab that indents: refused
    with pytest.raises(MapFormatError, match=rf"^{path}:4: a tab indents 'negate: 0': YAML "):
        load_map(path)  # it said "invalid yaml: while scanning for the next token ..."


def test_a_coarser_copy_of_the_fits_map_is_the_fits_map():
    """navigate --map: a map of the fit's house at twice its cell size covered "25 %" of the
    fit's free cells (one fit cell in four holds a map cell's centre) and was refused as "not
    the fit's map"; shifted, it still is refused."""
    from test_navigate import house_result

    from spcopyro.maps import OccupancyGrid
    from spcopyro.maps.coarse import coarsen_grid
    from spcopyro.robot.navigation.graph import check_same_map, map_coverage

    grid = house_result().grid
    coarse = coarsen_grid(grid, 2)
    coarse = OccupancyGrid(coarse.occupancy, coarse.resolution, coarse.origin)  # a map of its own
    assert map_coverage(grid, coarse) >= 0.8
    check_same_map(grid, coarse)
    shifted = OccupancyGrid(coarse.occupancy, coarse.resolution, (grid.origin[0] + 2.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="not the fit's map"):
        check_same_map(grid, shifted)


def ros_trinary(pixels: np.ndarray, occupied_thresh: float, free_thresh: float) -> np.ndarray:
    """ROS 1's image_loader.cpp / Nav2's map_io.cpp trinary reading of 8-bit grey ``pixels``
    (``negate: 0``), thresholds unchecked: occupied first, then free, else unknown."""
    occ = (255 - pixels.astype(np.float64)) / 255.0
    return np.where(occ > occupied_thresh, OCCUPIED, np.where(occ < free_thresh, FREE, UNKNOWN))


@pytest.mark.parametrize(
    ("occupied", "free", "line", "said"),
    [
        ("1.5", "0.196", 5, "'occupied_thresh' 1.5 is outside [0, 1], where a pixel's occupancy p "
         "lies: no pixel reads occupied, as map_server reads it"),
        ("0.65", "-0.1", 6, "'free_thresh' -0.1 is outside [0, 1], where a pixel's occupancy p "
         "lies: no pixel reads free, as map_server reads it"),
        ("-0.5", "-1", 5, "'occupied_thresh' -0.5 is outside [0, 1], where a pixel's occupancy "
         "p lies: every pixel reads occupied"),
        ("65", "19.6", 5, "'occupied_thresh' 65 is outside [0, 1], where a pixel's occupancy p "
         "lies: no pixel reads occupied, as map_server reads it; a percentage? write 0.65"),
        ("2", "1.5", 6, "'free_thresh' 1.5 is outside [0, 1], where a pixel's occupancy p "
         "lies: every pixel not occupied reads free"),
        (".inf", "0.196", 5, "'occupied_thresh' inf is outside [0, 1]"),
    ],
)  # fmt: skip
def test_thresholds_outside_0_1_load_as_ros_reads_them_with_a_warning(
    tmp_path, caplog, occupied, free, line, said
):
    """ROS 1's map_server and Nav2's map_io read the thresholds as doubles and check no range on
    loading: one outside [0, 1] makes every pixel, or none, occupied or free. They were refused
    here ("a number in [0, 1]") though both ROS loaders load the map; now read as they read
    them, each warned of, naming the yaml's line (a percentage such as 65 wipes out the walls)."""
    pixels = np.array([[0, 50, 100, 205, 254, 255]], dtype=np.uint8)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path, pixels, occupied_thresh=occupied, free_thresh=free))
    want = ros_trinary(pixels, *(float(v.replace(".inf", "inf")) for v in (occupied, free)))
    np.testing.assert_array_equal(grid.occupancy, want)
    messages = warnings_of(caplog)
    assert any(m.startswith(f"{tmp_path / 'room.yaml'}:{line}: key ") for m in messages), messages
    assert any(said in m for m in messages), messages


@pytest.mark.parametrize(
    ("keys", "said"),
    [
        ({"occupied_thresh": ".nan"}, ":5: key 'occupied_thresh' must be a number"),
        ({"free_thresh": "-.NaN"}, ":6: key 'free_thresh' must be a number"),
        ({"occupied_thresh": "-0.5", "free_thresh": "0.1"}, ":6: key 'free_thresh' (0.1) must "
         "not exceed 'occupied_thresh' (-0.5): swapped?"),
    ],
)  # fmt: skip
def test_thresholds_that_make_the_map_meaningless_are_refused(tmp_path, keys, said):
    """A nan threshold (map_server compares every pixel with it as false) and swapped ones stay
    refused, naming the yaml's line and the value."""
    with pytest.raises(MapFormatError) as info:
        load_map(write_map(tmp_path, **keys))
    assert f"{tmp_path / 'room.yaml'}{said}" in str(info.value)


def test_thresholds_within_0_1_are_not_warned_of(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_map(write_map(tmp_path, occupied_thresh="1.0", free_thresh="0.0"))
    assert warnings_of(caplog) == []


@pytest.mark.parametrize(
    ("keys", "resolution", "thresholds"),
    [
        # yaml-cpp's as<double>() converts a quoted scalar's text, its .inf spellings included
        ({"occupied_thresh": "'.inf'", "free_thresh": '"-.INF"'}, 0.05, (np.inf, -np.inf)),
        # C++'s >> leaves blanks after a number (std::ws): map_server reads it
        ({"resolution": '"0.05 "', "free_thresh": "'0.196\t'"}, 0.05, (0.65, 0.196)),
        # YAML 1.1 octal to PyYAML (8), ten to C++'s >> of a double
        ({"resolution": "010"}, 10.0, (0.65, 0.196)),
    ],
)
def test_number_keys_read_as_yaml_cpps_as_double_reads_them(tmp_path, keys, resolution, thresholds):
    """A quoted '.inf' threshold was refused ("must be a number, got '.inf'"), a quoted number
    with a blank after it too, and an unquoted 010 read as 8 m cells, where map_server (yaml-cpp)
    reads inf, the number and 10."""
    grid = load_map(write_map(tmp_path, **keys))
    assert grid.resolution == resolution
    occupied, free = thresholds
    np.testing.assert_array_equal(grid.occupancy, ros_trinary(PIXELS, occupied, free))


@pytest.mark.parametrize(
    ("keys", "said"),
    [
        ({"resolution": '" 0.05"'}, ":2: key 'resolution' must be a positive finite number, got "
         "' 0.05': map_server (yaml-cpp) reads no number with blanks before it; write 0.05"),
        ({"origin": "[' -2.5', -1.25, 0]"}, ":3: key 'origin' must be a list of 3 finite numbers "
         "[x, y, yaw], got [' -2.5', -1.25, 0]: map_server (yaml-cpp) reads no number with "
         "blanks before it; write -2.5"),
        ({"occupied_thresh": "' .inf'"}, ":5: key 'occupied_thresh' must be a number"),
        ({"resolution": "'.inf'"}, ":2: key 'resolution' must be a positive finite number, "
         "got inf"),
        ({"resolution": "1_000"}, ":2: key 'resolution' must be a positive finite number, got "
         "'1_000'"),
    ],
)  # fmt: skip
def test_number_keys_yaml_cpp_reads_no_number_from_are_refused(tmp_path, keys, said):
    """yaml-cpp's as<double>() does not skip blanks before a number (std::noskipws) and reads
    no '_' between digits (PyYAML's YAML 1.1 reads 1_000 as 1000): map_server refuses these, and
    so does load_map, naming the line and the value."""
    with pytest.raises(MapFormatError) as info:
        load_map(write_map(tmp_path, **keys))
    assert f"{tmp_path / 'room.yaml'}{said}" in str(info.value)


def test_bytes_that_are_not_utf8_read_as_yaml_cpp_reads_them(tmp_path):
    """yaml-cpp (map_server) passes bytes that are not UTF-8 through: a latin-1 or Shift-JIS
    comment, an image named in the file system's own bytes; and reads UTF-16 after its BOM. The
    loader refused all three ("'utf-8' codec can't decode byte 0xe9 in position 21")."""
    path = write_map(tmp_path)
    expected = load_map(path)
    text = path.read_text()
    path.write_bytes("# carte de la maison é\n".encode("latin-1") + text.encode())
    assert load_map(path) == expected
    path.write_bytes("# 地図\n".encode("shift_jis") + text.encode())
    assert load_map(path) == expected
    path.write_text(text, encoding="utf-16")  # with its byte-order mark
    assert load_map(path) == expected
    (tmp_path / "room.pgm").rename(tmp_path / b"carte\xe9.pgm".decode(errors="surrogateescape"))
    path.write_bytes(text.encode().replace(b"room.pgm", b"carte\xe9.pgm"))
    assert load_map(path) == expected
    path.write_bytes(text.encode().replace(b"0.05", b"0.0\xe95"))  # shown as its byte
    with pytest.raises(MapFormatError, match=r"key 'resolution' .*, got '0\.0\\xe95'$"):
        load_map(path)


def test_an_image_cut_short_says_how_short(tmp_path):
    """An empty or truncated pgm (an interrupted copy) was 'not a readable image' and no more."""
    path = write_map(tmp_path)
    pgm = tmp_path / "room.pgm"
    whole = pgm.read_bytes()  # P5, 16 x 12, maxval 255
    pgm.write_bytes(whole[:-5])
    said = r"header gives 16 x 12 pixels of maxval 255 \(192 bytes after it\) but 187 bytes follow"
    with pytest.raises(MapFormatError, match=said):
        load_map(path)
    pgm.write_bytes(b"")
    with pytest.raises(MapFormatError, match=r"not a readable image: the file is empty"):
        load_map(path)
    pgm.write_bytes(b"P2\n16 12\n255\n" + b" ".join(b"254" for _ in range(100)) + b"\n")
    with pytest.raises(MapFormatError, match=r"16 x 12 pixels \(192 levels\) but 100 follow it"):
        load_map(path)


def test_a_jpeg_map_is_warned_of_its_moved_greys(tmp_path, caplog):
    """A JPEG map loads as map_server loads it, but its compression moves map_saver's greys (a
    205 turned 206 reads free): it loaded without a word (room1dk5's map as a JPEG: 771
    unexplored cells read free)."""
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        grid = load_map(write_map(tmp_path, image="room.jpg"))
    moved = cv2.imread(str(tmp_path / "room.jpg"), cv2.IMREAD_UNCHANGED)
    assert grid == load_map(write_map(tmp_path, pixels=moved, image="room.png"))  # as it reads
    (said,) = warnings_of(caplog)
    off = int(np.count_nonzero(~np.isin(moved, (0, 205, 254, 255))))
    assert said.startswith(f"{tmp_path / 'room.yaml'}:1: key 'image': ")
    assert f"is a JPEG, whose lossy compression moves greys: {off} pixels are none of " in said


@pytest.mark.parametrize("image", ["room.png", "Room.pgm", "ROOM.PGM"])
def test_an_image_not_found_names_one_beside_it_of_another_case_or_suffix(tmp_path, image):
    """'image file 'room.png' not found' and no more, where room.pgm lay beside it."""
    path = write_map(tmp_path)
    path.write_text(path.read_text().replace("image: room.pgm", f"image: {image}"))
    with pytest.raises(MapFormatError, match=r"not found; beside it: 'room\.pgm': write image: "):
        load_map(path)


def test_an_image_named_by_a_windows_path_names_the_one_beside_the_yaml(tmp_path):
    path = write_map(tmp_path)
    path.write_text(path.read_text().replace("image: room.pgm", r"image: C:\maps\room.pgm"))
    with pytest.raises(
        MapFormatError, match=r"room\.pgm', beside the yaml, has its.*: write image: room\.pgm$"
    ):
        load_map(path)


def test_an_image_not_found_shows_a_byte_that_is_not_utf8_as_its_byte(tmp_path):
    """The error naming the image path is raised by the image decoder, after the yaml reader:
    it showed the name's byte 0xe9 as its surrogate, 'carte\\udce9.pgm' not found."""
    path = write_map(tmp_path)
    path.write_bytes(path.read_bytes().replace(b"room.pgm", b"carte\xe9.pgm"))
    with pytest.raises(MapFormatError, match=r"'[^']*carte\\xe9\.pgm' not found$") as info:
        load_map(path)
    assert "udce9" not in str(info.value)


def test_a_warning_shows_a_byte_that_is_not_utf8_as_its_byte(tmp_path, caplog):
    """A warning showed a byte of the yaml that is not UTF-8 as the stand-in it was read as (a
    misspelt key 'mod\\U000f00e9'), a JPEG's name as its surrogate ('carte\\udce9.jpg'), where
    a MapFormatError shows '\\xe9'."""
    path = write_map(tmp_path, image="room.jpg")
    (tmp_path / "room.jpg").rename(tmp_path / b"carte\xe9.jpg".decode(errors="surrogateescape"))
    path.write_bytes(path.read_bytes().replace(b"room.jpg", b"carte\xe9.jpg") + b"mod\xe9: 1\n")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_map(path)
    key, jpeg = warnings_of(caplog)
    assert key == (
        f"{path}:7: unknown key 'mod\\xe9' ignored, as map_server ignores it: did you mean 'mode'?"
    )
    assert f"{path}:1: key 'image': '{tmp_path}/carte\\xe9.jpg' is a JPEG, whose" in jpeg, jpeg
    assert not any(shown in key + jpeg for shown in ("U000f00", "udce9", "\U000f00e9"))


def test_every_warning_of_the_map_logger_shows_a_byte_that_is_not_utf8_as_its_byte(caplog):
    """One filter on load_map's logger shows such bytes in any warning (its whole text, as a
    MapFormatError's): each warning's call cleaned its own arguments, and a new one had to."""
    from spcopyro.maps.map_server import logger

    with caplog.at_level(logging.WARNING, logger="spcopyro"):  # a stand-in, a surrogate's repr
        logger.warning("%s: %s, %r, %d", "room.yaml:7", "mod\U000f00e9", "carte\udce9.jpg", 3)
    assert warnings_of(caplog) == ["room.yaml:7: mod\\xe9, 'carte\\xe9.jpg', 3"]


def test_a_map_in_a_folder_named_by_a_byte_that_is_not_utf8_shows_it_as_its_byte(tmp_path, capsys):
    """A map yaml in a folder b"caf\\xe9" (os.fsdecode: 'caf\\udce9', a lone surrogate): the
    messages naming it through an f-string held the surrogate itself, which _SHOWN_STAND_IN did
    not match (only its repr, '\\udce9' as text): stderr showed caf\\udce9, a strict UTF-8
    print raised UnicodeEncodeError. A MapFormatError (load_map) and the command line's error and
    warning lines (any ValueError: simulate --map's refusal of a map with no free cell) show it
    as caf\\xe9."""
    (tmp_path / "plain").mkdir()  # OpenCV's imwrite crashes on a path holding a surrogate
    write_map(tmp_path / "plain", resolution="abc").parent.rename(folder := tmp_path / "caf\udce9")
    assert os.fsencode(folder) == os.fsencode(tmp_path) + b"/caf\xe9"
    path = folder / "room.yaml"
    with pytest.raises(MapFormatError) as info:
        load_map(path)
    shown = str(info.value)
    assert shown.startswith(f"{tmp_path}/caf\\xe9/room.yaml:2: key 'resolution' "), shown
    shown.encode("utf-8")  # no surrogate left to refuse
    height, width = PIXELS.shape  # white everywhere, negate 1: no free cell
    (folder / "room.pgm").write_bytes(
        f"P5\n{width} {height}\n255\n".encode() + b"\xfe" * PIXELS.size
    )
    path.write_text(path.read_text().replace("abc", "0.05").replace("negate: 0", "negate: 1"))
    assert main(["simulate", "--map", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"error: {tmp_path}/caf\\xe9/room.yaml: the map has no free cell to tour: " in err
    assert f"{tmp_path}/caf\\xe9/room.yaml:4: negate 1;" in err, err
    err.encode("utf-8")
    assert "udce9" not in err


def test_a_byte_that_is_not_utf8_is_shown_by_the_message_helpers_shown_bytes():
    """shown_bytes is spcopyro._util.messages' (the message helpers' home, importing nothing of
    the package), used by map_yaml (MapFormatError, its logger's filter) and the command line's
    error and warning lines, which imported map_yaml's private _shown_bytes."""
    import spcopyro.cli.main as cli_main
    import spcopyro.maps.map_yaml as map_yaml
    from spcopyro._util import messages

    assert cli_main.shown_bytes is map_yaml.shown_bytes is messages.shown_bytes
    assert not hasattr(map_yaml, "_shown_bytes")
    shown = messages.shown_bytes("caf\udce9, \\udce9, \U000f00e9, \\U000f00e9, café")
    assert shown == "caf\\xe9, \\xe9, \\xe9, \\xe9, café"


@pytest.mark.parametrize(
    ("image", "said"),
    [
        (r"C:\maps\room.png", r"beside it: 'room\.pgm': write image: room\.pgm\?$"),
        (r"maps\room.png", r"beside it: 'room\.pgm': write image: room\.pgm\?$"),
        ("maps/Room.pgm", r"beside it: 'room\.pgm': write image: maps/room\.pgm\?$"),
        ("maps/room.png", r"beside the yaml: 'room\.pgm': write image: room\.pgm\?$"),
    ],
)
def test_an_image_of_another_suffix_in_a_windows_path_or_folder_is_found(tmp_path, image, said):
    """A Windows path's last part looked for its other case or suffix beside 'C:\\maps\\room'
    (nothing); one in a folder was to be written without its folder."""
    path = write_map(tmp_path)
    (tmp_path / "maps").mkdir()
    if image == "maps/Room.pgm":
        (tmp_path / "room.pgm").rename(tmp_path / "maps" / "room.pgm")
    path.write_text(path.read_text().replace("image: room.pgm", f"image: {image}"))
    with pytest.raises(MapFormatError, match=said):
        load_map(path)


def test_a_second_read_of_a_map_yaml_warns_of_nothing(tmp_path, caplog):
    """free_space re-reads the yaml load_map has read (warn=False); it silenced the duplicate
    warnings by disabling load_map's logger process-wide, other threads' warnings with them."""
    from spcopyro.maps.map_yaml import read_map_yaml

    path = write_map(tmp_path, resolution="50", free_thresh="-0.1", negat="0")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        read_map_yaml(path, warn=False)
        assert warnings_of(caplog) == []
        read_map_yaml(path)
    said = warnings_of(caplog)
    assert len(said) == 3 and "did you mean 'negate'?" in said[0]
