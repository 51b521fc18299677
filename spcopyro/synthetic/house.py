"""Drawing a whole synthetic house: the robot's tour, its images and utterances, and the files.

:func:`make_house` draws a complete :class:`~spcopyro.data.House` from a seed and a
:class:`~spcopyro.synthetic.spec.HouseSpec`; :func:`write_synthetic` stores it in the public
dataset's on-disk layout. After the floor plan and its ground truth (steps 1-3, in
:mod:`spcopyro.synthetic.floor_plan`):

4. **Tour.** In each of ``num_trials`` trials the robot visits every region once, in a random
   order, and takes ``images_per_room_per_trial`` images at free cells of the region, preferring
   cells more than ``clearance`` cells from any wall, in a sweep around the region's centre
   (with ``revisit_waypoints``, the positions of each region are drawn once and every trial
   takes its images there again, as the public houses' robot did; with ``waypoint_radius``, a
   visit's positions lie within that many metres of a random anchor cell of the region and a
   trial walks from a random region to the nearest unvisited one, as a robot would). A
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
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from spcopyro._util.number_checks import is_integer
from spcopyro.data.dataset import House, save_house
from spcopyro.data.observations import Observations
from spcopyro.maps.grid import OccupancyGrid
from spcopyro.synthetic.floor_plan import FloorPlan, _region_categories, floor_plan
from spcopyro.synthetic.lexicon import _OBJECT_TEMPLATES, _PLACE_TEMPLATES, lexicon_for
from spcopyro.synthetic.spec import HouseSpec

__all__ = ["make_house", "write_synthetic"]

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


def _nearest_neighbour_order(rows: np.ndarray, cols: np.ndarray, start: int) -> np.ndarray:
    """Regions in the order of a greedy walk from ``start`` to the nearest unvisited centre."""
    count = rows.size
    distance = np.hypot(rows[:, None] - rows[None, :], cols[:, None] - cols[None, :])  # [R, R]
    order = [start]
    visited = np.zeros(count, dtype=bool)
    visited[start] = True
    for _ in range(count - 1):
        step = np.where(visited, np.inf, distance[order[-1]])
        order.append(int(np.argmin(step)))
        visited[order[-1]] = True
    return np.asarray(order, dtype=np.int64)


@dataclass(frozen=True)
class _Tour:
    xy: np.ndarray  # [T, 2] float64 world positions
    yaw: np.ndarray  # [T] float64 heading towards the next position (radians)
    trial: np.ndarray  # [T] int64
    region: np.ndarray  # [T] int64
    visit_start: np.ndarray  # [V] index of each visit's first image (V = trials * regions)


def _tour(spec: HouseSpec, grid: OccupancyGrid, plan: FloorPlan, rng: np.random.Generator) -> _Tour:
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

    def draw(r: int) -> np.ndarray:  # [n] flat cells of one visit of region r
        candidates = roomy_cells[r] if roomy_cells[r].size else free_cells[r]
        if spec.waypoint_radius is not None:  # a spot of the room: cells near a random anchor
            anchor = rng.choice(candidates)
            drow, dcol = np.divmod(candidates, width)
            arow, acol = divmod(int(anchor), width)
            near = np.hypot(drow - arow, dcol - acol) * spec.resolution <= spec.waypoint_radius
            candidates = candidates[near]
        return rng.choice(candidates, size=n, replace=n > candidates.size)

    # With revisit_waypoints, one set of positions per region, revisited by every trial.
    waypoints = [draw(r) for r in range(plan.num_regions)] if spec.revisit_waypoints else None
    for _trial in range(spec.num_trials):
        order = rng.permutation(plan.num_regions)
        if spec.waypoint_radius is not None:  # a walk: from a random region to the nearest next
            order = _nearest_neighbour_order(centre_row, centre_col, int(order[0]))
        for r in order:
            chosen = waypoints[r] if waypoints is not None else draw(r)  # [n]
            rows, cols = np.divmod(chosen, width)
            # Sweep around the region's centre (around the spot with waypoint_radius), starting
            # at a random angle.
            if spec.waypoint_radius is not None:
                row0, col0 = rows.mean(), cols.mean()
            else:
                row0, col0 = centre_row[r], centre_col[r]
            angle = np.arctan2(-(rows - row0), cols - col0)
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


def tour_observations(
    spec: HouseSpec,
    grid: OccupancyGrid,
    plan: FloorPlan,
    region_category: np.ndarray,
    num_categories: int,
    rng: np.random.Generator,
) -> Observations:
    """The synthetic observation model on a floor plan: a tour of its regions (``plan.region``,
    ``region_category`` [R] the category of each), a place histogram per image from its
    category's Dirichlet, utterances at image positions from the category's lexicon. Used by
    :func:`make_house` and by ``simulate --map`` (:mod:`spcopyro.robot.map_simulation`)."""
    phi = _place_distributions(spec, num_categories, rng)  # [C, K]
    tour = _tour(spec, grid, plan, rng)
    image_category = region_category[tour.region]  # [T]
    features = _image_features(phi[image_category], spec.feature_concentration, rng)  # [T, K]
    spoken_at = _utterance_positions(spec, tour, rng)  # [U]
    utterances = _utterances(spec, image_category[spoken_at], num_categories, rng)
    return Observations(
        image_features=features,
        image_xy=tour.xy,
        image_trial=tour.trial,
        utterances=utterances,
        word_xy=tour.xy[spoken_at].copy(),
        word_trial=tour.trial[spoken_at].copy(),
        image_yaw=tour.yaw,
    )


def make_house(seed: int = 0, spec: HouseSpec | None = None, name: str = "synthetic") -> House:
    """Draw a synthetic house with ground truth from ``seed`` (see the module docstrings of
    :mod:`spcopyro.synthetic.floor_plan` and :mod:`spcopyro.synthetic.house`).

    Deterministic: one ``numpy.random.Generator(seed)`` drives every draw, in a fixed order.
    Raises :class:`HouseSpecError` when the floor plan cannot hold ``spec.num_rooms`` rooms.
    """
    if spec is None:
        spec = HouseSpec()
    if not isinstance(spec, HouseSpec):
        raise TypeError(f"spec must be a HouseSpec or None, got {type(spec).__name__}")
    if not is_integer(seed) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(seed)

    plan = floor_plan(spec, rng)
    region_category = _region_categories(spec, plan, rng)  # [R]
    num_categories = min(plan.num_regions, len(spec.category_names))
    truth = np.where(plan.region >= 0, region_category[plan.region], -1)  # [H, W] int64
    ox, oy = spec.world_origin
    grid = OccupancyGrid(
        occupancy=plan.occupancy, resolution=float(spec.resolution), origin=(ox, oy, 0.0)
    )

    observations = tour_observations(spec, grid, plan, region_category, num_categories, rng)
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
