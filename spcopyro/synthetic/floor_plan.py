"""The floor plan of a synthetic house: walled rooms, open-plan regions and their categories.

Steps 1-3 of drawing a house (:func:`spcopyro.synthetic.make_house`; steps 4-6, the robot's
tour and observations, are in :mod:`spcopyro.synthetic.house`):

1. **Floor plan.** The map is UNKNOWN outside the house (``margin`` cells, like a SLAM map), the
   house is a rectangle with a 1-cell OCCUPIED outer wall, and its inside is split recursively
   (binary space partitioning: always the largest room, across its longer side, at 35-65 % of its
   length) by 1-cell walls until there are ``num_rooms`` rooms, none narrower than
   ``min_room_size`` cells. Every wall gets one doorway of ``doorway_width`` cells, so every room
   is reachable from every other (the free space is one 4-connected component). With
   ``open_plan_share`` the first wall instead cuts the inside's longer side at that share: one
   side (at random) is split into the ``num_open_plan`` open-plan rooms, the other into the
   walled ones, so open plans can take most of the house (:meth:`HouseSpec.open_plan`).
2. **Open plan.** The ``num_open_plan`` largest rooms (with ``open_plan_share``: those of its
   side) hold ``categories_per_open_plan``
   categories each (default two), split along lines with *no* wall, so the ground truth has
   boundaries that the map does not show: the room's largest part (at first the room) is cut
   across its longer side at 35-65 % of its length until there are that many parts. They prefer
   :data:`OPEN_PLAN_CATEGORIES` (the default house's is living + kitchen; three parts: living,
   kitchen, dining, an LDK).
3. **Ground truth.** Each region (room, or part of an open-plan room) gets a category; the
   categories are the first ``min(R, len(category_names))`` names of ``spec.category_names`` (R
   regions), each used about equally often, so names repeat only when there are more regions than
   names (never within one open-plan room). Doorway cells take the category of the nearest room
   cell. ``truth`` is ``[H, W]`` int64, the category id per free cell, -1 elsewhere.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN
from spcopyro.synthetic.lexicon import OPEN_PLAN_CATEGORIES
from spcopyro.synthetic.spec import HouseSpec, HouseSpecError

# A rectangle of cells: rows top..bottom-1, columns left..right-1 (image row order).
_Rect = tuple[int, int, int, int]


@dataclass(frozen=True)
class FloorPlan:
    """A house's walls and regions: :func:`floor_plan`'s draw, or the rooms of a real map
    (:func:`~spcopyro.robot.map_simulation.simulate_on_map`), for
    :func:`~spcopyro.synthetic.house.tour_observations`."""

    occupancy: np.ndarray  # [H, W] int8 FREE / OCCUPIED / UNKNOWN
    region: np.ndarray  # [H, W] int64 region id per free cell, -1 elsewhere
    num_regions: int
    open_pairs: int  # open-plan rooms: the first open_pairs * open_size regions, in groups of
    # open_size consecutive regions that share one room ((0, 1), (2, 3), ... by default)
    open_size: int = 2  # regions per open-plan room (spec.categories_per_open_plan)


def _split_position(length: int, low: int, rng: np.random.Generator) -> int:
    """Offset of a cut in a side of ``length`` cells, in [low, length - low], near the middle."""
    offset = int(round(length * rng.uniform(0.35, 0.65)))
    return min(max(offset, low), length - low)


def _wall(
    room: _Rect, spec: HouseSpec, rng: np.random.Generator, offset: int | None = None
) -> tuple[_Rect, _Rect, _Rect, _Rect]:
    """Cut ``room`` by a wall with one doorway: (first part, second part, wall, door).

    The wall runs across the room's longer side (rows on a tie) where that side can hold two
    rooms of ``min_room_size`` and the wall, at ``offset`` cells from the room's start (default:
    35-65 % of the side). Raises ``ValueError`` when neither side can hold two rooms.
    """
    r0, r1, c0, c1 = room
    rows, cols = r1 - r0, c1 - c0
    m = spec.min_room_size
    can = [rows >= 2 * m + 1, cols >= 2 * m + 1]
    if not any(can):
        raise ValueError(f"{rows} x {cols}")
    across_rows = can[0] and (rows >= cols or not can[1])
    if across_rows:  # a horizontal wall at row r0 + k
        k = _split_position(rows - 1, m, rng) if offset is None else offset
        wall = (r0 + k, r0 + k + 1, c0, c1)
        first, second = (r0, r0 + k, c0, c1), (r0 + k + 1, r1, c0, c1)
        along = (c0, c1)
    else:  # a vertical wall at column c0 + k
        k = _split_position(cols - 1, m, rng) if offset is None else offset
        wall = (r0, r1, c0 + k, c0 + k + 1)
        first, second = (r0, r1, c0, c0 + k), (r0, r1, c0 + k + 1, c1)
        along = (r0, r1)
    lo_door, hi_door = spec.doorway_width
    width = int(rng.integers(lo_door, hi_door + 1))
    start = int(rng.integers(along[0] + 1, along[1] - width))  # a wall stub at each end
    if across_rows:
        door = (wall[0], wall[1], start, start + width)
    else:
        door = (start, start + width, wall[2], wall[3])
    return first, second, wall, door


def _bsp(
    room: _Rect,
    count: int,
    spec: HouseSpec,
    rng: np.random.Generator,
    walls: list[_Rect],
    doors: list[_Rect],
) -> list[_Rect]:
    """Split ``room`` into ``count`` rooms, always the largest first; appends the walls and
    their doorways to ``walls`` and ``doors``; returns the rooms in creation order."""
    # A max-heap of rooms by area: (-area, creation number, room); ties go to the older room.
    heap: list[tuple[int, int, _Rect]] = [(-(room[1] - room[0]) * (room[3] - room[2]), 0, room)]
    created = 1
    while len(heap) < count:
        _, _, largest = heapq.heappop(heap)
        try:
            first, second, wall, door = _wall(largest, spec, rng)
        except ValueError as error:
            raise HouseSpecError(
                f"cannot draw {spec.num_rooms} rooms of at least {spec.min_room_size} cells in a "
                f"{spec.height} x {spec.width} map: the largest room is {error} after "
                f"{len(heap) + 1} rooms; lower num_rooms or min_room_size, or enlarge the map"
            ) from None
        for part in (first, second):
            area = (part[1] - part[0]) * (part[3] - part[2])
            heapq.heappush(heap, (-area, created, part))
            created += 1
        walls.append(wall)
        doors.append(door)
    return [part for _, _, part in sorted(heap, key=lambda entry: entry[1])]  # creation order


def _partition(
    spec: HouseSpec, rng: np.random.Generator
) -> tuple[list[_Rect], list[_Rect], np.ndarray]:
    """Split the inside of the house into ``num_rooms`` rooms; returns (rooms, wall+door lines,
    indices of the open-plan rooms).

    Each wall is returned with its doorway as (wall, door) rectangles, walls first. The
    open-plan rooms are the ``num_open_plan`` largest (stable order); with
    ``open_plan_share``, a first wall across the inside's longer side gives that share of it to
    one side (at random), which holds the ``num_open_plan`` open-plan rooms, and the other side
    the walled ones.
    """
    top, left = spec.margin + 1, spec.margin + 1
    bottom, right = spec.height - spec.margin - 1, spec.width - spec.margin - 1
    inside = (top, bottom, left, right)
    walls: list[_Rect] = []
    doors: list[_Rect] = []
    if spec.open_plan_share is None:
        rooms = _bsp(inside, spec.num_rooms, spec, rng, walls, doors)
        areas = np.array([(r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in rooms])  # [num_rooms]
        open_rooms = np.argsort(-areas, kind="stable")[: spec.num_open_plan]
        return rooms, walls + doors, open_rooms
    length = max(bottom - top, right - left) - 1  # the longer side, less the wall
    open_first = bool(rng.random() < 0.5)
    open_cells = int(round(length * spec.open_plan_share))
    offset = open_cells if open_first else length - open_cells
    try:
        first, second, wall, door = _wall(inside, spec, rng, offset=offset)
    except ValueError as error:  # validation keeps both sides >= min_room_size: not reached
        raise HouseSpecError(f"cannot cut the {error} inside for open_plan_share") from None
    walls.append(wall)
    doors.append(door)
    open_side, walled_side = (first, second) if open_first else (second, first)
    open_part = _bsp(open_side, spec.num_open_plan, spec, rng, walls, doors)
    walled_part = _bsp(walled_side, spec.num_rooms - spec.num_open_plan, spec, rng, walls, doors)
    rooms = open_part + walled_part
    return rooms, walls + doors, np.arange(len(open_part))


def _open_plan_parts(room: _Rect, count: int, rng: np.random.Generator) -> list[_Rect]:
    """``count`` parts of an open-plan room, no wall between them: the largest part (the
    first of equals) is cut across its longer side (rows on a tie) until there are ``count``.

    A part replaces its parent in place, so two parts are the room's two halves in order
    (top/left first), as open-plan rooms have always been drawn."""
    parts = [room]
    while len(parts) < count:
        areas = [(r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in parts]
        largest = int(np.argmax(areas))
        r0, r1, c0, c1 = parts[largest]
        if r1 - r0 >= c1 - c0:
            k = _split_position(r1 - r0, 1, rng)
            halves = [(r0, r0 + k, c0, c1), (r0 + k, r1, c0, c1)]
        else:
            k = _split_position(c1 - c0, 1, rng)
            halves = [(r0, r1, c0, c0 + k), (r0, r1, c0 + k, c1)]
        parts[largest : largest + 1] = halves
    return parts


def floor_plan(spec: HouseSpec, rng: np.random.Generator) -> FloorPlan:
    """Occupancy and region map: BSP rooms with doorways, then open-plan splits (no wall).
    :func:`~spcopyro.synthetic.make_house`'s first draw from its ``rng``: the same seed gives
    the same plan (:mod:`spcopyro.experiments.open_plan` scores the open plans so)."""
    rooms, lines, open_rooms = _partition(spec, rng)
    num_walls = len(lines) // 2
    # The open-plan rooms (the largest, stable order) are split without walls.
    regions: list[_Rect] = []
    for index in open_rooms:
        regions += _open_plan_parts(rooms[index], spec.categories_per_open_plan, rng)
    is_open = np.zeros(len(rooms), dtype=bool)
    is_open[open_rooms] = True
    regions += [room for room, open_ in zip(rooms, is_open, strict=True) if not open_]

    occupancy = np.full((spec.height, spec.width), UNKNOWN, dtype=np.int8)  # [H, W]
    m = spec.margin
    occupancy[m : spec.height - m, m : spec.width - m] = OCCUPIED  # outer wall
    occupancy[m + 1 : spec.height - m - 1, m + 1 : spec.width - m - 1] = FREE
    for r0, r1, c0, c1 in lines[:num_walls]:
        occupancy[r0:r1, c0:c1] = OCCUPIED
    for r0, r1, c0, c1 in lines[num_walls:]:
        occupancy[r0:r1, c0:c1] = FREE

    region = np.full((spec.height, spec.width), -1, dtype=np.int64)  # [H, W]
    for index, (r0, r1, c0, c1) in enumerate(regions):
        region[r0:r1, c0:c1] = index
    free = occupancy == FREE  # [H, W] bool
    # Doorway cells belong to the nearest room cell.
    unlabelled = free & (region < 0)
    if unlabelled.any():
        _, (near_row, near_col) = ndimage.distance_transform_edt(region < 0, return_indices=True)
        region[unlabelled] = region[near_row[unlabelled], near_col[unlabelled]]
    return FloorPlan(
        occupancy, region, len(regions), spec.num_open_plan, spec.categories_per_open_plan
    )


def _region_categories(spec: HouseSpec, plan: FloorPlan, rng: np.random.Generator) -> np.ndarray:
    """Category id per region ([R] int64): names balanced, an open-plan room's parts always
    different.

    The multiset of categories is ``i mod n`` for ``i < R`` (n names). Each open-plan room takes
    the ``plan.open_size`` categories with most uses left, which keeps its parts distinct; ties go
    to the earliest in :data:`OPEN_PLAN_CATEGORIES` (living, kitchen, dining, ...), then at
    random. The walled rooms take the rest in random order.
    """
    num_names = len(spec.category_names)
    remaining = np.bincount(np.arange(plan.num_regions) % num_names, minlength=num_names)
    preference = np.array(  # [n] rank in OPEN_PLAN_CATEGORIES, len(...) when not listed
        [
            OPEN_PLAN_CATEGORIES.index(name)
            if name in OPEN_PLAN_CATEGORIES
            else len(OPEN_PLAN_CATEGORIES)
            for name in spec.category_names
        ]
    )
    region_category = np.empty(plan.num_regions, dtype=np.int64)  # [R]
    size = plan.open_size
    for room in range(plan.open_pairs):
        order = np.lexsort((rng.random(num_names), preference, -remaining))
        chosen = order[:size]
        region_category[size * room : size * (room + 1)] = rng.permutation(chosen)
        remaining[chosen] -= 1
    rest = np.repeat(np.arange(num_names), remaining)
    region_category[size * plan.open_pairs :] = rng.permutation(rest)
    return region_category
