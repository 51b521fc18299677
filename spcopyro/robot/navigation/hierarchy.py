r"""Hierarchical planning (issue 27 item 2, SpCoTMHP's hierarchy): over the place graph first,
then within the grid, kept to the route's places.

For every leg of a plan (from where the robot is to the next stop's goal cell):

1. **Places.** Every cell the robot fits on belongs to a place of the fit's place graph
   (:func:`node_places`): the place of the fit cell holding its centre; a cell of a region too
   small to be a place (or under a wall that coarsening thickened) takes the place of the
   nearest such cell along the planning graph.
2. **Route.** The shortest route over the place graph from the leg's first place to its last
   (:meth:`~spcopyro.robot.navigation.places.PlaceGraph.route`: passages weighted by the distance
   between the places' centroids). Planning on another map than the fit's grid (the finer map a
   coarse fit was made from), the graph first gains a passage for every two places whose cells
   the robot fits on touch on that map but not on the fit's grid (:func:`with_map_passages`):
   coarsening thickens walls and closes doorways, so a coarse fit's regions often do not touch
   where the robot can pass. A passage the robot cannot take -- its two places' corridor
   (below) does not join them: a one-cell contact of two regions, a doorway narrower than the
   robot -- is left out of the route (:func:`with_passability`).
3. **Corridor** (:func:`corridor`). The cells the leg may use: the allowed cells (the robot's
   clearance kept: :mod:`~spcopyro.robot.navigation.graph`) of the route's places, plus the
   shared border of every two consecutive places of the route: the allowed cells within
   ``margin`` metres of both (default :data:`BORDER_MARGIN` or the fit's cell size, the larger:
   region borders on a coarse fit are jagged at its cell size, and a doorway's few cells may
   carry a third concept's label).
4. **Grid path.** The shortest 8-connected path from the leg's start to its goal over the
   corridor's cells only.

**Fallback.** Where the graph has no route between the two places (a dropped small region was
their only link) or the corridor does not join start and goal (a doorway between two route
places that the robot's clearance or the fit's labels close), the leg is the shortest grid path
over every allowed cell, and the reason is recorded (:attr:`Leg.reason`) and printed. The goals
themselves do not change: they are chosen before (by unconstrained path length,
:func:`~spcopyro.robot.navigation.goals.choose_goal`), so the hierarchy changes the way, never
where the robot ends up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spcopyro.maps import OccupancyGrid
from spcopyro.robot.navigation.graph import PlanningGrid, trace_path
from spcopyro.robot.navigation.places import DOORWAY_WIDTH, Passage, PlaceGraph, told_apart

__all__ = [
    "BORDER_MARGIN",
    "GRID",
    "HIERARCHICAL",
    "PLANNERS",
    "Leg",
    "corridor",
    "node_places",
    "plan_leg",
    "with_map_passages",
    "with_passability",
]

HIERARCHICAL = "hierarchical"
"""The planner that keeps each leg to its route's places (module docstring)."""
GRID = "grid"
"""The planner that takes the shortest grid path over every allowed cell."""
PLANNERS = (HIERARCHICAL, GRID)
BORDER_MARGIN = 0.25
"""Metres: cells this close to both of two consecutive places of a route are their shared
border (at least the fit's cell size is used)."""


@dataclass(frozen=True)
class Leg:
    """One leg of a plan: from where the robot is to the next stop's goal."""

    places: tuple[int, ...]
    """The route over the place graph (place ids, the leg's first place to its last); () when
    the graph has none."""
    planner: str
    """How its path was planned: :data:`HIERARCHICAL` (kept to the route's places) or
    :data:`GRID` (asked for, or the fallback)."""
    reason: str | None
    """Why a hierarchical plan fell back to the grid path; None otherwise."""
    nodes: np.ndarray
    """[k] allowed indices from the leg's start to its goal (inclusive)."""
    length: float
    """Metres along the leg's path."""
    grid_length: float
    """Metres along the shortest grid path over every allowed cell (``length`` >= it)."""
    corridor: np.ndarray | None = None
    """[M] bool: the allowed cells the leg was kept to (:func:`corridor`); None for a grid
    path."""

    @property
    def detour(self) -> float:
        """``length / grid_length`` (1 for a leg of no length)."""
        return self.length / self.grid_length if self.grid_length > 0 else 1.0


def node_places(places: PlaceGraph, fit_grid: OccupancyGrid, planning: PlanningGrid) -> np.ndarray:
    """``[M]`` the place id of every allowed cell of ``planning`` (module docstring, 1): the
    place of the fit cell holding its centre; a cell whose fit cell is in no place (a wall that
    coarsening thickened, a dropped small region, off the fit's map) takes the place of the
    nearest such cell along the planning graph (geodesic: never a place behind a wall), or the
    Euclidean nearest place where its component holds none. All -1 for a graph without
    places."""
    from scipy.ndimage import distance_transform_edt
    from scipy.sparse.csgraph import dijkstra

    m = planning.num_allowed
    if not places.places or m == 0:
        return np.full(m, -1, dtype=np.int64)
    regions = places.regions  # [H, W] on the fit's grid
    centres = planning.grid.cell_to_world(planning.cells(np.arange(m)))  # [M, 2]
    cells = fit_grid.world_to_cell(centres)  # [M, 2] may lie off the fit's map
    height, width = regions.shape
    on = (cells[:, 0] >= 0) & (cells[:, 0] < height) & (cells[:, 1] >= 0) & (cells[:, 1] < width)
    rows, cols = np.clip(cells[:, 0], 0, height - 1), np.clip(cells[:, 1], 0, width - 1)
    direct = np.where(on, regions[rows, cols], -1).astype(np.int64)  # [M]
    seeds = np.flatnonzero(direct >= 0)
    out = direct.copy()
    rest = direct < 0
    if seeds.size and rest.any():
        distance, _, source = dijkstra(planning.graph, directed=False, indices=seeds,
                                       min_only=True, return_predecessors=True)  # fmt: skip
        reached = rest & np.isfinite(distance) & (source >= 0)
        out[reached] = direct[source[reached]]
        rest &= ~reached
    if rest.any():  # a component of the planning graph without a place's cell: the nearest
        _, (near_r, near_c) = distance_transform_edt(regions < 0, return_indices=True)
        out[rest] = regions[near_r[rows[rest], cols[rest]], near_c[rows[rest], cols[rest]]]
    return out


def with_map_passages(
    places: PlaceGraph, planning: PlanningGrid, node_place: np.ndarray
) -> PlaceGraph:
    """``places`` with a passage (:attr:`~spcopyro.robot.navigation.places.Passage.on_map`) for
    every two places whose allowed cells touch on the planning map (4-neighbours, ``node_place``
    from :func:`node_places`) and that have none yet; its border: the touching cell pairs x the
    planning map's cell size."""
    from dataclasses import replace

    from spcopyro.maps.regions import region_contacts

    cells = planning.cells(np.arange(planning.num_allowed))  # [M, 2]
    image = np.full(planning.grid.shape, -1, dtype=np.int64)  # [H, W]
    image[cells[:, 0], cells[:, 1]] = node_place
    known = {(min(e.a, e.b), max(e.a, e.b)) for e in places.passages}
    added = []
    for a, b, touching in zip(*region_contacts(image), strict=True):
        if (int(a), int(b)) in known:
            continue
        border = float(touching * planning.grid.resolution)
        gap = float(np.hypot(*np.subtract(places.places[a].centroid, places.places[b].centroid)))
        added.append(Passage(int(a), int(b), border, bool(border <= DOORWAY_WIDTH + 1e-9), gap,
                             on_map=True))  # fmt: skip
    return replace(places, passages=places.passages + tuple(added)) if added else places


def with_passability(
    places: PlaceGraph, planning: PlanningGrid, node_place: np.ndarray, margin: float
) -> PlaceGraph:
    """``places`` with every passage marked passable or not
    (:attr:`~spcopyro.robot.navigation.places.Passage.passable`): whether the :func:`corridor`
    of its two places joins a cell of one to a cell of the other (8-connected, over the cells
    the robot fits on). A region boundary one fit cell long, or a doorway narrower than the
    robot, is a passage of the fit's labels that the robot cannot take: a route through it
    would fall back to the grid path (module docstring) while naming places the path does not
    cross."""
    from dataclasses import replace

    from scipy.sparse.csgraph import connected_components

    marked = []
    for passage in places.passages:
        inside = np.flatnonzero(corridor(planning, node_place, (passage.a, passage.b), margin))
        _, component = connected_components(planning.graph[inside][:, inside], directed=False)
        own = node_place[inside]  # [m]
        joined = np.intersect1d(component[own == passage.a], component[own == passage.b]).size
        marked.append(replace(passage, passable=bool(joined)))
    return replace(places, passages=tuple(marked), robot_checked=True)


def corridor(
    planning: PlanningGrid, node_place: np.ndarray, route: tuple[int, ...], margin: float
) -> np.ndarray:
    """``[M]`` bool: the allowed cells a leg along ``route`` may use (module docstring, 3)."""
    from scipy.ndimage import distance_transform_edt

    inside = np.isin(node_place, np.asarray(route, dtype=np.int64))  # [M]
    if len(route) < 2:
        return inside
    cells = planning.cells(np.arange(planning.num_allowed))  # [M, 2]
    image = np.full(planning.grid.shape, -1, dtype=np.int64)  # [H, W] place of allowed cells
    image[cells[:, 0], cells[:, 1]] = node_place
    near = {}
    for place in set(route):
        distance = distance_transform_edt(image != place) * planning.grid.resolution  # [H, W]
        near[place] = distance[cells[:, 0], cells[:, 1]] <= margin + 1e-9  # [M]
    for a, b in zip(route[:-1], route[1:], strict=True):
        inside |= near[a] & near[b]
    return inside


def _names(places: PlaceGraph, route: tuple[int, ...] | list[int]) -> str:
    """The places of ``route`` as ``navigate`` prints a route: their names, told apart
    (:func:`~spcopyro.robot.navigation.places.told_apart`)."""
    return " -> ".join(told_apart(places, route))


def plan_leg(
    planning: PlanningGrid,
    places: PlaceGraph,
    node_place: np.ndarray,
    source: int,
    target: int,
    grid_distance: np.ndarray,
    grid_predecessors: np.ndarray,
    *,
    planner: str = HIERARCHICAL,
    margin: float = BORDER_MARGIN,
) -> Leg:
    """The leg from allowed cell ``source`` to ``target`` (module docstring);
    ``grid_distance``, ``grid_predecessors``: the unconstrained shortest paths from ``source``
    (:func:`~spcopyro.robot.navigation.graph.shortest_paths`), the fallback."""
    from scipy.sparse.csgraph import dijkstra

    if planner not in PLANNERS:
        raise ValueError(f"planner {planner!r}: one of {', '.join(PLANNERS)}")
    grid_length = float(grid_distance[target])
    start_place, goal_place = int(node_place[source]), int(node_place[target])
    route = places.route(start_place, goal_place) if min(start_place, goal_place) >= 0 else None
    places_on = tuple(route) if route is not None else ()

    def fallback(reason: str | None) -> Leg:
        nodes = trace_path(grid_predecessors, target)
        return Leg(places_on, GRID, reason, nodes, grid_length, grid_length)

    if planner == GRID:
        return fallback(None)
    if route is None:
        if min(start_place, goal_place) < 0:
            return fallback("the fit has no places (every region under the place graph's "
                            f"{places.min_area:g} m^2)")  # fmt: skip
        return fallback(
            f"no route over the place graph from {_names(places, [start_place])} (place "
            f"{start_place}) to {_names(places, [goal_place])} (place {goal_place})"
        )
    inside = corridor(planning, node_place, places_on, margin)  # [M]
    allowed = np.flatnonzero(inside)  # [m]
    local = np.full(planning.num_allowed, -1, dtype=np.int64)
    local[allowed] = np.arange(allowed.size)
    sub = planning.graph[allowed][:, allowed]
    distance, predecessors = dijkstra(
        sub, directed=False, indices=int(local[source]), return_predecessors=True
    )
    if not np.isfinite(distance[local[target]]):
        return fallback(
            f"the places of the route {_names(places, places_on)} do not join the leg's start "
            f"and goal with {planning.radius:g} m of clearance"
        )
    nodes = allowed[trace_path(predecessors, int(local[target]))]
    length = float(distance[local[target]])
    return Leg(places_on, HIERARCHICAL, None, nodes, length, grid_length, inside)
