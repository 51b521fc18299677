r"""Room segmentation of an occupancy map: the rooms cut at doorways up to a width.

The distance-transform segmentation surveyed by R. Bormann, F. Jordan, W. Li, J. Hampp,
M. Haegele: "Room segmentation: survey, implementation, and analysis", ICRA 2016 (the
``ipa_room_segmentation`` package, its "distance" method), in a hierarchical form that needs one
physical parameter, the widest doorway, and the door width read from a map
(:func:`auto_door_width`). Baseline (F) (:mod:`spcopyro.baselines.geometry`, which re-exports
every public name), the fit's rooms start and the reach share's door cut
(:mod:`spcopyro.data.footprint`) use it; it lives with the maps so that the data layer may.

Algorithm
---------
Let ``d(x)`` be the Euclidean distance from free cell x's centre to the nearest non-free cell's
centre (``scipy.ndimage.distance_transform_edt``; outside the map counts as non-free). A doorway
of width w (metres between the wall ends) has ``d <= w / 2`` in its middle, so the super-level
set ``{d > r}`` is cut at every doorway narrower than about 2r. With ``res`` the resolution and
``r_0 = door_width / 2``, the map is flooded from the top, level by level, for
``r = r_0, r_0 - res, r_0 - 2 res, ..., 0``:

1. **Grow.** The rooms found so far grow over ``{d > r}`` by a breadth-first wavefront
   (4-neighbourhood, one cell per step, all rooms at once; ties go to the neighbour above,
   below, left, right in that order) until they stop.
2. **New rooms.** Every connected component (4-neighbourhood) of ``{d > r}`` that holds no room
   yet and covers at least ``min_room_area`` becomes a room. At ``r_0`` these are the room
   cores: each is one room even if it has several distance maxima (they are joined by a
   passage wider than any door). Below ``r_0`` they are rooms and corridors too narrow to
   reach ``r_0``, cut from their neighbours by doorways narrower than themselves.

This is a marker-based watershed of ``-d``: rooms meet where d is lowest between them, in the
doorways. At ``r = 0`` every free cell connected to a room is reached; free components that hold
no room (cut-off pieces smaller than ``min_room_area``) become segments of their own, so every
free cell is labelled.

Parameters: ``door_width`` (metres, default 1.0: interior doors are 0.7-0.9 m wide; raise it
for maps whose rooms open into each other through wider passages, e.g. about 2 m for the
SIGVerse houses of the public dataset, whose rooms meet in openings of about 1.7 m) and
``min_room_area`` (square metres, default 0.25: a component smaller than this at its level is
a nook or noise, not a room). Segments are numbered ``0 .. n-1`` in order of first appearance
in map-image raster order.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from spcopyro._util.progress import setup_bar
from spcopyro.maps.coarse import grow_labels
from spcopyro.maps.grid import OccupancyGrid

__all__ = [
    "AUTO_DOOR_WIDTHS",
    "DEFAULT_DOOR_WIDTH",
    "DEFAULT_MIN_ROOM_AREA",
    "auto_door_width",
    "counts_as_room",
    "free_cell_rooms",
    "room_count",
    "room_segments",
]

DEFAULT_DOOR_WIDTH = 1.0  # metres: doorways up to this wide separate rooms
DEFAULT_MIN_ROOM_AREA = 0.25  # square metres: smallest new room at its level
AUTO_DOOR_WIDTHS = tuple(0.75 + 0.25 * k for k in range(10))
"""Metres: the door widths :func:`auto_door_width` tries, 0.75 to 3 m (doors to open arches)."""
_EPS = 1e-9  # cells


def _positive_number(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return float(value)


def _distance(free: np.ndarray) -> np.ndarray:
    """``[H, W]`` float64 distance in cells from each free cell's centre to the nearest non-free
    cell's (outside the map counts as non-free); 0 off free space."""
    padded = np.pad(free, 1, constant_values=False)  # [H + 2, W + 2]
    return ndimage.distance_transform_edt(padded)[1:-1, 1:-1]


def _levels(door_width: float, res: float) -> np.ndarray:
    """``[n_levels]`` descending flood levels in cells: r_0 = door_width / 2, then down one cell
    at a time, then 0. _EPS keeps a cell exactly at a level out of its super-level set despite
    rounding (0.3 / 0.1 = 2.99...96)."""
    top = door_width / 2.0 / res
    levels = top - np.arange(int(math.floor(top + _EPS)) + 1)  # [n_levels] descending
    return np.append(levels[levels > _EPS], 0.0)


def _min_cells(min_room_area: float, res: float) -> float:
    """The smallest new room in cells (a component of at least this many becomes one)."""
    return min_room_area / res**2 - _EPS


def _flood(distance: np.ndarray, levels: np.ndarray, min_cells: float, bar) -> np.ndarray:
    """``[H, W]`` int64 room id (1..) per reached cell, 0 elsewhere (the module's algorithm).

    ``distance`` ``[H, W]`` (0 off free space) and ``levels`` (descending, last 0) in cells,
    ``min_cells`` the smallest new room in cells; ``bar.update()`` after each level (a
    :func:`~spcopyro._util.progress.setup_bar`, which shows nothing on a small map).
    """
    rooms = np.zeros(distance.shape, dtype=np.int64)  # [H, W]
    next_id = 1
    for r in levels:
        above = distance > r + _EPS  # [H, W] bool
        rooms = grow_labels(rooms - 1, above) + 1  # room ids >= 1; 0: none yet
        components, count = ndimage.label(above)  # [H, W], 0 = background
        if count == 0:
            continue
        sizes = np.bincount(components.ravel(), minlength=count + 1)  # [count + 1]
        holds_room = np.bincount(components[rooms > 0], minlength=count + 1) > 0
        new = (sizes >= min_cells) & ~holds_room  # [count + 1] bool
        new[0] = False
        ids = np.zeros(count + 1, dtype=np.int64)  # component -> new room id, 0 if none
        ids[new] = next_id + np.arange(int(new.sum()))
        next_id += int(new.sum())
        rooms = np.where(ids[components] > 0, ids[components], rooms)
        bar.update()
    return rooms


def room_segments(
    grid: OccupancyGrid,
    *,
    door_width: float = DEFAULT_DOOR_WIDTH,
    min_room_area: float = DEFAULT_MIN_ROOM_AREA,
    progress: bool | None = None,
) -> np.ndarray:
    """``[H, W]`` int64 room segment of every free cell, -1 elsewhere (module docstring).

    Args:
        grid: the occupancy grid; only FREE vs not-FREE matters.
        door_width: metres; doorways up to about this wide separate rooms.
        min_room_area: square metres; smallest new room at its level.
        progress: a bar over the levels on a map of SETUP_PROGRESS_CELLS free cells or more
            (:func:`~spcopyro._util.progress.setup_bar`; 2000 x 2000 cells at 0.05 m: 5-15 s);
            None (the default): on unless under CI, as for :func:`auto_door_width`'s room
            counts (so the fit's rooms start, baseline (F) and the open-plan study show it);
            False: none.
    """
    door_width = _positive_number("door_width", door_width)
    min_room_area = _positive_number("min_room_area", min_room_area)
    free = np.asarray(grid.free, dtype=bool)  # [H, W]
    if not free.any():
        return np.full(grid.shape, -1, dtype=np.int64)
    res = grid.resolution
    levels = _levels(door_width, res)  # [n_levels]
    bar = setup_bar(int(free.sum()), len(levels) + 1, f"room segments at {door_width:g} m "
                    "doors", "level", progress)  # fmt: skip
    grown = _flood(_distance(free), levels, _min_cells(min_room_area, res), bar)
    leftover = free & (grown == 0)  # [H, W] bool
    if leftover.any():
        pieces, _ = ndimage.label(leftover)
        grown = np.where(leftover, pieces + int(grown.max()), grown)
    # Number the segments 0..n-1 by first appearance in raster order.
    on_free = grown[free]  # [N] ids >= 1
    _, first = np.unique(on_free, return_index=True)
    order = np.argsort(first, kind="stable")
    ids = np.unique(on_free)
    renumber = np.zeros(int(ids.max()) + 1, dtype=np.int64)
    renumber[ids[order]] = np.arange(ids.size)
    labels = np.full(grid.shape, -1, dtype=np.int64)
    labels[free] = renumber[on_free]
    bar.update()  # the leftover pieces and the numbering: one step
    bar.close()
    return labels


def free_cell_rooms(
    grid: OccupancyGrid, door_width: float = DEFAULT_DOOR_WIDTH, *, progress: bool | None = None
) -> np.ndarray:
    """``[N]`` int64 room segment (>= 0) of every free cell, in free-index order: the segments of
    :func:`room_segments` at doorways up to ``door_width`` metres (its default smallest room;
    ``progress`` as its), which labels every free cell. ``grid.free``'s raster order is the free
    index's (:attr:`~spcopyro.maps.grid.OccupancyGrid.free_index`), so its mask picks them."""
    return room_segments(grid, door_width=door_width, progress=progress)[grid.free]  # [N]


def counts_as_room(cells, res: float, min_room_area: float):
    """Whether segments of ``cells`` cells (an int or an ``[S]`` array of them) count as rooms:
    cover ``min_room_area`` square metres or more at ``res`` metres a cell."""
    return cells * res**2 >= min_room_area


def _counts_are_created(res: float, min_room_area: float) -> bool:
    """Whether the rooms of ``min_room_area`` or more are exactly those ``_flood`` creates.

    Every room ``_flood`` creates has ``smallest`` cells or more, so it counts, and a free piece
    no room reaches has fewer, so it does not; False when ``min_room_area / res^2`` lies a hair
    above an integer (rounding), where the segments must be counted as they come out.
    """
    smallest = max(math.ceil(_min_cells(min_room_area, res)), 1)  # smallest room _flood creates
    return bool(
        counts_as_room(smallest, res, min_room_area)
        and not counts_as_room(smallest - 1, res, min_room_area)
    )


def _room_counts(
    distance: np.ndarray,
    widths: list[float],
    res: float,
    min_cells: float,
    progress: bool | None = None,
) -> list[int]:
    """Rooms ``_flood`` creates at each door width in ``widths``, from labellings alone.

    A component C of ``{d > r}`` becomes a room iff it covers ``min_cells`` or more and holds no
    room yet, and it holds one iff a component of ``min_cells`` or more of the next level up
    lies in it (a room grows over its whole component, and level sets are nested). So the count
    at width w is the big components at its top level plus, per level below, the big components
    with no big one of the level above inside; neither depends on how rooms grow. A level's set
    depends only on how many distinct distances lie at or under it (its key), and the widths
    share most levels (at 0.05 m 1.25 m's are 0.75 m's and five more), so each distinct set is
    labelled once for all widths: 58 labellings on a 0.05 m map, where segmenting every
    candidate flooded 200 levels, each with a breadth-first growth.
    """
    values = np.unique(distance[distance > 0])  # [V] distinct free-cell distances, ascending
    chains = []  # per width: [(key, level)] from its top level down
    for width in widths:
        levels = _levels(width, res)
        keys = np.searchsorted(values, levels + _EPS, side="right")  # [n_levels]
        chains.append(list(zip(keys.tolist(), levels.tolist(), strict=True)))
    level_of = {key: level for chain in chains for key, level in chain}  # one level per set
    ups: dict[int, set[int]] = {}  # key -> keys of the levels just above it
    for chain in chains:
        for (up, _), (key, _) in zip(chain, chain[1:], strict=False):
            ups.setdefault(key, set()).add(up)
    waiting = dict.fromkeys(level_of, 0)  # key -> lower sets still to check against it
    for key, above in ups.items():
        for up in above - {key}:
            waiting[up] += 1
    bar = setup_bar(
        int((distance > 0).sum()),
        len(level_of),
        f"room counts at {len(widths)} door widths",
        "level",
        progress,
    )
    big_cells: dict[int, np.ndarray] = {}  # key -> [H, W] bool cells of its big components
    tops: dict[int, int] = {}  # key -> big components at that level
    fresh: dict[tuple[int, int], int] = {}  # (key, up) -> big components with none of up's in
    for key in sorted(level_of, reverse=True):  # smallest set (highest level) first
        components, count = ndimage.label(distance > level_of[key] + _EPS)  # [H, W]
        big = np.bincount(components.ravel(), minlength=count + 1) >= min_cells  # [count + 1]
        big[0] = False
        tops[key] = int(big.sum())
        for up in ups.get(key, ()):
            if up == key:  # the same set twice: every big component holds itself
                fresh[key, up] = 0
                continue
            holds = np.bincount(components[big_cells[up]], minlength=count + 1) > 0
            fresh[key, up] = int((big & ~holds).sum())
            waiting[up] -= 1
            if waiting[up] == 0:
                del big_cells[up]
        if waiting[key]:
            big_cells[key] = big[components]  # [H, W] bool
        bar.update(1)
    bar.close()
    return [
        tops[chain[0][0]]
        + sum(fresh[key, up] for (up, _), (key, _) in zip(chain, chain[1:], strict=False))
        for chain in chains
    ]


def auto_door_width(
    grid: OccupancyGrid,
    *,
    min_room_area: float,
    candidates: tuple[float, ...] = AUTO_DOOR_WIDTHS,
) -> tuple[float, int]:
    """The door width read from the map, and the number of rooms of ``min_room_area`` square
    metres or more that :func:`room_segments` cuts at it: the candidate at which that number
    rises the most over the next narrower candidate's (over one room for the narrowest),
    the narrowest of equal rises.

    Widening the cut from one candidate to the next separates the rooms whose doorways lie
    between the two widths, so the largest rise marks the widths most of the map's doorways
    have: its door scale. A fixed width suits some maps only: on the public houses 1 m finds one
    room in each, while 2 m finds one in room1dk6 and three in room1dk5 (their doorways and
    arches are 1.5 to 2.5 m wide in the scans). The narrowest width that separates two rooms
    is not the door scale on a large map: one narrow doorway there (a 0.8 m door of a drawn
    100 m office block whose 24 offices open through 1.2 m doors) cut 2 rooms at 1 m, where
    1.25 m cuts 26. When no candidate separates two rooms the widest is returned with its
    count (1; the caller says so). The counts come from one distance transform and a
    labelling per distinct level (``_room_counts``), not a segmentation per candidate: on a
    2000 x 2000 map at 0.05 m about 4 s, where segmenting every candidate took about 100 s.
    """
    if not candidates:
        raise ValueError("auto_door_width needs at least one candidate width")
    widths = sorted(_positive_number("door_width", width) for width in candidates)
    min_room_area = _positive_number("min_room_area", min_room_area)
    counts = _rooms_at(grid, widths, min_room_area)  # [len(widths)]
    rises = np.diff(counts, prepend=1)  # [len(widths)] rooms gained over the narrower width
    rises[np.asarray(counts) < 2] = 0  # one room (or none) is no separation
    best = int(np.argmax(rises))  # the first (narrowest) of equal rises
    if rises[best] <= 0:  # one room (or none) at every width
        return float(widths[-1]), counts[-1]
    return float(widths[best]), counts[best]


def room_count(grid: OccupancyGrid, door_width: float, min_room_area: float) -> int:
    """The rooms of ``min_room_area`` square metres or more that :func:`room_segments` cuts at
    ``door_width``: its segments that :func:`counts_as_room`.

    Counted from the level sets' labellings (``_room_counts``), without growing the rooms, where
    the rounding guard allows (``_counts_are_created``); else from the segmentation itself.
    """
    door_width = _positive_number("door_width", door_width)
    min_room_area = _positive_number("min_room_area", min_room_area)
    return _rooms_at(grid, [door_width], min_room_area, progress=False)[0]


def _rooms_at(
    grid: OccupancyGrid, widths: list[float], min_room_area: float, progress: bool | None = None
) -> list[int]:
    """[len(widths)] the rooms of ``min_room_area`` or more that :func:`room_segments` cuts at
    each width: from one distance transform and a labelling per level (``_room_counts``, its bar
    as ``progress`` asks) where the rounding guard allows (``_counts_are_created``); else (a
    ``min_room_area / res^2`` a hair above an integer) from a segmentation per width, counted
    as it comes out, without a bar of its own."""
    res = grid.resolution
    if _counts_are_created(res, min_room_area):
        distance = _distance(np.asarray(grid.free, dtype=bool))  # [H, W]
        min_cells = _min_cells(min_room_area, res)
        return _room_counts(distance, widths, res, min_cells, progress=progress)
    counts = []
    for width in widths:
        segments = room_segments(grid, door_width=width, min_room_area=min_room_area,
                                 progress=False)  # fmt: skip
        sizes = np.bincount(segments[segments >= 0])  # [S] cells per segment
        counts.append(int(counts_as_room(sizes, res, min_room_area).sum()))
    return counts
