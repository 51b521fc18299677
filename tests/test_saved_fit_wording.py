"""What a user of a saved fit reads (a QA pass): ``where``'s threshold line beside its region,
``navigate``'s route where two places share a top word, and ``trace.png``'s concept count beside
the reported map's."""

from __future__ import annotations

import dataclasses

import numpy as np
from hand_results import WORDS, two_rooms

from spcopyro.results.result import EmissionTable


def _tied_rooms():
    """tests/hand_results.py's two rooms without the speck, "kitchen" equally probable under
    both rooms' concepts: p(concept | kitchen) = 0.500 each under the area prior (150 cells
    each)."""
    result = two_rooms()
    labels = np.asarray(result.labels).copy()  # [N]
    labels[labels == 2] = 1  # the speck joins the right room: 150 cells a side
    w = np.array([[0.6, 0.2, 0.2], [0.6, 0.3, 0.1], [0.1, 0.45, 0.45]])  # [L, V]
    emissions = tuple(EmissionTable("words", WORDS, w) if t.name == "words" else t
                      for t in result.emissions)  # fmt: skip
    return dataclasses.replace(result, labels=labels, emissions=emissions)


def test_where_says_what_its_region_is_when_no_cell_exceeds_one_half(tmp_path, capsys):
    """A tie (p = 0.500) answered with a 150-cell region and "cells whose probability of being
    the place exceeds 0.5: 0" beside it, as if the two contradicted each other; the line now
    says the region's cells' probability and that the region is the most probable concept's."""
    from spcopyro.cli.main import main

    fit = _tied_rooms().save(tmp_path / "fit")
    assert main(["where", str(fit), "kitchen"]) == 0
    printed = capsys.readouterr().out
    assert "(p(concept | word) = 0.500, area prior" in printed and "region: 150 cells" in printed
    (line,) = [x for x in printed.splitlines() if x.startswith("cells whose probability")]
    assert line == (
        "cells whose probability of being the place exceeds 0.5: 0 (point estimate); the region "
        "is the cells of the word's most probable concept, not those above 0.5: its 150 cells "
        "have p(cell is the place) 0.500, none of them above 0.5"
    )


def test_where_s_threshold_line_is_unchanged_when_the_region_is_above_one_half():
    from spcopyro.results.uncertainty import threshold_line

    probability = np.array([0.9, 0.8, 0.1, 0.6])  # [N]
    region = np.array([True, True, False, False])  # [N]
    assert threshold_line(probability, region, "marginals") == (
        "cells whose probability of being the place exceeds 0.5: 3 (marginals)"
    )
    mixed = threshold_line(probability, np.array([True, False, True, False]), "marginals")
    assert mixed.endswith("its 2 cells have p(cell is the place) 0.100-0.900, 1 of them above 0.5")


def test_navigate_tells_apart_two_places_of_the_route_with_one_name(tmp_path, capsys):
    """On tests/test_navigate.py's house, "go to the bedroom via the kitchen" from bedroom A
    ends in bedroom E, a region of the same concept: the route printed "bedroom -> corridor ->
    kitchen -> bedroom". Places of one concept add their place id, places of different concepts
    their concept."""
    from test_navigate import START_A, house_result

    from spcopyro.cli.main import main
    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.places import place_graph

    result = house_result()
    fit = result.save(tmp_path / "fit")
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", str(fit), "go to the bedroom via the kitchen", start]) == 0
    (route,) = [x for x in capsys.readouterr().out.splitlines() if x.startswith("route: ")]
    assert route == "route: bedroom (place 3) -> corridor -> kitchen -> bedroom (place 4)"

    graph = place_graph(result)  # the corridor renamed "kitchen": two concepts, one word
    places = tuple(dataclasses.replace(p, name="kitchen", answers=("kitchen", *p.answers))
                   if p.name == "corridor" else p for p in graph.places)  # fmt: skip
    graph = dataclasses.replace(graph, places=places)
    plan = navigate(result, "go to the kitchen", START_A, places=graph)
    assert plan.route_words == ("bedroom", "kitchen", "kitchen")
    corridor, kitchen = (graph.places[p].concept for p in plan.route[1:])
    assert plan.route_names == ("bedroom", f"kitchen (concept {corridor})",
                                f"kitchen (concept {kitchen})")  # fmt: skip
    plain = navigate(result, "go to the kitchen", START_A)  # no name twice: as before
    assert plain.route_names == plain.route_words == ("bedroom", "corridor", "kitchen")


def test_navigate_tells_that_a_place_passed_and_a_stop_are_one_place():
    """The default demo's unrefined fit: "go to the kitchen via the living room" printed
    "entrance -> restroom -> sink -> living -> kitchen", "sink" the kitchen's place passed on
    the way (its top word) and "kitchen" the same place reached; both now add its place id."""
    from test_navigate import START_A, house_result

    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.places import place_graph

    result = house_result()
    graph = place_graph(result)  # the corridor's top word "hall", its concept still "corridor"'s
    places = tuple(dataclasses.replace(p, name="hall", answers=("hall", *p.answers))
                   if p.name == "corridor" else p for p in graph.places)  # fmt: skip
    graph = dataclasses.replace(graph, places=places)
    plan = navigate(result, "go to the corridor via the kitchen", START_A, places=graph)
    assert plan.route_words == ("bedroom", "hall", "kitchen", "corridor")
    hall = plan.route[1]
    assert plan.route[3] == hall and graph.places[hall].name == "hall"
    assert plan.route_names == ("bedroom", f"hall (place {hall})", "kitchen",
                                f"corridor (place {hall})")  # fmt: skip


def test_a_word_of_a_place_that_needs_its_id_shows_ids_wherever_it_is_said():
    """The top word "hall" of the bedroom and of the corridor (two concepts), the corridor also
    reached as the stop "corridor": the route printed "hall (concept 0) -> hall (concept 1) ->
    kitchen -> corridor (place 1)", the first rule (one word, two concepts) hiding that the
    second "hall" and "corridor" are one place. Every word of a place that needs its id now
    shows ids."""
    from test_navigate import START_A, house_result

    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.places import place_graph

    result = house_result()
    graph = place_graph(result)
    places = tuple(dataclasses.replace(p, name="hall", answers=("hall", *p.answers))
                   if p.name in ("corridor", "bedroom") else p for p in graph.places)  # fmt: skip
    graph = dataclasses.replace(graph, places=places)
    plan = navigate(result, "go to the corridor via the kitchen", START_A, places=graph)
    assert plan.route_words == ("hall", "hall", "kitchen", "corridor")
    bedroom, hall = plan.route[:2]
    assert plan.route[3] == hall and graph.places[bedroom].concept != graph.places[hall].concept
    assert plan.route_names == (f"hall (place {bedroom})", f"hall (place {hall})", "kitchen",
                                f"corridor (place {hall})")  # fmt: skip


def test_the_trace_draws_the_reported_map_s_count_beside_the_states():
    """The default demo's trace.png showed 15-60 labels per sweep of its refinement while the
    fit reported 10 concepts, with nothing in the figure to tell the two apart; the concept
    axis now draws the reported map's count, says it in the legend and, for a point estimate
    over kept samples, why the states hold more."""
    from spcopyro.figures.plotting import trace_figure

    result = dataclasses.replace(two_rooms(), method="gibbs")
    for agreement in (None, np.ones(result.grid.num_free)):
        fit = dataclasses.replace(result, agreement=agreement)
        _, bottom = trace_figure(fit).axes
        flat = [line for line in bottom.get_lines() if line.get_linestyle() == "--"
                and list(line.get_ydata()) == [3, 3]]  # fmt: skip
        assert len(flat) == 1  # the three concepts of the map (one a one-cell speck)
        (text,) = [t.get_text() for t in bottom.get_legend().get_texts()]
        assert text.startswith("the reported map: 3 concepts in use")
        assert ("adds labels that come and go" in text) == (agreement is not None)
