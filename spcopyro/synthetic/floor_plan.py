"""The floor plan of a synthetic house: walled rooms, open-plan regions and their categories.

Steps 1-3 of drawing a house (:func:`spcopyro.synthetic.make_house`; steps 4-6, the robot's
tour and observations, are in :mod:`spcopyro.synthetic.house`):

1. **Floor plan.** The map is UNKNOWN outside the house (``margin`` cells, like a SLAM map), the
   house is a rectangle with a 1-cell OCCUPIED outer wall, and its inside is split recursively
   (binary space partitioning: always the largest room, across its longer side, at 35-65 % of its
   length) by 1-cell walls until there are ``num_rooms`` rooms, none narrower than
   ``min_room_size`` cells. Every wall gets one doorway of ``doorway_width`` cells, so every room
   is reachable from every other (the free space is one 4-connected component).
2. **Open plan.** The ``num_open_plan`` largest rooms hold two categories each, split along a line
   with *no* wall, so the ground truth has boundaries that the map does not show. They prefer
   :data:`OPEN_PLAN_CATEGORIES` (the default house's is living + kitchen).
3. **Ground truth.** Each region (room, or half of an open-plan room) gets a category; the
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
class _FloorPlan:
    occupancy: np.ndarray  # [H, W] int8 FREE / OCCUPIED / UNKNOWN
    region: np.ndarray  # [H, W] int64 region id per free cell, -1 elsewhere
    num_regions: int
    open_pairs: int  # regions (0, 1), (2, 3), ... up to 2 * open_pairs are open-plan halves


def _split_position(length: int, low: int, rng: np.random.Generator) -> int:
    """Offset of a cut in a side of ``length`` cells, in [low, length - low], near the middle."""
    offset = int(round(length * rng.uniform(0.35, 0.65)))
    return min(max(offset, low), length - low)


def _partition(spec: HouseSpec, rng: np.random.Generator) -> tuple[list[_Rect], list[_Rect]]:
    """Split the inside of the house into ``num_rooms`` rooms; returns (rooms, wall+door lines).

    Each wall is returned with its doorway as (wall, door) rectangles, walls first.
    """
    top, left = spec.margin + 1, spec.margin + 1
    bottom, right = spec.height - spec.margin - 1, spec.width - spec.margin - 1
    # A max-heap of rooms by area: (-area, creation number, room); ties go to the older room.
    heap: list[tuple[int, int, _Rect]] = [
        (-(bottom - top) * (right - left), 0, (top, bottom, left, right))
    ]
    created = 1
    walls: list[_Rect] = []
    doors: list[_Rect] = []
    m = spec.min_room_size
    lo_door, hi_door = spec.doorway_width
    while len(heap) < spec.num_rooms:
        _, _, (r0, r1, c0, c1) = heapq.heappop(heap)  # the largest room
        rows, cols = r1 - r0, c1 - c0
        # Split across the longer side when it can hold two rooms and a wall.
        can = [rows >= 2 * m + 1, cols >= 2 * m + 1]
        if not any(can):
            raise HouseSpecError(
                f"cannot draw {spec.num_rooms} rooms of at least {m} cells in a "
                f"{spec.height} x {spec.width} map: the largest room is {rows} x {cols} after "
                f"{len(heap) + 1} rooms; lower num_rooms or min_room_size, or enlarge the map"
            )
        across_rows = can[0] and (rows >= cols or not can[1])
        if across_rows:  # a horizontal wall at row r0 + k
            k = _split_position(rows - 1, m, rng)
            wall = (r0 + k, r0 + k + 1, c0, c1)
            first, second = (r0, r0 + k, c0, c1), (r0 + k + 1, r1, c0, c1)
            along = (c0, c1)
        else:  # a vertical wall at column c0 + k
            k = _split_position(cols - 1, m, rng)
            wall = (r0, r1, c0 + k, c0 + k + 1)
            first, second = (r0, r1, c0, c0 + k), (r0, r1, c0 + k + 1, c1)
            along = (r0, r1)
        width = int(rng.integers(lo_door, hi_door + 1))
        start = int(rng.integers(along[0] + 1, along[1] - width))  # a wall stub at each end
        if across_rows:
            door = (wall[0], wall[1], start, start + width)
        else:
            door = (start, start + width, wall[2], wall[3])
        for room in (first, second):
            area = (room[1] - room[0]) * (room[3] - room[2])
            heapq.heappush(heap, (-area, created, room))
            created += 1
        walls.append(wall)
        doors.append(door)
    rooms = [room for _, _, room in sorted(heap, key=lambda entry: entry[1])]  # creation order
    return rooms, walls + doors


def _floor_plan(spec: HouseSpec, rng: np.random.Generator) -> _FloorPlan:
    """Occupancy and region map: BSP rooms with doorways, then open-plan splits (no wall)."""
    rooms, lines = _partition(spec, rng)
    num_walls = len(lines) // 2
    # The largest rooms (stable order) become open plan, split across their longer side.
    areas = np.array([(r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in rooms])  # [num_rooms]
    open_rooms = np.argsort(-areas, kind="stable")[: spec.num_open_plan]
    regions: list[_Rect] = []
    for index in open_rooms:
        r0, r1, c0, c1 = rooms[index]
        if r1 - r0 >= c1 - c0:
            k = _split_position(r1 - r0, 1, rng)
            regions += [(r0, r0 + k, c0, c1), (r0 + k, r1, c0, c1)]
        else:
            k = _split_position(c1 - c0, 1, rng)
            regions += [(r0, r1, c0, c0 + k), (r0, r1, c0 + k, c1)]
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
    return _FloorPlan(occupancy, region, len(regions), spec.num_open_plan)


def _region_categories(spec: HouseSpec, plan: _FloorPlan, rng: np.random.Generator) -> np.ndarray:
    """Category id per region ([R] int64): names balanced, open-plan halves always different.

    The multiset of categories is ``i mod n`` for ``i < R`` (n names). Each open-plan room takes
    the two categories with most uses left, which keeps its halves distinct; ties go to the
    earliest in :data:`OPEN_PLAN_CATEGORIES` (living, kitchen, dining, ...), then at random. The
    walled rooms take the rest in random order.
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
    for pair in range(plan.open_pairs):
        order = np.lexsort((rng.random(num_names), preference, -remaining))
        first, second = order[:2]
        region_category[2 * pair : 2 * pair + 2] = rng.permutation([first, second])
        remaining[[first, second]] -= 1
    rest = np.repeat(np.arange(num_names), remaining)
    region_category[2 * plan.open_pairs :] = rng.permutation(rest)
    return region_category
