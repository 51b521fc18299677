"""Open-plan synthetic houses against the baselines that read no data (issue 21, item 1).

:meth:`HouseSpec.open_plan <spcopyro.synthetic.HouseSpec.open_plan>` draws houses whose largest
walled space holds several categories side by side (a living-dining-kitchen). Cutting the map at
its doors cannot separate them, so the geometry baseline (F) is capped well below 1 there,
while a method that reads the words and images can tell the categories apart.
:func:`open_plan_scores` measures one house, :func:`open_plan_table` a few seeds;
:func:`observation_oracle` is a reference that no method can be (it reads the truth at the
observations) for how far the data alone place the borders in the open plan;
``python -m spcopyro.experiments.open_plan`` prints the table quoted in
:meth:`HouseSpec.open_plan` and in ``docs/defaults.md``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from spcopyro.baselines.geometry import DEFAULT_DOOR_WIDTH, geometry_semantic_map, room_segments
from spcopyro.baselines.nearest import nearest_word_map
from spcopyro.experiments.methods import PUBLIC_DOOR_WIDTH
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import HouseSpec, make_house
from spcopyro.synthetic.floor_plan import floor_plan

__all__ = [
    "OpenPlanScores",
    "categories_in_segments",
    "observation_oracle",
    "open_plan_scores",
    "open_plan_table",
]

MIN_SEGMENT_SHARE = 0.05
"""A category counts in a segment when it holds at least this share of the segment's cells."""


@dataclass(frozen=True)
class OpenPlanScores:
    """One open-plan house (seed) against the baselines; ARIs against ``house.truth``."""

    seed: int
    free_cells: int
    categories: int
    segments: int  # room segments of the geometry baseline at DEFAULT_DOOR_WIDTH
    most_in_one_segment: int  # the most truth categories holding >= 5 % of one such segment
    geometry: float  # (F) at DEFAULT_DOOR_WIDTH (1 m: its width for synthetic houses)
    geometry_wide: float  # (F) at PUBLIC_DOOR_WIDTH (2 m: its width for the public houses)
    nearest: float  # (E) the nearest utterance's word
    geometry_open: float  # (F), over the open-plan space's cells only
    nearest_open: float  # (E), over the open-plan space's cells only
    oracle: float  # observation_oracle: each observation's own truth region, nearest within walls


def categories_in_segments(
    segments: np.ndarray, truth: np.ndarray, share: float = MIN_SEGMENT_SHARE
) -> list[int]:
    """Per segment of ``segments`` ([H, W], 0..S-1, -1 off), the truth categories ([H, W])
    holding at least ``share`` of its cells (doorway cells take the nearest room's category,
    so a segment cut at a door holds a few cells of its neighbour's)."""
    counts = []
    for s in range(int(segments.max()) + 1):
        inside = truth[(segments == s) & (truth >= 0)]  # [n_s]
        sizes = np.bincount(inside)
        counts.append(int((sizes >= share * inside.size).sum()) if inside.size else 0)
    return counts


def observation_oracle(grid, observations, truth: np.ndarray) -> np.ndarray:
    """``[H, W]`` every free cell labelled with the truth region of the nearest observation
    (image or utterance, by straight-line distance) inside its room segment (the geometry
    baseline's rooms at ``DEFAULT_DOOR_WIDTH``); a segment without observations is one label.

    Not a method: it reads ``truth`` at the observations. It is what a fit would report if it
    recognised every observation's place perfectly and, with nothing observed in between, put
    each border half-way between the places' observations (a Voronoi cut). On the open-plan
    houses the observations of a place lie within 0.25 m of one spot anywhere in its region, so
    the truth's borders in the open plan are not in the data; this reference says how much of
    them a fit can place from the data alone (docs/real_houses.md).
    """
    free = np.asarray(grid.free, dtype=bool)  # [H, W]
    segments = room_segments(grid, door_width=DEFAULT_DOOR_WIDTH)  # [H, W]
    cells = np.concatenate([grid.world_to_cell(observations.image_xy),
                            grid.world_to_cell(observations.word_xy)])  # fmt: skip  # [T, 2]
    inside = grid.in_bounds(cells)  # [T] bool
    cells = cells[inside]
    cells = cells[free[cells[:, 0], cells[:, 1]]]  # [T', 2] observations on free cells
    labels = np.full(grid.shape, -1, dtype=np.int64)  # [H, W]
    spare = int(truth.max()) + 1  # labels for the segments nobody observed
    for segment in range(int(segments.max()) + 1):
        here = segments == segment  # [H, W] bool
        mine = cells[here[cells[:, 0], cells[:, 1]]]  # [t, 2]
        if mine.size == 0:
            labels[here] = spare + segment
            continue
        observed = np.zeros(grid.shape, dtype=bool)
        observed[mine[:, 0], mine[:, 1]] = True
        _, (rows, cols) = ndimage.distance_transform_edt(~observed, return_indices=True)
        labels[here] = truth[rows, cols][here]
    return labels


def open_plan_scores(seed: int, spec: HouseSpec | None = None) -> OpenPlanScores:
    """Score the geometry (F) and nearest-utterance (E) baselines on one open-plan house
    (``spec`` default :meth:`HouseSpec.open_plan`), over the house and over its open plan."""
    spec = HouseSpec.open_plan() if spec is None else spec
    house = make_house(seed=seed, spec=spec)
    truth = house.truth
    assert truth is not None and house.category_names is not None
    # The floor plan is make_house's first draw: the same seed gives the same regions.
    plan = floor_plan(spec, np.random.default_rng(seed))
    np.testing.assert_array_equal(plan.occupancy, house.grid.occupancy)
    open_truth = np.where(plan.region < plan.open_pairs * plan.open_size, truth, -1)  # [H, W]
    grid, observations = house.grid, house.observations
    geometry = geometry_semantic_map(grid, observations, door_width=DEFAULT_DOOR_WIDTH)
    wide = geometry_semantic_map(grid, observations, door_width=PUBLIC_DOOR_WIDTH)
    nearest = nearest_word_map(grid, observations)
    segments = room_segments(grid, door_width=DEFAULT_DOOR_WIDTH)  # [H, W]
    most = max(categories_in_segments(segments, truth))
    return OpenPlanScores(
        seed=seed,
        free_cells=int(grid.num_free),
        categories=len(house.category_names),
        segments=int(segments.max()) + 1,
        most_in_one_segment=int(most),
        geometry=adjusted_rand_index(geometry.label_image(), truth),
        geometry_wide=adjusted_rand_index(wide.label_image(), truth),
        nearest=adjusted_rand_index(nearest.label_image(), truth),
        geometry_open=adjusted_rand_index(geometry.label_image(), open_truth),
        nearest_open=adjusted_rand_index(nearest.label_image(), open_truth),
        oracle=adjusted_rand_index(observation_oracle(grid, observations, truth), truth),
    )


def open_plan_table(seeds: Iterable[int] = range(5), spec: HouseSpec | None = None) -> str:
    """A markdown table of :func:`open_plan_scores` per seed and their mean."""
    rows = [open_plan_scores(seed, spec) for seed in seeds]
    lines = [
        "| seed | free cells | categories | (F) segments (1 m) | most categories in one segment* "
        "| (F) 1 m ARI | (F) 2 m ARI | (E) nearest ARI | open plan only: (F) 1 m / (E) ARI "
        "| oracle** ARI |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.seed} | {r.free_cells} | {r.categories} | {r.segments} "
            f"| {r.most_in_one_segment} | {r.geometry:.3f} | {r.geometry_wide:.3f} "
            f"| {r.nearest:.3f} | {r.geometry_open:.3f} / {r.nearest_open:.3f} "
            f"| {r.oracle:.3f} |"
        )

    def mean(key: str) -> float:
        return float(np.mean([getattr(r, key) for r in rows]))

    lines.append(
        f"| mean | {mean('free_cells'):.0f} | {mean('categories'):g} | {mean('segments'):g} "
        f"| {mean('most_in_one_segment'):g} | **{mean('geometry'):.3f}** "
        f"| **{mean('geometry_wide'):.3f}** | {mean('nearest'):.3f} "
        f"| {mean('geometry_open'):.3f} / {mean('nearest_open'):.3f} | {mean('oracle'):.3f} |"
    )
    lines.append("")
    lines.append(
        f"*: categories holding >= {MIN_SEGMENT_SHARE:.0%} of the segment's cells; "
        "ARIs against the house's truth over all free cells, or over the open-plan space's. "
        "**: observation_oracle, which reads the truth at the observations (not a method)."
    )
    return "\n".join(lines) + "\n"


def main() -> None:
    """Print the table for :meth:`HouseSpec.open_plan`, seeds 0-4."""
    print(open_plan_table())


if __name__ == "__main__":
    main()
