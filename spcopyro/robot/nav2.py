r"""A fitted semantic map as Nav2 costmap-filter masks: keep out of a word's place, or slow down
in it.

Nav2's costmap filters read a *filter mask* (a map_server map, published by a second
``map_server`` node) and a ``nav2_msgs/CostmapFilterInfo`` message (published by a
``costmap_filter_info_server`` node) that says how to decode it:
``filter_value = base + multiplier * mask_value`` for mask values 0..100 (Nav2 documentation:
"Navigating with Keepout Zones", "Navigating with Speed Limits", "Costmap Filter Info Server").
:func:`export_nav2` writes, for each word, such a mask and the parameters of both nodes:

**Keepout** (``type: 0``, ``base: 0.0``, ``multiplier: 1.0``: the mask value is the cost, 100 =
lethal, 0 = free). The word's place -- by default the region of the where-answer
(:meth:`SpCoResult.where <spcopyro.results.result.SpCoResult.where>`, eq. 19 with the area prior),
or, with ``threshold``, the free cells whose probability of belonging to the word's place
(:func:`~spcopyro.results.uncertainty.where_probability`) is at least ``threshold`` -- gets 100,
every other cell -1, no information: the KeepoutFilter leaves such a costmap cell alone, while
it writes a mask's 0 into a cell that has no information (``keepout_filter.cpp``: ``data >
old_data || old_data == NO_INFORMATION``), which made the map's unknown space free.

**Speed** (``type: 1``: the filter value is a speed limit in percent of the robot's maximum;
``base: 100.0``, ``multiplier: -1.0``, as in Nav2's speed-filter tutorial, so the limit is
``100 - mask`` and darker pixels are slower). A free cell whose probability of belonging to the
word's place is p gets the limit

.. math::

    s(p) = s_\max - (s_\max - s_\min)\, p \quad\text{(percent, rounded to 1\%)},

non-increasing in p; its mask value is ``100 - s(p)``. A value of 0 means *no limit* to the
SpeedFilter, which is also what ``s = 100%`` means, so the encoding has no gap. Non-free cells
get 0.

The speed mask is written in ``mode: scale`` with ``free_thresh: 0.0``, ``occupied_thresh: 1.0``
(:func:`spcopyro.maps.save_filter_mask`): pixel lightness maps linearly onto 0..100. The keepout
mask, which needs -1, is written in ``mode: trinary`` as map_saver writes a map (pixels 0, 254,
205; thresholds 0.65, 0.196): the Nav2 keepout tutorial's mask is a copy of the map.
Every mask has the fitted map's resolution and origin (yaw 0) and its size, the image's first row
being the map's top.

The export folder holds ``map.yaml``/``map.pgm`` (the occupancy map the fit used, or for a
coarse fit the robot's map it was coarsened from, ``robot_map``),
``semantic_map.yaml``/``.pgm``/``.labels.json`` (the concept labels, ``mode: raw``),
``MODE_WORD.yaml``/``.pgm`` (a mask), ``MODE_WORD_params.yaml`` (the ``ros__parameters`` of
the mask server ``MODE_WORD_mask_server`` and of ``MODE_WORD_filter_info_server``),
``costmap_filters.yaml`` (the costmap plugin entries to merge into ``nav2_params.yaml``; not
written without a word, which has none) and ``nav2_export.json`` (what was exported, from which
fit, with which settings).

**Nodes in a namespace.** ROS 2 gives a node the parameters of a params file's key that matches
its fully qualified name, a key without a leading ``/`` read as one with it (rclcpp
``parameter_map_from``); nested keys join with ``/``. ``MODE_WORD_params.yaml`` is keyed by the
bare node names, as Nav2's own params files are: it applies to nodes started in no namespace.
Passed unchanged (``--params-file``, launch_ros ``parameters=[file]``) to nodes started in a
namespace (``/robot1/MODE_WORD_mask_server``), it applies to **neither node, silently**: wrap it
in the namespace first, as Nav2's launch files do (``RewrittenYaml(root_key=namespace)``,
nav2_bringup and ``nav2_costmap_filters_demo``'s ``costmap_filter_info.launch.py``), which keys
it ``robot1/MODE_WORD_mask_server``. A wildcard key (``/**/NAME``) would reach them unwrapped on
Humble and later (rclcpp pull request 1839) but not with ``RewrittenYaml`` (``robot1//**/NAME``:
rcl refuses a repeated ``/``), on Foxy or Galactic, or in a component container before
launch_ros pull request 465 (Humble's, Nav2's default composition), so it is not used.
``costmap_filters.yaml``'s entries are merged into ``nav2_params.yaml`` and follow its keys.
Every topic is absolute (in the export's ``namespace``): none depends on the nodes' namespace.
"""

from __future__ import annotations

import json
import os
import re
import unicodedata
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from spcopyro._util.number_checks import is_number
from spcopyro._util.outputs import stage_marked_folder
from spcopyro.maps import OccupancyGrid, save_filter_mask, save_label_map_server, save_map
from spcopyro.maps.coarse import is_coarsening
from spcopyro.results.result import SpCoResult
from spcopyro.results.semantic_map import word_index
from spcopyro.results.uncertainty import where_probability
from spcopyro.results.where import DEFAULT_WHERE_PRIOR

__all__ = [
    "DEFAULT_MAX_SPEED",
    "DEFAULT_MIN_SPEED",
    "EXPORT_MARKER",
    "FILTER_TYPES",
    "MODES",
    "ExportedMask",
    "Nav2Export",
    "check_robot_map",
    "export_nav2",
    "keepout_values",
    "speed_percent",
    "speed_values",
    "word_place",
]

MODES = ("keepout", "speed")
FILTER_TYPES = {"keepout": 0, "speed": 1}
"""``CostmapFilterInfo.type``: 0 keepout zones / preferred lanes, 1 speed limit in percent."""
MASK_MODES = {"keepout": "trinary", "speed": "scale"}
"""The map_server ``mode`` each filter's mask is written in (module docstring)."""
BASE_MULTIPLIER = {"keepout": (0.0, 1.0), "speed": (100.0, -1.0)}
"""(base, multiplier) of ``filter_value = base + multiplier * mask_value`` per mode."""
DEFAULT_MIN_SPEED, DEFAULT_MAX_SPEED = 30.0, 100.0
"""Percent of the maximum speed at probability 1 and 0 of being in the word's place."""
EXPORT_MARKER = "nav2_export.json"
"""A folder holding it was written by :func:`export_nav2`: the only kind ``overwrite`` replaces."""
SPEED_LIMIT_TOPIC = "/speed_limit"
PARAMS_NAMESPACE_NOTE = (
    "Keyed by node name in no namespace: for nodes started in a namespace NS, wrap this\n"
    "file under NS (nav2_common RewrittenYaml(root_key=NS), as Nav2's launch files do),\n"
    "or ROS 2 gives neither node these parameters"
)
"""The header lines of a mask's params file on its keys (module docstring, nodes in a
namespace): given unwrapped to nodes in a namespace, ROS 2 applies none of it, silently."""


# ---------------------------------------------------------------------------------------------
# Mask values
# ---------------------------------------------------------------------------------------------


def word_place(
    result: SpCoResult,
    word: str,
    *,
    prior: str = DEFAULT_WHERE_PRIOR,
    threshold: float | None = None,
) -> np.ndarray:
    """[H, W] bool the word's place: the where-answer's region, or (``threshold`` in (0, 1]) the
    free cells whose :func:`~spcopyro.results.uncertainty.where_probability` is at least
    ``threshold``.
    Raises :class:`~spcopyro.results.semantic_map.UnknownWordError` (naming close words) for a word
    outside the vocabulary."""
    if threshold is None:
        return np.asarray(result.where(word, prior=prior).region, dtype=bool)
    _check_threshold(threshold)
    probability = where_probability(result, word, prior)  # [N]
    place = np.zeros(result.grid.shape, dtype=bool)  # [H, W]
    place[result.grid.free] = probability >= threshold  # free cells in free_index order
    return place


def keepout_values(place: np.ndarray) -> np.ndarray:
    """[H, W] int8 keepout mask values: 100 (lethal) on ``place`` ([H, W] bool), -1 (no
    information: the costmap's own cell stays) elsewhere (module docstring)."""
    return np.where(np.asarray(place, dtype=bool), 100, -1).astype(np.int8)


def speed_percent(
    probability: np.ndarray,
    min_speed: float = DEFAULT_MIN_SPEED,
    max_speed: float = DEFAULT_MAX_SPEED,
) -> np.ndarray:
    """[N] speed limit in percent, ``max - (max - min) p``, rounded to whole percent, for the
    ``[N]`` probabilities ``p`` of being in the word's place (module docstring)."""
    _check_speeds(min_speed, max_speed)
    p = np.clip(np.asarray(probability, dtype=np.float64), 0.0, 1.0)
    return np.rint(max_speed - (max_speed - min_speed) * p)


def speed_values(
    result: SpCoResult,
    word: str,
    *,
    prior: str = DEFAULT_WHERE_PRIOR,
    min_speed: float = DEFAULT_MIN_SPEED,
    max_speed: float = DEFAULT_MAX_SPEED,
) -> tuple[np.ndarray, np.ndarray]:
    """([H, W] int8 speed mask values ``100 - limit`` (0 off free space: no limit), [N] the
    probabilities of the word's place they come from)."""
    probability = where_probability(result, word, prior)  # [N]
    percent = speed_percent(probability, min_speed, max_speed)  # [N]
    values = np.zeros(result.grid.shape, dtype=np.int8)  # [H, W]
    values[result.grid.free] = (100.0 - percent).astype(np.int8)
    return values, probability


def _check_threshold(threshold: float) -> None:
    if not (is_number(threshold) and 0.0 < threshold <= 1.0):
        raise ValueError(f"the place's probability threshold must lie in (0, 1], got {threshold!r}")


MIN_SPEED_LIMIT = 1.0
"""Percent: the smallest speed limit a mask may set. Nav2 reads a limit of 0 as "no speed
limit" (``NO_SPEED_LIMIT``), so a limit rounded to 0 % would let the robot drive at full speed
exactly where the word's place is (issue 24 item 2)."""


def _check_speeds(min_speed: float, max_speed: float) -> None:
    flag = isinstance(min_speed, bool | np.bool_) or isinstance(max_speed, bool | np.bool_)
    if flag or not (MIN_SPEED_LIMIT <= min_speed <= max_speed <= 100.0):
        raise ValueError(
            "speed limits must satisfy 1 <= min <= max <= 100 (percent of the maximum speed; "
            "Nav2 reads a 0 % limit as no limit at all), "
            f"got min {min_speed!r}, max {max_speed!r}"
        )


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ExportedMask:
    """One word's mask and the nodes that serve it."""

    word: str
    mode: str
    name: str
    """``MODE_WORD``: the files' stem and the prefix of the nodes and topics."""
    mask_yaml: Path
    params_yaml: Path
    cells: int
    """Free cells with a positive mask value (kept out of, or slowed down in)."""
    concept: int | None = None
    """The where-answer's concept (keepout without a threshold)."""
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class Nav2Export:
    """What :func:`export_nav2` wrote."""

    out: Path
    map_yaml: Path
    semantic_map_yaml: Path
    costmap_filters_yaml: Path | None
    """The costmap plugin entries; None when no word was exported (no filter to merge: an
    export without a word wrote an empty ``{}`` file and pointed the user at it)."""
    masks: tuple[ExportedMask, ...] = field(default_factory=tuple)


MAX_NAME_CHARS = 64
"""The most characters of a word a mask's name keeps (a 300-letter word made a file name over
the file system's limit of 255 bytes, and the export failed)."""


def _ros_name(word: str, index: int) -> str:
    """A ROS-name-safe form of the vocabulary's word ``index``: lower case, ``[a-z0-9_]`` only,
    accents dropped (``café``: ``cafe``), no repeated underscore (``rock--roll``: ``rock_roll``;
    ROS 2's naming article discourages one, though its validator accepts it), at most
    :data:`MAX_NAME_CHARS` characters; ``word3`` for one with no such letter (``台所``)."""
    ascii_word = unicodedata.normalize("NFKD", word.lower()).encode("ascii", "ignore").decode()
    name = re.sub(r"[^a-z0-9]+", "_", ascii_word).strip("_")
    return name[:MAX_NAME_CHARS].rstrip("_") or f"word{index}"


def mask_names(mode: str, words: list[str], indices: list[int]) -> list[str]:
    """Each word's mask name ``MODE_WORD`` (:func:`_ros_name` of the vocabulary's word
    ``indices[k]``), its files ``NAME.yaml``, ``NAME.pgm`` and ``NAME_params.yaml``, distinct:
    a second word of one name (``café`` beside ``cafe``) gets ``_2``, ``_3``, ... (``cafe_2``),
    and so does a name whose files another's would replace (``x`` beside ``x params``, whose
    mask ``MODE_x_params.yaml`` is ``x``'s params file)."""
    taken: set[str] = set()  # the file stems of the names given so far
    names: list[str] = []
    for word, index in zip(words, indices, strict=True):
        base = name = f"{mode}_{_ros_name(word, index)}"
        k = 1
        while name in taken or f"{name}_params" in taken:  # café and cafe: cafe, cafe_2
            k += 1  # (was cafe_, whose filter was cafe__filter: ROS 2's article discourages "__")
            name = f"{base}_{k}"
        names.append(name)
        taken.update((name, f"{name}_params"))
    return names


def topic(name: str, namespace: str | None = None) -> str:
    """The absolute topic ``/NAME``, or ``/NAMESPACE/NAME`` for a robot in a namespace (the
    filters' topics must follow the robot's namespace: issue 24 item 3)."""
    return f"/{namespace.strip('/')}/{name}" if namespace and namespace.strip("/") else f"/{name}"


def check_namespace(namespace: str | None) -> str | None:
    """A ROS namespace (``robot1``, ``/fleet/robot1``, ``/fleet/_robot1``), stripped of its outer
    slashes; None or empty: none. ValueError for a name refused by the character and part rules
    of ROS 2's ``rmw_validate_namespace`` (its length limit is not checked): a character other
    than letters, digits, ``_`` and ``/``, an empty part (``//``) or a part starting with a digit.
    A part may start with ``_`` (a hidden namespace, which was refused here) or hold ``__`` (ROS 2
    accepts both)."""
    if namespace is None or not namespace.strip("/"):
        return None
    clean = namespace.strip("/")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*", clean):
        raise ValueError(
            f"namespace {namespace!r}: ROS 2 namespaces are letters, digits and underscores, "
            "parts separated by single slashes, none starting with a digit"
        )
    return clean


_FRAME_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_/")


def check_frame(frame: str) -> str:
    """A tf frame id (letters, digits, ``_``, ``/``, not starting with ``/``); ValueError
    otherwise."""
    if not frame or not set(frame) <= _FRAME_CHARS or frame.strip("/") == "":
        raise ValueError(f"frame {frame!r}: a tf frame id is letters, digits, _ and /")
    if frame.startswith("/"):  # tf2 refuses such a goal's frame_id: the plan would not run
        raise ValueError(
            f"frame {frame!r}: tf2 frame ids cannot start with '/' (tf2 refuses them); use "
            f"{frame.lstrip('/')!r}"
        )
    return frame


def check_robot_map(grid: OccupancyGrid, robot_map: OccupancyGrid) -> None:
    """Refuse a ``robot_map`` that ``grid`` (a coarse fit's) was not coarsened from: its origin,
    a whole number of its cells a side of ``grid``'s and ``grid``'s size in those blocks
    (:func:`spcopyro.maps.coarse.is_coarsening`, the origin within a thousandth of its cell)
    must hold, else the masks, on ``grid``, would lie shifted or scaled on Nav2's main map (a
    data folder's map saved again after the fit, by a new SLAM run with another origin, say).

    Raises:
        ValueError: naming the map's file and both grids' origin, resolution and size.
    """
    if is_coarsening(grid, robot_map):
        return

    def geometry(g: OccupancyGrid) -> str:
        return (f"origin ({g.origin[0]:g}, {g.origin[1]:g}), {g.resolution:g} m cells, "
                f"{g.height} x {g.width}")  # fmt: skip

    raise ValueError(
        f"map {robot_map.source or '(given)'} is not the map the fit's {grid.resolution:g} m "
        f"cells were coarsened from: {geometry(robot_map)}, the fit's grid {geometry(grid)}; "
        "its masks would lie off place on it in Nav2: give the map the fit was made on (as its "
        "robot_map.yaml), or fit again on this one"
    )


def mask_params(
    mode: str, name: str, mask_yaml: Path, namespace: str | None = None, frame: str = "map"
) -> dict[str, object]:
    """The ``ros__parameters`` of the mask's ``map_server`` and ``costmap_filter_info_server``
    nodes, as one params file (Nav2 keepout / speed-filter tutorials, step 2); their topics in
    the robot's ``namespace`` when one is given, the mask in tf frame ``frame`` (the robot's
    global frame, ``robot1/map`` for a robot whose frames carry a prefix)."""
    base, multiplier = BASE_MULTIPLIER[mode]
    mask_topic = topic(f"{name}_filter_mask", namespace)
    return {
        f"{name}_mask_server": {
            "ros__parameters": {
                "frame_id": frame,
                "topic_name": mask_topic,
                "yaml_filename": str(mask_yaml),
            }
        },
        f"{name}_filter_info_server": {
            "ros__parameters": {
                "type": FILTER_TYPES[mode],
                "filter_info_topic": topic(f"{name}_filter_info", namespace),
                "mask_topic": mask_topic,
                "base": base,
                "multiplier": multiplier,
            }
        },
    }


def costmap_filters(
    masks: list[tuple[str, str]], namespace: str | None = None
) -> dict[str, object]:
    """The costmap entries (``filters`` list and one plugin per mask) for ``nav2_params.yaml``:
    keepout filters in the global and the local costmap (plans avoid the place, and the
    controller does not drive in), speed filters in the global costmap only (Nav2: never in
    both, or the limit flips at every boundary). ``masks``: (mode, name) pairs."""
    costmaps: dict[str, dict[str, object]] = {"global_costmap": {}, "local_costmap": {}}
    for mode, name in masks:
        info = topic(f"{name}_filter_info", namespace)
        plugin: dict[str, object] = {"enabled": True, "filter_info_topic": info}
        if mode == "keepout":
            plugin = {"plugin": "nav2_costmap_2d::KeepoutFilter", **plugin}
            targets = ("global_costmap", "local_costmap")
        else:
            plugin = {
                "plugin": "nav2_costmap_2d::SpeedFilter",
                **plugin,
                "speed_limit_topic": topic(SPEED_LIMIT_TOPIC.lstrip("/"), namespace),
            }
            targets = ("global_costmap",)
        for costmap in targets:
            costmaps[costmap][f"{name}_filter"] = dict(plugin)  # no shared node: no yaml alias
    document: dict[str, object] = {}
    for costmap, plugins in costmaps.items():
        if plugins:
            parameters = {"filters": list(plugins), **plugins}
            document[costmap] = {costmap: {"ros__parameters": parameters}}
    return document


def grid_record(grid: OccupancyGrid) -> dict[str, object]:
    """Where the grid lies and how big it is, for a JSON summary (resolution, origin, size)."""
    return {
        "resolution": grid.resolution,
        "origin": list(grid.origin),
        "height": grid.height,
        "width": grid.width,
    }


def write_commented_yaml(path: Path, document: dict[str, object], comment: str) -> None:
    """``document`` as block YAML in its own key order, under ``comment`` as ``#`` lines."""
    text = yaml.safe_dump(document, sort_keys=False, default_flow_style=False)
    header = "".join(f"# {line}\n" for line in comment.splitlines())
    path.write_text(header + text, encoding="utf-8")


def _warn_of_shared_places(
    masks: list[ExportedMask], records: list[dict[str, object]]
) -> tuple[list[ExportedMask], list[dict[str, object]]]:
    """Each keepout mask whose where-answer's concept another word's shares, with a warning
    naming them: the map does not tell those places apart, so their masks are the same cells
    (two identical masks came back with nothing said)."""
    words_of: dict[int, list[str]] = {}
    for mask in masks:
        if mask.concept is not None:
            words_of.setdefault(mask.concept, []).append(mask.word)
    shared_masks, shared_records = [], []
    for mask, record in zip(masks, records, strict=True):
        sharing = [] if mask.concept is None else words_of[mask.concept]
        others = [w for w in sharing if w != mask.word]
        if others:
            warning = (
                f"the same place as {', '.join(map(repr, others))} (concept {mask.concept}): "
                "the semantic map does not tell them apart, so their masks are the same cells"
            )
            mask = replace(mask, warnings=(*mask.warnings, warning))
            record = {**record, "warnings": [*record["warnings"], warning]}  # type: ignore[misc]
        shared_masks.append(mask)
        shared_records.append(record)
    return shared_masks, shared_records


def export_nav2(
    result: SpCoResult,
    out: str | os.PathLike[str],
    words: tuple[str, ...] | list[str] = (),
    *,
    mode: str = "keepout",
    prior: str = DEFAULT_WHERE_PRIOR,
    threshold: float | None = None,
    min_speed: float = DEFAULT_MIN_SPEED,
    max_speed: float = DEFAULT_MAX_SPEED,
    overwrite: bool = False,
    source: str | os.PathLike[str] | None = None,
    namespace: str | None = None,
    robot_map: OccupancyGrid | None = None,
    frame: str = "map",
) -> Nav2Export:
    """Write ``result``'s map, semantic map and one ``mode`` mask per word into ``out`` (module
    docstring), whole or not at all (a staging folder beside ``out``, renamed when done).

    Args:
        result: the fit (:meth:`SpCoResult.load`).
        out: the export folder; a non-empty one needs ``overwrite`` and must be an export's.
        words: the words to export, each read as ``spcopyro where`` reads it
            (:func:`~spcopyro.results.semantic_map.word_key`) and exported once.
        mode: ``"keepout"`` or ``"speed"``.
        prior: p(C) of the where-answer (``"area"`` or ``"pi"``).
        threshold: keepout only: the place is the cells whose probability of being the word's
            place is at least this, instead of the where-answer's region.
        min_speed, max_speed: speed only: the limits (percent) at probability 1 and 0.
        overwrite: replace an earlier export in ``out``.
        source: the fit's folder (recorded in ``nav2_export.json``).
        namespace: the robot's ROS namespace: the masks', filter infos' and speed limit's
            topics are put in it (``/NS/speed_kitchen_filter_mask``); None: absolute topics.
        robot_map: the map a coarse fit's grid was coarsened from (its ``robot_map.yaml``),
            written as Nav2's main ``map.yaml`` in place of the fit's grid, whose thickened
            walls can close doorways; the semantic map and the masks stay on the fit's grid
            (a costmap filter mask is a map of its own: Nav2 reads it at its resolution).
            None: the fit's grid is the main map.
        frame: the tf frame of the masks (their mask servers' ``frame_id``): the map frame of
            the robot's tf tree, ``robot1/map`` for a robot whose frames carry a prefix (a
            costmap filter transforms its mask from this frame into the costmap's global frame,
            so a frame missing from the tree leaves the filter without a mask).

    Raises:
        UnknownWordError: a word outside the vocabulary (with the closest known words); nothing
            is written.
        ValueError: a bad mode, threshold or speed; OutputError (a ValueError) for ``out``.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if threshold is not None:
        if mode != "keepout":
            raise ValueError("a probability threshold applies to keepout masks only")
        _check_threshold(threshold)
    _check_speeds(min_speed, max_speed)
    namespace = check_namespace(namespace)
    frame = check_frame(frame)
    if robot_map is not None:
        check_robot_map(result.grid, robot_map)
    # every word known before anything is written, and each read as `where` reads it: "Kitchen",
    # "kitchen." and a full-width "ｋｉｔｃｈｅｎ" are one word, one mask (each got its own)
    indices = list(dict.fromkeys(word_index(result.vocabulary, w) for w in words))
    words = [result.vocabulary[i] for i in indices]
    names = mask_names(mode, words, indices)

    staged = stage_marked_folder(
        out, overwrite, option="--nav2", marker=EXPORT_MARKER, writer="Nav2 export"
    )
    with staged:
        folder, final = staged.path, staged.out
        grid = result.grid
        main_map = grid if robot_map is None else robot_map
        map_yaml = save_map(main_map, folder / "map.yaml")
        semantic_yaml = save_label_map_server(result.label_image(), grid,
                                              folder / "semantic_map.yaml")  # fmt: skip
        masks: list[ExportedMask] = []
        records: list[dict[str, object]] = []
        for word, name in zip(words, names, strict=True):
            concept, warnings = None, ()
            if mode == "keepout":
                if threshold is None:
                    answer = result.where(word, prior=prior)
                    concept, warnings = answer.concept, answer.warnings
                values = keepout_values(word_place(result, word, prior=prior,
                                                   threshold=threshold))  # fmt: skip
            else:
                values, _ = speed_values(result, word, prior=prior, min_speed=min_speed,
                                         max_speed=max_speed)  # fmt: skip
            mask_yaml = save_filter_mask(values, grid, folder / f"{name}.yaml",
                                         MASK_MODES[mode])  # fmt: skip
            params_yaml = folder / f"{name}_params.yaml"
            write_commented_yaml(
                params_yaml,
                mask_params(mode, name, final / mask_yaml.name, namespace, frame),
                f"Nav2 {mode} filter for {word!r} (spcopyro export): params of its mask server "
                f"and costmap filter info server.\n{PARAMS_NAMESPACE_NOTE}",
            )
            cells = int((values[grid.free] > 0).sum())
            masks.append(ExportedMask(word, mode, name, final / mask_yaml.name,
                                      final / params_yaml.name, cells, concept,
                                      tuple(warnings)))  # fmt: skip
            records.append({"word": word, "name": name, "mask": mask_yaml.name,
                            "params": params_yaml.name, "cells": cells, "concept": concept,
                            "warnings": list(warnings)})  # fmt: skip
        masks, records = _warn_of_shared_places(masks, records)
        filters_yaml = folder / "costmap_filters.yaml"
        if names:  # no word: no filter, nothing to merge, no file
            write_commented_yaml(
                filters_yaml,
                costmap_filters([(mode, name) for name in names], namespace),
                "Costmap filter entries for nav2_params.yaml (spcopyro export): merge them into\n"
                "the global_costmap / local_costmap sections (Nav2 Foxy, from before the "
                "'filters'\nparameter of Galactic, lists filters under 'plugins')",
            )
        base, multiplier = BASE_MULTIPLIER[mode]
        summary = {
            "source": None if source is None else str(Path(source).resolve()),
            "mode": mode,
            "type": FILTER_TYPES[mode],
            "base": base,
            "multiplier": multiplier,
            "prior": prior,
            "threshold": threshold,
            "min_speed": min_speed if mode == "speed" else None,
            "max_speed": max_speed if mode == "speed" else None,
            "namespace": namespace,
            "frame": frame,
            "map": grid_record(main_map),
            "masks_grid": grid_record(grid),
            "masks": records,
        }
        (folder / EXPORT_MARKER).write_text(json.dumps(summary, indent=2) + "\n")
        staged.commit()
    return Nav2Export(
        out=final,
        map_yaml=final / map_yaml.name,
        semantic_map_yaml=final / semantic_yaml.name,
        costmap_filters_yaml=final / filters_yaml.name if names else None,
        masks=tuple(masks),
    )
