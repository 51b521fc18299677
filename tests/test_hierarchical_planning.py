"""Hierarchical planning (issue 27 item 2, SpCoTMHP): the place graph's route first, then the grid
path kept to the route's places, the shortest grid path as a reported fallback.

The third-room house (0.1 m cells): a corridor B along the top (rows 1-3, cols 1-29); below it,
behind a wall (row 4), a bedroom A (rows 5-14, cols 1-9), a tall living room T (rows 5-40,
cols 11-19) and a kitchen C (rows 5-14, cols 21-29). Doors 0.5 m wide: A-B (row 4, cols 3-7),
B-C (row 4, cols 23-27), A-T (col 10, rows 8-12) and T-C (col 20, rows 8-12); T and B do not
touch. Through T is the shortest way from A to C on the grid; over the place graph (centroid
distances: A-T-C 2 x 1.64 m, A-B-C 2 x 1.25 m by hand) the route is A-B-C. Variants: the B-C
door narrowed to 0.2 m (a passage the robot cannot take), the corridor B pinched to 0.2 m
between its doors (a route whose places do not join), the A-B door walled up.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hand_results import one_word_per_concept
from test_navigate import START_A, house_result

from spcopyro.cli.main import main
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.results.result import SpCoResult
from spcopyro.robot.navigation import navigate
from spcopyro.robot.navigation.hierarchy import corridor, node_places
from spcopyro.robot.navigation.places import place_graph

WORDS = ("bedroom", "corridor", "kitchen", "living")
RES = 0.1
ROOMS = {  # rows [start, stop), cols [start, stop), concept
    "A": ((5, 15), (1, 10), 0),
    "B": ((1, 4), (1, 30), 1),
    "C": ((5, 15), (21, 30), 2),
    "T": ((5, 41), (11, 20), 3),
}


def third_room_result(
    bc_door: tuple[int, int] = (23, 28), ab_door: bool = True, b_pinch: bool = False
) -> SpCoResult:
    """The third-room house (module docstring); ``bc_door``: the B-C door's columns [a, b);
    ``ab_door=False``: the A-B door walled up (as a coarse fit's thickened walls close one);
    ``b_pinch``: the corridor B narrowed to 0.2 m (rows 1-2) over columns 14-16, between its
    two doors."""
    occupancy = np.full((42, 31), OCCUPIED, dtype=np.int8)  # [H, W]
    image = np.full(occupancy.shape, -1)
    for (r0, r1), (c0, c1), concept in ROOMS.values():
        occupancy[r0:r1, c0:c1] = FREE
        image[r0:r1, c0:c1] = concept
    if b_pinch:
        occupancy[3, 14:17] = OCCUPIED
        image[3, 14:17] = -1
    doors = [((4, 5), bc_door, 1), ((8, 13), (10, 11), 3), ((8, 13), (20, 21), 3)]
    doors += [((4, 5), (3, 8), 1)] if ab_door else []
    for (r0, r1), (c0, c1), concept in doors:
        occupancy[r0:r1, c0:c1] = FREE
        image[r0:r1, c0:c1] = concept
    grid = OccupancyGrid(occupancy=occupancy, resolution=RES, origin=(0.0, 0.0, 0.0))
    return one_word_per_concept(grid, image[grid.free], WORDS)


def cell_xy(row: int, col: int) -> tuple[float, float]:
    x, y = third_room_result().grid.cell_to_world(np.array([row, col]))
    return float(x), float(y)


START = cell_xy(10, 5)  # in A, level with the A-T door


def concepts_on(result: SpCoResult, path_xy: np.ndarray) -> set[int]:
    cells = result.grid.world_to_cell(path_xy)
    return set(result.label_image()[cells[:, 0], cells[:, 1]].tolist())


def path_places(plan) -> set[int]:
    cells = plan.planning.grid.world_to_cell(plan.path_xy)
    return set(plan.places.regions[cells[:, 0], cells[:, 1]].tolist())


def test_the_hierarchical_path_stays_inside_the_routes_places():
    result = house_result()
    plan = navigate(result, "go to the bedroom via the kitchen", START_A, radius=0.1)
    assert plan.planner == "hierarchical" and plan.planned == "hierarchical"
    assert plan.fallbacks == ()
    assert plan.route_words == ("bedroom", "corridor", "kitchen", "bedroom")
    assert path_places(plan) <= set(plan.route)
    for leg in plan.legs:  # each leg inside its own route's places
        cells = plan.planning.cells(leg.nodes)
        assert set(plan.places.regions[cells[:, 0], cells[:, 1]].tolist()) <= set(leg.places)
        assert leg.length >= leg.grid_length - 1e-9
    # here the route is also the grid's shortest way: the same length as the grid planner's
    grid_plan = navigate(result, "go to the bedroom via the kitchen", START_A, radius=0.1,
                         planner="grid")  # fmt: skip
    assert plan.length == pytest.approx(grid_plan.length)
    assert plan.grid_length == pytest.approx(grid_plan.length)
    assert grid_plan.planned == "grid" and grid_plan.fallbacks == ()


def test_a_route_that_would_cut_through_a_third_room_keeps_to_the_route():
    result = third_room_result()
    graph = place_graph(result)
    assert len(graph.places) == 4 and len(graph.passages) == 4  # A-B, B-C, A-T, T-C
    grid_plan = navigate(result, "go to the kitchen", START, radius=0.1, planner="grid")
    assert 3 in concepts_on(result, grid_plan.path_xy)  # the shortest grid path crosses T
    plan = navigate(result, "go to the kitchen", START, radius=0.1)
    assert plan.route_words == ("bedroom", "corridor", "kitchen")
    assert plan.planned == "hierarchical" and plan.fallbacks == ()
    assert concepts_on(result, plan.path_xy) == {0, 1, 2}  # never in T
    assert path_places(plan) <= set(plan.route)
    assert plan.goal.xy == grid_plan.goal.xy  # the same goal, another way there
    assert plan.length > grid_plan.length
    assert plan.grid_length == pytest.approx(grid_plan.length)
    assert plan.legs[0].detour == pytest.approx(plan.length / grid_plan.length)
    # the path still keeps the clearance
    clearance = plan.planning.clearance
    cells = result.grid.world_to_cell(plan.path_xy)
    assert (clearance[cells[:, 0], cells[:, 1]] >= 0.1 - 1e-9).all()


def test_the_corridor_is_the_routes_places_and_their_shared_borders():
    result = third_room_result()
    graph = place_graph(result)
    plan = navigate(result, "go to the kitchen", START, radius=0.0)
    planning = plan.planning
    node_place = node_places(graph, result.grid, planning)
    a, b, c = plan.route
    only = corridor(planning, node_place, (a,), 0.0)
    assert only.sum() == (node_place == a).sum()
    mask = corridor(planning, node_place, (a, b, c), 0.0)
    assert mask.sum() == np.isin(node_place, [a, b, c]).sum()
    wider = corridor(planning, node_place, (a, b, c), 0.25)
    extra = planning.cells(np.flatnonzero(wider & ~mask))  # near both A and B, or B and C
    assert len(extra) > 0
    assert set(result.label_image()[extra[:, 0], extra[:, 1]].tolist()) == {3}  # T's corners
    assert (extra[:, 0] <= 6).all()  # only by the wall under the corridor, not T's middle


def test_a_passage_narrower_than_the_robot_is_left_out_of_the_route():
    # the B-C door 0.2 m wide: a robot of radius 0.1 m cannot pass it, so the passage B-C is
    # not passable and the route goes A-T-C, the path kept to it (before, the route A-B-C was
    # planned, did not join, and the leg fell back to the grid path through T)
    result = third_room_result(bc_door=(25, 27))
    plan = navigate(result, "go to the kitchen", START, radius=0.1)
    names = {frozenset({plan.places.places[e.a].name, plan.places.places[e.b].name}): e
             for e in plan.places.passages}  # fmt: skip
    assert not names[frozenset({"corridor", "kitchen"})].passable
    assert names[frozenset({"bedroom", "corridor"})].passable
    assert plan.route_words == ("bedroom", "living", "kitchen") and plan.route_from == "graph"
    assert plan.planned == "hierarchical" and plan.fallbacks == ()
    assert plan.length == pytest.approx(plan.grid_length)  # through T is the way anyway
    assert [e["passable"] for e in plan.places.to_json()["passages"]].count(False) == 1
    # a robot that fits through the door takes the route A-B-C again
    small = navigate(result, "go to the kitchen", START, radius=0.0)
    assert small.route_words == ("bedroom", "corridor", "kitchen")


def test_a_fallback_to_the_grid_path_is_reported():
    # the corridor B pinched to 0.2 m between its doors: both doors are passable, but a robot
    # of radius 0.1 m cannot go along B, so the route A-B-C's places do not join start and goal
    # and the leg falls back to the shortest grid path (through T), which the route then names
    result = third_room_result(b_pinch=True)
    plan = navigate(result, "go to the kitchen", START, radius=0.1)
    assert plan.planned == "grid"
    assert len(plan.fallbacks) == 1 and "do not join" in plan.fallbacks[0]
    assert "bedroom -> corridor -> kitchen" in plan.fallbacks[0]
    assert plan.route_words == ("bedroom", "living", "kitchen") and plan.route_from == "path"
    assert 3 in concepts_on(result, plan.path_xy)
    assert plan.length == pytest.approx(plan.grid_length)
    # no route over the graph at all: reported, the path's places stand in for the route
    graph = replace(place_graph(third_room_result()), passages=())
    plan = navigate(third_room_result(), "go to the kitchen", START, radius=0.1, places=graph)
    assert plan.planned == "grid" and "no route over the place graph" in plan.fallbacks[0]
    assert plan.route_from == "path"
    assert plan.route_words == ("bedroom", "living", "kitchen")


def test_a_fallback_names_the_route_s_places_told_apart():
    """The corridor's top word "kitchen" too: the pinched corridor's fallback said "the places
    of the route bedroom -> kitchen -> kitchen do not join", two places by one name; it now
    tells them apart as navigate's printed route does."""
    result = third_room_result(b_pinch=True)
    graph = place_graph(result)
    graph = replace(
        graph,
        places=tuple(
            replace(p, name="kitchen", answers=("kitchen", *p.answers))  # stored, not derived
            if p.name == "corridor"
            else p
            for p in graph.places
        ),
    )
    plan = navigate(result, "go to the kitchen", START, radius=0.1, places=graph)
    (reason,) = plan.fallbacks
    corridor_concept, kitchen_concept = ROOMS["B"][2], ROOMS["C"][2]
    assert (f"bedroom -> kitchen (concept {corridor_concept}) -> kitchen (concept "
            f"{kitchen_concept}) do not join") in reason  # fmt: skip


def test_a_finer_map_adds_the_passages_its_doorways_open():
    """A fit whose grid has the A-B door walled up, planned on the map that has it: the place
    graph gains the passage A-B (on_map), and the route goes A-B-C as on the full map."""
    fit = third_room_result(ab_door=False)
    robot_map = third_room_result().grid
    graph = place_graph(fit)
    assert len(graph.passages) == 3  # B-C, A-T, T-C
    on_own = navigate(fit, "go to the kitchen", START, radius=0.1)
    assert on_own.route_words == ("bedroom", "living", "kitchen")
    plan = navigate(fit, "go to the kitchen", START, radius=0.1, grid=robot_map)
    added = [e for e in plan.places.passages if e.on_map]
    assert len(added) == 1
    assert {plan.places.places[added[0].a].name, plan.places.places[added[0].b].name} == {
        "bedroom", "corridor"}  # fmt: skip
    assert added[0].doorway
    assert plan.route_words == ("bedroom", "corridor", "kitchen")
    assert plan.planned == "hierarchical"
    assert concepts_on(fit, plan.path_xy) <= {0, 1, 2, -1}  # never in T (-1: the door)
    assert plan.places.to_json()["passages"][-1]["on_map"] is True


def test_an_unknown_planner_is_refused():
    with pytest.raises(ValueError, match="planner"):
        navigate(house_result(), "go to the kitchen", START_A, planner="astar")


def test_navigate_prints_and_writes_the_planner(tmp_path, capsys):
    fit = third_room_result(b_pinch=True).save(tmp_path / "fit")
    start = f"--start={START[0]},{START[1]}"
    out = tmp_path / "plan"
    assert main(["navigate", str(fit), "go to the kitchen", start, "--radius", "0.1",
                 "--out", str(out), "--no-figure"]) == 0  # fmt: skip
    printed = capsys.readouterr()
    assert "planner: grid (hierarchical asked; fell back" in printed.out
    assert "do not join" in printed.out
    written = json.loads((out / "navigate.json").read_text())
    assert written["planner"]["asked"] == "hierarchical"
    assert written["planner"]["used"] == "grid"
    assert "do not join" in written["planner"]["legs"][0]["fallback"]
    # the leg's closed route over the graph is kept; the plan's route is the path's places
    assert written["route"]["from"] == "path"
    assert written["route"]["words"] == ["bedroom", "living", "kitchen"]
    assert written["planner"]["legs"][0]["route"] != written["route"]["places"]
    assert "(the places the path crosses)" in printed.out

    fit = third_room_result().save(tmp_path / "fit2")
    assert main(["navigate", str(fit), "go to the kitchen", start, "--radius", "0.1"]) == 0
    assert "planner: hierarchical" in capsys.readouterr().out
    assert main(["navigate", str(fit), "go to the kitchen", start, "--radius", "0.1",
                 "--planner", "grid"]) == 0  # fmt: skip
    assert "planner: grid (asked)" in capsys.readouterr().out
