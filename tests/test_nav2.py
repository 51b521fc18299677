"""`spcopyro export --nav2`: costmap-filter masks in Nav2's conventions, read back through the
package's own map_server loader (:func:`spcopyro.maps.load_filter_mask`, which decodes a mask
as nav2_map_server's map_io does)."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
import yaml

from spcopyro.cli.main import main
from spcopyro.config import SpCoConfig
from spcopyro.maps import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    OccupancyGrid,
    load_filter_mask,
    load_map,
    save_filter_mask,
    save_map,
)
from spcopyro.results.result import EmissionTable, SpCoResult, Trace
from spcopyro.results.uncertainty import where_probability
from spcopyro.robot.nav2 import export_nav2, speed_percent, word_place

WORDS = ("kitchen", "bed", "sofa")
H, W = 13, 20


def top_and_bottom() -> SpCoResult:
    """A 13 x 20 map at 0.05 m, origin (1.5, -2.0): a wall on row 6, an unknown column 0.
    Concept 0 (kitchen words) labels the top room, concept 1 (bed words) the bottom one; the
    marginals make p(C_i = 0) grow from left to right in each room, so the probability of the
    kitchen's place varies over the cells."""
    occupancy = np.full((H, W), FREE, dtype=np.int8)
    occupancy[6, :] = OCCUPIED
    occupancy[:, 0] = UNKNOWN
    grid = OccupancyGrid(occupancy=occupancy, resolution=0.05, origin=(1.5, -2.0, 0.0))
    image = np.full(grid.shape, -1)
    image[:6] = 0
    image[7:] = 1
    labels = image[grid.free]  # [N]
    rows, cols = np.nonzero(grid.free)  # free cells in raster (free_index) order
    lean = 0.5 + 0.45 * cols / (W - 1)  # [N] weight of the cell's own concept
    marginals = np.zeros((grid.num_free, 2))  # [N, L]
    marginals[np.arange(grid.num_free), labels] = lean
    marginals[np.arange(grid.num_free), 1 - labels] = 1 - lean
    w = np.array([[0.7, 0.1, 0.2], [0.1, 0.7, 0.2]])  # [L, V]
    return SpCoResult(
        grid=grid,
        config=SpCoConfig(num_concepts=2, prior="dirichlet"),
        labels=labels,
        pi=np.full(2, 0.5),
        emissions=(
            EmissionTable("images", ("0", "1"), np.full((2, 2), 0.5)),
            EmissionTable("words", WORDS, w),
        ),
        trace=Trace(objective=np.zeros(1), num_concepts=np.array([2]), seconds=np.zeros(1)),
        best_iteration=0,
        marginals=marginals,
    )


@pytest.fixture
def fit(tmp_path):
    return top_and_bottom().save(tmp_path / "fit")


def _read_yaml(path):
    return yaml.safe_load(path.read_text())


def test_keepout_mask_is_the_where_answer_in_nav2_conventions(fit, tmp_path, capsys):
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", "Bed"]) == 0
    assert (
        "keepout mask for 'kitchen' (concept 0): 114 of 228 free cells" in capsys.readouterr().out
    )
    result = SpCoResult.load(fit)

    doc = _read_yaml(out / "keepout_kitchen.yaml")
    assert doc == {
        "image": "keepout_kitchen.pgm",
        "resolution": 0.05,
        "origin": [1.5, -2.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
        "mode": "trinary",
    }
    mask = load_filter_mask(out / "keepout_kitchen.yaml")
    assert mask.mode == "trinary" and mask.values.shape == (H, W)
    assert (mask.resolution, mask.origin) == (result.grid.resolution, result.grid.origin)
    assert set(np.unique(mask.values)) == {-1, 100}  # -1: no information, the costmap's stays
    # The occupied (lethal) cells are exactly the where-answer's region, the TOP room: the
    # image's first row is the map's top (largest world y).
    assert np.array_equal(mask.values == 100, result.where("kitchen").region)
    assert (mask.values[:6, 1:] == 100).all() and (mask.values[6:] == -1).all()
    top_row, _ = result.grid.world_to_cell(np.array([[1.5 + 0.3, -2.0 + 12.5 * 0.05]]))[0]
    assert top_row == 0 and mask.values[top_row, 5] == 100
    bed = load_filter_mask(out / "keepout_bed.yaml").values
    assert np.array_equal(bed == 100, result.where("bed").region) and bed[7:, 1:].all()
    assert load_map(out / "map.yaml") == result.grid  # the map the masks lie on

    params = _read_yaml(out / "keepout_kitchen_params.yaml")
    info = params["keepout_kitchen_filter_info_server"]["ros__parameters"]
    server = params["keepout_kitchen_mask_server"]["ros__parameters"]
    assert info == {"type": 0, "filter_info_topic": "/keepout_kitchen_filter_info",
                    "mask_topic": "/keepout_kitchen_filter_mask", "base": 0.0,
                    "multiplier": 1.0}  # fmt: skip
    assert server["topic_name"] == info["mask_topic"] and server["frame_id"] == "map"
    assert server["yaml_filename"] == str((out / "keepout_kitchen.yaml").resolve())
    costmaps = _read_yaml(out / "costmap_filters.yaml")
    for costmap in ("global_costmap", "local_costmap"):
        ros = costmaps[costmap][costmap]["ros__parameters"]
        assert ros["filters"] == ["keepout_kitchen_filter", "keepout_bed_filter"]
        assert ros["keepout_kitchen_filter"] == {
            "plugin": "nav2_costmap_2d::KeepoutFilter", "enabled": True,
            "filter_info_topic": info["filter_info_topic"]}  # fmt: skip
    summary = json.loads((out / "nav2_export.json").read_text())
    assert [m["word"] for m in summary["masks"]] == ["kitchen", "bed"]


def test_keepout_with_a_probability_threshold(fit, tmp_path):
    result = SpCoResult.load(fit)
    export = export_nav2(result, tmp_path / "nav2", ["kitchen"], threshold=0.6)
    values = load_filter_mask(export.masks[0].mask_yaml).values
    probability = where_probability(result, "kitchen")  # [N]
    assert np.array_equal(values[result.grid.free] == 100, probability >= 0.6)
    assert (values[~result.grid.free] == -1).all()
    assert 0 < export.masks[0].cells < 114  # part of the top room only


def test_speed_mask_decodes_to_a_limit_falling_with_the_probability(fit, tmp_path):
    out = tmp_path / "speed"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", "--mode", "speed",
                 "--min-speed", "20", "--max-speed", "90"]) == 0  # fmt: skip
    result = SpCoResult.load(fit)
    params = _read_yaml(out / "speed_kitchen_params.yaml")
    info = params["speed_kitchen_filter_info_server"]["ros__parameters"]
    assert (info["type"], info["base"], info["multiplier"]) == (1, 100.0, -1.0)
    costmaps = _read_yaml(out / "costmap_filters.yaml")
    assert "local_costmap" not in costmaps  # Nav2: a speed filter in one costmap only
    plugin = costmaps["global_costmap"]["global_costmap"]["ros__parameters"]["speed_kitchen_filter"]
    assert plugin["plugin"] == "nav2_costmap_2d::SpeedFilter"

    mask = load_filter_mask(out / "speed_kitchen.yaml")
    assert (mask.resolution, mask.origin) == (0.05, (1.5, -2.0, 0.0))
    values = mask.values[result.grid.free].astype(float)  # [N]
    assert ((0 <= mask.values) & (mask.values <= 100)).all()
    assert (mask.values[~result.grid.free] == 0).all()  # off free space: no limit
    # SpeedFilter: 0 = no limit, else limit = base + multiplier * value (percent).
    limit = np.where(values == 0, 100.0, info["base"] + info["multiplier"] * values)  # [N]
    probability = where_probability(result, "kitchen")  # [N]
    assert np.array_equal(limit, np.rint(90 - 70 * probability))
    assert ((20 <= limit) & (limit <= 90)).all() and len(np.unique(limit)) > 10
    order = np.argsort(probability, kind="stable")
    assert (np.diff(limit[order]) <= 0).all()  # monotone: more probable, slower
    assert speed_percent(np.array([0.0, 1.0]), 1.0, 100.0).tolist() == [100.0, 1.0]


def test_every_mask_value_reads_back_exactly(tmp_path):
    grid = OccupancyGrid(np.zeros((11, 11), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    values = np.append(np.arange(101), [0] * 20).reshape(11, 11)
    mask = load_filter_mask(save_filter_mask(values, grid, tmp_path / "m.yaml"))
    assert np.array_equal(mask.values, values)
    with pytest.raises(ValueError, match="0..100"):
        save_filter_mask(values + 1, grid, tmp_path / "bad.yaml")


def test_load_filter_mask_decodes_like_nav2_map_server(tmp_path):
    """Hand-computed cells of map_io.cpp's three modes, without and with ``negate``.

    nav2_map_server ``map_io.cpp`` (``loadMapFromFile``): ``shade`` = the pixel's mean over its
    channels in [0, 1]; ``occ = negate ? shade : 1 - shade``; trinary and scale threshold
    ``occ``, while raw takes ``round(shade * 255)`` -- ``shade``, not ``occ``, so ``negate``
    does not apply in raw mode."""
    pixels = np.array([[0, 64, 128, 200, 255]], dtype=np.uint8)  # shade 0, .251, .502, .784, 1
    grid = OccupancyGrid(np.zeros((1, 5), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    save_filter_mask(np.zeros((1, 5), dtype=int), grid, tmp_path / "m.yaml")
    import cv2

    cv2.imwrite(str(tmp_path / "m.pgm"), pixels)
    text = (tmp_path / "m.yaml").read_text()
    expected = {  # (mode, negate): cells; thresholds free 0.25, occupied 0.65
        # negate 0: occ = 1 - shade = 1.0, 0.749, 0.498, 0.216, 0.0
        ("scale", 0): [100, 100, 62, 0, 0],  # rint((occ - .25) / .4 * 100) in between
        ("trinary", 0): [100, 100, -1, 0, 0],
        ("raw", 0): [0, 64, -1, -1, -1],  # the byte itself when <= 100
        # negate 1: occ = shade = 0.0, 0.251, 0.502, 0.784, 1.0
        ("scale", 1): [0, 0, 63, 100, 100],  # rint(.00098 / .4 * 100) = 0, rint(62.99) = 63
        ("trinary", 1): [0, -1, -1, 100, 100],  # .251 is not below free_thresh .25
        ("raw", 1): [0, 64, -1, -1, -1],  # as without negate
    }
    for (mode, negate), cells in expected.items():
        (tmp_path / "m.yaml").write_text(
            text.replace("mode: scale", f"mode: {mode}")
            .replace("negate: 0", f"negate: {negate}")
            .replace("occupied_thresh: 1.0", "occupied_thresh: 0.65")
            .replace("free_thresh: 0.0", "free_thresh: 0.25")
        )
        mask = load_filter_mask(tmp_path / "m.yaml")
        assert mask.negate == bool(negate)
        assert mask.values.tolist() == [cells], (mode, negate)


def test_load_filter_mask_averages_alpha_in_trinary_like_map_server_and_load_map(tmp_path):
    """map_io.cpp pushes ``MaxRGB - alphaQuantum()`` (GraphicsMagick's opacity: 0 = opaque), i.e.
    the alpha value itself, 255 for an opaque pixel: an opaque white RGBA pixel is free, a
    transparent one (mean 190.5, occ 0.25) unknown. Before the fix it averaged ``255 - alpha`` in,
    so every opaque white pixel read as unknown, unlike map_server and ``load_map``."""
    import cv2

    bgra = np.array([[[254] * 3 + [255], [254] * 3 + [0], [0, 0, 0, 255]]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    grid = OccupancyGrid(np.zeros((1, 3), dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    save_filter_mask(np.zeros((1, 3), dtype=int), grid, tmp_path / "a.yaml")
    text = (tmp_path / "a.yaml").read_text().replace("a.pgm", "a.png")
    (tmp_path / "a.yaml").write_text(
        text.replace("mode: scale", "mode: trinary")
        .replace("occupied_thresh: 1.0", "occupied_thresh: 0.65")
        .replace("free_thresh: 0.0", "free_thresh: 0.196")
    )
    assert load_filter_mask(tmp_path / "a.yaml").values.tolist() == [[0, -1, 100]]
    assert load_map(tmp_path / "a.yaml").occupancy.tolist() == [[0, -1, 100]]


@pytest.mark.parametrize(
    "options",
    [
        {"mode": "keepout"},
        {"mode": "keepout", "prior": "pi"},
        {"mode": "keepout", "threshold": 0.6},
        {"mode": "keepout", "threshold": 1.0},
        {"mode": "speed"},
        {"mode": "speed", "min_speed": 1.0, "max_speed": 100.0},
        {"mode": "speed", "min_speed": 20.0, "max_speed": 90.0, "prior": "pi"},
        {"mode": "speed", "min_speed": 50.0, "max_speed": 50.0},
    ],
    ids=lambda options: "-".join(f"{k}={v}" for k, v in options.items()),
)
def test_every_exported_mask_reads_back_as_intended_by_nav2s_rules(fit, tmp_path, options):
    """Issue 24 item 2: every mask the exporter writes (keepout and speed, for every word and
    every option that changes the values) loaded with map_server's rules
    (:func:`load_filter_mask`, with the yaml's own mode, negate and thresholds) and decoded with
    the filter info's ``base + multiplier * value``: lethal cells (keepout 100) are exactly the
    word's place, and the speed limit of every free cell is exactly the intended one, never the
    "no limit" value (0) where a limit below 100 % was intended."""
    from spcopyro.robot.nav2 import (
        DEFAULT_MAX_SPEED,
        DEFAULT_MIN_SPEED,
        keepout_values,
        speed_values,
        word_place,
    )

    result = SpCoResult.load(fit)
    export = export_nav2(result, tmp_path / "nav2", list(WORDS), **options)
    mode = options["mode"]
    rest = {k: v for k, v in options.items() if k != "mode"}
    free = result.grid.free  # [H, W] bool
    assert [m.word for m in export.masks] == list(WORDS)
    for exported in export.masks:
        mask = load_filter_mask(exported.mask_yaml)
        info = _read_yaml(exported.params_yaml)[f"{exported.name}_filter_info_server"]
        base, multiplier = info["ros__parameters"]["base"], info["ros__parameters"]["multiplier"]
        assert mask.values.shape == result.grid.shape
        filter_value = base + multiplier * mask.values.astype(float)  # [H, W]
        if mode == "keepout":
            place = word_place(result, exported.word, **rest)  # [H, W] bool
            assert np.array_equal(mask.values, keepout_values(place)), exported.word
            assert np.array_equal(filter_value == 100, place)  # lethal: exactly the place
            # no information everywhere else: the KeepoutFilter leaves those costmap cells as
            # they are (a 0 made the map's unknown cells free: keepout_filter.cpp)
            assert (mask.values[~place] == -1).all()
            assert exported.cells == int(place[free].sum())
        else:
            assert (mask.values >= 0).all()
            intended, probability = speed_values(result, exported.word, **rest)  # [H, W], [N]
            assert np.array_equal(mask.values, intended), exported.word
            # SpeedFilter: mask value 0 = no limit; otherwise the limit in percent.
            limit = np.where(mask.values == 0, 100.0, filter_value)  # [H, W]
            want = speed_percent(probability, rest.get("min_speed", DEFAULT_MIN_SPEED),
                                 rest.get("max_speed", DEFAULT_MAX_SPEED))  # fmt: skip
            assert np.array_equal(limit[free], want)
            limited = want < 100  # [N] cells meant to be slowed down
            assert (mask.values[free][limited] != 0).all()  # none reads as "no limit"
            assert (limit[free][limited] >= 1).all()
            assert (mask.values[~free] == 0).all()  # off free space: no limit
            assert exported.cells == int(limited.sum())


def test_unknown_word_is_a_clear_error_and_writes_nothing(fit, tmp_path, capsys):
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchn"]) == 2
    assert "'kitchn' is not in the vocabulary of 3 words; did you mean kitchen?" in (
        capsys.readouterr().err
    )
    assert not out.exists() and list(tmp_path.iterdir()) == [fit]
    assert main(["export", str(fit), "--nav2", str(out), "--word", "garage"]) == 2
    assert "known words: bed, kitchen, sofa" in capsys.readouterr().err


def test_an_export_without_a_word_writes_and_names_no_empty_filter_file(fit, tmp_path, capsys):
    """QA (a new user's walk): `export OUT --nav2 DIR` without --word said 'wrote the map and the
    semantic map only', then 'costmap plugin entries for nav2_params.yaml: DIR/costmap_filters.yaml'
    for a file that held only `{}`: nothing to merge, and a line saying otherwise."""
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "wrote the map and the semantic map only" in printed
    assert "--word WORD adds a mask and its costmap filter entries" in printed
    assert "costmap_filters.yaml" not in printed and "costmap plugin entries" not in printed
    assert not (out / "costmap_filters.yaml").exists()
    assert {"map.yaml", "semantic_map.yaml", "nav2_export.json"} <= {p.name for p in out.iterdir()}
    assert export_nav2(SpCoResult.load(fit), tmp_path / "api", []).costmap_filters_yaml is None
    # with a word the entries are written and named, as before
    assert main(["export", str(fit), "--nav2", str(out), "--word", "bed", "--overwrite"]) == 0
    assert f"costmap plugin entries for nav2_params.yaml: {out / 'costmap_filters.yaml'}" in (
        capsys.readouterr().out
    )
    assert _read_yaml(out / "costmap_filters.yaml")["global_costmap"]


def test_an_existing_folder_needs_overwrite(fit, tmp_path, capsys):
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen"]) == 0
    before = sorted(p.name for p in out.iterdir())
    assert main(["export", str(fit), "--nav2", str(out), "--word", "bed"]) == 2
    assert "exists and is not empty; pass --overwrite" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == before
    assert main(["export", str(fit), "--nav2", str(out), "--word", "bed", "--overwrite"]) == 0
    names = {p.name for p in out.iterdir()}
    assert "keepout_bed.yaml" in names and "keepout_kitchen.yaml" not in names  # replaced whole
    assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name]

    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    assert main(["export", str(fit), "--nav2", str(other), "--overwrite"]) == 2
    assert "no Nav2 export wrote" in capsys.readouterr().err
    assert (other / "notes.txt").read_text() == "keep me"


def test_bad_options_are_refused(fit, tmp_path, capsys):
    out = str(tmp_path / "n")
    assert main(["export", str(fit), "--nav2", out, "--word", "bed", "--mode", "speed",
                 "--threshold", "0.5"]) == 2  # fmt: skip
    assert "--threshold applies to --mode keepout only" in capsys.readouterr().err
    assert main(["export", str(fit), "--nav2", out, "--mode", "speed", "--min-speed", "80",
                 "--max-speed", "50"]) == 2  # fmt: skip
    with pytest.raises(SystemExit):
        main(["export", str(fit), "--nav2", out, "--threshold", "1.5"])
    assert not (tmp_path / "n").exists()


def test_a_speed_mask_never_writes_no_limit_inside_the_place(fit, tmp_path, capsys):
    """Issue 24 item 2: --min-speed 0 made the cells surest to be the place a 0 % limit, which
    Nav2 reads as "no speed limit": the place became the one where the robot drives fastest.
    --min-speed below 1 is refused; at 1 every limited cell keeps a limit of at least 1 %."""
    from spcopyro.robot.nav2 import speed_percent

    out = tmp_path / "n"
    with pytest.raises(SystemExit):
        main(["export", str(fit), "--nav2", str(out), "--word", "bed", "--mode", "speed",
              "--min-speed", "0"])  # fmt: skip
    assert "Nav2 reads a 0 % limit as no limit" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(ValueError, match="1 <= min"):
        speed_percent(np.array([1.0]), min_speed=0.0)
    percent = speed_percent(np.linspace(0, 1, 101), min_speed=1.0, max_speed=100.0)
    assert percent.min() >= 1 and percent[0] == 100  # p = 0: no limit, as intended


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"threshold": True}, r"probability threshold must lie in \(0, 1\], got True"),
        ({"min_speed": True}, "speed limits must satisfy 1 <= min <= max <= 100"),
        ({"min_speed": 1, "max_speed": True}, "speed limits must satisfy 1 <= min <= max <= 100"),
    ],
    ids=["threshold", "min_speed", "max_speed"],
)
def test_a_bool_is_no_threshold_or_speed_limit(tmp_path, arguments, message):
    """True is an int: ``threshold=True`` kept out the cells of probability 1, ``min_speed=True``
    set a 1 % floor, and ``max_speed=True`` with ``min_speed=1`` a 1 % limit everywhere (each
    passed ``1 <= min <= max <= 100``; a library caller's, the command line parses numbers).
    Refused as a bad value is, before anything is written. (``max_speed=True`` with the default
    min_speed of 30 failed ``min <= max`` before.)"""
    result, out = top_and_bottom(), tmp_path / "n"
    mode = "keepout" if "threshold" in arguments else "speed"
    with pytest.raises(ValueError, match=message):
        export_nav2(result, out, ["kitchen"], mode=mode, **arguments)
    assert not out.exists()
    if "threshold" in arguments:
        with pytest.raises(ValueError, match=message):
            word_place(result, "kitchen", **arguments)
    else:
        with pytest.raises(ValueError, match=message):
            speed_percent(np.array([0.5]), **arguments)


@pytest.mark.slow
def test_simulate_fit_export_end_to_end(tmp_path, capsys):
    """Your floor plan -> simulated tour -> fit -> keepout mask on that floor plan (~10 s)."""
    from test_map_simulation import three_rooms

    plan, grid = three_rooms(tmp_path)
    assert main(["simulate", "--map", str(plan), "--out", str(tmp_path / "data")]) == 0
    fit = ["fit", str(tmp_path / "data" / "flat"), "--sweeps", "20", "--backend", "torch",
           "--preset", "original-code", "--gamma", "3", "--out", str(tmp_path / "fit")]  # fmt: skip
    assert main(fit) == 0
    out = tmp_path / "nav2"
    assert main(["export", str(tmp_path / "fit"), "--nav2", str(out), "--word", "kitchen"]) == 0
    mask = load_filter_mask(out / "keepout_kitchen.yaml")
    assert (mask.resolution, mask.origin, mask.values.shape) == (0.1, (-2.0, 1.0, 0.0), grid.shape)
    region = SpCoResult.load(tmp_path / "fit").where("kitchen").region
    assert region.any() and np.array_equal(mask.values == 100, region)


def test_topics_follow_the_robots_namespace(fit, tmp_path):
    """Issue 24 item 3: the filter topics were absolute, so a namespaced robot could not use
    them as written."""
    out = tmp_path / "ns"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", "--mode", "speed",
                 "--namespace", "/robot1/"]) == 0  # fmt: skip
    params = _read_yaml(out / "speed_kitchen_params.yaml")
    mask = params["speed_kitchen_mask_server"]["ros__parameters"]
    info = params["speed_kitchen_filter_info_server"]["ros__parameters"]
    assert mask["topic_name"] == info["mask_topic"] == "/robot1/speed_kitchen_filter_mask"
    assert info["filter_info_topic"] == "/robot1/speed_kitchen_filter_info"
    costmaps = _read_yaml(out / "costmap_filters.yaml")
    plugin = costmaps["global_costmap"]["global_costmap"]["ros__parameters"]["speed_kitchen_filter"]
    assert plugin["filter_info_topic"] == "/robot1/speed_kitchen_filter_info"
    assert plugin["speed_limit_topic"] == "/robot1/speed_limit"
    with pytest.raises(ValueError, match="namespace"):
        from spcopyro.robot.nav2 import check_namespace

        check_namespace("robot 1")


@pytest.mark.parametrize(
    ("namespace", "expected"),
    [("robot1", "robot1"), ("/fleet/robot1/", "fleet/robot1"), ("_hidden", "_hidden"),
     ("/fleet/_robot1", "fleet/_robot1"), ("robot__1", "robot__1"), ("/", None), ("", None)],
)  # fmt: skip
def test_a_namespace_follows_ros2s_rules(namespace, expected):
    """A namespace as ROS 2 validates it (rmw_validate_namespace): a part may start with ``_``
    (a hidden namespace, e.g. ``/fleet/_robot1``), which was refused as not starting with a
    letter; a part starting with a digit, an empty part or another character is refused, the
    error naming the value."""
    from spcopyro.robot.nav2 import check_namespace

    assert check_namespace(namespace) == expected


@pytest.mark.parametrize("namespace", ["robot 1", "1robot", "fleet/2", "fleet//robot1", "robot-1"])
def test_a_namespace_ros2_refuses_is_refused_by_its_value(namespace):
    from spcopyro.robot.nav2 import check_namespace

    with pytest.raises(ValueError, match=re.escape(f"namespace {namespace!r}: ROS 2 namespaces")):
        check_namespace(namespace)


def test_a_coarse_fits_main_map_is_the_robots_map_it_was_coarsened_from(fit, tmp_path, capsys):
    """`fit` keeps a coarse fit's source map as robot_map.yaml; `export` writes it as Nav2's main
    map (the fit's thickened walls can close doorways) and keeps the masks on the fit's cells."""
    fine = OccupancyGrid(np.full((2 * H, 2 * W), FREE, dtype=np.int8), 0.025, (1.5, -2.0, 0.0))
    save_map(fine, fit / "robot_map.yaml")
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen"]) == 0
    assert "the main map is" in capsys.readouterr().out
    assert load_map(out / "map.yaml") == fine
    mask = load_filter_mask(out / "keepout_kitchen.yaml")
    assert (mask.resolution, mask.values.shape) == (0.05, (H, W))
    record = _read_yaml(out / "nav2_export.json")
    assert record["map"]["resolution"] == 0.025 and record["masks_grid"]["resolution"] == 0.05


def test_an_older_coarse_fits_main_map_is_the_map_its_data_came_with(fit, tmp_path, capsys):
    """A coarse fit written before `fit` kept robot_map.yaml: `export` finds the robot's map as
    `navigate` does, at DATA/../map/HOUSE.yaml from the fit's provenance; without it, the fit's
    own grid is the main map."""
    import dataclasses

    from spcopyro.config import DataPreparation

    result = SpCoResult.load(fit)
    fine = OccupancyGrid(np.full((2 * H, 2 * W), FREE, dtype=np.int8), 0.025, (1.5, -2.0, 0.0))
    save_map(fine, tmp_path / "data" / "map" / "flat.yaml")
    source = {"data": str(tmp_path / "data" / "flat"), "house": "flat"}
    older = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.05),
                                provenance={"source": source})  # fmt: skip
    folder = older.save(tmp_path / "older")
    assert main(["export", str(folder), "--nav2", str(tmp_path / "a"), "--word", "kitchen"]) == 0
    assert f"the main map is {tmp_path / 'data' / 'map' / 'flat.yaml'}" in capsys.readouterr().out
    assert load_map(tmp_path / "a" / "map.yaml") == fine
    (tmp_path / "data" / "map" / "flat.yaml").unlink()
    assert main(["export", str(folder), "--nav2", str(tmp_path / "b"), "--word", "kitchen"]) == 0
    assert "the main map is" not in capsys.readouterr().out
    assert load_map(tmp_path / "b" / "map.yaml") == result.grid


@pytest.mark.parametrize(
    ("origin", "resolution", "shape"),
    [
        ((1.0, -2.5, 0.0), 0.025, (2 * H, 2 * W)),  # the map saved again with another origin
        ((1.5, -2.0, 0.0), 0.02, (2 * H, 2 * W)),  # another resolution
        ((1.5, -2.0, 0.0), 0.025, (2 * H + 6, 2 * W)),  # mapped further: 3 fit cells taller
    ],
)
def test_a_main_map_the_fit_was_not_coarsened_from_is_refused(
    fit, tmp_path, capsys, origin, resolution, shape
):
    """A coarse fit written before robot_map.yaml takes its data folder's map as Nav2's main
    map; saved again since the fit (a new SLAM run: another origin, resolution or size), it was
    written beside masks on the fit's cells, which then lay shifted on it in Nav2, without a
    word (navigate refuses it). Now refused, naming the map and both geometries, nothing
    written; as is a fit's own robot_map.yaml that does not match its grid."""
    from spcopyro.config import DataPreparation

    result = SpCoResult.load(fit)
    moved = OccupancyGrid(np.full(shape, FREE, dtype=np.int8), resolution, origin)
    save_map(moved, tmp_path / "data" / "map" / "flat.yaml")
    source = {"data": str(tmp_path / "data" / "flat"), "house": "flat"}
    older = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.05),
                                provenance={"source": source})  # fmt: skip
    folder = older.save(tmp_path / "older")
    out = tmp_path / "nav2"
    assert main(["export", str(folder), "--nav2", str(out), "--word", "kitchen"]) == 2
    err = capsys.readouterr().err
    assert f"map {tmp_path / 'data' / 'map' / 'flat.yaml'} is not the map" in err, err
    assert f"origin ({origin[0]:g}, {origin[1]:g}), {resolution:g} m cells" in err, err
    assert f"the fit's grid origin (1.5, -2), 0.05 m cells, {H} x {W}" in err, err
    assert not out.exists()
    save_map(moved, fit / "robot_map.yaml")  # the fit's own copy, replaced
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen"]) == 2
    assert f"map {fit / 'robot_map.yaml'} is not the map" in capsys.readouterr().err
    assert not out.exists()


def test_several_speed_words_warn_that_their_filters_share_one_topic(fit, tmp_path, capsys):
    out = tmp_path / "speed2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", "bed",
                 "--mode", "speed"]) == 0  # fmt: skip
    assert "2 speed filters publish on one speed_limit topic" in capsys.readouterr().err
    assert main(["export", str(fit), "--nav2", str(tmp_path / "one"), "--word", "kitchen",
                 "--mode", "speed"]) == 0  # fmt: skip
    assert "speed_limit topic" not in capsys.readouterr().err


def test_keepout_refuses_speed_options_and_warns_of_an_empty_mask(fit, tmp_path, capsys):
    """QA: --mode keepout --min-speed 10 was accepted and ignored (--threshold with --mode
    speed is an error), and a --threshold no cell reaches wrote a mask of 0 cells, exit 0,
    without a word."""
    out = tmp_path / "n"
    for extra, said in (
        (["--min-speed", "10"], "error: --min-speed applies to --mode speed only"),
        (["--max-speed", "90"], "error: --max-speed applies to --mode speed only"),
        (["--min-speed", "10", "--max-speed", "90"],
         "error: --min-speed and --max-speed apply to --mode speed only"),
    ):  # fmt: skip
        assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", *extra]) == 2
        assert said in capsys.readouterr().err, extra
    assert not out.exists()
    highest = where_probability(SpCoResult.load(fit), "kitchen", "area").max()
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen",
                 "--threshold", "0.99999"]) == 0  # fmt: skip
    printed = capsys.readouterr()
    assert "keepout mask for 'kitchen' (per-cell probability): 0 of" in printed.out
    assert (
        "warning: 'kitchen': the mask keeps out no cell: no free cell's probability of being "
        f"the place reaches --threshold 0.99999 (the highest is {highest:.4g}); lower --threshold"
    ) in printed.err
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", "--overwrite",
                 "--threshold", str(highest * 0.99)]) == 0  # fmt: skip
    assert "keeps out no cell" not in capsys.readouterr().err


def test_one_word_written_in_several_ways_is_one_mask(tmp_path):
    """QA: `--word kitchen kitchen. ＫＩＴＣＨＥＮ` (where reads all three as 'kitchen') wrote three
    keepout masks of the one place, named keepout_kitchen, keepout_kitchen_ and keepout_word;
    and every word without ASCII letters was named 'word', 'word_', ..."""
    result = top_and_bottom()
    export = export_nav2(result, tmp_path / "a", ["kitchen", "Kitchen.", "ＫＩＴＣＨＥＮ"])
    assert [(m.word, m.name) for m in export.masks] == [("kitchen", "keepout_kitchen")]
    filters = yaml.safe_load(export.costmap_filters_yaml.read_text())
    assert filters["global_costmap"]["global_costmap"]["ros__parameters"]["filters"] == [
        "keepout_kitchen_filter"
    ]
    words = EmissionTable("words", ("台所", "café", "sofa"), result.emissions[1].probabilities)
    other = dataclasses.replace(result, emissions=(result.emissions[0], words))
    export = export_nav2(other, tmp_path / "b", ["台所", "CAFÉ", "café"], mode="speed")
    assert [(m.word, m.name) for m in export.masks] == [
        ("台所", "speed_word0"), ("café", "speed_cafe")]  # fmt: skip


def test_words_of_one_ros_name_get_readable_distinct_names(tmp_path):
    """Two words of one ROS-safe form (café and cafe) were named speed_cafe and speed_cafe_,
    whose filter was speed_cafe__filter, and rock--roll speed_rock__roll: ROS 2 names repeat
    no underscore. Now: speed_cafe, speed_cafe_2, speed_rock_roll."""
    result = top_and_bottom()
    vocabulary = ("café", "cafe", "rock--roll")
    words = EmissionTable("words", vocabulary, result.emissions[1].probabilities)
    other = dataclasses.replace(result, emissions=(result.emissions[0], words))
    export = export_nav2(other, tmp_path / "b", list(vocabulary), mode="speed")
    names = [m.name for m in export.masks]
    assert names == ["speed_cafe", "speed_cafe_2", "speed_rock_roll"]
    written = export.costmap_filters_yaml.read_text() + "".join(
        p.name + p.read_text() for p in (tmp_path / "b").glob("*.yaml")
    )
    assert "__" not in written.replace("ros__parameters", ""), written


def test_an_export_or_plan_under_a_file_says_so(fit, tmp_path, capsys):
    """QA: export --nav2 FILE/x and navigate --out FILE/x said "cannot write in FILE ([Errno 17]
    File exists: ...)"."""
    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    for argv, option in [
        (["export", str(fit), "--word", "kitchen", "--nav2"], "--nav2"),
        (["navigate", str(fit), "kitchen", "--start", "1.6,-1.9", "--out"], "--out"),
    ]:
        out = taken / "x"
        assert main([*argv, str(out)]) == 2
        assert f"error: {option} {out}: {taken} is a file, not a folder" in capsys.readouterr().err
    assert taken.read_text() == "mine"


def test_words_of_one_place_are_warned_their_masks_are_the_same(tmp_path, capsys):
    """Two words whose where-answer is one concept got two identical keepout masks and nothing
    said: each mask now warns, naming the other word (the library's warnings and the CLI's)."""
    result = top_and_bottom()
    w = np.array([[0.5, 0.1, 0.4], [0.1, 0.7, 0.2]])  # [L, V]: sofa now the kitchen's concept
    result = dataclasses.replace(
        result, emissions=(result.emissions[0], EmissionTable("words", WORDS, w))
    )
    export = export_nav2(result, tmp_path / "nav2", ["kitchen", "sofa", "bed"])
    kitchen, sofa, bed = export.masks
    assert kitchen.concept == sofa.concept == 0 and bed.concept == 1
    assert any("the same place as 'sofa' (concept 0)" in x for x in kitchen.warnings)
    assert any("the same place as 'kitchen' (concept 0)" in x for x in sofa.warnings)
    assert not any("same place" in x for x in bed.warnings)
    record = json.loads((tmp_path / "nav2" / "nav2_export.json").read_text())["masks"][1]
    assert any("the same place as 'kitchen'" in x for x in record["warnings"])


@pytest.mark.parametrize(
    ("shift", "same"),
    [(0.0, True), (1e-10, True), (4e-7, True), (4.9e-5, True), (1e-3, False), (0.05, False)],
)
def test_nav2_and_placement_agree_on_what_a_coarsening_is(shift, same):
    """check_robot_map (the robot's map in `export --nav2`) and free_block_of_map_cells (a
    coarse grid against the map it keeps) each checked the coarsening with an origin tolerance
    of its own, 1e-9 m and exact: a grid 1e-10 m off was the robot map's coarsening to one and
    not to the other. One function (spcopyro.maps.coarse.is_coarsening) now decides, within a
    thousandth of a map cell (5e-5 m at 0.05 m): ROS 1's map_saver's 6-decimal rounding of the
    origin (up to 5e-7 m) passes, a shift of a fiftieth of a cell does not."""
    from spcopyro.maps.coarse import coarsen_grid, free_block_of_map_cells
    from spcopyro.robot.nav2 import check_robot_map

    fine = OccupancyGrid(np.full((7, 10), FREE, dtype=np.int8), 0.05, (1.5, -2.0, 0.0))
    moved = dataclasses.replace(fine, origin=(1.5 + shift, -2.0 - shift, 0.0))
    coarse = coarsen_grid(fine, 3)  # keeps fine as its coarsened_from
    kept_moved = dataclasses.replace(coarse, coarsened_from=moved)  # as fit --init-from sets it
    verdicts = []
    for check in (
        lambda: check_robot_map(coarse, moved),
        lambda: free_block_of_map_cells(kept_moved),
    ):
        try:
            check()
            verdicts.append(True)
        except ValueError:
            verdicts.append(False)
    assert verdicts == [same, same]


def test_a_robot_map_saved_again_by_ros1_map_saver_is_the_fits(tmp_path):
    """ROS 1's map_saver writes the origin with printf's %f (6 decimals): the robot's map saved
    again by it lies up to 5e-7 m from the fit's grid's origin, and `export --nav2` refused it
    as "not the map the fit's cells were coarsened from" (an absolute tolerance of 1e-9 m)."""
    from spcopyro.maps.coarse import coarsen_grid
    from spcopyro.robot.nav2 import check_robot_map

    fine = OccupancyGrid(
        np.full((7, 10), FREE, dtype=np.int8), 0.05, (-12.3456789, 3.14159265, 0.0)
    )
    path = save_map(fine, tmp_path / "robot_map.yaml")
    doc = yaml.safe_load(path.read_text())
    doc["origin"] = "[{:f}, {:f}, {:f}]".format(*fine.origin)  # as map_saver writes it (%f)
    path.write_text("".join(f"{key}: {value}\n" for key, value in doc.items()))
    resaved = load_map(path)
    assert resaved.origin != fine.origin
    check_robot_map(coarsen_grid(fine, 5), resaved)  # no error


@pytest.mark.parametrize("fit_on_resaved", [False, True])
def test_a_robot_map_whose_resolution_map_saver_rounded_is_the_fits(tmp_path, fit_on_resaved):
    """ROS 1's map_saver writes the resolution with %f too: a map of 0.05 / 3 m cells saved again
    by it reads 0.016667 m (relative 2e-5 off), and `export --nav2` refused it against the
    fit's 0.25 m grid (15 cells a side) as "not the map the fit's cells were coarsened from"
    (relative 1e-9), either way round. The resolution now has the origin's tolerance, a
    thousandth of a cell: a map 0.2 % finer is still refused."""
    from spcopyro.maps.coarse import coarsen_grid, free_block_of_map_cells
    from spcopyro.robot.nav2 import check_robot_map

    fine = OccupancyGrid(np.full((31, 47), FREE, dtype=np.int8), 0.05 / 3, (-1.2345678, 0.5, 0.0))
    path = save_map(fine, tmp_path / "robot_map.yaml")
    doc = yaml.safe_load(path.read_text())
    doc["resolution"] = f"{fine.resolution:f}"  # as map_saver writes it (%f)
    doc["origin"] = "[{:f}, {:f}, {:f}]".format(*fine.origin)
    path.write_text("".join(f"{key}: {value}\n" for key, value in doc.items()))
    resaved = load_map(path)
    assert resaved.resolution == 0.016667
    fitted_on, robot_map = (resaved, fine) if fit_on_resaved else (fine, resaved)
    coarse = coarsen_grid(fitted_on, 15)
    check_robot_map(coarse, robot_map)  # no error
    placed = free_block_of_map_cells(dataclasses.replace(coarse, coarsened_from=robot_map))
    assert (placed >= 0).all()
    finer = dataclasses.replace(robot_map, resolution=robot_map.resolution * 0.998)
    with pytest.raises(ValueError, match="not the map the fit's"):
        check_robot_map(coarse, finer)


def test_the_mask_lines_say_what_the_counted_cells_get(fit, tmp_path, capsys):
    """`export`'s line for a mask counts cells: a keepout mask's are kept out, a speed mask's
    slowed, and it gives the limits the mask sets on them. Before, the speed line read "631 of
    860 free cells" with no word of what they get (room1ldk5's 'sofa', whose p(cell is the
    place) is at most 0.42: every limit lies between 71 and 99 %, nowhere near --min-speed)."""
    assert main(["export", str(fit), "--nav2", str(tmp_path / "k"), "--word", "kitchen"]) == 0
    assert "(concept 0): 114 of 228 free cells kept out -> " in capsys.readouterr().out
    assert main(["export", str(fit), "--nav2", str(tmp_path / "s"), "--word", "kitchen",
                 "--mode", "speed", "--min-speed", "20", "--max-speed", "90"]) == 0  # fmt: skip
    limit = np.rint(90 - 70 * where_probability(SpCoResult.load(fit), "kitchen"))  # [N]
    assert 20 < limit.min() < limit.max() < 90  # p neither 0 nor 1: every free cell slowed
    assert (
        f"speed mask for 'kitchen' (per-cell probability): 228 of 228 free cells slowed, to "
        f"{limit.min():.0f}-{limit.max():.0f}% of the maximum speed (90% where p(cell is the "
        "place) = 0, down "
        "to 20% where it is 1) -> "
    ) in capsys.readouterr().out
