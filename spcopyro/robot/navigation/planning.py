r"""``spcopyro navigate``: from an instruction and a start to goals and one path through them.

:func:`navigate` parses the instruction into place words
(:func:`~spcopyro.robot.navigation.goals.parse_instruction`), then, from the start, for each place
in order: the shortest paths from where the robot is
(:func:`~spcopyro.robot.navigation.graph.shortest_paths`) and the word's goal among the regions it
can reach (:func:`~spcopyro.robot.navigation.goals.choose_goal`). Then each leg (start to the first
stop, stop to stop): hierarchically by default, the route over the place graph first and the grid
path kept to the route's places, else the shortest grid path with the reason
(:mod:`~spcopyro.robot.navigation.hierarchy`); ``planner="grid"``: the shortest grid path. The path
is the legs joined (the stops are fixed one after the other, not jointly). Everything is
deterministic: the same fit, instruction and start give the same plan.

Orientation: every pose of the path faces the next one; the last faces along the last step
(a path of one cell faces +x). A waypoint's pose faces along the step that reached it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from spcopyro.maps import OccupancyGrid
from spcopyro.results.result import SpCoResult
from spcopyro.results.uncertainty import unmapped_note, where_probability
from spcopyro.results.where import DEFAULT_WHERE_PRIOR, close_odds
from spcopyro.robot.navigation.goals import (
    AmbiguousGoalError,
    GoalChoice,
    Instruction,
    NavigationError,
    choose_goal,
    parse_instruction,
)
from spcopyro.robot.navigation.graph import (
    PlanningGrid,
    check_same_map,
    fit_cells_on,
    planning_grid,
    shortest_paths,
)
from spcopyro.robot.navigation.hierarchy import (
    BORDER_MARGIN,
    GRID,
    HIERARCHICAL,
    Leg,
    node_places,
    plan_leg,
    with_map_passages,
    with_passability,
)
from spcopyro.robot.navigation.places import PlaceGraph, place_graph, places_along, told_apart

__all__ = ["DEFAULT_RADIUS", "NavigationPlan", "Stop", "navigate", "start_node"]

DEFAULT_RADIUS = 0.2
"""Metres: the robot's radius (clearance from walls) when none is given."""


@dataclass(frozen=True)
class Stop:
    """One place of the instruction and where the robot goes for it."""

    word: str
    via: bool
    choice: GoalChoice
    xy: tuple[float, float]
    yaw: float
    """Radians: facing along the step that reached it."""
    path_index: int
    """Index of its pose in the path."""
    probability: np.ndarray
    """[N] p(cell in the word's place) over the planning map's free cells."""
    said: str = ""
    """The word as the instruction spells it ("TV" for the fit's "tv"); empty: :attr:`word`."""

    @property
    def shown(self) -> str:
        """The word as printed and drawn: as the instruction spells it."""
        return self.said or self.word


@dataclass(frozen=True)
class NavigationPlan:
    """What :func:`navigate` planned."""

    instruction: Instruction
    start: tuple[float, float]
    radius: float
    prior: str
    stops: tuple[Stop, ...]
    path_xy: np.ndarray
    """[K, 2] world x, y of the path's cells (start first, goal last)."""
    path_yaw: np.ndarray
    """[K] radians."""
    length: float
    """Metres along the path."""
    planning: PlanningGrid
    places: PlaceGraph | None = None
    """The fit's place graph (:func:`~spcopyro.robot.navigation.places.place_graph`); planning on
    another map, with the passages that map adds
    (:func:`~spcopyro.robot.navigation.hierarchy.with_map_passages`)."""
    route: tuple[int, ...] = ()
    """Place ids from the start's place through every stop's place: the legs' routes over the
    place graph joined (each leg's shortest route, :mod:`~spcopyro.robot.navigation.hierarchy`).
    Where a leg's path is not kept to a route over the graph (it has none, or it fell back to the
    grid path, or the grid planner was asked for), the places its path crosses, in order, so
    that the route names the places the robot drives through; ``route_from`` says which
    (``graph``: every leg's route; ``path``: some leg's crossed places)."""
    route_from: str = "graph"
    stop_places: tuple[int, ...] = ()
    """The place each leg ends in on :attr:`route` (the stops' places), in order."""
    planner: str = HIERARCHICAL
    """The planner asked for (``hierarchical`` or ``grid``)."""
    legs: tuple[Leg, ...] = ()
    """Start to the first stop, then stop to stop: how each was planned."""
    margin: float = BORDER_MARGIN
    """Metres: the width of the shared borders a hierarchical leg may use."""
    off_map: bool = False
    """Whether some of the fit's cell probability lies on concepts absent from the map
    (:func:`~spcopyro.results.uncertainty.unmapped_note`): the stops' probability, as where's,
    counts the map's concepts only, and navigate.png's colour bar says so."""

    @property
    def planned(self) -> str:
        """How the path was planned: ``hierarchical`` (every leg kept to its route's places),
        ``grid`` (asked for, or every leg fell back) or ``mixed``."""
        used = {leg.planner for leg in self.legs}
        return used.pop() if len(used) == 1 else ("mixed" if used else self.planner)

    @property
    def fallbacks(self) -> tuple[str, ...]:
        """Why legs fell back to the grid path (one line per such leg)."""
        return tuple(f"leg {k + 1}: {leg.reason}" for k, leg in enumerate(self.legs)
                     if leg.reason)  # fmt: skip

    @property
    def grid_length(self) -> float:
        """Metres along the shortest grid path through the same stops (the hierarchy's cost:
        ``length / grid_length``)."""
        return float(sum(leg.grid_length for leg in self.legs))

    @property
    def route_words(self) -> tuple[str, ...]:
        """A word for every place of :attr:`route`: a stop's place reads as the instruction's word
        for it (the robot sent to the kitchen reads "kitchen" there, though the place's name may
        be another word ``where`` answers with it), every other place as its name
        (:attr:`~spcopyro.robot.navigation.places.Place.name`). A place where several
        stops lie in a row reads as their words joined by ``/`` ("go to the kitchen via the
        sink", both in one place: ``sink/kitchen``; only the last was named before)."""
        if not self.places:
            return ()
        said: dict[int, list[str]] = {}  # route position -> the words of the stops there
        position = 0
        for place, stop in zip(self.stop_places, self.stops, strict=False):
            if place < 0:  # a leg that ends in no place
                continue
            # each leg ends at its stop's place, at or after where the last leg ended
            ahead = [k for k in range(position, len(self.route)) if self.route[k] == place]
            if ahead:
                position = ahead[0]
                words = said.setdefault(position, [])
                if stop.shown not in words:
                    words.append(stop.shown)
        return tuple("/".join(said[k]) if k in said else self.places.places[i].name
                     for k, i in enumerate(self.route))  # fmt: skip

    @property
    def route_names(self) -> tuple[str, ...]:
        """:attr:`route_words` as ``navigate`` prints them, told apart
        (:func:`~spcopyro.robot.navigation.places.told_apart`): a word naming two places of the
        route adds each one's concept ("kitchen (concept 1)", "kitchen (concept 2)"); a place
        that needs its id for any reason shows it with every word that names it: two regions of
        one concept ("bedroom (place 3) -> corridor -> kitchen -> bedroom (place 4)"), or one
        place named by two words, passed as its top word and reached as a stop (the default
        demo's unrefined fit, "go to the kitchen via the living room": "entrance -> restroom ->
        sink (place 5) -> living -> kitchen (place 5)", printed "... sink -> living -> kitchen"
        before). Where "sink" also names another place, of another concept, that one reads
        "sink (place 7)": one word, one kind of tag."""
        if not self.places:
            return ()
        return told_apart(self.places, self.route, self.route_words)

    @property
    def goal(self) -> Stop:
        return self.stops[-1]

    @property
    def notes(self) -> tuple[str, ...]:
        return tuple(note for stop in self.stops for note in stop.choice.notes)


def start_node(planning: PlanningGrid, start: tuple[float, float]) -> int:
    """The allowed index of the start's cell; NavigationError saying why it is none (off the map,
    on a wall or unknown cell, closer to a wall than the robot's radius)."""
    grid = planning.grid
    x, y = float(start[0]), float(start[1])
    if not (math.isfinite(x) and math.isfinite(y)):
        raise NavigationError(f"--start {x},{y}: not a finite point")
    try:  # a point as far as 1e308 overflowed and said only "xy is too far from the map origin"
        with np.errstate(over="ignore", invalid="ignore"):
            cell = grid.world_to_cell(np.array([x, y]))
    except ValueError:
        cell = None
    if cell is None or not bool(grid.in_bounds(cell)):
        corners = np.array([[grid.height - 1, 0], [0, grid.width - 1]])  # lower left, upper right
        (x0, y0), (x1, y1) = grid.cell_to_world(corners)
        half = grid.resolution / 2
        raise NavigationError(
            f"--start {x:g},{y:g} is off the map, which spans x {x0 - half:.2f}..{x1 + half:.2f}, "
            f"y {y0 - half:.2f}..{y1 + half:.2f} m"
        )
    if not bool(grid.is_free(cell)):
        raise NavigationError(
            f"--start {x:g},{y:g} lies on a cell that is not free (a wall or unknown space); "
            "give the robot's position on free space"
        )
    node = planning.node_of(cell)
    if node < 0:
        clearance = float(planning.clearance[cell[0], cell[1]])
        hint = ""
        if planning.num_allowed:
            centres = grid.cell_to_world(planning.allowed.free_cells)  # [M, 2]
            near = int(np.argmin(np.hypot(centres[:, 0] - x, centres[:, 1] - y)))
            near_x, near_y = centres[near]
            away = float(np.hypot(near_x - x, near_y - y))
            hint = (
                f"; the nearest cell with that clearance is at x={near_x:.2f} y={near_y:.2f} "
                f"({away:.2f} m away)"
            )
        raise NavigationError(
            f"--start {x:g},{y:g} is {clearance:.2f} m from a wall or unknown space, closer than "
            f"the robot's radius {planning.radius:g} m (--radius){hint}"
        )
    return node


def _yaws(xy: np.ndarray) -> np.ndarray:
    """[K] the heading of every pose: towards the next, the last along the last step."""
    if len(xy) < 2:
        return np.zeros(len(xy))
    step = np.diff(xy, axis=0)  # [K-1, 2]
    heading = np.arctan2(step[:, 1], step[:, 0])
    return np.concatenate([heading, heading[-1:]])


def navigate(
    result: SpCoResult,
    instruction: str,
    start: tuple[float, float],
    *,
    radius: float = DEFAULT_RADIUS,
    strict: bool = False,
    prior: str = DEFAULT_WHERE_PRIOR,
    grid: OccupancyGrid | None = None,
    planning: PlanningGrid | None = None,
    places: PlaceGraph | None = None,
    planner: str = HIERARCHICAL,
    margin: float = BORDER_MARGIN,
) -> NavigationPlan:
    """Plan ``instruction`` from ``start`` (world x, y in metres) on ``grid``: a map in the
    fit's frame (the map a coarse fit was made from: walls as thin as the robot's map has
    them), the fit's probabilities carried onto its cells
    (:func:`~spcopyro.robot.navigation.graph.fit_cells_on`); None: the fit's own grid.
    ``planning``: a ready :func:`planning_grid` of that grid (reused across calls); ``places``: a
    ready :func:`~spcopyro.robot.navigation.places.place_graph` of the fit. ``planner``:
    ``hierarchical`` (each leg over the place graph, then kept to its route's places; ``margin``
    metres: the shared borders' width, at least the fit's cell size) or ``grid``
    (:mod:`~spcopyro.robot.navigation.hierarchy`).

    Raises:
        ValueError: a misspelt word or none naming a place (the close known words named), an
            unknown planner, a ``grid`` that is not the fit's map
            (:func:`~spcopyro.robot.navigation.graph.check_same_map`).
        NavigationError: a bad start; UnreachableGoalError, AmbiguousGoalError (``strict``).
    """
    if planner not in (HIERARCHICAL, GRID):
        raise ValueError(f"planner {planner!r}: {HIERARCHICAL} or {GRID}")
    parsed = parse_instruction(instruction, result.vocabulary)
    grid = result.grid if grid is None else grid
    if grid is not result.grid:
        check_same_map(result.grid, grid)
    planning = planning_grid(grid, radius) if planning is None else planning
    carry = None if grid is result.grid else fit_cells_on(result.grid, grid)  # [N_map]
    places = place_graph(result) if places is None else places
    node_place = node_places(places, result.grid, planning)  # [M]
    if carry is not None:  # another map: passages its doorways open (hierarchy, 2.)
        places = with_map_passages(places, planning, node_place)
    margin = max(float(margin), result.grid.resolution)
    places = with_passability(places, planning, node_place, margin)  # the robot's passages
    current = start_node(planning, start)
    legs: list[Leg] = []
    stops_info = []
    for k, (word, via) in enumerate(zip(parsed.places, parsed.via, strict=True)):
        probability = where_probability(result, word, prior)  # [N] on the fit's cells
        if carry is not None:
            probability = probability[carry]  # [N] on the planning map's cells
        distance, predecessors = shortest_paths(planning, current)
        said = parsed.spelling(k)
        choice = choose_goal(planning, said, probability, distance, strict=strict)
        choice = _with_where_warnings(choice, result, word, prior, strict)
        legs.append(plan_leg(planning, places, node_place, current, choice.node, distance,
                             predecessors, planner=planner, margin=margin))  # fmt: skip
        stops_info.append((word, via, choice, probability, sum(len(g.nodes) - 1 for g in legs),
                           said))  # fmt: skip
        current = choice.node
    nodes = np.concatenate([legs[0].nodes[:1]] + [leg.nodes[1:] for leg in legs])  # [K]
    xy = planning.grid.cell_to_world(planning.cells(nodes))  # [K, 2]
    yaw = _yaws(xy)
    steps = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.zeros(0)
    stops = []
    for word, via, choice, probability, index, said in stops_info:
        arrive = float(yaw[index - 1]) if index > 0 else float(yaw[index])
        stops.append(Stop(word, via, choice, (float(xy[index, 0]), float(xy[index, 1])), arrive,
                          index, probability, said))  # fmt: skip
    route, route_from, stop_places = _route(result, places, legs, planning)
    return NavigationPlan(
        instruction=parsed,
        start=(float(start[0]), float(start[1])),
        radius=float(radius),
        prior=prior,
        stops=tuple(stops),
        path_xy=xy,
        path_yaw=yaw,
        length=float(steps.sum()),
        planning=planning,
        places=places,
        route=route,
        route_from=route_from,
        stop_places=stop_places,
        planner=planner,
        legs=tuple(legs),
        margin=margin,
        off_map=bool(unmapped_note(result)),  # computed once per result, as where's figures
    )


def _with_where_warnings(
    choice: GoalChoice, result: SpCoResult, word: str, prior: str, strict: bool
) -> GoalChoice:
    """``choice`` with the warnings ``spcopyro where`` gives for ``word`` among its notes (an
    answer not clearly more probable than the runner-up concept, a word that says little, a
    speck): the robot drove to an answer ``where`` warns of without a word. ``strict``: an
    answer whose odds over the runner-up are below :data:`~spcopyro.results.where.ODDS_WARNING`
    is an :class:`AmbiguousGoalError`, as two regions of near-equal probability are."""
    answer = result.where(word, prior)
    if strict and answer.close_to_guess and answer.runner_up is not None:  # odds < 3: has one
        odds = close_odds(answer.concept, answer.runner_up, answer.probability,
                          answer.runner_up_probability)  # fmt: skip
        raise AmbiguousGoalError(f"{word!r} is ambiguous: {odds}: --strict drives to no such "
                                 "answer")  # fmt: skip
    notes = tuple(f"where {word!r}: {w}" for w in answer.warnings)
    return dataclasses.replace(choice, notes=choice.notes + notes, where_odds=answer.odds,
                               concept=answer.concept, shared_with=answer.shared_with)  # fmt: skip


def _route(
    result: SpCoResult, places: PlaceGraph, legs: list[Leg], planning: PlanningGrid
) -> tuple[tuple[int, ...], str, tuple[int, ...]]:
    """:attr:`NavigationPlan.route`: the legs' routes joined; where it came from (``graph``, or
    ``path`` where a leg's path was not kept to its route and the places it crosses stand in);
    and the place each leg ends in (:attr:`NavigationPlan.stop_places`)."""
    route: list[int] = []
    ends: list[int] = []
    source = "graph"
    for leg in legs:
        if leg.places and leg.planner == HIERARCHICAL:
            part = list(leg.places)
        else:
            source = "path"
            xy = planning.grid.cell_to_world(planning.cells(leg.nodes))  # [k, 2]
            part = list(places_along(places, result.grid.world_to_cell(xy)))
        route += part[1:] if route and part and part[0] == route[-1] else part
        ends.append(part[-1] if part else -1)  # -1: in no place
    return tuple(route), source, tuple(ends)
