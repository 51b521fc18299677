"""What a reader of navigate.png and show --graph's graph.png sees (properties of the artists,
not pixels): a long corridor in readable strips with the path running on across them."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")


def _corridor(tall: bool = False):
    """A 100 m x 2 m corridor (0.05 m cells) of five 20 m rooms joined by 0.8 m doorways, each
    room's concept naming it: ``one_word_per_concept``'s result."""
    from hand_results import one_word_per_concept

    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid

    occupancy = np.full((44, 2004), OCCUPIED, dtype=np.int8)
    occupancy[2:-2, 2:-2] = FREE
    for x in range(402, 2000, 400):
        occupancy[:, x : x + 2] = OCCUPIED
        occupancy[14:30, x : x + 2] = FREE
    if tall:
        occupancy = np.ascontiguousarray(occupancy.T[::-1])  # x along the map's rows
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    along = np.nonzero(grid.free)[0 if tall else 1]  # [N]
    if tall:
        along = grid.height - 1 - along
    labels = np.minimum((along - 2) // 400, 4)  # [N]: five rooms
    words = ("kitchen", "bed", "sofa", "bath", "door")
    return one_word_per_concept(grid, labels, words, num_concepts=5)


def _boxes(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    for ax in fig.axes:
        ax.apply_aspect()
    return renderer, [ax.get_window_extent(renderer) for ax in fig.axes]


def _holds(ax, x: float, y: float) -> bool:
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    return x0 <= x <= x1 and y0 <= y <= y1


@pytest.mark.parametrize("tall", [False, True])
def test_navigate_png_of_a_long_corridor_is_drawn_in_strips(tall):
    """navigate.png of a 100 m x 2 m corridor was one strip 40 pixels high under a square colour
    bar, the stop's name over the title; it is cut into strips at one scale, the path drawn in
    every strip (clipped to it: it runs on from one strip into the next), start, stops and goal
    where they fall, the colour bar beside the last strip."""
    from spcopyro.figures.map_pieces import STRIP_ASPECT
    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.figure import plan_figure

    result = _corridor(tall)
    start = (1.0, 2.0) if tall else (2.0, 1.0)
    plan = navigate(result, "go to the door via the sofa", start)
    fig = plan_figure(plan)
    renderer, boxes = _boxes(fig)
    assert len(boxes) == 7, len(boxes)
    sizes = {(round(b.width), round(b.height)) for b in boxes}
    assert len(sizes) == 1, sizes  # one scale
    ((w, h),) = sizes
    # at most STRIP_ASPECT, margins (3% longer at both ends, strip_axes) included
    assert max(w, h) / min(w, h) <= STRIP_ASPECT and min(w, h) >= 0.9 * fig.dpi, sizes
    order = "left to right" if tall else "top to bottom"
    assert fig.axes[0].get_title().endswith(f"(the map in 7 strips, {order})")
    along = plan.path_xy[:, 1 if tall else 0]  # [P]
    holding = []  # the strips showing a part of the path
    for k, ax in enumerate(fig.axes):
        (path,) = [line for line in ax.get_lines() if line.get_label() == "path"]
        assert np.array_equal(path.get_xydata(), plan.path_xy)  # the whole path, clipped
        assert path.get_clip_on()
        if any(_holds(ax, x, y) for x, y in plan.path_xy):
            holding.append(k)
        stars = [ln for ln in ax.get_lines() if ln.get_marker() == "*"]
        assert len(stars) == 1 and tuple(stars[0].get_xydata()[0]) == tuple(plan.goal.xy)
        assert len(ax.images) == 2  # the map and the destination's probability
    # 79 m: from the start's strip into the goal's, 5 strips on, through every strip between
    assert np.ptp(along) > 70 and holding == list(range(holding[0], holding[0] + 6)), holding
    (stop,) = plan.stops[:-1]
    texts = [(ax, t) for ax in fig.axes for t in ax.texts]
    assert [t.get_text() for _, t in texts] == [stop.shown]
    assert _holds(texts[0][0], *stop.xy)
    assert any(_holds(ax, *plan.start) for ax in fig.axes)
    legend = fig.axes[-1].get_legend()
    assert legend is not None
    box = legend.get_window_extent(renderer)
    assert not any(box.overlaps(b) for b in boxes)
    assert [t.get_text() for t in legend.get_texts()][:2] == ["route's places (outline)", "path"]
    bars = [child for child in fig.axes[-1].child_axes if child.get_ylabel().startswith("p(")]
    assert len(bars) == 1  # the colour bar, beside the last strip


@pytest.mark.parametrize("tall", [False, True])
def test_the_place_graph_of_a_long_corridor_is_drawn_in_strips(tall):
    """show --graph on a 100 m x 2 m corridor drew one thin strip, its labels over the title;
    its strips carry the passages and markers, each label on a strip showing its place, inside
    that strip's axes and overlapping no other."""
    from matplotlib.collections import PathCollection

    from spcopyro.robot.navigation.figure import place_graph_figure
    from spcopyro.robot.navigation.places import place_graph

    result = _corridor(tall)
    graph = place_graph(result)
    assert len(graph.places) == 5
    fig = place_graph_figure(result, graph)
    renderer, boxes = _boxes(fig)
    assert len(boxes) == 7 and len({(round(b.width), round(b.height)) for b in boxes}) == 1
    assert "(the map in 7 strips, " in fig.axes[0].get_title()
    texts = [(ax, box, t) for ax, box in zip(fig.axes, boxes, strict=True) for t in ax.texts]
    assert len(texts) == 5
    extents = [t.get_window_extent(renderer) for _, _, t in texts]
    for (ax, box, text), extent in zip(texts, extents, strict=True):
        place = next(p for p in graph.places if text.get_text().startswith(p.name + " "))
        assert _holds(ax, *place.centroid), text.get_text()
        assert box.x0 <= extent.x0 and extent.x1 <= box.x1, text.get_text()
        assert box.y0 <= extent.y0 and extent.y1 <= box.y1, text.get_text()
    for i, extent in enumerate(extents):
        assert not any(extent.overlaps(other) for other in extents[i + 1 :])
    for ax in fig.axes:
        assert len([c for c in ax.collections if isinstance(c, PathCollection)]) == 1
        assert len([ln for ln in ax.get_lines() if len(ln.get_xydata())]) == len(graph.passages)
    legend = [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    assert len(legend) == 1
    box = legend[0].get_window_extent(renderer)
    assert not any(box.overlaps(b) for b in boxes)


def test_a_label_by_a_cut_goes_on_the_strip_showing_its_marker_whole():
    """A place's centroid 0.16 m before a strip's end (in the next strip's overlap too) was
    labelled on the first strip, beside half a marker."""
    from matplotlib.figure import Figure

    from spcopyro.robot.navigation.figure import _showing

    fig = Figure()
    first, second = fig.subplots(2, 1)
    first.set_xlim(0.0, 10.0)
    second.set_xlim(9.5, 19.5)
    for ax in (first, second):
        ax.set_ylim(0.0, 2.0)
    assert _showing([first, second], 9.8, 1.0) is second
    assert _showing([first, second], 9.4, 1.0) is first
    assert _showing([first, second], 30.0, 1.0) is first  # shown nowhere: the first


def test_navigate_png_explains_its_stops_and_other_candidates_in_the_legend():
    """navigate.png drew each 'via' stop as an orange square (C1, near the route's orange
    outline it often sits on) and the candidate goals not taken (the other bedroom) as small
    purple crosses, neither in the legend: a reader could not tell what they were."""
    from matplotlib.colors import to_rgb
    from test_navigate import START_A, house_result

    from spcopyro.maps.palette import delta_e
    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.figure import ROUTE_RGB, plan_figure

    plan = navigate(house_result(), "go to the bedroom via the kitchen", START_A)
    assert len(plan.goal.choice.candidates) == 2  # the bedroom: rooms A and E
    ax = plan_figure(plan).axes[0]  # the map (the colour bar's axes follow)
    handles, labels = ax.get_legend_handles_labels()
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts == labels
    assert "stop ('via' place)" in labels and "other candidate goal (not taken)" in labels
    stop = handles[labels.index("stop ('via' place)")]
    squares = [ln for ln in ax.get_lines() if ln.get_marker() == "s"]
    assert len(squares) == 1 and tuple(squares[0].get_xydata()[0]) == tuple(plan.stops[0].xy)
    face = np.array(to_rgb(stop.get_markerfacecolor())) * 255
    edge = np.array(to_rgb(stop.get_markeredgecolor())) * 255
    route = np.array(ROUTE_RGB) * 255
    assert max(delta_e(face, route), delta_e(edge, route)) >= 50  # apart from the outline
    crosses = [ln for ln in ax.get_lines() if ln.get_marker() == "x"]
    assert len(crosses) == 1  # the other bedroom, once in the legend


def test_navigate_png_tells_the_goal_heading_from_the_path():
    """navigate.png drew the goal's heading as an arrow in the path's red, in no legend: on
    room1ldk5 ('go to the bath via the kitchen') the path seemed to run on past the goal star.
    The arrow is black and the goal's legend entry names it."""
    from matplotlib.colors import to_rgb
    from matplotlib.patches import FancyArrow
    from test_navigate import START_A, house_result

    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.figure import plan_figure

    plan = navigate(house_result(), "go to the bedroom via the kitchen", START_A)
    ax = plan_figure(plan).axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"goal: {plan.goal.shown} (arrow: its heading)" in labels
    (arrow,) = [p for p in ax.patches if isinstance(p, FancyArrow)]
    (path,) = [ln for ln in ax.get_lines() if ln.get_label() == "path"]
    assert to_rgb(arrow.get_facecolor()) != to_rgb(path.get_color())


def test_a_place_label_with_no_free_corner_is_left_out_and_counted():
    """graph.png of room1ldk5's CAVI fit (23 places, many small) drew "washroom (0.25 m²)" over
    "washroom (0.31 m²)": a label free at none of its corners went to the first one anyway,
    and neither could be read. Such a label is left out and the title counts it (256 places
    of 2 x 2 cells: most labels find no free corner)."""
    from hand_results import one_word_per_concept
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.maps import FREE, OccupancyGrid
    from spcopyro.robot.navigation.figure import place_graph_figure
    from spcopyro.robot.navigation.places import place_graph

    grid = OccupancyGrid(np.full((32, 32), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    rows, cols = np.nonzero(grid.free)  # [N]
    labels = (rows // 2) * 16 + cols // 2  # [N]: 256 blocks of 2 x 2 cells
    words = tuple(f"w{k}" for k in range(256))
    result = one_word_per_concept(grid, labels, words, num_concepts=256)
    graph = place_graph(result, min_area=0.01)
    assert len(graph.places) == 256
    fig = place_graph_figure(result, graph)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    (ax,) = fig.axes
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    assert 0 < len(boxes) < 256
    assert not any(a.overlaps(b) for k, a in enumerate(boxes) for b in boxes[k + 1 :])
    assert f"256 places, {256 - len(boxes)} left unlabelled (crowded), " in ax.get_title()


def test_places_whose_labels_would_read_the_same_are_told_apart():
    """graph.png of room1ldk5's CAVI fit labelled two places "door (0.44 m²)" (concepts 38 and
    78): the reader could not tell which was which, where navigate's route says "door (concept
    38)". Such labels add the concept, or the place id for two regions of one concept; other
    labels are as they were. Three regions of concept 1 and one of concept 2 all add their
    place ids, as a route names them (told_apart)."""
    import dataclasses

    from hand_results import one_word_per_concept

    from spcopyro.maps import FREE, OccupancyGrid
    from spcopyro.robot.navigation.figure import place_graph_figure
    from spcopyro.robot.navigation.places import place_graph

    grid = OccupancyGrid(np.full((10, 40), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    rows, cols = np.nonzero(grid.free)  # [N]
    labels = np.zeros(len(rows), dtype=np.int64)  # [N]: concept 0 around four 3 x 3 blocks
    for concept, left in ((1, 2), (2, 12), (1, 22), (1, 32)):
        labels[(rows >= 3) & (rows < 6) & (cols >= left) & (cols < left + 3)] = concept
    result = one_word_per_concept(grid, labels, ("hall", "door", "bed"), num_concepts=3)
    graph = place_graph(result, min_area=0.01)
    door = [p for p in graph.places if p.concept in (1, 2)]
    assert len(door) == 4 and len({p.area_text for p in door}) == 1
    renamed = tuple(dataclasses.replace(p, name="door") if p.concept in (1, 2) else p
                    for p in graph.places)  # fmt: skip
    graph = dataclasses.replace(graph, places=renamed)
    fig = place_graph_figure(result, graph)
    texts = sorted(t.get_text() for ax in fig.axes for t in ax.texts)
    area = door[0].area_text
    assert texts == sorted([f"hall ({graph.places[0].area_text} m²)"]
                           + [f"door (place {p.id}, {area} m²)" for p in door])  # fmt: skip


@pytest.mark.parametrize(
    ("concepts", "adds"),
    [((1, 2), "concept"), ((1, 1), "place"), ((1, 2, 1), "place"), ((2, 1, 1), "place")],
)
def test_graph_labels_that_read_the_same_are_told_apart_as_a_route_tells_them(concepts, adds):
    """Places whose graph.png labels would read the same add what told_apart adds to the same
    words: three labels "door (0.09 m²)" of concepts 1, 2 and 1 each added their place id where
    they were of concept 1 but the concept where it was 2 (door (concept 2, ...)), while a route
    through the three names each by its place id (two of them are regions of one concept). A
    pair adds the concepts, or the place ids for one concept, as before."""
    import dataclasses

    from hand_results import one_word_per_concept

    from spcopyro.maps import FREE, OccupancyGrid
    from spcopyro.robot.navigation.figure import _place_texts
    from spcopyro.robot.navigation.places import place_graph, told_apart

    grid = OccupancyGrid(np.full((10, 40), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    rows, cols = np.nonzero(grid.free)  # [N]
    labels = np.zeros(len(rows), dtype=np.int64)  # [N]: concept 0 around 3 x 3 blocks
    for concept, left in zip(concepts, (2, 14, 26), strict=False):
        labels[(rows >= 3) & (rows < 6) & (cols >= left) & (cols < left + 3)] = concept
    result = one_word_per_concept(grid, labels, ("hall", "door", "bed"), num_concepts=3)
    graph = place_graph(result, min_area=0.01)
    renamed = tuple(dataclasses.replace(p, name="door") if p.concept else p
                    for p in graph.places)  # fmt: skip
    graph = dataclasses.replace(graph, places=renamed)
    door = [p for p in graph.places if p.concept]
    assert len(door) == len(concepts) and len({p.area_text for p in door}) == 1
    texts = _place_texts(graph)
    route = told_apart(graph, [p.id for p in door])
    for p, said in zip(door, route, strict=True):
        added = f"{adds} {p.id if adds == 'place' else p.concept}"
        assert said == f"door ({added})"
        assert texts[p.id] == f"door ({added}, {p.area_text} m²)"
    assert texts[0] == f"hall ({graph.places[0].area_text} m²)"


def test_a_passage_is_drawn_along_free_cells_not_across_a_wall():
    """show --graph drew each passage as a straight line between the two centroids: on a
    U-shaped map (a wall from the top between its arms) the line from the U-shaped place's
    centroid, itself on the wall, to the place at the top of the right arm crossed the wall.
    The line runs over the two places' cells, from markers on their own cells."""
    from hand_results import one_word_per_concept
    from matplotlib.collections import PathCollection

    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
    from spcopyro.robot.navigation.figure import place_graph_figure
    from spcopyro.robot.navigation.places import place_graph

    occupancy = np.full((12, 13), FREE, dtype=np.int8)
    occupancy[:8, 5:8] = OCCUPIED  # the wall between the arms
    grid = OccupancyGrid(occupancy, 0.1, (0.0, 0.0, 0.0))
    rows, cols = np.nonzero(grid.free)  # [N] in free-index order
    labels = ((rows < 4) & (cols >= 8)).astype(np.int64)  # [N]: 1 the top of the right arm
    result = one_word_per_concept(grid, labels, ("bedroom", "kitchen"), num_concepts=2)
    graph = place_graph(result, min_area=0.1)
    assert len(graph.places) == 2 and len(graph.passages) == 1
    bedroom = next(p for p in graph.places if p.name == "bedroom")
    assert not grid.is_free(grid.world_to_cell(np.array(bedroom.centroid)))  # on the wall
    fig = place_graph_figure(result, graph)
    (ax,) = fig.axes
    (line,) = [ln for ln in ax.get_lines() if len(ln.get_xydata())]
    points = line.get_xydata()  # [K, 2]
    assert len(points) > 2  # not one straight segment
    t = np.linspace(0.0, 1.0, 101)[:, None]  # [101, 1]
    for p, q in zip(points[:-1], points[1:], strict=True):
        cells = grid.world_to_cell(p + t * (q - p))  # [101, 2]
        assert grid.is_free(cells).all(), (p, q, cells[~grid.is_free(cells)])
    (markers,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    assert grid.is_free(grid.world_to_cell(markers.get_offsets())).all()
    (e,) = graph.passages
    assert np.allclose(points[[0, -1]], markers.get_offsets()[[e.a, e.b]])  # marker to marker


def test_navigate_png_colour_bar_is_as_tall_as_the_map():
    """navigate.png of one map drew its colour bar at 0.8 of the figure's height: on a wide
    house it stood well above and below the map (the strips' and the per-cell maps' colour
    bars are as tall as the map beside them)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from test_navigate import START_A, house_result

    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.figure import plan_figure

    fig = plan_figure(navigate(house_result(), "go to the kitchen", START_A))
    FigureCanvasAgg(fig).draw()
    axes = [ax for ax in fig.axes if not ax.get_ylabel().startswith("p(")]
    assert len(axes) == 1
    (ax,) = axes
    bars = [a for a in [*fig.axes, *ax.child_axes] if a.get_ylabel().startswith("p(")]
    assert len(bars) == 1
    renderer = fig.canvas.get_renderer()
    map_box, bar_box = ax.get_window_extent(renderer), bars[0].get_window_extent(renderer)
    assert abs(bar_box.y0 - map_box.y0) <= 1 and abs(bar_box.y1 - map_box.y1) <= 1, (
        map_box, bar_box)  # fmt: skip
    assert bar_box.x0 >= map_box.x1  # beside it


def test_a_place_label_covers_no_other_place_marker():
    """show --graph on room1ldk5's words: the largest place by the map's right edge had its
    label pushed to its marker's left, onto a smaller place's marker (``washroom (6.2 m²)``
    over ``wall``'s), where it read as that place's name. A label now covers no other place's
    marker where a corner of its own marker leaves it clear."""
    from hand_results import one_word_per_concept
    from matplotlib.transforms import Bbox

    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
    from spcopyro.robot.navigation.figure import place_graph_figure, place_points
    from spcopyro.robot.navigation.places import place_graph

    occupancy = np.full((64, 124), OCCUPIED, dtype=np.int8)  # 6.2 m x 3.2 m, 0.05 m cells
    occupancy[2:-2, 2:-2] = FREE
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    rows, cols = np.nonzero(grid.free)  # [N] each
    labels = (cols >= 96).astype(np.int64)  # [N]: 1 the right 1.3 m, 0 the rest
    # a 0.6 m square of concept 2 just left of the right part's centre (5.45, 1.6), where the
    # right part's label went when the map's edge left no room on its marker's right
    labels[(rows >= 22) & (rows < 34) & (cols >= 84) & (cols < 96)] = 2
    result = one_word_per_concept(grid, labels, ("living", "washroom", "wall"), num_concepts=3)
    graph = place_graph(result)
    assert sorted(p.name for p in graph.places) == ["living", "wall", "washroom"]
    fig = place_graph_figure(result, graph)
    renderer, _ = _boxes(fig)
    ax = fig.axes[0]
    xy, _ = place_points(result.grid, graph)  # [N, 2]
    area = np.array([p.area for p in graph.places])  # [N]
    radius = np.sqrt(40 + 260 * area / area.max()) / 2 * fig.dpi / 72  # [N] pixels
    markers = {}
    for p in graph.places:
        cx, cy = ax.transData.transform(xy[p.id])
        r = radius[p.id]
        markers[p.name] = Bbox.from_extents(cx - r, cy - r, cx + r, cy + r)
    assert len(ax.texts) == 3
    for text in ax.texts:
        name = text.get_text().split(" (")[0]
        extent = text.get_window_extent(renderer)
        covered = [other for other, m in markers.items() if other != name and extent.overlaps(m)]
        assert not covered, f"{text.get_text()!r} covers the marker of {covered}"


def test_navigate_png_s_colour_bar_says_where_the_map_s_concepts_only_are_counted():
    """navigate.png's colour bar never said "; the map's concepts only", while where's figures
    do: both draw where_probability, which leaves out the cells' mass on concepts absent from
    the map (uncertainty.unmapped_note). It says so where some such mass is, as where's do."""
    import dataclasses

    from hand_results import two_rooms
    from test_where_shared import unmapped_result

    from spcopyro.results.uncertainty import cell_probability_label
    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.figure import plan_figure

    result, _ = unmapped_result()  # 0.4 of a cell's mass on concept 2, absent from the map
    point = dataclasses.replace(result, marginals=np.eye(3)[result.labels])  # none left out
    for fit, off_map in ((result, True), (point, False), (two_rooms(), False)):
        plan = navigate(fit, "go to the bed", (2.3, 0.5))
        assert plan.off_map is off_map
        (bar,) = plan_figure(plan).axes[-1].child_axes  # beside the map
        assert bar.get_ylabel() == cell_probability_label("bed", off_map)
    assert cell_probability_label("bed", True).endswith("; the map's concepts only")
