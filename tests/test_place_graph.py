"""The place graph (issue 27 item 2): regions as nodes, shared borders as edges, the route.

On the house of tests/test_navigate.py (0.1 m cells): A bedroom (cols 1-9), B corridor (cols
11-19 and the two doorway columns 10 and 20, rows 8-12), C kitchen (cols 21-29 and the doorway
column 30), E bedroom again (cols 31-39), all rows 1-18; D closet below (rows 20-27, cols 1-39),
walled off. Hand-counted: A = E = 18 x 9 = 162 cells, B = 162 + 2 x 5 = 172, C = 162 + 5 = 167,
D = 8 x 39 = 312; each doorway column touches the next room along 5 cells = 0.5 m.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from test_cli_startup import heavy_imports
from test_navigate import CONCEPT, START_A, house_result

from spcopyro.cli.main import main
from spcopyro.robot.navigation import navigate
from spcopyro.robot.navigation.places import place_graph, places_along

CONCEPT_D = CONCEPT["D"]
ROOM_CELLS = {"D": 312, "B": 172, "C": 167, "A": 162, "E": 162}  # largest first = place ids


@pytest.fixture(scope="module")
def result():
    return house_result()


def _by_room(graph):
    """Room letter -> place, told apart by where each centroid lies."""
    rooms = {}
    for place in graph.places:
        x, y = place.centroid
        room = "D" if y < 1.0 else "ABCE"[min(int(x), 3)]
        rooms[room] = place
    return rooms


def test_nodes_have_the_hand_counted_areas_words_and_centroids(result):
    graph = place_graph(result)
    assert [p.cells for p in graph.places] == list(ROOM_CELLS.values())
    rooms = _by_room(graph)
    assert sorted(rooms) == sorted(ROOM_CELLS)
    for room, cells in ROOM_CELLS.items():
        assert rooms[room].cells == cells
        assert rooms[room].area == pytest.approx(cells * 0.01)
    assert [rooms[r].name for r in "ABCED"] == ["bedroom", "corridor", "kitchen", "bedroom",
                                                 "closet"]  # fmt: skip
    assert rooms["A"].concept == rooms["E"].concept  # one concept, two places
    assert len(rooms["B"].words) == 3
    # A: columns 1..9 -> x = 0.15..0.95, mean 0.55; rows 1..18 -> y mean 1.9
    assert rooms["A"].centroid == pytest.approx((0.55, 1.9))
    assert graph.dropped == 0 and graph.dropped_area == 0
    assert (graph.regions >= 0).sum() == sum(ROOM_CELLS.values())


def _filler_on_top(result):
    """The house with the corridor B's and the closet D's most probable word "the" (w 0.5 and
    0.55, their own words 0.4 next): ``where the`` answers the closet (0.55 x 312 cells against
    0.5 x 172), so the corridor's top word is not a word whose where-answer it is."""
    w = np.full((4, 5), 0.025)  # [L, V] bedroom, corridor, kitchen, closet, the
    w[0, 0] = w[2, 2] = 0.9
    w[1, [4, 1]] = 0.5, 0.4
    w[3, [4, 3]] = 0.55, 0.4
    w /= w.sum(1, keepdims=True)
    words = replace(result.emission("words"), probabilities=w)
    return replace(result, emissions=(result.emissions[0], words))


def test_places_are_named_by_the_word_where_answers_with_them(result, tmp_path, capsys):
    """``show OUT --graph`` named a region after its concept's top word, which ``where`` may
    answer with another region (room2ldk4: two places "bedroom"). A place is named by its
    concept's most probable word among those whose where-answer is the concept: the corridor
    "corridor", not "the" (its top word, but the closet's answer); the closet "the" (its top
    word, w 0.55, and where's answer for it, p(C | word) 0.63), not "closet" (w 0.4): ranking
    the answering words by p(C | word) named it after the word most exclusive to it (closet,
    p 0.88), not the most said there (room2ldk4's 31.8 m^2 place read "entrance", its top word
    "bedroom" answering it too). concepts.json's "name", graph.json and the semantic map's
    label of a concept's further region say the same."""
    from spcopyro.figures.map_pieces import region_text

    filler = _filler_on_top(result)
    corridor, closet = CONCEPT["B"], CONCEPT_D
    assert filler.top_words(corridor, 1)[0][0] == filler.top_words(closet, 1)[0][0] == "the"
    assert filler.where("the").concept == closet and filler.where("corridor").concept == corridor
    assert filler.where("the").probability < filler.where("closet").probability  # 0.63 < 0.88
    rooms = _by_room(place_graph(filler))
    assert [rooms[r].name for r in "ABCED"] == ["bedroom", "corridor", "kitchen", "bedroom",
                                                 "the"]  # fmt: skip
    assert rooms["B"].answers == ("corridor",) and rooms["D"].answers == ("the", "closet")
    plan = navigate(filler, "go to the kitchen", START_A)
    assert plan.route_words == ("bedroom", "corridor", "kitchen")
    names = {c["concept"]: c["name"] for c in filler.concepts()}
    assert names == {0: "bedroom", corridor: "corridor", 2: "kitchen", closet: "the"}
    assert region_text(filler, corridor, largest=False) == f"[{corridor}] corridor"
    assert region_text(filler, closet, largest=False) == f"[{closet}] the"

    fit = filler.save(tmp_path / "fit")
    assert main(["show", str(fit), "--graph", "--out", str(tmp_path / "graph.png")]) == 0
    out = capsys.readouterr().out
    assert "corridor (1.7 m^2)" in out and ": the (3.1 m^2)" in out and "closet (" not in out
    assert "where answers it for: the, closet" in out  # most probable in the closet first
    written = json.loads((tmp_path / "graph.json").read_text())
    assert sorted(p["name"] for p in written["places"]) == ["bedroom", "bedroom", "corridor",
                                                           "kitchen", "the"]  # fmt: skip
    saved = json.loads((fit / "concepts.json").read_text())
    saved = saved["concepts"] if isinstance(saved, dict) else saved
    assert {c["concept"]: c["name"] for c in saved} == names


def test_the_semantic_map_ranks_the_words_once_for_every_further_region(result, monkeypatch):
    """Each further region's label is its concept's name; the semantic map named them with
    :func:`concept_names` once, not with one :func:`answered_words` (a pass over the whole
    vocabulary) per further region. The closet D split into three (a bedroom left, a kitchen
    right) gives two further regions of bedroom and one of kitchen: one ranking, not three,
    and the labels as :func:`region_text` writes them alone."""
    import matplotlib.pyplot as plt

    from spcopyro.figures.map_pieces import region_text
    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.results import concept_names as names_module

    image = result.label_image().copy()  # [H, W]
    image[20:28, 1:10], image[20:28, 31:40] = CONCEPT["A"], CONCEPT["C"]
    split = replace(result, labels=image[result.grid.free])
    calls = []
    ranked = names_module.answered_words
    monkeypatch.setattr(names_module, "answered_words",
                        lambda *a, **k: calls.append(1) or ranked(*a, **k))  # fmt: skip
    figure = semantic_map_figure(split)
    texts = {t.get_text() for ax in figure.axes for t in ax.texts}
    plt.close(figure)
    assert len(calls) == 1
    further = {
        region_text(split, CONCEPT["A"], largest=False),
        region_text(split, CONCEPT["C"], largest=False),
    }
    assert further == {"[0] bedroom", "[2] kitchen"} and further <= texts


def test_a_place_stores_its_concepts_name_from_the_one_naming_rule(result, monkeypatch):
    """Place.name was a property repeating concept_name's fallback chain; it is now the name
    place_graph read from concept_name, so a change of that rule reaches the places too."""
    import dataclasses

    from spcopyro.robot.navigation import places as places_module

    graph = place_graph(result)
    assert "name" in {f.name for f in dataclasses.fields(graph.places[0])}
    names = {c["concept"]: c["name"] for c in result.concepts()}
    assert all(p.name == names[p.concept] for p in graph.places)
    monkeypatch.setattr(places_module, "concept_name", lambda _, c, __=None: f"room {c}")
    assert {p.name for p in place_graph(result).places} == {f"room {c}" for c in CONCEPT.values()}


def test_a_place_where_no_word_was_heard_is_named_by_its_concept(result):
    """Its top words are the prior's (ties, a fit printed 'restroom' for one-cell specks), so it
    has none and is called ``concept N``, as the fit's listing says "no words heard"."""
    names = [t.name for t in result.emissions]
    totals = np.ones((result.config.num_concepts, 1 + len(names)))
    totals[CONCEPT_D, 1 + names.index("words")] = 0.0  # closet D: no word heard
    graph = place_graph(replace(result, concept_totals=totals))
    rooms = _by_room(graph)
    assert rooms["D"].words == () and rooms["D"].name == f"concept {CONCEPT_D}"
    assert rooms["C"].name == "kitchen"  # words heard: named as before


def test_edges_are_the_doorways_with_their_border_lengths(result):
    graph = place_graph(result)
    rooms = _by_room(graph)
    ids = {p.id: room for room, p in rooms.items()}
    edges = {frozenset((ids[e.a], ids[e.b])): e for e in graph.passages}
    assert set(edges) == {frozenset("AB"), frozenset("BC"), frozenset("CE")}  # D: no door
    for edge in edges.values():
        assert edge.border == pytest.approx(0.5)  # 5 touching cell pairs x 0.1 m
        assert edge.doorway
        assert edge.distance == pytest.approx(
            np.hypot(*np.subtract(graph.places[edge.a].centroid, graph.places[edge.b].centroid))
        )
    as_json = json.loads(json.dumps(graph.to_json()))
    assert len(as_json["places"]) == 5 and len(as_json["passages"]) == 3
    assert as_json["passages"][0]["border_m"] == pytest.approx(0.5)


def test_a_wide_shared_border_is_not_a_doorway(result):
    """Open the wall between A and B along rows 1..18 (1.8 m): one long border, no doorway."""
    grid = result.grid
    occupancy = grid.occupancy.copy()
    occupancy[1:19, 10] = 0  # FREE
    open_grid = replace(grid, occupancy=occupancy)
    image = result.label_image()
    image[1:19, 10] = np.where(image[1:19, 10] >= 0, image[1:19, 10], 1)  # the corridor's
    opened = replace(result, grid=open_grid, labels=image[open_grid.free])
    graph = place_graph(opened)
    ab = [e for e in graph.passages if {graph.places[e.a].name, graph.places[e.b].name}
          == {"bedroom", "corridor"} and min(graph.places[e.a].centroid[0],
                                              graph.places[e.b].centroid[0]) < 1]  # fmt: skip
    assert len(ab) == 1
    assert ab[0].border == pytest.approx(1.8) and not ab[0].doorway


def test_small_regions_are_dropped_and_counted(result):
    graph = place_graph(result, min_area=1.65)  # A and E (1.62 m^2) go
    assert graph.dropped == 2
    assert graph.dropped_area == pytest.approx(3.24)
    assert [p.cells for p in graph.places] == [312, 172, 167]
    assert len(graph.passages) == 1  # only corridor - kitchen is left
    assert graph.regions[4, 3] == -1  # a cell of A
    # a cell in a dropped region belongs to the nearest place (A's -> the corridor's doorway)
    assert graph.places[graph.place_of(np.array([4, 3]))].name == "corridor"


def test_the_route_lists_the_rooms_passed_in_order(result):
    plan = navigate(result, "go to the kitchen", START_A)
    assert plan.route_words == ("bedroom", "corridor", "kitchen")
    assert plan.route_from == "graph"
    assert plan.route == (3, 1, 2)  # A, B, C by the hand-counted sizes
    # through a via place and on to the far bedroom (E, the nearer bedroom from the kitchen)
    plan = navigate(result, "go to the bedroom via the kitchen", START_A)
    assert plan.route_words == ("bedroom", "corridor", "kitchen", "bedroom")
    assert plan.route == (3, 1, 2, 4)
    # the grid path itself crosses the same places in the same order
    assert places_along(plan.places, result.grid.world_to_cell(plan.path_xy)) == plan.route


def test_a_stop_s_place_reads_as_the_word_the_robot_was_sent_with(result):
    """A kitchen whose most probable word is "sink" is named "kitchen" on a route to the kitchen;
    a place passed on the way keeps its top word."""
    graph = place_graph(result)
    places = tuple(
        replace(p, name="sink", answers=("sink", *p.answers))  # the name is stored, not derived
        if p.name in ("kitchen", "corridor")
        else p
        for p in graph.places
    )
    plan = navigate(result, "go to the kitchen", START_A, places=replace(graph, places=places))
    assert plan.route == (3, 1, 2)
    assert plan.route_words == ("bedroom", "sink", "kitchen")  # the corridor stays "sink"


def test_without_a_route_over_the_graph_the_path_s_places_are_reported(result):
    graph = replace(place_graph(result), passages=())
    plan = navigate(result, "go to the kitchen", START_A, places=graph)
    assert plan.route_from == "path"
    assert plan.route_words == ("bedroom", "corridor", "kitchen")


def test_navigate_prints_and_writes_the_route(result, tmp_path, capsys):
    fit = result.save(tmp_path / "fit")
    out = tmp_path / "plan"
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", str(fit), "go to the kitchen", start, "--out", str(out),
                 "--no-figure"]) == 0  # fmt: skip
    assert "route: bedroom -> corridor -> kitchen" in capsys.readouterr().out
    written = json.loads((out / "navigate.json").read_text())
    assert written["route"]["words"] == ["bedroom", "corridor", "kitchen"]
    assert len(written["place_graph"]["places"]) == 5


def test_show_graph_writes_png_and_json_and_imports_no_torch(result, tmp_path):
    fit = result.save(tmp_path / "fit")
    png = tmp_path / "figs" / "graph.png"
    imported, printed = heavy_imports(["show", str(fit), "--graph", "--out", str(png)])
    assert imported == []
    assert png.is_file() and png.stat().st_size > 1000
    graph = json.loads((png.parent / "graph.json").read_text())
    assert len(graph["places"]) == 5 and len(graph["passages"]) == 3
    # no robot here: whether it can pass is unknown, not "true" for every passage
    assert {p["passable"] for p in graph["passages"]} == {None}
    assert "5 places, 3 passages (3 doorways)" in printed
    other = tmp_path / "figs" / "other.png"  # a second graph in the folder keeps the first's
    heavy_imports(["show", str(fit), "--graph", "--min-area", "100", "--out", str(other)])
    assert json.loads((png.parent / "graph.json").read_text()) == graph
    assert json.loads((png.parent / "other.json").read_text())["places"] == []


def test_show_graph_refuses_a_negative_min_area(result, tmp_path, capsys):
    fit = result.save(tmp_path / "fit")
    with pytest.raises(SystemExit) as error:
        main(["show", str(fit), "--graph", "--min-area", "-1", "--out", str(tmp_path / "g.png")])
    assert error.value.code == 2
    assert "--min-area: '-1': the area is square metres >= 0" in capsys.readouterr().err
    assert not (tmp_path / "g.png").exists()


def test_show_min_area_without_graph_is_refused(tmp_path, capsys, monkeypatch):
    """--min-area without --graph was ignored silently; with --graph its default is the
    library's."""
    from spcopyro.robot.navigation.places import DEFAULT_MIN_AREA

    assert main(["show", "--min-area", "3", "--out", str(tmp_path / "h.png")]) == 2
    assert "--min-area 3 sizes the places of --graph: add --graph" in capsys.readouterr().err
    assert not (tmp_path / "h.png").exists()
    seen = []
    monkeypatch.setattr("spcopyro.cli.navigate.show_graph", lambda a: seen.append(a.min_area) or 0)
    assert main(["show", "x", "--graph", "--out", str(tmp_path / "g.png")]) == 0
    assert seen == [DEFAULT_MIN_AREA]


def test_show_graph_needs_a_fit_folder(tmp_path):
    assert main(["show", "--graph", "--out", str(tmp_path / "g.png")]) == 2


def test_show_of_a_fit_folder_without_graph_points_to_it(result, tmp_path, capsys):
    fit = result.save(tmp_path / "fit")
    assert main(["show", str(fit), "--out", str(tmp_path / "house.png")]) == 2
    assert "is the output folder of `spcopyro fit`" in capsys.readouterr().err
    assert not (tmp_path / "house.png").exists()


def test_show_graph_says_what_it_left_out_only_where_it_left_out_something(result, tmp_path):
    """`show OUT --graph` printed "0 regions under 0.25 m^2 left out (0.00 m^2)" where it left
    out nothing (room1ldk5's CAVI fit); the figure's title says nothing then, nor does the line."""
    fit = result.save(tmp_path / "fit")
    _, printed = heavy_imports(["show", str(fit), "--graph", "--out", str(tmp_path / "g.png")])
    first = printed.splitlines()[0]
    assert first == "5 places, 3 passages (3 doorways)", printed
    _, printed = heavy_imports(["show", str(fit), "--graph", "--min-area", "100",
                                "--out", str(tmp_path / "h.png")])  # fmt: skip
    assert printed.splitlines()[0].startswith("0 places, 0 passages (0 doorways); 5 regions "
                                              "under 100 m^2 left out (")  # fmt: skip
    # one text for the line and graph.png's title, in each one's spelling of the unit
    assert place_graph(result).dropped_text() == ""
    assert place_graph(result, min_area=100).dropped_text("m²") == "5 regions under 100 m² left out"


def test_a_place_under_one_square_metre_shows_its_area_to_two_decimals(result, tmp_path):
    """`show OUT --graph` and graph.png wrote areas to one decimal: room1ldk5's CAVI fit kept a
    place of 0.25 m^2 (4 cells of 0.25 m) and printed it as "0.2 m^2" under "regions under
    0.25 m^2 left out". Below 1 m^2 an area has two decimals."""
    from hand_results import one_word_per_concept
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from test_navigate import WORDS

    from spcopyro.robot.navigation.figure import place_graph_figure

    image = result.label_image()  # [H, W]
    image[22:24, 5:7] = CONCEPT["A"]  # a 2 x 2 speck of room A's concept in room D
    result = one_word_per_concept(result.grid, image[result.grid.free], WORDS)
    graph = place_graph(result, min_area=0.0)
    small = [p for p in graph.places if p.area < 1.0]
    assert small and all(p.area_text == f"{p.area:.2f}" for p in small)
    big = next(p for p in graph.places if p.area >= 1.0)
    assert big.area_text == f"{big.area:.1f}"
    assert replace(big, area=0.25).area_text == "0.25"
    fit = result.save(tmp_path / "fit")
    _, printed = heavy_imports(["show", str(fit), "--graph", "--min-area", "0",
                                "--out", str(tmp_path / "g.png")])  # fmt: skip
    for p in small:
        assert f"  {p.id}: {p.name} ({p.area:.2f} m^2) at " in printed
    fig = place_graph_figure(result, graph)
    FigureCanvasAgg(fig).draw()
    texts = {t.get_text() for ax in fig.axes for t in ax.texts}
    assert {f"{p.name} ({p.area:.2f} m²)" for p in small} <= texts
