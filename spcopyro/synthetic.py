"""Seeded synthetic houses with known ground truth: the package's embedded default data set.

:func:`make_house` draws a complete :class:`~spcopyro.data.House` from a seed and a
:class:`HouseSpec`: an occupancy grid, a ground-truth spatial category for every free cell, and
what a robot touring the house observed (place-class image histograms and utterances at world
positions). The same seed and spec always give the same house; different seeds give different
houses. :func:`write_synthetic` stores it in the public dataset's on-disk layout (plus
``truth.npy`` and ``categories.json``) so every loader and command can read it.

How a house is drawn
--------------------
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
4. **Tour.** In each of ``num_trials`` trials the robot visits every region once, in a random
   order, and takes ``images_per_room_per_trial`` images at free cells of the region, preferring
   cells more than ``clearance`` cells from any wall, in a sweep around the region's centre. A
   position is its cell's centre plus a uniform jitter of at most 0.45 cells per axis, so it never
   leaves its free cell; the yaw of an image is the heading towards the next position of the trial.
5. **Images.** Category c has a place-class distribution over the K classes (Places205: 205),
   phi_c = (1 - m) b + m w_c with a shared indoor background b ~ Dir(1_K), mass
   m = ``dominant_mass`` on ``dominant_classes`` dominant classes D_c and w_c ~ Dir(2, ..., 2) on
   D_c; ``shared_dominant_classes`` of D_c are also dominant in the previous category, so the
   categories overlap. An image of category c has the feature row f ~ Dir(kappa phi_c) with
   kappa = ``feature_concentration``: a probability histogram, like the softmax output of the
   CNN of the paper (Section 3.3's image features).
6. **Utterances** at ``utterances_per_room_per_trial`` of each visit's image positions (same
   world position as the image). An utterance is, with probability ``sentence_fraction``, a
   sentence with filler words ("here is the kitchen", "there is a sofa here"), else a single word
   as in the public dataset; it names the place (probability ``name_word_fraction``) or one of
   its objects (:data:`CATEGORY_LEXICON`; some words, such as "table" and "room", belong to
   several categories). With probability ``word_noise`` it is a single word of another category.

Sizes and benchmarks
--------------------
The default spec (60 x 80 cells at 0.1 m, 5 rooms, one open plan, 6 categories, 3 trials,
180 images, 54 single-word utterances) has about 3600 free cells and is drawn in milliseconds.
For benchmarks, :meth:`HouseSpec.scaled` keeps the room size and the observations per room and
scales the number of rooms with the area::

    from spcopyro.synthetic import HouseSpec, make_house, write_synthetic

    spec = HouseSpec.scaled(1000, 1000)   # ~1100 rooms, ~1e6 cells, ~40k images
    house = make_house(seed=0, spec=spec) # under a second; every step is vectorised over cells
    write_synthetic("out/bench", seed=0, spec=spec, name="synthetic1000")  # ~10 s, ~180 MB CSV

Pass further fields to :meth:`HouseSpec.scaled` (e.g. ``images_per_room_per_trial=3``) to thin
the observations.
"""

from __future__ import annotations

import heapq
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from spcopyro.data import House, Observations, save_house
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

__all__ = [
    "CATEGORY_LEXICON",
    "DEFAULT_CATEGORY_NAMES",
    "FILLER_WORDS",
    "OPEN_PLAN_CATEGORIES",
    "CategoryLexicon",
    "HouseSpec",
    "HouseSpecError",
    "lexicon_for",
    "make_house",
    "write_synthetic",
]


# --------------------------------------------------------------------------------------------
# Vocabulary
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CategoryLexicon:
    """The words a speaker uses for one place category.

    ``name_word`` is the single word naming the place (as in the public dataset: "living"),
    ``place_phrase`` the tokens naming it inside a sentence (("living", "room")), and
    ``object_words`` things found there. Words may be shared between categories.
    """

    name_word: str
    place_phrase: tuple[str, ...]
    object_words: tuple[str, ...]

    @property
    def words(self) -> tuple[str, ...]:
        """All distinct words of the category, in order name, phrase, objects."""
        return tuple(dict.fromkeys((self.name_word, *self.place_phrase, *self.object_words)))


def _lex(name: str, phrase: str, objects: str) -> CategoryLexicon:
    return CategoryLexicon(name, tuple(phrase.split()), tuple(objects.split()))


CATEGORY_LEXICON: dict[str, CategoryLexicon] = {
    "kitchen": _lex("kitchen", "kitchen", "refrigerator sink stove table"),
    "living": _lex("living", "living room", "sofa tv table room"),
    "bedroom": _lex("bedroom", "bedroom", "bed closet room"),
    "bathroom": _lex("bathroom", "bathroom", "shower bathtub"),
    "toilet": _lex("toilet", "toilet", "restroom paper"),
    "entrance": _lex("entrance", "entrance", "door shoes"),
    "dining": _lex("dining", "dining room", "table chair room"),
    "study": _lex("study", "study", "desk bookshelf computer room"),
    "washroom": _lex("washroom", "washroom", "washbasin mirror towel"),
    "corridor": _lex("corridor", "corridor", "hallway hall"),
    "closet": _lex("closet", "closet", "clothes hanger"),
    "garage": _lex("garage", "garage", "car bicycle"),
}
"""Words per category name. Shared on purpose: table (kitchen, living, dining), room (living,
bedroom, dining, study), closet (bedroom, closet)."""

DEFAULT_CATEGORY_NAMES: tuple[str, ...] = tuple(CATEGORY_LEXICON)
"""Category names in the order they are used: a house with R regions uses the first R."""

# Sentence templates; "{}" is the place phrase or an object word.
_PLACE_TEMPLATES: tuple[str, ...] = (
    "here is the {}",
    "this is the {}",
    "we are in the {}",
    "this place is the {}",
)
_OBJECT_TEMPLATES: tuple[str, ...] = (
    "there is a {} here",
    "this is the {}",
    "the {} is here",
)
FILLER_WORDS: frozenset[str] = frozenset(
    token
    for template in _PLACE_TEMPLATES + _OBJECT_TEMPLATES
    for token in template.split()
    if token != "{}"
)
"""Tokens of the sentence templates that name no place ("here", "is", "the", ...)."""

OPEN_PLAN_CATEGORIES: tuple[str, ...] = ("living", "kitchen", "dining", "entrance", "corridor")
"""Categories that open-plan rooms prefer, best first (an LDK: living + kitchen + dining)."""

_TOKEN = re.compile(r"[a-z0-9_]+")


def lexicon_for(name: str) -> CategoryLexicon:
    """The lexicon of a category name; a name outside :data:`CATEGORY_LEXICON` is its own word."""
    return CATEGORY_LEXICON.get(name, CategoryLexicon(name, (name,), ()))


# --------------------------------------------------------------------------------------------
# Spec
# --------------------------------------------------------------------------------------------


class HouseSpecError(ValueError):
    """An invalid :class:`HouseSpec` field, or a spec whose floor plan cannot be drawn."""


_DEFAULT_ROOM_AREA = 900  # cells per room that HouseSpec.scaled aims at (default: ~800)


@dataclass(frozen=True)
class HouseSpec:
    """Every knob of :func:`make_house`; the defaults give the embedded default house.

    Sizes are in cells. "Room" in the per-room counts means a ground-truth region: a walled
    room, or one half of an open-plan room.
    """

    height: int = 60  # map rows
    width: int = 80  # map columns
    resolution: float = 0.1  # metres per cell
    origin: tuple[float, float] | None = None  # world (x, y) of the lower-left cell's corner;
    # None centres the map on the world origin
    margin: int = 3  # UNKNOWN cells around the house
    num_rooms: int = 5  # walled rooms
    num_open_plan: int = 1  # rooms holding two categories with no wall between them
    min_room_size: int = 12  # smallest side of a walled room
    doorway_width: tuple[int, int] = (2, 4)  # inclusive range of doorway widths (>= 2)
    clearance: int = 2  # image positions prefer cells more than this many cells from a wall
    category_names: tuple[str, ...] = DEFAULT_CATEGORY_NAMES
    num_feature_classes: int = 205  # K, like Places205
    dominant_classes: int = 5  # |D_c|: classes carrying the category's own mass
    shared_dominant_classes: int = 1  # of those, shared with the previous category
    dominant_mass: float = 0.7  # m in phi_c = (1 - m) b + m w_c
    feature_concentration: float = 30.0  # kappa in f ~ Dir(kappa phi_c)
    num_trials: int = 3
    images_per_room_per_trial: int = 10
    utterances_per_room_per_trial: int = 3  # at most images_per_room_per_trial
    sentence_fraction: float = 0.0  # share of sentences (the public data: single words only)
    name_word_fraction: float = 0.5  # share of utterances naming the place (else an object)
    word_noise: float = 0.05  # share of single words of another category

    def __post_init__(self) -> None:
        if isinstance(self.category_names, str) or not isinstance(self.category_names, Sequence):
            raise HouseSpecError(
                f"HouseSpec.category_names must be a sequence of names, got {self.category_names!r}"
            )
        object.__setattr__(self, "category_names", tuple(self.category_names))
        if isinstance(self.doorway_width, Sequence) and len(self.doorway_width) == 2:
            object.__setattr__(self, "doorway_width", tuple(self.doorway_width))
        if self.origin is not None:
            if not isinstance(self.origin, Sequence) or len(self.origin) != 2:
                raise HouseSpecError(
                    f"HouseSpec.origin must be None or two numbers (x, y), got {self.origin!r}"
                )
            origin = tuple(_finite("origin", v) for v in self.origin)
            object.__setattr__(self, "origin", origin)
        self._validate()

    def _validate(self) -> None:
        _int_at_least("height", self.height, 1)
        _int_at_least("width", self.width, 1)
        _positive("resolution", self.resolution)
        _int_at_least("margin", self.margin, 0)
        _int_at_least("num_rooms", self.num_rooms, 1)
        _int_at_least("num_open_plan", self.num_open_plan, 0)
        if self.num_open_plan > self.num_rooms:
            raise HouseSpecError(
                f"HouseSpec.num_open_plan must be at most num_rooms ({self.num_rooms}), "
                f"got {self.num_open_plan}"
            )
        if not (
            len(self.doorway_width) == 2
            and all(_is_int(v) for v in self.doorway_width)
            and 2 <= self.doorway_width[0] <= self.doorway_width[1]
        ):
            # Width 2 at least: a later wall may end next to one doorway cell, never two.
            raise HouseSpecError(
                "HouseSpec.doorway_width must be two integers (lo, hi) with 2 <= lo <= hi, "
                f"got {self.doorway_width!r}"
            )
        # A wall is at least min_room_size long and keeps 1 cell of wall at each end of its door.
        _int_at_least("min_room_size", self.min_room_size, max(4, self.doorway_width[1] + 2))
        inner_h, inner_w = self.inner_shape
        if min(inner_h, inner_w) < self.min_room_size:
            raise HouseSpecError(
                f"HouseSpec height x width {self.height} x {self.width} leaves a "
                f"{inner_h} x {inner_w} inside after the margin ({self.margin}) and the outer "
                f"wall: both sides must be at least min_room_size ({self.min_room_size})"
            )
        if self.num_rooms * self.min_room_size**2 > inner_h * inner_w:
            raise HouseSpecError(
                f"HouseSpec.num_rooms {self.num_rooms} rooms of at least "
                f"{self.min_room_size} x {self.min_room_size} cells cannot fit in the "
                f"{inner_h} x {inner_w} inside of the house; lower num_rooms or min_room_size, "
                "or enlarge the map"
            )
        _int_at_least("clearance", self.clearance, 0)
        names = self.category_names
        if not names:
            raise HouseSpecError("HouseSpec.category_names must not be empty")
        for name in names:
            if not isinstance(name, str) or _TOKEN.fullmatch(name) is None:
                raise HouseSpecError(
                    "HouseSpec.category_names entries must be single lower-case tokens "
                    f"([a-z0-9_]+), got {name!r}"
                )
        if len(set(names)) != len(names):
            raise HouseSpecError(f"HouseSpec.category_names has duplicates: {names!r}")
        if self.num_open_plan > 0 and len(names) < 2:
            raise HouseSpecError(
                f"HouseSpec.num_open_plan > 0 needs at least two category_names, got {names!r}"
            )
        _int_at_least("num_feature_classes", self.num_feature_classes, 1)
        _int_at_least("dominant_classes", self.dominant_classes, 1)
        if self.dominant_classes > self.num_feature_classes:
            raise HouseSpecError(
                f"HouseSpec.dominant_classes must be at most num_feature_classes "
                f"({self.num_feature_classes}), got {self.dominant_classes}"
            )
        _int_at_least("shared_dominant_classes", self.shared_dominant_classes, 0)
        if self.shared_dominant_classes >= self.dominant_classes:
            raise HouseSpecError(
                "HouseSpec.shared_dominant_classes must be less than dominant_classes "
                f"({self.dominant_classes}), got {self.shared_dominant_classes}"
            )
        _fraction("dominant_mass", self.dominant_mass)
        _positive("feature_concentration", self.feature_concentration)
        _int_at_least("num_trials", self.num_trials, 1)
        _int_at_least("images_per_room_per_trial", self.images_per_room_per_trial, 1)
        _int_at_least("utterances_per_room_per_trial", self.utterances_per_room_per_trial, 0)
        if self.utterances_per_room_per_trial > self.images_per_room_per_trial:
            raise HouseSpecError(
                "HouseSpec.utterances_per_room_per_trial must be at most "
                f"images_per_room_per_trial ({self.images_per_room_per_trial}): utterances are "
                f"made at image positions; got {self.utterances_per_room_per_trial}"
            )
        _fraction("sentence_fraction", self.sentence_fraction)
        _fraction("name_word_fraction", self.name_word_fraction)
        _fraction("word_noise", self.word_noise)

    @property
    def inner_shape(self) -> tuple[int, int]:
        """(rows, cols) inside the outer wall."""
        return self.height - 2 * self.margin - 2, self.width - 2 * self.margin - 2

    @property
    def num_regions(self) -> int:
        """Ground-truth regions: every walled room, plus one more per open-plan room."""
        return self.num_rooms + self.num_open_plan

    @property
    def world_origin(self) -> tuple[float, float]:
        """World (x, y) of the lower-left cell's corner (``origin``, or centred on (0, 0))."""
        if self.origin is not None:
            return self.origin
        return -0.5 * self.width * self.resolution, -0.5 * self.height * self.resolution

    @classmethod
    def scaled(cls, height: int, width: int, **changes: object) -> HouseSpec:
        """A spec for a ``height x width`` map with rooms of the default size.

        The number of rooms grows with the inside area (one per ~900 cells, at least 1), one room
        in five is open plan, and the per-room observation counts stay, so the number of
        observations grows with the area too. ``changes`` override any field.
        """
        base = cls()
        margin = int(changes.get("margin", base.margin))  # type: ignore[call-overload]
        inner = max(height - 2 * margin - 2, 0) * max(width - 2 * margin - 2, 0)
        num_rooms = changes.get("num_rooms", max(1, inner // _DEFAULT_ROOM_AREA))
        fields: dict[str, object] = dict(height=height, width=width, num_rooms=num_rooms)
        if _is_int(num_rooms):
            fields["num_open_plan"] = max(1, num_rooms // 5) if num_rooms > 1 else 0  # type: ignore[operator]
        fields.update(changes)
        return cls(**fields)  # type: ignore[arg-type]


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _int_at_least(field: str, value: object, low: int) -> None:
    if not _is_int(value) or value < low:  # type: ignore[operator]
        raise HouseSpecError(f"HouseSpec.{field} must be an integer >= {low}, got {value!r}")


def _finite(field: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise HouseSpecError(f"HouseSpec.{field} must be a number, got {value!r}")
    if not math.isfinite(float(value)):
        raise HouseSpecError(f"HouseSpec.{field} must be finite, got {value!r}")
    return float(value)


def _positive(field: str, value: object) -> None:
    if _finite(field, value) <= 0:
        raise HouseSpecError(f"HouseSpec.{field} must be > 0, got {value!r}")


def _fraction(field: str, value: object) -> None:
    if not 0.0 <= _finite(field, value) <= 1.0:
        raise HouseSpecError(f"HouseSpec.{field} must lie in [0, 1], got {value!r}")


# --------------------------------------------------------------------------------------------
# Floor plan
# --------------------------------------------------------------------------------------------

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


# --------------------------------------------------------------------------------------------
# Observations
# --------------------------------------------------------------------------------------------


def _place_distributions(
    spec: HouseSpec, num_categories: int, rng: np.random.Generator
) -> np.ndarray:
    """phi [C, K]: (1 - m) b + m w_c, dominant sets overlapping with the previous category."""
    k, d, s = spec.num_feature_classes, spec.dominant_classes, spec.shared_dominant_classes
    background = rng.dirichlet(np.ones(k))  # [K]
    phi = np.tile((1.0 - spec.dominant_mass) * background, (num_categories, 1))  # [C, K]
    previous: np.ndarray | None = None
    for c in range(num_categories):
        if previous is None or s == 0:
            dominant = rng.choice(k, size=d, replace=False)  # [d]
        else:
            shared = previous[-s:]
            others = np.setdiff1d(np.arange(k), shared)
            own = rng.choice(others, size=min(d - s, others.size), replace=False)
            dominant = np.concatenate([own, shared])
        phi[c, dominant] += spec.dominant_mass * rng.dirichlet(np.full(dominant.size, 2.0))
        previous = dominant
    return phi / phi.sum(axis=1, keepdims=True)


def _image_features(phi: np.ndarray, concentration: float, rng: np.random.Generator) -> np.ndarray:
    """Rows ~ Dir(concentration * phi_row) via normalised gammas; [T, K] -> [T, K].

    A row whose gammas all underflow to 0 (only for tiny concentrations) becomes one-hot at a
    class drawn from phi, the Dirichlet's limit as the concentration goes to 0.
    """
    gammas = rng.standard_gamma(concentration * phi)  # [T, K]
    totals = gammas.sum(axis=1)  # [T]
    empty = totals <= 0.0
    if empty.any():
        cumulative = np.cumsum(phi[empty], axis=1)  # [E, K]
        draws = rng.random(int(empty.sum()))[:, None] * cumulative[:, -1:]
        classes = np.minimum((cumulative < draws).sum(axis=1), phi.shape[1] - 1)
        gammas[np.flatnonzero(empty), classes] = 1.0
        totals = gammas.sum(axis=1)
    return gammas / totals[:, None]


def _cells_by_region(mask: np.ndarray, region: np.ndarray, num_regions: int) -> list[np.ndarray]:
    """Flat cell indices where ``mask`` holds, grouped by region: R arrays of int64."""
    cells = np.flatnonzero(mask)  # [N]
    labels = region.ravel()[cells]  # [N]
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(num_regions + 1))
    return [cells[order[bounds[r] : bounds[r + 1]]] for r in range(num_regions)]


@dataclass(frozen=True)
class _Tour:
    xy: np.ndarray  # [T, 2] float64 world positions
    yaw: np.ndarray  # [T] float64 heading towards the next position (radians)
    trial: np.ndarray  # [T] int64
    region: np.ndarray  # [T] int64
    visit_start: np.ndarray  # [V] index of each visit's first image (V = trials * regions)


def _tour(
    spec: HouseSpec, grid: OccupancyGrid, plan: _FloorPlan, rng: np.random.Generator
) -> _Tour:
    """Image positions: each trial visits every region once, in a random order."""
    free = grid.free  # [H, W] bool
    roomy = ndimage.distance_transform_edt(free) > spec.clearance  # [H, W] bool
    roomy_cells = _cells_by_region(roomy, plan.region, plan.num_regions)
    free_cells = _cells_by_region(free, plan.region, plan.num_regions)
    width = spec.width
    # Region centres (row, col): means over each region's free cells.
    rows_all, cols_all = np.divmod(np.flatnonzero(free), width)  # [N], [N]
    labels = plan.region[free]  # [N] (row-major, like flatnonzero)
    sizes = np.bincount(labels, minlength=plan.num_regions)  # [R]
    centre_row = np.bincount(labels, rows_all, plan.num_regions) / sizes  # [R]
    centre_col = np.bincount(labels, cols_all, plan.num_regions) / sizes  # [R]
    n = spec.images_per_room_per_trial
    flat_parts: list[np.ndarray] = []
    region_parts: list[np.ndarray] = []
    for _trial in range(spec.num_trials):
        for r in rng.permutation(plan.num_regions):
            candidates = roomy_cells[r] if roomy_cells[r].size else free_cells[r]
            chosen = rng.choice(candidates, size=n, replace=n > candidates.size)  # [n]
            rows, cols = np.divmod(chosen, width)
            # Sweep around the region's centre, starting at a random angle.
            angle = np.arctan2(-(rows - centre_row[r]), cols - centre_col[r])
            angle = np.mod(angle - rng.uniform(-np.pi, np.pi), 2 * np.pi)
            flat_parts.append(chosen[np.argsort(angle, kind="stable")])
            region_parts.append(np.full(n, r, dtype=np.int64))
    flat = np.concatenate(flat_parts)  # [T]
    cells = np.stack(np.divmod(flat, width), axis=-1)  # [T, 2] (row, col)
    jitter = rng.uniform(-0.45, 0.45, size=cells.shape) * spec.resolution  # [T, 2]
    xy = grid.cell_to_world(cells) + jitter  # [T, 2]
    num_visits = spec.num_trials * plan.num_regions
    trial = np.repeat(np.arange(spec.num_trials, dtype=np.int64), n * plan.num_regions)  # [T]
    # Heading towards the next image of the same trial; the last image keeps the one before.
    yaw = np.zeros(len(flat))  # [T]
    step = xy[1:] - xy[:-1]  # [T-1, 2]
    has_next = np.append(trial[1:] == trial[:-1], False)  # [T] bool
    yaw[has_next] = np.arctan2(step[:, 1], step[:, 0])[has_next[:-1]]
    last = np.flatnonzero(~has_next)
    last = last[(last > 0) & (trial[np.maximum(last - 1, 0)] == trial[last])]
    yaw[last] = yaw[last - 1]
    return _Tour(
        xy=xy,
        yaw=yaw,
        trial=trial,
        region=np.concatenate(region_parts),
        visit_start=np.arange(num_visits, dtype=np.int64) * n,
    )


def _utterance_positions(spec: HouseSpec, tour: _Tour, rng: np.random.Generator) -> np.ndarray:
    """Image indices where words are spoken: ``utterances_per_room_per_trial`` per visit."""
    u, n = spec.utterances_per_room_per_trial, spec.images_per_room_per_trial
    if u == 0:
        return np.zeros(0, dtype=np.int64)
    # A random u-subset of each visit's n images, in tour order: argsort of uniform keys.
    keys = rng.random((tour.visit_start.size, n))  # [V, n]
    picks = np.sort(np.argsort(keys, axis=1)[:, :u], axis=1)  # [V, u]
    return (tour.visit_start[:, None] + picks).ravel()  # [U]


def _utterances(
    spec: HouseSpec,
    category: np.ndarray,
    num_categories: int,
    rng: np.random.Generator,
) -> tuple[tuple[str, ...], ...]:
    """One utterance per entry of ``category`` ([U] int64 category id of its position)."""
    size = category.size
    noisy = (rng.random(size) < spec.word_noise) & (num_categories > 1)  # [U] bool
    # Another category, uniformly: shift by 1..C-1.
    shift = rng.integers(1, max(num_categories, 2), size=size)  # [U]
    spoken = np.where(noisy, (category + shift) % num_categories, category)  # [U]
    sentence = (rng.random(size) < spec.sentence_fraction) & ~noisy  # [U] bool
    naming = rng.random(size) < spec.name_word_fraction  # [U] bool
    choice = rng.integers(0, 2**31, size=(size, 2))  # [U, 2] object word, template
    lexicons = [lexicon_for(name) for name in spec.category_names[:num_categories]]
    result: list[tuple[str, ...]] = []
    for c, is_sentence, is_name, (pick, template) in zip(
        spoken.tolist(), sentence.tolist(), naming.tolist(), choice.tolist(), strict=True
    ):
        lexicon = lexicons[c]
        objects = lexicon.object_words
        if is_name or not objects:
            if is_sentence:
                text = _PLACE_TEMPLATES[template % len(_PLACE_TEMPLATES)]
                result.append(tuple(text.replace("{}", " ".join(lexicon.place_phrase)).split()))
            else:
                result.append((lexicon.name_word,))
        else:
            word = objects[pick % len(objects)]
            if is_sentence:
                text = _OBJECT_TEMPLATES[template % len(_OBJECT_TEMPLATES)]
                result.append(tuple(text.replace("{}", word).split()))
            else:
                result.append((word,))
    return tuple(result)


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


def make_house(seed: int = 0, spec: HouseSpec | None = None, name: str = "synthetic") -> House:
    """Draw a synthetic house with ground truth from ``seed`` (see the module docstring).

    Deterministic: one ``numpy.random.Generator(seed)`` drives every draw, in a fixed order.
    Raises :class:`HouseSpecError` when the floor plan cannot hold ``spec.num_rooms`` rooms.
    """
    if spec is None:
        spec = HouseSpec()
    if not isinstance(spec, HouseSpec):
        raise TypeError(f"spec must be a HouseSpec or None, got {type(spec).__name__}")
    if not _is_int(seed) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(seed)

    plan = _floor_plan(spec, rng)
    region_category = _region_categories(spec, plan, rng)  # [R]
    num_categories = min(plan.num_regions, len(spec.category_names))
    truth = np.where(plan.region >= 0, region_category[plan.region], -1)  # [H, W] int64
    ox, oy = spec.world_origin
    grid = OccupancyGrid(
        occupancy=plan.occupancy, resolution=float(spec.resolution), origin=(ox, oy, 0.0)
    )

    phi = _place_distributions(spec, num_categories, rng)  # [C, K]
    tour = _tour(spec, grid, plan, rng)
    image_category = region_category[tour.region]  # [T]
    features = _image_features(phi[image_category], spec.feature_concentration, rng)  # [T, K]
    spoken_at = _utterance_positions(spec, tour, rng)  # [U]
    utterances = _utterances(spec, image_category[spoken_at], num_categories, rng)

    observations = Observations(
        image_features=features,
        image_xy=tour.xy,
        image_trial=tour.trial,
        utterances=utterances,
        word_xy=tour.xy[spoken_at].copy(),
        word_trial=tour.trial[spoken_at].copy(),
        image_yaw=tour.yaw,
    )
    return House(
        name=name,
        grid=grid,
        observations=observations,
        truth=truth.astype(np.int64),
        category_names=tuple(spec.category_names[:num_categories]),
    )


def write_synthetic(
    root: str | os.PathLike[str],
    seed: int = 0,
    spec: HouseSpec | None = None,
    name: str = "synthetic",
    *,
    overwrite: bool = False,
) -> Path:
    """Draw a house and write it with :func:`spcopyro.data.save_house`; returns the room folder.

    ``root`` gets ``map/NAME.{pgm,yaml}`` and ``NAME/`` in the public dataset's layout, plus
    ``NAME/truth.npy`` and ``NAME/categories.json`` (the ground truth). An existing house of the
    same name is an error (``FileExistsError`` from ``save_house``) unless ``overwrite``.
    """
    house = make_house(seed=seed, spec=spec, name=name)
    return save_house(house, root, overwrite=overwrite)
