r"""A simulated robot tour on *your* floor plan: ``spcopyro simulate --map MAP.yaml``.

Before recording anything, a user can test settings on their own map: :func:`simulate_on_map`
takes any map_server map, cuts its free space into rooms and places on it what a robot touring
those rooms would have observed, with the observation model of the synthetic houses
(:mod:`spcopyro.synthetic.house`, steps 4-6); :func:`write_simulated_map` writes that in the
public dataset's layout (so ``spcopyro fit`` reads it) together with the ground truth it used.

1. **Rooms.** The free space is cut into rooms by baseline (F)'s geometric room segmentation
   (:func:`spcopyro.baselines.geometry.room_segments`: a distance-transform watershed that cuts
   at doorways narrower than ``door_width``). ``door_width="auto"`` (the default) reads it from
   the map (:func:`~spcopyro.baselines.geometry.auto_door_width`: of 0.75, 1.0, ..., 3 m the
   width at which the room count rises the most); a map that stays one room (at the width
   given, or at every width ``auto`` tries) is simulated as one room, with a warning (its truth
   has one category, so ARI against it says nothing).
   Segments smaller than ``min_room_area`` (nooks, scan noise, free specks outside the walls)
   are not rooms: the robot does not visit them and their ground truth is -1 (undefined), as
   for unlabelled cells of any house.
2. **Categories.** With R rooms and n names (``categories``), the multiset of categories is
   ``i mod n`` for ``i < R`` (balanced; the first min(R, n) names are used), assigned to the rooms
   in a random order. One name for several rooms is warned of, as one room is: the truth then
   has one category.
3. **Tour, images, utterances** as in a synthetic house: in each of ``num_trials`` trials the
   robot visits every room once in a random order and takes ``images_per_room`` images at free
   cells of the room, preferring cells more than :data:`CLEARANCE` metres from any non-free
   cell; a position is its cell's centre plus a jitter of at most 0.45 cells per axis (so it
   stays on its free cell). Category c's images are place-class histograms
   f ~ Dir(kappa phi_c) over 205 classes; utterances are made at ``utterances_per_room`` of each
   visit's image positions and name the place or one of its objects
   (:data:`~spcopyro.synthetic.CATEGORY_LEXICON`; a name outside it is its own only word),
   with 5% of single words from another category.

Ground truth written beside the dataset files: ``truth.npy`` ([H, W] category per cell, -1 off
the rooms) and ``categories.json`` (as a synthetic house's), ``rooms.npy`` ([H, W] room id per
cell, -1 off the rooms) and ``rooms.json`` (per room: its category, cells and area, and the
segmentation's settings).
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from spcopyro._util.number_checks import is_positive_number
from spcopyro.baselines.geometry import (
    auto_door_width,
    counts_as_room,
    room_count,
    room_segments,
)
from spcopyro.data import House, save_house
from spcopyro.maps import UNKNOWN, OccupancyGrid, load_map
from spcopyro.maps.free_space import check_free_cells, negate_hint
from spcopyro.synthetic import DEFAULT_CATEGORY_NAMES, HouseSpec, HouseSpecError
from spcopyro.synthetic.floor_plan import FloorPlan
from spcopyro.synthetic.house import tour_observations

logger = logging.getLogger("spcopyro")

__all__ = [
    "CLEARANCE",
    "COMMAND_OPTIONS",
    "DEFAULT_MIN_ROOM_AREA",
    "MapTour",
    "SimulatedMap",
    "simulate_on_map",
    "write_simulated_map",
]

DEFAULT_MIN_ROOM_AREA = 1.0
"""Square metres: smaller segments of the free space are not visited (not rooms)."""
CLEARANCE = 0.3
"""Metres: image positions prefer cells farther than this from any non-free cell."""


COMMAND_OPTIONS = {"min_room_area": "--min-room-area", "door_width": "--door-width",
                   "categories": "--categories"}  # fmt: skip
"""How ``spcopyro simulate --map`` names the :class:`MapTour` knobs its messages tell the user to
change (``options`` of :func:`simulate_on_map`); a study file, and Python, name them by the
fields themselves (``min_room_area``: a study's ``[data.NAME]`` key)."""


def _option(field: str, options: Mapping[str, str] | None) -> str:
    """What the user changes to set the MapTour ``field``: the command's option or the field."""
    return (options or {}).get(field, field)


@dataclass(frozen=True)
class MapTour:
    """The knobs of :func:`simulate_on_map` (defaults: those of the synthetic house)."""

    categories: tuple[str, ...] = DEFAULT_CATEGORY_NAMES
    door_width: float | Literal["auto"] = "auto"
    """Metres, or ``"auto"``: read from the map (module docstring)."""
    min_room_area: float = DEFAULT_MIN_ROOM_AREA
    num_trials: int = 3
    images_per_room: int = 10
    utterances_per_room: int = 3
    sentence_fraction: float = 0.0


@dataclass(frozen=True)
class SimulatedMap:
    """A simulated house on a given map, with the rooms it was simulated from."""

    house: House
    rooms: np.ndarray
    """[H, W] int64 room id of every visited free cell, -1 elsewhere."""
    room_category: np.ndarray
    """[R] int64 category id (index into ``house.category_names``) of every room."""
    tour: MapTour
    door_width: float = math.nan
    """The door width the rooms were cut at, metres (``tour.door_width`` resolved)."""


def _house_spec(grid: OccupancyGrid, tour: MapTour) -> HouseSpec:
    """A :class:`HouseSpec` carrying the tour's observation knobs for the synthetic house's
    tour and observation steps (its floor-plan fields are unused: the map is given)."""
    height, width = grid.shape
    if min(height, width) < 6:
        raise ValueError(f"{grid.source or 'map'}: {height} x {width} cells is too small to tour")
    try:
        return HouseSpec(
            height=height, width=width, resolution=grid.resolution, margin=0, num_rooms=1,
            num_open_plan=0, min_room_size=4, doorway_width=(2, 2),
            clearance=max(0, math.ceil(CLEARANCE / grid.resolution)),
            category_names=tuple(tour.categories), num_trials=tour.num_trials,
            images_per_room_per_trial=tour.images_per_room,
            utterances_per_room_per_trial=tour.utterances_per_room,
            sentence_fraction=tour.sentence_fraction,
        )  # fmt: skip
    except HouseSpecError as error:  # name the option, not the HouseSpec field
        message = str(error)
        for field, option in (
            ("category_names", "categories"),
            ("images_per_room_per_trial", "images per room"),
            ("utterances_per_room_per_trial", "utterances per room"),
        ):
            message = message.replace(f"HouseSpec.{field}", option)
        raise ValueError(message.replace("HouseSpec.", "")) from None


def _one_room_warning(
    grid: OccupancyGrid, tour: MapTour, door_width: float, options: Mapping[str, str] | None
) -> str:
    """What a tour of one room says: at which width(s) the free space stayed one room, what
    ``min_room_area`` did to smaller segments, and (for a larger ``min_room_area`` than the
    default) how many rooms the default finds."""
    where = (
        f"at every door width up to {door_width:g} m"
        if tour.door_width == "auto"
        else f"at door width {door_width:g} m"
    )
    message = f"{grid.source or 'map'}: the free space is one room {where}"
    if tour.min_room_area > DEFAULT_MIN_ROOM_AREA:
        message = (
            f"{grid.source or 'map'}: the free space has no two rooms of at least "
            f"{tour.min_room_area:g} m^2 ({_option('min_room_area', options)}) "
            f"{where.replace('every', 'any')}: "
            "smaller segments were merged into a neighbour or left unvisited"
        )
        width, found = (
            auto_door_width(grid, min_room_area=DEFAULT_MIN_ROOM_AREA)
            if tour.door_width == "auto"
            else (door_width, room_count(grid, door_width, DEFAULT_MIN_ROOM_AREA))
        )
        if found >= 2:
            message += (
                f"; with the default {DEFAULT_MIN_ROOM_AREA:g} m^2 it has {found} rooms at "
                f"{width:g} m"
            )
    elif tour.door_width != "auto":
        message += (f" ({_option('door_width', options)} auto reads from the map the width "
                    "at which the room count rises the most)")  # fmt: skip
    message += ": the simulated truth has one category, so a fit's ARI against it says nothing"
    if inverted := negate_hint(grid):  # the one room: the walls, read free
        message += f"; is the map read inverted? {inverted}"
    return message


def simulate_on_map(
    grid: OccupancyGrid,
    *,
    seed: int = 0,
    tour: MapTour | None = None,
    name: str = "simulated",
    options: Mapping[str, str] | None = None,
) -> SimulatedMap:
    """Rooms, categories, a tour and its observations on ``grid`` (module docstring).

    Deterministic in ``seed``. Raises ValueError when the map has no free cell, no segment of
    at least ``min_room_area``, or a bad knob (the message names it). ``options``: how the
    messages name the knobs to change (:data:`COMMAND_OPTIONS` for the command line; None: the
    MapTour fields, as a study file's keys are).
    """
    tour = tour or MapTour()
    spec = _house_spec(grid, tour)
    check_free_cells(grid, str(grid.source or "map"), "the map has no free cell to tour")
    rng = np.random.default_rng(seed)

    door_width = tour.door_width
    if door_width == "auto":
        door_width, _ = auto_door_width(grid, min_room_area=tour.min_room_area)
    elif not is_positive_number(door_width):
        raise ValueError(f"door width must be 'auto' or metres > 0, got {door_width!r}")
    # a bar on a large map (unless under CI), as auto_door_width's room counts have
    segments = room_segments(grid, door_width=door_width, min_room_area=tour.min_room_area,
                             progress=None)  # fmt: skip
    sizes = np.bincount(segments[segments >= 0])  # [S] cells per segment
    large = np.flatnonzero(counts_as_room(sizes, grid.resolution, tour.min_room_area))  # [R] ids
    if large.size == 0:
        raise ValueError(
            f"{grid.source or 'map'}: no room of at least {tour.min_room_area:g} m^2 in the free "
            f"space (largest: {sizes.max() * grid.resolution**2:.2f} m^2); lower "
            f"{_option('min_room_area', options)}"
        )
    room_of_segment = np.full(sizes.size, -1, dtype=np.int64)
    room_of_segment[large] = np.arange(large.size)
    rooms = np.where(segments >= 0, room_of_segment[np.maximum(segments, 0)], -1)  # [H, W]
    num_rooms = int(large.size)
    if num_rooms < 2:
        logger.warning("%s", _one_room_warning(grid, tour, float(door_width), options))
    elif len(spec.category_names) == 1:  # every room the same category: one in the truth
        logger.warning(
            "%s: %d rooms, all %s (one category given): the simulated truth has one category, "
            "so a fit's ARI against it says nothing; give %s two or more names",
            grid.source or "map", num_rooms, spec.category_names[0],
            _option("categories", options),
        )  # fmt: skip

    num_categories = min(num_rooms, len(spec.category_names))
    room_category = rng.permutation(np.arange(num_rooms) % len(spec.category_names))  # [R]
    truth = np.where(rooms >= 0, room_category[np.maximum(rooms, 0)], -1)  # [H, W]

    # The tour sees only the rooms: free cells outside them count as walls for it.
    occupancy = np.where(np.asarray(grid.free) & (rooms < 0), UNKNOWN, grid.occupancy)
    tour_grid = OccupancyGrid(occupancy.astype(np.int8), grid.resolution, grid.origin)
    plan = FloorPlan(tour_grid.occupancy, rooms, num_rooms, 0)

    observations = tour_observations(spec, tour_grid, plan, room_category, num_categories, rng)
    house = House(
        name=name,
        grid=grid,
        observations=observations,
        truth=truth.astype(np.int64),
        category_names=tuple(spec.category_names[:num_categories]),
    )
    return SimulatedMap(
        house=house, rooms=rooms, room_category=room_category, tour=tour,
        door_width=float(door_width),
    )  # fmt: skip


def write_simulated_map(
    map_yaml: str | os.PathLike[str],
    root: str | os.PathLike[str],
    *,
    seed: int = 0,
    tour: MapTour | None = None,
    name: str | None = None,
    overwrite: bool = False,
    options: Mapping[str, str] | None = None,
) -> tuple[Path, SimulatedMap]:
    """Load ``map_yaml`` (:func:`spcopyro.maps.load_map`: a malformed map is a
    :class:`~spcopyro.maps.MapFormatError` naming the file), simulate on it and write
    ``root/map/NAME.{yaml,pgm}`` and ``root/NAME/`` (:func:`spcopyro.data.save_house`, with
    ``truth.npy`` and ``categories.json``) plus ``rooms.npy`` and ``rooms.json``. ``name``
    defaults to the map's file name (ValueError for ``map.yaml``, Nav2's default: ``map`` is
    the maps' folder). Returns the room folder and the simulation. ``options``: as for
    :func:`simulate_on_map`."""
    if not name and Path(map_yaml).stem == "map":  # Nav2's map_saver default: map.yaml
        raise ValueError(
            f"{map_yaml}: the map's file name 'map' cannot name the house (ROOT/map/ holds the "
            "maps): give the house a name (--name NAME)"
        )
    grid = load_map(map_yaml)
    name = name or Path(map_yaml).stem
    simulated = simulate_on_map(grid, seed=seed, tour=tour, name=name, options=options)

    def write_rooms(room: Path) -> None:  # into the house folder before it is moved in
        np.save(room / "rooms.npy", simulated.rooms)
        names = simulated.house.category_names or ()
        cells = np.bincount(
            simulated.rooms[simulated.rooms >= 0], minlength=len(simulated.room_category)
        )
        record = {
            "map": str(Path(map_yaml).resolve()),
            "seed": seed,
            "door_width": simulated.door_width,
            "door_width_option": simulated.tour.door_width,
            "min_room_area": simulated.tour.min_room_area,
            "free_cells": int(grid.num_free),
            "free_cells_in_rooms": int(cells.sum()),
            "rooms": [
                {
                    "room": r,
                    "category": names[c],
                    "cells": int(n),
                    "area_m2": round(float(n) * grid.resolution**2, 4),
                }
                for r, (c, n) in enumerate(
                    zip(simulated.room_category.tolist(), cells, strict=True)
                )
            ],  # fmt: skip
        }
        (room / "rooms.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")

    return save_house(simulated.house, root, overwrite=overwrite, extra=write_rooms), simulated
