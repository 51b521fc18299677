"""`spcopyro export --nav2` read back as Nav2 reads it, without the package's own loaders.

Every rule below is written here from Nav2's source and documentation, so that a convention the
package gets wrong in both its writer and its reader (a row order, an origin corner, a threshold)
still shows:

* ``nav2_map_server/src/map_io.cpp`` (``loadMapYaml``, ``loadMapFromFile``): the image name is
  relative to the yaml's folder; ``shade`` = the pixel over its full scale, ``occ = negate ?
  shade : 1 - shade``; trinary: ``occupied_thresh < occ`` -> 100, ``occ < free_thresh`` -> 0,
  else -1; scale: the same, else ``rint((occ - free) / (occupied - free) * 100)``; raw:
  ``round(shade * 255)`` if in 0..100, else -1; image pixel (x, y) goes to
  ``data[width * (height - y - 1) + x]`` (the image's first row is the map's top, the origin its
  lower-left corner).
* ``nav2_util::worldToMap`` (``occ_grid_utils.hpp``): ``mx = (wx - origin_x) / resolution``
  truncated, ``resolution`` a float32 (``nav_msgs/MapMetaData``).
* ``Costmap2D(const OccupancyGrid &)`` / ``CostmapFilter::getMaskCost``: -1 -> NO_INFORMATION
  (255), else ``round(v * 254 / 100)``.
* ``keepout_filter.cpp``: a mask cell of NO_INFORMATION is skipped; otherwise written where
  ``data > old_data || old_data == NO_INFORMATION``; base and multiplier must be 0.0 and 1.0.
* ``speed_filter.cpp`` (``getSpeedLimitAtPose``): mask 0 -> no limit, -1 -> error (no limit
  published), else ``speed_limit = value * multiplier + base`` (percent for type 1), outside
  [0, 100] -> no limit.
* ROS 2 parameters: ``costmap_filter_info_server`` declares ``type`` an int and ``base`` /
  ``multiplier`` doubles (a yaml ``100`` for a double is refused as the wrong type).
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import yaml
from test_nav2 import top_and_bottom

from spcopyro.results.uncertainty import where_probability
from spcopyro.robot.nav2 import export_nav2

NO_INFORMATION, LETHAL_OBSTACLE, FREE_SPACE = 255, 254, 0


def read_p5(path) -> np.ndarray:
    """[H, W] uint8 pixels of a binary pgm, image row order (netpbm: magic, width, height,
    maxval, one whitespace, raster)."""
    data = path.read_bytes()
    match = re.match(rb"P5\s+(\d+)\s+(\d+)\s+(\d+)\s", data)
    assert match, f"{path}: not a binary pgm"
    width, height, maxval = (int(g) for g in match.groups())
    assert maxval == 255
    raster = np.frombuffer(data[match.end() :], dtype=np.uint8)
    assert raster.size == width * height
    return raster.reshape(height, width)


def map_io_load(yaml_path) -> dict:
    """The ``nav_msgs/OccupancyGrid`` map_server publishes for ``yaml_path`` (map_io.cpp)."""
    doc = yaml.safe_load(yaml_path.read_text())
    pixels = read_p5(yaml_path.parent / doc["image"]).astype(np.float64)  # [H, W] image rows
    shade = pixels / 255.0
    occ = shade if doc["negate"] else 1.0 - shade
    free, occupied = doc["free_thresh"], doc["occupied_thresh"]
    mode = doc.get("mode", "trinary")
    if mode == "raw":
        cell = np.round(shade * 255)
        cell = np.where((cell >= 0) & (cell <= 100), cell, -1)
    else:
        middle = -1 if mode == "trinary" else np.rint((occ - free) / (occupied - free) * 100.0)
        cell = np.where(occupied < occ, 100, np.where(occ < free, 0, middle))
    height, width = pixels.shape
    data = np.empty(height * width, dtype=np.int8)
    for y in range(height):  # data[width * (height - y - 1) + x] = cell of image pixel (x, y)
        data[width * (height - y - 1) : width * (height - y)] = cell[y]
    origin = doc["origin"]
    return {"width": width, "height": height, "resolution": np.float32(doc["resolution"]),
            "origin": (float(origin[0]), float(origin[1])), "data": data}  # fmt: skip


def world_to_map(grid: dict, wx: float, wy: float) -> int | None:
    """The index into ``data`` of world point (wx, wy), or None off the map
    (``nav2_util::worldToMap``)."""
    ox, oy = grid["origin"]
    if wx < ox or wy < oy:
        return None
    mx = int((wx - ox) / grid["resolution"])
    my = int((wy - oy) / grid["resolution"])
    if mx >= grid["width"] or my >= grid["height"]:
        return None
    return my * grid["width"] + mx


def cost(value: int) -> int:
    """Costmap2D's cost of an OccupancyGrid value."""
    value = int(value)
    return NO_INFORMATION if value == -1 else round(value * (LETHAL_OBSTACLE - FREE_SPACE) / 100)


# World points of the test map (13 x 20 cells of 0.05 m, origin (1.5, -2.0)): image rows 0-5
# (the kitchen, concept 0) lie at y in [-1.65, -1.35), the wall row 6 at [-1.70, -1.65), rows
# 7-12 (the bed, concept 1) at [-2.0, -1.70); image column 0 (x in [1.5, 1.55)) is unknown.
KITCHEN, BED, WALL, UNKNOWN_SPOT = (2.01, -1.39), (2.01, -1.91), (2.01, -1.67), (1.52, -1.39)
KITCHEN_CELL, BED_CELL = (0, 10), (12, 10)  # their (image row, column), from the numbers above


def free_index(result, row: int, col: int) -> int:
    """The index among the free cells (raster order) of image cell (row, col)."""
    return int(
        np.flatnonzero(result.grid.free.ravel()).tolist().index(row * result.grid.width + col)
    )


def test_keepout_export_as_map_server_and_the_keepout_filter_read_it(tmp_path):
    result = top_and_bottom()
    export = export_nav2(result, tmp_path / "nav2", ["kitchen"])
    mask_doc = yaml.safe_load(export.masks[0].mask_yaml.read_text())
    assert (mask_doc["mode"], mask_doc["negate"]) == ("trinary", 0)
    static = map_io_load(export.map_yaml)
    mask = map_io_load(export.masks[0].mask_yaml)
    assert (mask["width"], mask["height"], mask["origin"]) == (20, 13, (1.5, -2.0))

    def filtered(point):
        """The global costmap's cell at ``point``: the static layer, then the KeepoutFilter."""
        old = cost(static["data"][world_to_map(static, *point)])
        data = cost(mask["data"][world_to_map(mask, *point)])
        if data == NO_INFORMATION:
            return old
        return data if data > old or old == NO_INFORMATION else old

    assert filtered(KITCHEN) == LETHAL_OBSTACLE  # the top room is kept out of
    assert filtered(BED) == FREE_SPACE  # the bottom room stays free
    assert filtered(WALL) == LETHAL_OBSTACLE
    assert filtered(UNKNOWN_SPOT) == NO_INFORMATION  # unknown space stays unknown
    # every cell of the map: lethal exactly on the kitchen's free cells, the rest as it was
    lethal = np.array([cost(v) for v in mask["data"]]) == LETHAL_OBSTACLE  # [H * W] msg order
    region = result.where("kitchen").region[::-1].ravel()  # image rows -> msg rows (y up)
    assert np.array_equal(lethal, region)

    params = yaml.safe_load(export.masks[0].params_yaml.read_text())
    info = params["keepout_kitchen_filter_info_server"]["ros__parameters"]
    assert (info["type"], info["base"], info["multiplier"]) == (0, 0.0, 1.0)  # keepout's defaults
    _check_links(export, params, info, "KeepoutFilter")


def test_speed_export_as_map_server_and_the_speed_filter_read_it(tmp_path):
    result = top_and_bottom()
    export = export_nav2(result, tmp_path / "nav2", ["kitchen"], mode="speed", min_speed=20.0,
                         max_speed=90.0)  # fmt: skip
    mask = map_io_load(export.masks[0].mask_yaml)
    params = yaml.safe_load(export.masks[0].params_yaml.read_text())
    info = params["speed_kitchen_filter_info_server"]["ros__parameters"]
    assert info["type"] == 1  # speed limit in percent of the maximum speed

    def speed_limit(point):
        """SpeedFilter::getSpeedLimitAtPose: the percent limit at ``point``, 100 for none."""
        value = int(mask["data"][world_to_map(mask, *point)])
        assert value != -1, f"{point}: an unknown mask cell, which the SpeedFilter refuses"
        if value == 0:
            return 100.0
        limit = value * info["multiplier"] + info["base"]
        return 100.0 if not 0.0 <= limit <= 100.0 else limit

    probability = where_probability(result, "kitchen")  # [N] free cells, raster order
    for point, (row, col) in ((KITCHEN, KITCHEN_CELL), (BED, BED_CELL)):
        p = probability[free_index(result, row, col)]
        assert speed_limit(point) == np.rint(90.0 - 70.0 * p), point
    assert speed_limit(KITCHEN) < speed_limit(BED) <= 90.0  # slower in the kitchen
    assert speed_limit(WALL) == speed_limit(UNKNOWN_SPOT) == 100.0  # off free space: no limit
    assert (mask["data"] >= 0).all()  # no cell the SpeedFilter would refuse
    _check_links(export, params, info, "SpeedFilter")


def _check_links(export, params, info, plugin):
    """The nodes' parameters name one another, with the types the nodes declare."""
    mask = export.masks[0]
    server = params[f"{mask.name}_mask_server"]["ros__parameters"]
    assert server["topic_name"] == info["mask_topic"]
    assert server["frame_id"] == "map"
    assert server["yaml_filename"] == str(mask.mask_yaml)
    assert type(info["type"]) is int
    assert type(info["base"]) is float and type(info["multiplier"]) is float
    costmaps = yaml.safe_load(export.costmap_filters_yaml.read_text())
    entry = costmaps["global_costmap"]["global_costmap"]["ros__parameters"]
    assert entry["filters"] == [f"{mask.name}_filter"]
    assert entry[f"{mask.name}_filter"]["plugin"] == f"nav2_costmap_2d::{plugin}"
    assert entry[f"{mask.name}_filter"]["filter_info_topic"] == info["filter_info_topic"]
    assert entry[f"{mask.name}_filter"]["enabled"] is True


@pytest.mark.parametrize("name", ["map", "semantic_map"])
def test_the_maps_as_map_server_reads_them(tmp_path, name):
    result = top_and_bottom()
    export = export_nav2(result, tmp_path / "nav2", [])
    grid = map_io_load(tmp_path / "nav2" / f"{name}.yaml")
    assert (grid["width"], grid["height"], grid["origin"]) == (20, 13, (1.5, -2.0))
    assert grid["resolution"] == np.float32(0.05)
    at = {point: int(grid["data"][world_to_map(grid, *point)])
          for point in (KITCHEN, BED, WALL, UNKNOWN_SPOT)}  # fmt: skip
    assert (at[WALL], at[UNKNOWN_SPOT]) == (100, -1)
    if name == "map":
        assert at[KITCHEN] == at[BED] == 0
    else:  # mode raw: the concept's grey, named in the labels sidecar
        assert export.semantic_map_yaml.name == "semantic_map.yaml"
        sidecar = json.loads((tmp_path / "nav2" / "semantic_map.labels.json").read_text())
        concept = {int(g): c for g, c in sidecar["grey_to_concept"].items()}
        assert (concept[at[KITCHEN]], concept[at[BED]]) == (0, 1)


def ros2_node_parameters(document: dict, node_fqn: str) -> dict:
    """The ``ros__parameters`` a node named ``node_fqn`` (``/ns/name``) takes from a params
    file (``document``, as yaml loads it), by ROS 2's rule: ``rcl_yaml_param_parser`` joins the
    keys down to ``ros__parameters`` with ``/`` (``add_name_to_ns``: none after one ending in
    ``/``); rclcpp's ``parameter_map_from`` puts a ``/`` before a name without one, turns ``/*``
    into ``(/\\w+)`` (so ``/**`` into ``(/\\w+)*``) and keeps the keys whose name matches the
    node's whole name, later keys' values over earlier ones'."""
    taken: dict = {}

    def walk(mapping: dict, name: str) -> None:
        for key, value in mapping.items():
            if key == "ros__parameters":
                full = name if name.startswith("/") else "/" + name
                if re.fullmatch(full.replace("/*", r"(/\w+)"), node_fqn):
                    taken.update(value)
            elif isinstance(value, dict):
                walk(value, key if not name else name + ("" if name.endswith("/") else "/") + key)

    walk(document, "")
    return taken


@pytest.mark.parametrize("mode", ["keepout", "speed"])
def test_the_mask_nodes_params_reach_them_as_ros2_applies_a_params_file(tmp_path, mode):
    """A params file keyed by node name applies to nodes in no namespace, and, wrapped under
    the namespace as Nav2's launch files wrap theirs (nav2_common ``RewrittenYaml(root_key=NS)``
    in nav2_bringup and costmap_filter_info.launch.py), to nodes in it. Given unwrapped to nodes
    in a namespace it applies to neither, with no error: the file's header says what to do
    (it said nothing, and a multi-robot launch ran both servers without their parameters)."""
    export = export_nav2(top_and_bottom(), tmp_path / "nav2", ["kitchen"], mode=mode,
                         namespace="robot1")  # fmt: skip
    mask = export.masks[0]
    document = yaml.safe_load(mask.params_yaml.read_text())
    for node in (f"{mask.name}_mask_server", f"{mask.name}_filter_info_server"):
        own = document[node]["ros__parameters"]
        assert ros2_node_parameters(document, f"/{node}") == own
        wrapped = {"robot1": document}  # RewrittenYaml: {root_key: data}
        assert ros2_node_parameters(wrapped, f"/robot1/{node}") == own
        assert ros2_node_parameters(document, f"/robot1/{node}") == {}  # the documented limit
    assert ros2_node_parameters(document, f"/{mask.name}_mask_server")["topic_name"] == (
        f"/robot1/{mask.name}_filter_mask"  # the topics carry the namespace themselves
    )
    header = "".join(
        line[2:] for line in mask.params_yaml.read_text().splitlines(keepends=True)
        if line.startswith("# ")
    )  # fmt: skip
    assert "for nodes started in a namespace NS, wrap this\nfile under NS" in header
    assert "RewrittenYaml(root_key=NS)" in header
    assert "ROS 2 gives neither node these parameters" in header


def test_the_params_file_reader_follows_ros2s_wildcards():
    """The reader above against the rules it copies: ``/**`` any node, ``/**/NAME`` NAME in any
    namespace (none too), ``/*`` one level, nested keys joined."""
    document = {
        "/**": {"ros__parameters": {"a": 1}},
        "/**/node": {"ros__parameters": {"b": 2}},
        "ns": {"node": {"ros__parameters": {"c": 3}}},
        "/*/other": {"ros__parameters": {"d": 4}},
    }
    assert ros2_node_parameters(document, "/node") == {"a": 1, "b": 2}
    assert ros2_node_parameters(document, "/ns/node") == {"a": 1, "b": 2, "c": 3}
    assert ros2_node_parameters(document, "/x/y/node") == {"a": 1, "b": 2}
    assert ros2_node_parameters(document, "/x/other") == {"a": 1, "d": 4}
    assert ros2_node_parameters(document, "/other") == {"a": 1}
