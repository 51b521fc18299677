"""Where a figure's pieces stand: legends off the panels and maps they would cover, labels that
do not run into each other, long maps cut into strips of a readable aspect (the drawn boxes'
geometry, not pixels). What the pieces say and their colours: test_figure_legibility.py."""

from __future__ import annotations

import numpy as np
import pytest


def test_place_graph_labels_do_not_overlap_and_the_legend_leaves_the_map():
    """show --graph on a corridor of small places: two labels ran into one ("concept 34
    (0.8 m²).9 m²)") and the legend (loc="best") covered a room."""
    from hand_results import one_word_per_concept
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.maps import FREE, OccupancyGrid
    from spcopyro.robot.navigation.figure import place_graph_figure
    from spcopyro.robot.navigation.places import place_graph

    grid = OccupancyGrid(np.full((6, 60), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    labels = (np.arange(60) // 6)[None, :].repeat(6, axis=0)[grid.free]  # [N]: 10 places
    words = tuple(f"place{k}" for k in range(10))
    result = one_word_per_concept(grid, labels, words, num_concepts=10)
    fig = place_graph_figure(result, place_graph(result, min_area=0.1))
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    assert len(fig.axes) == 2  # 6 m x 0.6 m: two strips (STRIP_ASPECT)
    texts = [t for ax in fig.axes for t in ax.texts]
    boxes = [t.get_window_extent(renderer) for t in texts]
    assert len(boxes) == 10
    for i, box in enumerate(boxes):
        assert not any(box.overlaps(other) for other in boxes[i + 1 :]), texts[i].get_text()
    (legend,) = [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    legend = legend.get_window_extent(renderer)
    assert not any(legend.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)


def _overlaps_an_axes(fig, artist) -> bool:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    box = artist.get_window_extent(renderer)
    return any(box.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)


def test_the_comparison_legend_leaves_the_panels():
    """comparison_public.png: the methods' legend (inside the first panel) covered the top-1
    lines; it stands below the panels."""
    from spcopyro.experiments.comparison_figure import curves_figure
    from spcopyro.experiments.inference_comparison import VARIANTS

    curve = [{"seconds": s, "top1": 0.5, "distance_m": 1.0} for s in (0.1, 1.0, 10.0)]
    records = {key: [{"curve": curve}] for key in VARIANTS}  # every method: seven entries
    fig = curves_figure({"records": {"public": records},
                         "methods": {key: v.label for key, v in VARIANTS.items()}},
                        "public")  # fmt: skip
    (legend,) = fig.legends
    assert len(legend.get_texts()) == len(VARIANTS) + 1  # and the last point's marker
    assert not _overlaps_an_axes(fig, legend)
    assert not any(ax.get_legend() for ax in fig.axes)


def test_the_ablation_legend_names_table_2_and_leaves_the_panels():
    """ablation.png drew Table 2's category counts as black lines that its legend (inside the
    synthetic panel, loc="best", over the bars) did not name."""
    from spcopyro.experiments.ablation import AblationSettings
    from spcopyro.experiments.ablation_report import ablation_figure
    from spcopyro.experiments.ablation_variants import parse_variant

    settings = AblationSettings(variants=(parse_variant("a"), parse_variant("b")),
                                baselines=("F-geometry",), synthetic=("dense",))  # fmt: skip
    score = {"mean": 0.5, "sd": 0.1, "n": 2}
    summary = {
        row: {"dense": {"ari": score, "ari_off": score}, "room1dk5": {"concepts_1pct": score}}
        for row in ("a", "b", "F-geometry")
    }
    report = {"summary": summary, "records": [{"house": "room1dk5", "public": True}]}
    fig = ablation_figure(report, settings)
    (legend,) = fig.legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts[:3] == ["a", "b", "F-geometry"], texts
    assert any(t.startswith("Table 2") for t in texts), texts
    assert any(t.startswith("observations off") for t in texts), texts
    assert not _overlaps_an_axes(fig, legend)


def test_a_long_corridor_is_drawn_in_readable_strips():
    """show on a 100 m x 2 m map drew a strip 40 pixels high, its markers spilling over the
    walls; it is cut into strips of at most STRIP_ASPECT, at one scale (tall maps: side by
    side). An ordinary house stays one map."""
    import dataclasses

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.figures.map_pieces import STRIP_ASPECT
    from spcopyro.figures.plotting import house_figure
    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
    from spcopyro.synthetic import make_house

    house = make_house(seed=0)
    assert len(house_figure(house).axes) == 1
    occupancy = np.full((44, 2004), OCCUPIED, dtype=np.int8)
    occupancy[2:-2, 2:-2] = FREE  # 100 m x 2 m inside, 0.05 m cells
    for grid_cells in (occupancy, occupancy.T):
        grid = OccupancyGrid(np.ascontiguousarray(grid_cells), 0.05, (0.0, 0.0, 0.0))
        fig = house_figure(dataclasses.replace(house, grid=grid, truth=None))
        renderer = FigureCanvasAgg(fig).get_renderer()
        for ax in fig.axes:
            ax.apply_aspect()
        boxes = [ax.get_window_extent(renderer) for ax in fig.axes]
        assert len(boxes) == 7, len(boxes)
        sizes = {(round(b.width), round(b.height)) for b in boxes}
        assert len(sizes) == 1, sizes  # one scale
        ((w, h),) = sizes
        assert max(w, h) / min(w, h) <= STRIP_ASPECT and min(w, h) >= 0.9 * fig.dpi, sizes
        assert "(the map in 7 strips, " in fig.axes[0].get_title()


def test_the_semantic_map_of_a_long_corridor_is_drawn_in_strips(tmp_path):
    """semantic_map.png of a 100 m x 2 m corridor: a strip 40 pixels high under labels that
    ran over the axis and the title; its strips carry each region's label on the strip that
    shows the region's label point. where.png and the per-cell maps likewise."""
    from hand_results import one_word_per_concept

    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid

    occupancy = np.full((44, 2004), OCCUPIED, dtype=np.int8)
    occupancy[2:-2, 2:-2] = FREE
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    columns = np.nonzero(grid.free)[1]  # [N]
    labels = np.minimum((columns - 2) // 400, 4)  # [N]: five rooms of 20 m
    words = ("kitchen", "bed", "sofa", "bath", "door")
    result = one_word_per_concept(grid, labels, words, num_concepts=5)
    fig = semantic_map_figure(result)
    assert len(fig.axes) == 7
    title = fig.axes[0].get_title()
    assert "5 labelled regions" in title and "(the map in 7 strips, top to bottom)" in title
    texts = [(ax, t) for ax in fig.axes for t in ax.texts]
    assert len(texts) == 5
    for ax, text in texts:
        x, _ = text.get_position()
        assert ax.get_xlim()[0] <= x <= ax.get_xlim()[1], (text.get_text(), ax.get_xlim())

    from matplotlib.image import imread

    from spcopyro.figures.plotting import plot_where_probability, where_figure

    height, width = imread(plot_where_probability(result, "bath", tmp_path / "p.png")).shape[:2]
    assert height > 0.5 * width, (height, width)  # whole, the map was a line: 181 x 1252
    fig = where_figure(result, result.where("bath"))  # a point estimate: no colour bar
    assert len(fig.axes) == 7
    assert fig.axes[0].get_title().endswith("\n(the map in 7 strips, top to bottom)")
    legend = fig.axes[-1].get_legend()
    assert legend is not None and not _overlaps_an_axes(fig, legend)


@pytest.mark.parametrize("shape", [(44, 2004), (10, 160), (2004, 44), (160, 10), (10, 81)])
def test_a_strip_keeps_the_aspect_bound_with_its_margins(shape):
    """A long map's strips were counted without their 3% margins at both ends: a 100 m x 2 m
    corridor's 6 strips were each 8.05:1, a 10 x 160 cell map's 2 strips 8.48:1. Each strip,
    margins included, is at most STRIP_ASPECT:1 (limits and drawn box), all at one scale."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.figures.map_axes import map_axes
    from spcopyro.figures.map_pieces import STRIP_ASPECT
    from spcopyro.maps import FREE, OccupancyGrid

    grid = OccupancyGrid(np.full(shape, FREE, dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    rgb = np.full((*shape, 3), 255, dtype=np.uint8)
    fig, axes, _, _ = map_axes(grid, rgb, (8, 8))
    assert len(axes) > 1, shape
    renderer = FigureCanvasAgg(fig).get_renderer()
    spans = set()
    for ax in axes:
        ax.apply_aspect()
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        assert max(x1 - x0, y1 - y0) <= STRIP_ASPECT * min(x1 - x0, y1 - y0) * (1 + 1e-9), (
            ax.get_xlim(), ax.get_ylim())  # fmt: skip
        box = ax.get_window_extent(renderer)
        assert max(box.width, box.height) <= STRIP_ASPECT * min(box.width, box.height) + 1.0
        spans.add((round(x1 - x0, 9), round(y1 - y0, 9)))
    assert len(spans) == 1, spans  # one scale


def test_the_stability_log_joint_legend_stands_below_its_panel():
    """stability.png's right panel (ARI against the log joint) placed its legend with
    loc="best": inside the axes, wherever the points left room (slow on a big plot, and it
    moved between runs). It stands below the panel, as the left one's does."""
    from spcopyro.experiments.figures import stability_figure

    def row(ari: float) -> dict:
        chains = [[{"ari": ari + d, "best_log_joint": -100 * d} for d in (0.0, 0.1, 0.2)]]
        return {"method": "A-dp", "single": [ari], "best_of_chains": [ari], "chains": chains}

    names = ("A-dp random", "A-dp spcoa", "A-dp random anneal", "A-dp random cluster")
    settings = {name: row(0.2 * k) for k, name in enumerate(names)}
    fig = stability_figure({"settings": settings, "chains": 3, "seeds": [0], "sweeps": 10})
    right = fig.axes[1]
    legend = right.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == list(names)
    assert not _overlaps_an_axes(fig, legend)


def test_a_map_legend_under_a_wide_title_starts_at_its_left():
    """house.png's words legend centred its entries under its two-line title: the markers
    stood some 100 pixels in from the title's left, in a column of their own. They start at
    the title's left (map_legend aligns left)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.figures.plotting import house_figure
    from spcopyro.synthetic import make_house

    fig = house_figure(make_house(seed=0))
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    legend = fig.axes[0].get_legend()
    title = legend.get_title().get_window_extent(renderer)
    first = legend.get_texts()[0].get_window_extent(renderer)
    em = legend.get_texts()[0].get_fontsize() * fig.dpi / 72  # pixels
    assert first.x0 - title.x0 < 5 * em, (title, first)  # the marker and its pad: 3.5 em
