"""Tests of spcopyro.maps: map_server loading, grid geometry, neighbourhoods and map output."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from spcopyro.maps import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    MapFileNotFoundError,
    MapFormatError,
    OccupancyGrid,
    label_colours,
    load_filter_mask,
    load_label_map_server,
    load_map,
    render_labels,
    save_label_map_server,
    save_label_png,
    save_map,
)

PAPER_FREE_PIXELS = {
    "room1dk5": 18622,
    "room1dk6": 26254,
    "room1ldk4": 18026,
    "room1ldk5": 22139,
    "room2ldk4": 27746,
}

# An asymmetric map, written top row first as in the pgm: a wall only in the top-left corner,
# an L-shaped free area (left column band + bottom band), unknown elsewhere.
ART = (
    "##??????",
    "#..?????",
    "...?????",
    "...?????",
    "........",
    "........",
)
ART_PIXEL = {"#": 0, ".": 254, "?": 205}
ART_CODE = {"#": OCCUPIED, ".": FREE, "?": UNKNOWN}
ART_RES = 0.5
ART_ORIGIN = (-1.0, 2.0, 0.0)  # map spans x in [-1, 3), y in [2, 5)


def write_pgm(path: Path, pixels: np.ndarray, maxval: int = 255) -> Path:
    """A binary P5 pgm written byte by byte (independent of OpenCV's writer)."""
    height, width = pixels.shape
    dtype = ">u2" if maxval > 255 else np.uint8
    header = f"P5\n{width} {height}\n{maxval}\n".encode()
    path.write_bytes(header + np.ascontiguousarray(pixels, dtype=dtype).tobytes())
    return path


def write_yaml(path: Path, **overrides: object) -> Path:
    """A map_server yaml with the standard keys; overrides replace keys, None removes them."""
    doc: dict[str, object] = {
        "image": "map.pgm",
        "resolution": 0.5,
        "origin": [-1.0, 2.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    for key, value in overrides.items():
        if value is None:
            doc.pop(key, None)
        else:
            doc[key] = value
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return path


@pytest.fixture
def art_yaml(tmp_path: Path) -> Path:
    pixels = np.array([[ART_PIXEL[c] for c in row] for row in ART], dtype=np.uint8)
    write_pgm(tmp_path / "map.pgm", pixels)
    return write_yaml(tmp_path / "art.yaml")


@pytest.fixture
def art(art_yaml: Path) -> OccupancyGrid:
    return load_map(art_yaml)


def random_grid(rng: np.random.Generator, shape: tuple[int, int]) -> OccupancyGrid:
    codes = rng.choice([FREE, FREE, FREE, OCCUPIED, UNKNOWN], size=shape).astype(np.int8)
    return OccupancyGrid(codes, 0.05, (-10.0, -10.0, 0.0))


# ---------------------------------------------------------------------- orientation
def test_asymmetric_map_loads_in_image_row_order(art: OccupancyGrid, art_yaml: Path) -> None:
    expected = np.array([[ART_CODE[c] for c in row] for row in ART], dtype=np.int8)
    assert art.occupancy.dtype == np.int8
    np.testing.assert_array_equal(art.occupancy, expected)
    assert art.shape == (6, 8) and art.height == 6 and art.width == 8
    assert art.resolution == 0.5 and art.origin == ART_ORIGIN
    assert art.source == art_yaml
    assert art.num_free == 2 + 3 + 3 + 8 + 8


@pytest.mark.parametrize(
    ("xy", "cell", "code"),
    [
        ((-0.9, 4.9), (0, 0), OCCUPIED),  # world top-left: the wall
        ((2.9, 4.9), (0, 7), UNKNOWN),  # world top-right
        ((-0.9, 2.1), (5, 0), FREE),  # world bottom-left
        ((2.9, 2.1), (5, 7), FREE),  # world bottom-right
        ((0.1, 4.4), (1, 2), FREE),  # col floor(1.1/0.5)=2, grid_j floor(2.4/0.5)=4 -> row 1
        ((-0.4, 4.6), (0, 1), OCCUPIED),  # col 1, grid_j 5 -> row 0
        ((1.6, 3.4), (3, 5), UNKNOWN),  # col 5, grid_j 2 -> row 3
    ],
)
def test_world_points_land_in_expected_cells(
    art: OccupancyGrid, xy: tuple[float, float], cell: tuple[int, int], code: int
) -> None:
    got = art.world_to_cell(np.array(xy))
    assert got.dtype == np.int64
    assert tuple(got.tolist()) == cell
    assert art.occupancy[cell] == code
    assert bool(art.is_free(got)) == (code == FREE)


def test_world_to_cell_is_vectorised_and_does_not_clip(art: OccupancyGrid) -> None:
    xy = np.array([[[-1.1, 2.1], [0.0, 5.0]], [[3.0, 2.0], [-1.0, 1.99]]])  # [2, 2, 2]
    cells = art.world_to_cell(xy)
    np.testing.assert_array_equal(cells, [[[5, -1], [-1, 2]], [[5, 8], [6, 0]]])
    np.testing.assert_array_equal(art.in_bounds(cells), [[False, False], [False, False]])
    np.testing.assert_array_equal(art.is_free(cells), [[False, False], [False, False]])
    assert art.world_to_cell(np.zeros((0, 2))).shape == (0, 2)


def test_cell_to_world_gives_cell_centres(art: OccupancyGrid) -> None:
    cells = np.array([[0, 0], [5, 7], [5, 0], [-1, 8]])
    np.testing.assert_allclose(
        art.cell_to_world(cells),
        [[-0.75, 4.75], [2.75, 2.25], [-0.75, 2.25], [3.25, 5.25]],
        rtol=0,
        atol=1e-12,
    )


def test_world_to_cell_rejects_non_finite_and_bad_shapes(art: OccupancyGrid) -> None:
    with pytest.raises(ValueError, match="finite"):
        art.world_to_cell([[0.0, 3.0], [np.nan, 3.0]])
    with pytest.raises(ValueError, match="finite"):
        art.world_to_cell([np.inf, 3.0])
    with pytest.raises(ValueError, match=r"\[\.\.\., 2\]"):
        art.world_to_cell([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="integer"):
        art.cell_to_world([0.5, 1.0])


def test_cells_on_map_keeps_the_in_bounds_cells_of_the_map_a_grid_was_coarsened_from(
    art: OccupancyGrid,
) -> None:
    """cells_on_map (count_on_occupied's and negate_hint's one conversion): the cells on the
    fine map, in the points' order, of the points inside it; points not finite, too far to
    convert, or off the map dropped rather than refused."""
    from spcopyro.maps.coarse import coarsen_grid
    from spcopyro.maps.grid import cells_on_map

    xy = [[-0.9, 4.9], [np.nan, 3.0], [1e300, 0.0], [3.0, 2.0], [2.9, 2.1], [-0.4, 4.6]]
    on_art = [[0, 0], [5, 7], [0, 1]]  # [3, 2]: nan, far and (5, 8) off the map dropped
    np.testing.assert_array_equal(cells_on_map(art, xy), on_art)
    coarse = coarsen_grid(art, 2)  # [3, 4]: (2.9, 2.1) is its (2, 3)
    got = cells_on_map(coarse, np.array(xy))
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, on_art)
    assert cells_on_map(art, np.zeros((0, 2))).shape == (0, 2)


def test_round_trips(rng: np.random.Generator) -> None:
    grid = OccupancyGrid(np.zeros((50, 70), np.int8), 0.05, (-10.0, -7.5, 0.0))
    cells = np.stack([rng.integers(-20, 70, 5000), rng.integers(-20, 90, 5000)], axis=1)
    np.testing.assert_array_equal(grid.world_to_cell(grid.cell_to_world(cells)), cells)

    xy = rng.uniform([-12.0, -9.0], [-5.0, -4.0], size=(5000, 2))
    centres = grid.cell_to_world(grid.world_to_cell(xy))
    assert np.abs(centres - xy).max() <= 0.025 + 1e-9
    np.testing.assert_array_equal(grid.world_to_cell(centres), grid.world_to_cell(xy))


# ---------------------------------------------------------------------- trinary interpretation
def test_trinary_thresholds_are_strict(tmp_path: Path) -> None:
    occ_t, free_t = (255 - 89) / 255, (255 - 204) / 255  # hit p exactly for pixels 89 and 204
    values = np.array([[0, 88, 89, 90, 203, 204, 205, 254, 255]], dtype=np.uint8)
    write_pgm(tmp_path / "map.pgm", values)
    path = write_yaml(tmp_path / "t.yaml", occupied_thresh=occ_t, free_thresh=free_t)
    grid = load_map(path)
    o, f, u = OCCUPIED, FREE, UNKNOWN
    np.testing.assert_array_equal(grid.occupancy, [[o, o, u, u, u, u, f, f, f]])


def test_trinary_negate(tmp_path: Path) -> None:
    occ_t, free_t = 166 / 255, 51 / 255
    values = np.array([[0, 50, 51, 52, 165, 166, 167, 255]], dtype=np.uint8)
    write_pgm(tmp_path / "map.pgm", values)
    path = write_yaml(tmp_path / "t.yaml", negate=1, occupied_thresh=occ_t, free_thresh=free_t)
    o, f, u = OCCUPIED, FREE, UNKNOWN
    np.testing.assert_array_equal(load_map(path).occupancy, [[f, f, u, u, u, u, o, o]])


def test_colour_images_are_averaged_over_channels(tmp_path: Path) -> None:
    # BGR (0, 255, 255): mean 170 -> p = 1/3 -> UNKNOWN (a luminance conversion would say FREE).
    # BGR (30, 30, 30): p = 225/255 -> OCCUPIED; BGR (254, 250, 255): mean 253 -> FREE.
    bgr = np.array([[[0, 255, 255], [30, 30, 30], [254, 250, 255]]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "c.png"), bgr)
    grid = load_map(write_yaml(tmp_path / "c.yaml", image="c.png"))
    np.testing.assert_array_equal(grid.occupancy, [[UNKNOWN, OCCUPIED, FREE]])
    # map_server's trinary mode averages alpha in too: (254, 254, 254, 0) -> mean 190.5 -> unknown
    bgra = np.array([[[254, 254, 254, 255], [254, 254, 254, 0]]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    grid = load_map(write_yaml(tmp_path / "a.yaml", image="a.png"))
    np.testing.assert_array_equal(grid.occupancy, [[FREE, UNKNOWN]])


def test_absolute_image_path(tmp_path: Path) -> None:
    image = write_pgm(tmp_path / "abs.pgm", np.array([[254, 0]], dtype=np.uint8))
    (tmp_path / "sub").mkdir()
    grid = load_map(write_yaml(tmp_path / "sub" / "m.yaml", image=str(image)))
    np.testing.assert_array_equal(grid.occupancy, [[FREE, OCCUPIED]])


# ---------------------------------------------------------------------- free cells and neighbours
def test_free_index_and_free_cells(art: OccupancyGrid) -> None:
    expected = np.full((6, 8), -1)
    expected[1, 1:3] = [0, 1]
    expected[2, 0:3] = [2, 3, 4]
    expected[3, 0:3] = [5, 6, 7]
    expected[4] = np.arange(8, 16)
    expected[5] = np.arange(16, 24)
    assert art.free_index.dtype == np.int64
    np.testing.assert_array_equal(art.free_index, expected)
    np.testing.assert_array_equal(art.free_cells, np.argwhere(expected >= 0))
    np.testing.assert_array_equal(art.free, expected >= 0)


def test_two_by_two_neighbours_by_hand() -> None:
    grid = OccupancyGrid(np.zeros((2, 2), np.int8), 1.0, (0.0, 0.0, 0.0))
    np.testing.assert_array_equal(
        grid.neighbour_table(4), [[-1, 2, -1, 1], [-1, 3, 0, -1], [0, -1, -1, 3], [1, -1, 2, -1]]
    )
    np.testing.assert_array_equal(
        grid.neighbour_table(8)[:, 4:],
        [[-1, -1, -1, 3], [-1, -1, 2, -1], [-1, 1, -1, -1], [0] + [-1] * 3],
    )
    np.testing.assert_array_equal(grid.neighbour_pairs(4), [[0, 1], [0, 2], [1, 3], [2, 3]])
    np.testing.assert_array_equal(
        grid.neighbour_pairs(8), [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    )
    assert [c.tolist() for c in grid.colour_classes(4)] == [[0, 3], [1, 2]]
    assert [c.tolist() for c in grid.colour_classes(8)] == [[0], [1], [2], [3]]


OFFSETS_8 = [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]


@pytest.mark.parametrize("connectivity", [4, 8])
def test_neighbours_match_brute_force(rng: np.random.Generator, connectivity: int) -> None:
    grid = random_grid(rng, (7, 9))
    codes = grid.occupancy.tolist()
    index: dict[tuple[int, int], int] = {}
    for r in range(7):
        for c in range(9):
            if codes[r][c] == FREE:
                index[(r, c)] = len(index)
    table, pairs = [], set()
    for (r, c), i in index.items():
        row = []
        for dr, dc in OFFSETS_8[:connectivity]:
            j = index.get((r + dr, c + dc), -1)
            row.append(j)
            if j >= 0:
                pairs.add((min(i, j), max(i, j)))
        table.append(row)

    assert grid.num_free == len(index)
    np.testing.assert_array_equal(grid.neighbour_table(connectivity), table)
    got_pairs = grid.neighbour_pairs(connectivity)
    assert got_pairs.dtype == np.int64 and got_pairs.shape == (len(pairs), 2)
    np.testing.assert_array_equal(got_pairs, sorted(pairs))

    classes = grid.colour_classes(connectivity)
    assert len(classes) == (2 if connectivity == 4 else 4)
    everything = np.concatenate(classes)
    np.testing.assert_array_equal(np.sort(everything), np.arange(grid.num_free))
    for members in classes:
        assert members.dtype == np.int64
        assert np.all(np.diff(members) > 0)
        inside = set(members.tolist())
        assert not any(a in inside and b in inside for a, b in pairs)


def test_colour_classes_on_full_grid_have_no_internal_edges() -> None:
    grid = OccupancyGrid(np.zeros((5, 6), np.int8), 1.0, (0.0, 0.0, 0.0))
    for connectivity in (4, 8):
        colour = np.full(grid.num_free, -1)
        for k, members in enumerate(grid.colour_classes(connectivity)):
            colour[members] = k
        pairs = grid.neighbour_pairs(connectivity)
        assert np.all(colour[pairs[:, 0]] != colour[pairs[:, 1]])
    with pytest.raises(ValueError, match="connectivity"):
        grid.neighbour_table(6)


# ---------------------------------------------------------------------- grid validation
def test_grid_validation_and_immutability() -> None:
    with pytest.raises(ValueError, match="cell \\(row 1, col 0\\) is 5"):
        OccupancyGrid(np.array([[0, 100], [5, -1]]), 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="integer"):
        OccupancyGrid(np.zeros((2, 2)), 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="2-D"):
        OccupancyGrid(np.zeros(3, np.int8), 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="resolution"):
        OccupancyGrid(np.zeros((2, 2), np.int8), 0.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="rotated"):
        OccupancyGrid(np.zeros((2, 2), np.int8), 1.0, (0.0, 0.0, 0.5))
    source = np.zeros((2, 2), np.int64)
    grid = OccupancyGrid(source, 1.0, (0, 0, 0))
    source[0, 0] = OCCUPIED  # the grid holds its own copy
    assert grid.occupancy[0, 0] == FREE and grid.occupancy.dtype == np.int8
    with pytest.raises(ValueError):
        grid.occupancy[0, 0] = OCCUPIED
    with pytest.raises(ValueError):
        grid.free_index[0, 0] = 7
    walled = grid.with_occupancy(np.array([[100, 0], [0, -1]]))
    assert walled.num_free == 2 and walled.resolution == 1.0 and grid.num_free == 4
    assert walled != grid and walled == OccupancyGrid(walled.occupancy, 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="shape"):
        grid.with_occupancy(np.zeros((3, 2), np.int8))


# ---------------------------------------------------------------------- bad input
def bad_case(tmp_path: Path, **overrides: object) -> Path:
    write_pgm(tmp_path / "map.pgm", np.array([[254, 0]], dtype=np.uint8))
    return write_yaml(tmp_path / "bad.yaml", **overrides)


@pytest.mark.parametrize(
    ("overrides", "fragments"),
    [
        ({"resolution": None}, ["missing required key 'resolution', metres per cell"]),
        ({"image": None}, ["key 'image', the map image's path (pgm, png, ...), relative to"]),
        ({"origin": None}, ["missing required key 'origin', the world pose [x, y, yaw] of"]),
        ({"negate": None}, ["missing required key 'negate', 0 where white is free"]),
        ({"occupied_thresh": None}, ["key 'occupied_thresh', the occupancy p above which"]),
        ({"free_thresh": None}, ["key 'free_thresh', the occupancy p below which"]),
        ({"resolution": "abc"}, ["bad.yaml:2:", "'resolution'", "'abc'"]),
        ({"resolution": -0.05}, ["bad.yaml:2:", "'resolution'", "-0.05"]),
        ({"origin": [1.0, 2.0]}, ["bad.yaml:3:", "'origin'", "[1.0, 2.0]"]),
        ({"origin": [1.0, 2.0, "a"]}, ["'origin'", "'a'"]),
        ({"origin": [1.0, 2.0, 0.3]}, ["'origin'", "0.3", "rotated maps are not supported"]),
        ({"negate": 1.0}, ["bad.yaml:4:", "'negate'", "got 1.0"]),
        ({"occupied_thresh": "nan"}, ["bad.yaml:5:", "'occupied_thresh'", "nan"]),
        ({"free_thresh": "abc"}, ["'free_thresh'", "'abc'"]),
        ({"free_thresh": 0.7}, ["'free_thresh'", "0.7", "0.65"]),
        ({"mode": "scale"}, ["'mode'", "'scale'", "not supported"]),
        ({"mode": "raw"}, ["'mode'", "'raw'", "load_filter_mask", "load_label_map_server"]),
        ({"mode": "fancy"}, ["'mode'", "'fancy'"]),
        ({"mode": "Trinary"}, ["bad.yaml:7:", "got 'Trinary'", "; did you mean 'trinary'?"]),
        (
            {"mode": "SCALE"},
            [
                "bad.yaml:7: key 'mode': 'SCALE' (taken for 'scale'; map_server "
                "refuses it as written) is not supported by load_map",
                "is an occupancy map: write 'mode: trinary' in its yaml",
            ],
        ),
        ({"mode": "Raw"}, ["'Raw' (taken for 'raw'", "load_filter_mask", "load_label_map_server"]),
        ({"image": "."}, ["bad.yaml:1:", "key 'image': ", "is a folder, not an image file"]),
        ({"image": 3}, ["'image'", "got 3"]),
    ],
)
def test_bad_yaml_values(tmp_path: Path, overrides: dict, fragments: list[str]) -> None:
    path = bad_case(tmp_path, **overrides)
    with pytest.raises(MapFormatError) as info:
        load_map(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message


@pytest.mark.parametrize(
    ("mode", "load", "fragment"),
    [
        ("SCALE", load_map, "is not supported by load_map"),
        ("scal", load_map, "'scal' (taken for 'scale'; map_server refuses it as written)"),
        (
            "Trinary",
            load_label_map_server,
            "a semantic map needs 'mode: raw' and 'negate: 0', "
            "got mode 'Trinary' (taken for 'trinary'",
        ),
        ("Trinary", load_map, "; did you mean 'trinary'?"),
        ("RAW", load_label_map_server, "; did you mean 'raw'?"),
        ("SCALE", load_filter_mask, "; did you mean 'scale'?"),
    ],
)
def test_a_mode_in_the_wrong_case_gets_the_loaders_own_note_at_once(
    tmp_path: Path, mode: str, load, fragment: str
) -> None:
    """``mode: SCALE`` given to load_map: its note on 'scale' (read as trinary), not a
    did-you-mean 'scale' that it would refuse next; a did-you-mean only where the loader takes
    the mode it suggests."""
    path = bad_case(tmp_path, mode=mode)
    with pytest.raises(MapFormatError) as info:
        load(path)
    message = str(info.value)
    assert str(path) in message and fragment in message
    assert ("did you mean" in message) == ("did you mean" in fragment)


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("- a\n- b\n", "must be a mapping"),
        ("just a string\n", "must be a mapping"),
        ("", "must be a mapping"),
        ("image: [unclosed\n", "invalid yaml"),
        ("image: a.pgm\nimage: b.pgm\n", "bad.yaml:2: duplicate key 'image'"),
        ("---\nimage: a\n---\nimage: b\n", "invalid yaml"),
    ],
)
def test_bad_yaml_documents(tmp_path: Path, text: str, fragment: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(MapFormatError) as info:
        load_map(path)
    assert str(path) in str(info.value) and fragment in str(info.value)


def test_missing_files(tmp_path: Path) -> None:
    missing = tmp_path / "nope.yaml"
    with pytest.raises(MapFileNotFoundError, match="nope.yaml"):
        load_map(missing)
    with pytest.raises(FileNotFoundError):  # also catchable as the builtin
        load_map(missing)
    path = write_yaml(tmp_path / "m.yaml", image="gone.pgm")
    with pytest.raises(MapFileNotFoundError) as info:
        load_map(path)
    assert all(s in str(info.value) for s in (str(path), "'image'", "gone.pgm", "not found"))


def test_the_maps_image_given_for_its_yaml_says_so(tmp_path: Path) -> None:
    """load_map(X.pgm) said "cannot read map yaml: 'utf-8' codec can't decode byte ..."."""
    image = tmp_path / "map.pgm"
    image.write_bytes(b"P5\n2 2\n255\n\xff\xfe\x00\x01")
    with pytest.raises(MapFormatError, match=r"map\.pgm: the map's image; give its yaml"):
        load_map(image)


@pytest.mark.parametrize("content", [b"", b"this is not an image\n", b"P5\n2 2\n255\n"])
def test_unreadable_image(tmp_path: Path, content: bytes) -> None:
    (tmp_path / "map.pgm").write_bytes(content)
    path = write_yaml(tmp_path / "m.yaml")
    with pytest.raises(MapFormatError) as info:
        load_map(path)
    assert all(s in str(info.value) for s in (str(path), "'image'", "map.pgm", "not a readable"))


def test_sixteen_bit_images_are_scaled_by_their_full_scale_as_map_server_does(
    tmp_path: Path,
) -> None:
    """A 16-bit pgm or png was refused; map_server reads it over its full scale (65535)."""
    write_pgm(tmp_path / "map.pgm", np.array([[65000, 0, 52000]], dtype=np.uint16), maxval=65535)
    path = write_yaml(tmp_path / "m.yaml")
    np.testing.assert_array_equal(load_map(path).occupancy, [[FREE, OCCUPIED, UNKNOWN]])
    cv2.imwrite(str(tmp_path / "deep.png"), np.array([[65000, 0, 52000]], dtype=np.uint16))
    deep = write_yaml(tmp_path / "deep.yaml", image="deep.png")
    np.testing.assert_array_equal(load_map(deep).occupancy, [[FREE, OCCUPIED, UNKNOWN]])
    with pytest.raises(MapFormatError, match="uint16.*only 8-bit images are supported here"):
        load_filter_mask(deep)  # a mask's values are 8-bit codes


@pytest.mark.parametrize("header", [b"P5\n3 1\n100\n", b"P5 # by hand\n3 1 # size\n100\n"])
def test_a_pgms_maxval_scales_its_pixels_as_map_server_does(tmp_path: Path, header: bytes) -> None:
    """map_server scales a pgm's pixels by its maxval (100 is white under maxval 100); OpenCV
    does not, so the white pixel read as 100/255 (unknown) and 80 (free) as occupied."""
    (tmp_path / "map.pgm").write_bytes(header + bytes([100, 0, 80]))
    path = write_yaml(tmp_path / "m.yaml")
    np.testing.assert_array_equal(load_map(path).occupancy, [[FREE, OCCUPIED, UNKNOWN]])
    with pytest.raises(MapFormatError) as info:  # a mask's 8-bit codes: refused, not misread
        load_filter_mask(path)
    assert all(s in str(info.value) for s in (str(path), "map.pgm", "maxval 100"))
    write_pgm(tmp_path / "map.pgm", np.array([[254, 0, 205]], dtype=np.uint8))  # maxval 255
    np.testing.assert_array_equal(load_map(path).occupancy, [[FREE, OCCUPIED, UNKNOWN]])


@pytest.mark.parametrize(
    ("header", "maxval"), [(b"P2\n", 100), (b"P2 # by hand\n", 100), (b"P2\n", 254)]
)
def test_a_plain_pgms_maxval_scales_its_pixels_once(
    tmp_path: Path, header: bytes, maxval: int
) -> None:
    """A plain (ASCII) P2 pgm of maxval below 255: OpenCV scales its levels up to 0..255 (a
    binary P5's it leaves as they are), and load_map divided them by maxval again, so under
    maxval 100 a wall of 20 (p 0.8) read as unknown and a grey of 80 (p 0.2) as free; map_server
    scales them once. Row: white, black, grey 0.8, wall 0.2 (p 0.8), grey 0.5."""
    grey = [maxval, 0, round(0.8 * maxval), round(0.2 * maxval), round(0.5 * maxval)]
    text = header + f"5 1\n{maxval}\n".encode() + " ".join(map(str, grey)).encode() + b"\n"
    (tmp_path / "map.pgm").write_bytes(text)
    path = write_yaml(tmp_path / "m.yaml")
    expected = [[FREE, OCCUPIED, UNKNOWN, OCCUPIED, UNKNOWN]]
    np.testing.assert_array_equal(load_map(path).occupancy, expected)
    (tmp_path / "map.pgm").write_bytes(  # a plain colour P3: the grey in all three channels
        b"P3\n5 1\n"
        + f"{maxval}\n".encode()
        + " ".join(f"{g} {g} {g}" for g in grey).encode()
        + b"\n"
    )
    np.testing.assert_array_equal(load_map(path).occupancy, expected)
    (tmp_path / "map.pgm").write_bytes(b"P2\n2 1\n" + f"{maxval}\n".encode() + b"0 300\n")
    with pytest.raises(MapFormatError, match=r"m\.yaml:1: key 'image': .*map\.pgm.*'300'"):
        load_map(path)  # a level above maxval is named


def test_numbers_in_exponent_notation_read_as_map_server_reads_them(tmp_path: Path) -> None:
    """yaml-cpp (map_server) reads ``5e-1`` as a number; PyYAML's YAML 1.1 rules want a dot and
    read it as a string, so a map map_server loads was refused ("got '5e-1'")."""
    write_pgm(tmp_path / "map.pgm", np.array([[254, 0]], dtype=np.uint8))
    path = tmp_path / "m.yaml"
    path.write_text(
        "image: map.pgm\nresolution: 5e-1\norigin: [-1E1, 2e0, 0]\nnegate: 0\n"
        "occupied_thresh: 0.65e0\nfree_thresh: 1.96e-1\n"
    )
    grid = load_map(path)
    assert grid.resolution == 0.5 and grid.origin == (-10.0, 2.0, 0.0)
    np.testing.assert_array_equal(grid.occupancy, [[FREE, OCCUPIED]])


def test_quoted_numbers_read_as_map_server_reads_them(tmp_path: Path) -> None:
    """map_server reads values with yaml-cpp's ``as<double>()``, which converts a quoted scalar
    too (``resolution: "0.05"``); such a map was refused ("got '0.05'"). Quoted text that is
    no number is still refused."""
    write_pgm(tmp_path / "map.pgm", np.array([[254, 0]], dtype=np.uint8))
    path = tmp_path / "m.yaml"
    path.write_text(
        "image: map.pgm\nresolution: '0.5'\norigin: [\"-1.5\", '2', 0]\nnegate: \"0\"\n"
        "occupied_thresh: '0.65'\nfree_thresh: \"1.96e-1\"\n"
    )
    grid = load_map(path)
    assert grid.resolution == 0.5 and grid.origin == (-1.5, 2.0, 0.0)
    np.testing.assert_array_equal(grid.occupancy, [[FREE, OCCUPIED]])
    path.write_text(path.read_text().replace("'0.5'", "'0.5 m'"))
    with pytest.raises(MapFormatError, match=r"m\.yaml:2: key 'resolution' .*'0\.5 m'"):
        load_map(path)


# ---------------------------------------------------------------------- writing
def test_save_map_round_trip(tmp_path: Path, rng: np.random.Generator) -> None:
    grid = OccupancyGrid(random_grid(rng, (13, 17)).occupancy, 0.07, (-3.25, 1.5, 0.0))
    path = save_map(grid, tmp_path / "out" / "saved.yaml")
    assert path == tmp_path / "out" / "saved.yaml"
    raw = (tmp_path / "out" / "saved.pgm").read_bytes()
    assert raw.startswith(b"P5")
    pixels = cv2.imread(str(tmp_path / "out" / "saved.pgm"), cv2.IMREAD_UNCHANGED)
    expected = np.select([grid.occupancy == FREE, grid.occupancy == OCCUPIED], [254, 0], 205)
    np.testing.assert_array_equal(pixels, expected)
    doc = yaml.safe_load(path.read_text())
    assert doc == {
        "image": "saved.pgm",
        "resolution": 0.07,
        "origin": [-3.25, 1.5, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    loaded = load_map(path)
    assert loaded == grid and loaded.source == path
    with pytest.raises(ValueError, match=r"\.yaml"):
        save_map(grid, tmp_path / "x.pgm")


def test_label_colours() -> None:
    # tab:blue, tab:orange, tab:green
    np.testing.assert_array_equal(label_colours(3), [[31, 119, 180], [255, 127, 14], [44, 160, 44]])
    many = label_colours(1000)
    assert many.shape == (1000, 3) and many.dtype == np.uint8
    assert len({tuple(c) for c in many.tolist()}) == 1000
    assert not {(0, 0, 0), (255, 255, 255), (205, 205, 205)} & {tuple(c) for c in many.tolist()}
    np.testing.assert_array_equal(many[:3], label_colours(3))
    np.testing.assert_array_equal(label_colours(1000), many)
    assert label_colours(0).shape == (0, 3)


def label_fixture() -> tuple[OccupancyGrid, np.ndarray]:
    occupancy = np.array([[100, 0, 0], [-1, 0, 0]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 0.5, (1.0, 2.0, 0.0))
    labels = np.array([[-1, 0, 2], [-1, -1, 0]])
    return grid, labels


def test_render_labels_and_png(tmp_path: Path) -> None:
    grid, labels = label_fixture()
    blue, green = [31, 119, 180], [44, 160, 44]
    expected = np.array([[[0, 0, 0], blue, green], [[205, 205, 205], [255, 255, 255], blue]])
    np.testing.assert_array_equal(render_labels(labels, grid), expected)
    no_grid = render_labels(labels)
    np.testing.assert_array_equal(no_grid[0, 0], [255, 255, 255])

    path = save_label_png(labels, tmp_path / "labels.png", grid)
    assert path == tmp_path / "labels.png"
    bgr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(bgr[..., ::-1], expected)


def test_labels_must_sit_on_free_cells() -> None:
    grid, labels = label_fixture()
    labels[0, 0] = 1
    with pytest.raises(ValueError, match=r"cell \(row 0, col 0\) with label 1 and map code 100"):
        render_labels(labels, grid)
    with pytest.raises(ValueError, match="-1 or a concept id"):
        render_labels(np.array([[-2]]))
    with pytest.raises(ValueError, match="shape"):
        render_labels(np.zeros((3, 3), np.int64), grid)


def test_label_map_server_round_trip(tmp_path: Path) -> None:
    occupancy = np.array([[100, 0, 0, 0], [-1, 0, 0, 100]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 0.05, (-10.0, -10.0, 0.0))
    labels = np.array([[-1, 300, 7, -1], [-1, 3, 7, -1]])
    path = save_label_map_server(labels, grid, tmp_path / "sem.yaml")

    pixels = cv2.imread(str(tmp_path / "sem.pgm"), cv2.IMREAD_UNCHANGED)
    # concepts 3, 7, 300 -> grey 1, 2, 3; wall 100, unknown 255, free unlabelled 0
    np.testing.assert_array_equal(pixels, [[100, 3, 2, 0], [255, 1, 2, 100]])
    doc = yaml.safe_load(path.read_text())
    assert doc["mode"] == "raw" and doc["negate"] == 0 and doc["image"] == "sem.pgm"
    assert doc["resolution"] == 0.05 and doc["origin"] == [-10.0, -10.0, 0.0]
    sidecar = json.loads((tmp_path / "sem.labels.json").read_text())
    assert sidecar["grey_to_concept"] == {"1": 3, "2": 7, "3": 300}

    got_labels, got_grid = load_label_map_server(path)
    np.testing.assert_array_equal(got_labels, labels)
    assert got_grid == grid
    with pytest.raises(MapFormatError, match="'raw'"):
        load_map(path)


def test_label_map_server_grey_values_skip_occupied_code(tmp_path: Path, caplog) -> None:
    grid = OccupancyGrid(np.zeros((1, 253), np.int8), 0.05, (0.0, 0.0, 0.0))
    labels = np.arange(253)[None, :] * 2  # 253 distinct concepts: exactly the capacity
    with caplog.at_level("WARNING", logger="spcopyro"):
        few = np.where(labels < 2 * 99, labels, 0)  # 99 distinct concepts: grey 1..99
        save_label_map_server(few, grid, tmp_path / "fits.yaml")
        assert not caplog.records
        path = save_label_map_server(labels, grid, tmp_path / "full.yaml")
    (warning,) = caplog.records  # Nav2's map_server: a raw value above 100 is unknown (-1)
    assert "253 distinct concepts" in warning.getMessage()
    assert "first 99 (concepts 198, ...) are above 100" in warning.getMessage()
    pixels = cv2.imread(str(tmp_path / "full.pgm"), cv2.IMREAD_UNCHANGED)[0]
    assert pixels[98] == 99 and pixels[99] == 101 and pixels[252] == 254
    assert 100 not in pixels.tolist()
    got_labels, _ = load_label_map_server(path)
    np.testing.assert_array_equal(got_labels, labels)

    wide = OccupancyGrid(np.zeros((1, 254), np.int8), 0.05, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="254 distinct concepts.*253 grey values"):
        save_label_map_server(np.arange(254)[None, :], wide, tmp_path / "over.yaml")


def test_label_map_server_rejects_unknown_grey(tmp_path: Path) -> None:
    grid, labels = label_fixture()
    path = save_label_map_server(labels, grid, tmp_path / "sem.yaml")
    write_pgm(tmp_path / "sem.pgm", np.array([[100, 1, 2], [255, 0, 77]], dtype=np.uint8))
    with pytest.raises(MapFormatError, match=r"pixel \(row 1, col 2\) has value 77"):
        load_label_map_server(path)
    (tmp_path / "sem.labels.json").unlink()
    with pytest.raises(MapFileNotFoundError, match="sem.labels.json"):
        load_label_map_server(path)


def test_a_semantic_maps_yaml_errors_name_the_line(tmp_path: Path) -> None:
    """The mode / negate refusal and the image's errors named the yaml but not the line of
    the key (map_server's own key errors do)."""
    grid, labels = label_fixture()
    path = save_label_map_server(labels, grid, tmp_path / "sem.yaml")
    text = path.read_text()
    line = {
        key: n
        for n, row in enumerate(text.splitlines(), 1)
        for key in ("mode", "negate", "image")
        if row.startswith(f"{key}:")
    }
    path.write_text(text.replace("mode: raw", "mode: trinary"))
    with pytest.raises(MapFormatError, match=rf"sem\.yaml:{line['mode']}: a semantic map needs"):
        load_label_map_server(path)
    path.write_text(text.replace("negate: 0", "negate: 1"))
    with pytest.raises(MapFormatError, match=rf"sem\.yaml:{line['negate']}: a semantic map"):
        load_label_map_server(path)
    path.write_text(text)
    (tmp_path / "sem.pgm").write_bytes(b"P5\n8 6\n255\n\x01")
    with pytest.raises(MapFormatError, match=rf"sem\.yaml:{line['image']}: key 'image'"):
        load_label_map_server(path)


# ---------------------------------------------------------------------- the public dataset
@pytest.mark.dataset
@pytest.mark.parametrize("room", sorted(PAPER_FREE_PIXELS))
def test_dataset_maps_match_paper(dataset_root: Path, room: str) -> None:
    grid = load_map(dataset_root / "map" / f"{room}.yaml")
    assert grid.num_free == PAPER_FREE_PIXELS[room]
    assert grid.shape == (384, 384)
    assert grid.resolution == 0.05 and grid.origin == (-10.0, -10.0, 0.0)
    assert grid.neighbour_table(4).shape == (PAPER_FREE_PIXELS[room], 4)

    # Orientation on real data: the robot took its images standing in free space, so with the
    # correct (flipped) row convention most image positions land on free cells.
    xy = np.stack(
        [np.loadtxt(dataset_root / room / "Xtx.csv"), np.loadtxt(dataset_root / room / "Xty.csv")],
        axis=1,
    )
    cells = grid.world_to_cell(xy)
    on_free = grid.is_free(cells).mean()
    unflipped = cells.copy()
    unflipped[:, 0] = grid.height - 1 - cells[:, 0]
    assert on_free >= 0.85
    assert on_free > grid.is_free(unflipped).mean() + 0.1


# ---------------------------------------------------------------------- Nav2 map_io's readings
@pytest.mark.parametrize(
    ("text", "negate"),
    [
        ("true", 1),
        ("false", 0),
        ('"true"', 1),
        ("y", 1),
        ("'Yes'", 1),
        ("OFF", 0),
        ('"1"', 1),
        ("2", 1),
        ("-1", 1),
        ("'2'", 1),
        ("0x10", 1),
        ("00", 0),
    ],  # fmt: skip
)
def test_negate_as_nav2_reads_it(tmp_path: Path, text: str, negate: int) -> None:
    """Nav2's map_io reads ``negate`` with yaml-cpp as an int, else as a bool (``y``, ``yes``,
    ``true``, ``on`` and their opposites, quoted or not, in lower, upper or title case), and
    keeps it as a C++ bool, as ROS 1's map_server does its ``int negate``: any nonzero integer
    negates (``negate: 2`` was refused, though both ROS loaders read it)."""
    write_pgm(tmp_path / "map.pgm", np.array([[0, 255]], dtype=np.uint8))
    path = tmp_path / "m.yaml"
    path.write_text(
        "image: map.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n"
        f"negate: {text}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    dark_free = [[FREE, OCCUPIED]] if negate else [[OCCUPIED, FREE]]
    np.testing.assert_array_equal(load_map(path).occupancy, dark_free)


@pytest.mark.parametrize("text", ["1.0", "'maybe'", "tRUE", "1_000", "09", "4294967296"])
def test_negate_nav2_refuses_is_refused(tmp_path: Path, text: str) -> None:
    write_pgm(tmp_path / "map.pgm", np.array([[0, 255]], dtype=np.uint8))
    path = tmp_path / "m.yaml"
    path.write_text(
        "image: map.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n"
        f"negate: {text}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    with pytest.raises(MapFormatError, match=r"m\.yaml:4: key 'negate' must be an integer"):
        load_map(path)


def test_equal_thresholds_read_as_map_server_reads_them(tmp_path: Path) -> None:
    """map_io checks no order of the thresholds on loading: equal ones split the greys in two,
    a pixel exactly at them unknown (153: p = (255 - 153) / 255 = 0.4)."""
    write_pgm(tmp_path / "map.pgm", np.array([[0, 102, 153, 200, 255]], dtype=np.uint8))
    path = write_yaml(tmp_path / "eq.yaml", occupied_thresh=0.4, free_thresh=0.4)
    o, f, u = OCCUPIED, FREE, UNKNOWN
    np.testing.assert_array_equal(load_map(path).occupancy, [[o, o, u, f, f]])


def test_scale_mask_with_equal_thresholds_is_refused(tmp_path: Path) -> None:
    """Scale mode divides by occupied_thresh - free_thresh: equal ones (which a trinary map may
    have) leave a pixel at them without a value (map_io's rint of 0/0)."""
    write_pgm(tmp_path / "map.pgm", np.array([[0, 153, 255]], dtype=np.uint8))
    path = write_yaml(tmp_path / "s.yaml", mode="scale", occupied_thresh=0.4, free_thresh=0.4)
    with pytest.raises(MapFormatError, match=r"s\.yaml:6: key 'free_thresh' 0\.4 equals"):
        load_filter_mask(path)


@pytest.mark.parametrize("occupied", [math.inf, 0.65])
def test_scale_mask_with_free_thresh_minus_infinity_is_refused(tmp_path: Path, occupied) -> None:
    """Thresholds outside [0, 1] load, as in map_server; in scale mode a free_thresh of -inf
    leaves every pixel between the thresholds at (occ + inf) / (occupied_thresh + inf), nan,
    which was cast to an int8 mask value without a word -- with occupied_thresh infinite too
    and (found in review) with it finite: [[0, 153, 255]] read as [[100, 0, 0]]."""
    write_pgm(tmp_path / "map.pgm", np.array([[0, 153, 255]], dtype=np.uint8))
    path = write_yaml(tmp_path / "s.yaml", mode="scale", occupied_thresh=occupied,
                      free_thresh=-math.inf)  # fmt: skip
    with pytest.raises(MapFormatError, match=r"s\.yaml:6: key 'free_thresh' -inf with"):
        load_filter_mask(path)


def test_scale_mask_with_occupied_thresh_infinity_reads_between_as_free(tmp_path: Path) -> None:
    """occupied_thresh inf with a finite free_thresh is a value: (occ - free) / inf = 0."""
    write_pgm(tmp_path / "map.pgm", np.array([[0, 153, 255]], dtype=np.uint8))
    path = write_yaml(tmp_path / "s.yaml", mode="scale", occupied_thresh=math.inf,
                      free_thresh=0.2)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the 'outside [0, 1]' warning
        warnings.simplefilter("error", RuntimeWarning)  # no nan from numpy
        mask = load_filter_mask(path)
    assert mask.values.tolist() == [[0, 0, 0]]


# ---------------------------------------------------------------------- maps without free space
def _no_free(tmp_path: Path, pixels: list[list[int]], **overrides: object) -> str:
    """The refusal of a map of ``pixels`` with the yaml ``overrides`` (it has no free cell)."""
    from spcopyro.maps.free_space import check_free_cells

    write_pgm(tmp_path / "map.pgm", np.array(pixels, dtype=np.uint8))
    grid = load_map(write_yaml(tmp_path / "t.yaml", **overrides))
    assert grid.num_free == 0
    with pytest.raises(ValueError, match=r"house 'h': the map .*t\.yaml has no free cell") as info:
        check_free_cells(grid, "house 'h'")
    return str(info.value)


def test_no_free_cell_names_the_yaml_lines_and_the_greys(tmp_path: Path) -> None:
    message = _no_free(tmp_path, [[0, 205, 254]], occupied_thresh=1.0, free_thresh=0.0)
    for fragment in (
        "t.yaml:4: negate 0;",
        "t.yaml:6: free_thresh 0.0;",
        "t.yaml:5: occupied_thresh 1.0;",
        "greys 0..254 of 255",
        "p = (255 - grey) / 255 runs 0.003922..1: none is below free_thresh 0.0",
    ):
        assert fragment in message, (fragment, message)


def test_no_free_cell_says_when_the_other_negate_frees_cells(tmp_path: Path) -> None:
    message = _no_free(tmp_path, [[205, 254, 254]], negate=1)
    assert "t.yaml:4: negate 1;" in message and "with negate 0, 2 cells would be free" in message


@pytest.mark.parametrize(
    ("negate", "shown"), [(2, "2 (true)"), (-1, "-1 (true)"), ("yes", "yes (true)"), (True, "true")]
)
def test_no_free_cell_names_negate_as_the_yaml_writes_it(tmp_path: Path, negate, shown) -> None:
    """``negate: 2`` reads as map_server reads it (nonzero: true); the refusal printed it as
    ``negate 1``, a value the yaml does not hold. Now as written, with its reading."""
    message = _no_free(tmp_path, [[205, 254, 254]], negate=negate)
    assert f"t.yaml:4: negate {shown};" in message and "with negate 0, 2 cells" in message


def test_a_semantic_map_with_negate_2_is_refused_naming_it_as_written(tmp_path: Path) -> None:
    from spcopyro.maps.render import load_label_map_server

    write_pgm(tmp_path / "map.pgm", np.array([[0, 254]], dtype=np.uint8))
    path = write_yaml(tmp_path / "t.yaml", mode="raw", negate=2)
    with pytest.raises(MapFormatError, match=r"t\.yaml:4: .*got mode 'raw', negate 2 \(true\)$"):
        load_label_map_server(path)


def test_no_free_cell_says_when_every_pixel_is_unknown_grey(tmp_path: Path) -> None:
    message = _no_free(tmp_path, [[205, 205]])
    assert "every pixel is map_saver's unknown grey 205" in message


def test_no_free_cell_of_a_grid_edited_in_memory_blames_no_yaml_line(tmp_path: Path) -> None:
    from spcopyro.maps.free_space import check_free_cells

    write_pgm(tmp_path / "map.pgm", np.array([[0, 254]], dtype=np.uint8))
    grid = load_map(write_yaml(tmp_path / "t.yaml"))  # one free cell in the yaml's reading
    walls = grid.with_occupancy(np.full(grid.shape, OCCUPIED, dtype=np.int8))
    with pytest.raises(ValueError, match="has no free cell") as info:
        check_free_cells(walls, "house 'h'")
    assert "t.yaml:" not in str(info.value) and "check the map image" in str(info.value)
    source_free = OccupancyGrid(walls.occupancy, walls.resolution, walls.origin)  # no yaml
    with pytest.raises(ValueError, match="house 'h': the map has no free cell, nothing to label"):
        check_free_cells(source_free, "house 'h'")  # not "the map  has" (no source, one space)


def _room_without_free_cells(tmp_path: Path) -> tuple[Path, Path, int]:
    """A synthetic room folder whose map yaml says free_thresh 0.0 (no cell is free), without
    its truth; its yaml's path and the 1-based line of free_thresh."""
    from spcopyro.synthetic import HouseSpec, write_synthetic

    room = write_synthetic(
        tmp_path / "data", seed=1, spec=HouseSpec(height=30, width=40, num_rooms=2)
    )
    for name in ("truth.npy", "categories.json"):
        (room / name).unlink()
    yaml_path = room.parent / "map" / f"{room.name}.yaml"
    text = yaml_path.read_text()
    yaml_path.write_text(text.replace("free_thresh: 0.196", "free_thresh: 0.0"))
    return room, yaml_path, 1 + text.split("\n").index("free_thresh: 0.196")


def test_fit_refuses_a_map_without_free_cells_before_its_summary(tmp_path: Path, capsys) -> None:
    """``spcopyro fit`` refuses before printing the summary (whose placement line listed every
    observation as unplaced) and before the model's cells warn of leaving no free cell."""
    from spcopyro.cli.main import main

    room, yaml_path, line = _room_without_free_cells(tmp_path)
    out = tmp_path / "out"
    assert main(["fit", str(room), "--out", str(out), "--sweeps", "3", "--no-figures"]) == 2
    printed = capsys.readouterr()
    assert not out.exists() and "placement" not in printed.out and "house " not in printed.out
    assert "leave no free cell" not in printed.err
    assert f"{yaml_path}:{line}: free_thresh 0.0;" in printed.err.strip().splitlines()[-1]


def test_show_says_a_map_has_no_free_cell_in_place_of_placement(tmp_path: Path, capsys) -> None:
    """``spcopyro show`` of a map without free cells listed every image and word as unplaced
    (with two warnings blaming the map's origin) where ``fit`` refuses it with the reason: show
    prints that reason in place of the placement lines, and still draws the house."""
    from spcopyro.cli.main import main

    room, yaml_path, line = _room_without_free_cells(tmp_path)
    assert main(["show", str(room), "--out", str(tmp_path / "house.png")]) == 0
    printed = capsys.readouterr()
    assert "placement" not in printed.out and "unplaced" not in printed.err
    said = [row for row in printed.out.splitlines() if row.startswith("no free cell ")]
    assert len(said) == 1 and f"{yaml_path}:{line}: free_thresh 0.0;" in said[0], printed.out
    assert f"the map {yaml_path} has no free cell, nothing to label" in said[0]
    assert (tmp_path / "house.png").is_file()


def test_the_summary_of_a_map_without_free_cells_places_nothing(
    tmp_path: Path, monkeypatch
) -> None:
    """The summary of a map without free cells decides that first: its lines are the house's,
    then why nothing can be labelled; no observed cells, no placement, and no footprints
    spread over cells that are not there (the summary used to count them, then drop the
    lines)."""
    import spcopyro.cli.common as common
    from spcopyro.config import DataPreparation
    from spcopyro.data import load_house

    spread = []
    monkeypatch.setattr(common, "prepared_cell_counts", lambda *a, **k: spread.append(a))
    room, yaml_path, _ = _room_without_free_cells(tmp_path)
    lines = common._summary(load_house(room), preparation=DataPreparation(footprint_radius=1.0))
    heads = [line[:17].strip() for line in lines.splitlines()]
    assert heads == ["house", "map", "images", "utterances", "no free cell"], lines
    assert f"the map {yaml_path} has no free cell, nothing to label" in lines
    assert spread == []


def test_the_package_docstring_names_every_public_name_it_does_not_re_export() -> None:
    """spcopyro.maps' docstring said everything public was re-exported; same_frame,
    same_free_cells, describe_map and others are imported from their module. Its list of those
    is each module's ``__all__`` less the package's."""
    import importlib
    import pkgutil
    import re

    import spcopyro.maps as maps

    missing = {}
    for info in pkgutil.iter_modules(maps.__path__):
        public = getattr(importlib.import_module(f"spcopyro.maps.{info.name}"), "__all__", ())
        if rest := set(public) - set(maps.__all__):
            missing[info.name] = rest
    listed = maps.__doc__.split("Not re-exported")[1]
    said = {
        module: set(re.findall(r"``(\w+)``", names))
        for module, names in re.findall(r":mod:`~spcopyro\.maps\.(\w+)`: ([^*]*)", listed)
    }
    assert said == missing
    assert "everything public is re-exported" not in maps.__doc__
