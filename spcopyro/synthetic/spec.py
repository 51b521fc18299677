"""The knobs of a synthetic house: :class:`HouseSpec`, its validation and :class:`HouseSpecError`.

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
the observations. :meth:`HouseSpec.public_like` is as sparse as the public houses and
:meth:`HouseSpec.open_plan` adds a living-dining-kitchen that no door separates.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from spcopyro._util.number_checks import is_integer
from spcopyro.synthetic.lexicon import DEFAULT_CATEGORY_NAMES, is_category_token

__all__ = ["HouseSpec", "HouseSpecError"]


class HouseSpecError(ValueError):
    """An invalid :class:`HouseSpec` field, or a spec whose floor plan cannot be drawn."""


_DEFAULT_ROOM_AREA = 900  # cells per room that HouseSpec.scaled aims at (default: ~800)


@dataclass(frozen=True)
class HouseSpec:
    """Every knob of :func:`make_house`; the defaults give the embedded default house.

    Sizes are in cells. "Room" in the per-room counts means a ground-truth region: a walled
    room, or one part of an open-plan room (``categories_per_open_plan`` parts, each of its own
    category).
    """

    height: int = 60  # map rows
    width: int = 80  # map columns
    resolution: float = 0.1  # metres per cell
    origin: tuple[float, float] | None = None  # world (x, y) of the lower-left cell's corner;
    # None centres the map on the world origin
    margin: int = 3  # UNKNOWN cells around the house
    num_rooms: int = 5  # walled rooms
    num_open_plan: int = 1  # rooms holding several categories with no wall between them
    categories_per_open_plan: int = 2  # regions (categories) per open-plan room
    open_plan_share: float | None = None  # share of the inside's longer side that a first wall
    # gives to the open-plan rooms (the rest to the walled ones); None: the largest rooms
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
    revisit_waypoints: bool = False  # every trial revisits one set of image positions per room
    # (the public houses' tour: ~80 waypoints, each photographed once per trial)
    waypoint_radius: float | None = None  # metres: a visit's images lie within this distance of
    # one random spot of the room (None: anywhere in the room)

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
            and all(is_integer(v) for v in self.doorway_width)
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
        # Every room needs min_room_size cells and a wall cell along each axis: no partition by
        # walls holds more rooms than this grid (issue 24 item 7: the area bound let
        # HouseSpec(30, 40, num_rooms=3) through, and make_house then failed for every seed).
        side = self.min_room_size + 1
        most = ((inner_h + 1) // side) * ((inner_w + 1) // side)
        if self.num_rooms > most:
            raise HouseSpecError(
                f"HouseSpec.num_rooms {self.num_rooms}: rooms of at least {self.min_room_size} "
                f"cells a side with a wall between them fit at most {most} to the "
                f"{inner_h} x {inner_w} inside of a {self.height} x {self.width} house; lower "
                "num_rooms or min_room_size, or enlarge the map"
            )
        if self.num_rooms * self.min_room_size**2 > inner_h * inner_w:
            raise HouseSpecError(
                f"HouseSpec.num_rooms {self.num_rooms} rooms of at least "
                f"{self.min_room_size} x {self.min_room_size} cells cannot fit in the "
                f"{inner_h} x {inner_w} inside of the house; lower num_rooms or min_room_size, "
                "or enlarge the map"
            )
        if self.open_plan_share is not None:
            share = _finite("open_plan_share", self.open_plan_share)
            if not 0.0 < share < 1.0:
                raise HouseSpecError(
                    f"HouseSpec.open_plan_share must be None or lie in (0, 1), got {share!r}"
                )
            if not 1 <= self.num_open_plan < self.num_rooms:
                raise HouseSpecError(
                    "HouseSpec.open_plan_share needs 1 <= num_open_plan < num_rooms (open-plan "
                    f"rooms on one side, walled rooms on the other), got num_open_plan "
                    f"{self.num_open_plan} of num_rooms {self.num_rooms}"
                )
            length = max(inner_h, inner_w) - 1  # the longer side, less the first wall
            sides = round(length * share), length - round(length * share)
            if min(sides) < self.min_room_size:
                raise HouseSpecError(
                    f"HouseSpec.open_plan_share {share:g} cuts the inside's longer side "
                    f"({length} cells) into {sides[0]} + {sides[1]}: both must be at least "
                    f"min_room_size ({self.min_room_size})"
                )
        _int_at_least("clearance", self.clearance, 0)
        names = self.category_names
        if not names:
            raise HouseSpecError("HouseSpec.category_names must not be empty")
        for name in names:
            if not is_category_token(name):
                raise HouseSpecError(
                    "HouseSpec.category_names entries must each be one lower-case word (no "
                    f"space or comma, no punctuation at its ends), got {name!r}"
                )
        if len(set(names)) != len(names):
            raise HouseSpecError(f"HouseSpec.category_names has duplicates: {names!r}")
        _int_at_least("categories_per_open_plan", self.categories_per_open_plan, 2)
        parts = self.categories_per_open_plan
        if self.num_open_plan > 0 and len(names) < parts:
            count = "two" if parts == 2 else str(parts)
            raise HouseSpecError(
                f"HouseSpec.num_open_plan > 0 needs at least {count} category_names (one per "
                f"part of an open-plan room: categories_per_open_plan = {parts}), got {names!r}"
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
        if self.waypoint_radius is not None:
            _positive("waypoint_radius", self.waypoint_radius)
        if not isinstance(self.revisit_waypoints, bool | np.bool_):
            raise HouseSpecError(
                f"HouseSpec.revisit_waypoints must be True or False, got {self.revisit_waypoints!r}"
            )

    @property
    def inner_shape(self) -> tuple[int, int]:
        """(rows, cols) inside the outer wall."""
        return self.height - 2 * self.margin - 2, self.width - 2 * self.margin - 2

    @property
    def num_regions(self) -> int:
        """Ground-truth regions: every walled room, plus ``categories_per_open_plan - 1`` more
        per open-plan room."""
        return self.num_rooms + self.num_open_plan * (self.categories_per_open_plan - 1)

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
        if is_integer(num_rooms):
            fields["num_open_plan"] = max(1, num_rooms // 5) if num_rooms > 1 else 0  # type: ignore[operator]
        fields.update(changes)
        return cls(**fields)  # type: ignore[arg-type]

    @classmethod
    def embedded(cls, **changes: object) -> HouseSpec:
        """The embedded default of the commands (``spcopyro fit`` with no DATA, ``show``,
        ``simulate``, ``simulate-bag``, ``navigate``'s examples): :class:`HouseSpec`'s defaults
        with doorways of 0.7-0.9 m (:data:`EMBEDDED_DOORWAY_WIDTH` cells at 0.1 m).

        The plain defaults' doorways are 0.2-0.4 m, narrower than a robot (0.2 m radius: no
        path into any room) and closed on the default preset's 0.3 m model grid, whose walls
        thicken to one model cell (:mod:`spcopyro.maps.coarse`): every room an island. They stay
        as they are because the synthetic benchmarks' "dense" houses (issues 14 and 21), the
        pinned seeded outputs and the studies' stored numbers are measured on them. The same
        seed draws the same rooms, categories, tour and words here; only the doorways' widths
        and places (and so the images' and words' positions near them) differ.
        ``changes`` override any field.
        """
        fields: dict[str, object] = dict(doorway_width=EMBEDDED_DOORWAY_WIDTH)
        fields.update(changes)
        return cls(**fields)  # type: ignore[arg-type]

    @classmethod
    def public_like(cls, **changes: object) -> HouseSpec:
        """A house as sparse as the five public SpCoMapping houses (issue #14 item 5).

        Measured on the public houses (:func:`spcopyro.synthetic.statistics.house_statistics`;
        ranges over the five): 18,026-27,746 free cells at 0.05 m (45-69 m^2), 58-86 observed
        cells (0.29-0.43 % of the free cells), 142-223 images and 45-76 single-word utterances
        in 3 trials, a tour of 58-75 m, with every trial revisiting the same ~60-90 waypoints
        (one image per waypoint and trial, utterances at image positions). This spec draws
        160 x 165 cells at 0.05 m with 6 walled rooms, one of them open plan (7 regions, 7
        categories, as in Table 2's LDK houses): about 23,500 free cells (59 m^2); 10 waypoints
        per region within 0.25 m of one spot of the room, revisited by each of the 3 trials
        (210 images on ~70 cells: density ~0.30 %), 3 utterances per region and trial (63),
        and a tour walking to the nearest unvisited room (~74 m over the 3 trials; seeds 0-4).
        Doorways are 0.7-0.9 m wide and images stay 0.3 m from walls. The default
        :class:`HouseSpec` is 15 times denser (176 observed cells of 3,600, 4.9 %).
        ``changes`` override any field, e.g. ``num_rooms=3`` or ``height=240, width=240,
        num_rooms=12`` for other layouts and sizes.
        """
        fields = dict(PUBLIC_LIKE_FIELDS)
        fields.update(changes)
        return cls(**fields)  # type: ignore[arg-type]

    @classmethod
    def open_plan(cls, **changes: object) -> HouseSpec:
        """A public-like house whose open-plan space holds several categories (issue 21).

        :meth:`public_like` sparsity (160 x 165 cells at 0.05 m, 10 waypoints per region within
        0.25 m of one spot, revisited by 3 trials, 3 utterances per region and trial), but a
        first wall gives 65 % of the inside's longer side to one walled space holding three
        categories side by side with no wall between them (living, dining, kitchen, as in the
        public LDK houses), and the other side holds 3 small walled rooms (bedroom, bathroom,
        toilet): 4 walled rooms, 6 regions, 6 categories, ~23,650 free cells, ~65 % of them in
        the open plan. Each category has its own spot, images and utterances, so the data can
        separate what no door separates. ``changes`` override any field (e.g.
        ``categories_per_open_plan=4``, ``num_open_plan=2``, ``open_plan_share=0.7``).

        Cutting at doors is capped well below 1 here. Measured on seeds 0-4
        (``python -m spcopyro.experiments.open_plan``; ARI against the truth over the free
        cells; (F) the geometry baseline, (E) the nearest utterance's word)::

            seed  (F) segments  (F) 1 m  (F) 2 m  (E) nearest  open plan only: (F) / (E)
            0     4             0.438    0.438    0.310        0.000 / 0.233
            1     4             0.418    0.418    0.233        0.000 / 0.139
            2     4             0.429    0.429    0.398        0.000 / 0.303
            3     4             0.450    0.450    0.277        0.000 / 0.193
            4     4             0.424    0.424    0.284        0.000 / 0.190
            mean  4             0.432    0.432    0.300        0.000 / 0.211

        One (F) segment holds the 3 open-plan categories in every seed (1 m is (F)'s door width
        for synthetic houses, 2 m its width for the public houses). For comparison (F) scores
        0.913 on :meth:`public_like` (one open plan of two categories in 6 rooms).
        """
        fields = dict(PUBLIC_LIKE_FIELDS)
        fields.update(OPEN_PLAN_FIELDS)
        fields.update(changes)
        return cls(**fields)  # type: ignore[arg-type]


OPEN_PLAN_FIELDS: dict[str, object] = dict(
    num_rooms=4,
    num_open_plan=1,
    categories_per_open_plan=3,
    open_plan_share=0.65,
    category_names=("living", "dining", "kitchen", "bedroom", "bathroom", "toilet")
    + tuple(
        name
        for name in DEFAULT_CATEGORY_NAMES
        if name not in ("living", "dining", "kitchen", "bedroom", "bathroom", "toilet")
    ),
)
"""The fields of :meth:`HouseSpec.open_plan` on top of :data:`PUBLIC_LIKE_FIELDS`."""


EMBEDDED_DOORWAY_WIDTH: tuple[int, int] = (7, 9)
"""Doorway widths, in cells, of :meth:`HouseSpec.embedded` (0.7-0.9 m at 0.1 m)."""


PUBLIC_LIKE_FIELDS: dict[str, object] = dict(
    height=160,
    width=165,
    resolution=0.05,
    num_rooms=6,
    num_open_plan=1,
    min_room_size=24,
    doorway_width=(14, 18),
    clearance=6,
    images_per_room_per_trial=10,
    utterances_per_room_per_trial=3,
    revisit_waypoints=True,
    waypoint_radius=0.25,
)
"""The fields of :meth:`HouseSpec.public_like` (see there for the measured statistics)."""


def _int_at_least(field: str, value: object, low: int) -> None:
    if not is_integer(value) or value < low:  # type: ignore[operator]
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
