"""A word or image placed off the map (outside the grid: fitting snaps it or leaves it out) kept
house.png's and the semantic map's axes autoscaling: a word heard 30 m off the default house's
8 m map stretched the axes to 35 m, the map a quarter of them. The axes keep the map's limits and
the point is a triangle at the edge, counted in the legend (the axes' limits, not pixels)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hand_results import two_rooms
from matplotlib.colors import to_rgb

from spcopyro.figures.map_axes import known_bounds, map_extent
from spcopyro.figures.off_map import EDGE_MARKER_AREA, draw_at_edge, off_axes
from spcopyro.figures.plotting import house_figure, semantic_map_figure
from spcopyro.synthetic import make_house


def _limits(ax) -> tuple[float, float, float, float]:
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return float(x0), float(x1), float(y0), float(y1)


def _edge_marks(fig) -> list[np.ndarray]:
    """The [n, 2] world points of each scatter of triangles at the edge (drawn unclipped)."""
    return [
        np.asarray(c.get_offsets())
        for ax in fig.axes
        for c in ax.collections
        if len(c.get_offsets()) and c.get_sizes()[0] == EDGE_MARKER_AREA and not c.get_clip_on()
    ]


def _legend(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().texts]


def _house_off_the_map():
    """The default synthetic house (an 8 m x 6 m map) with its first word 30 m east of the map
    and its first two images 20 m south of it."""
    house = make_house(seed=0)
    obs = house.observations
    words = np.asarray(obs.word_xy, dtype=np.float64).copy()  # [U, 2]
    words[0] = [34.0, 1.0]
    images = np.asarray(obs.image_xy, dtype=np.float64).copy()  # [I, 2]
    images[:2] = [[0.0, -23.0], [1.0, -23.0]]
    moved = dataclasses.replace(obs, word_xy=words, image_xy=images)
    return dataclasses.replace(house, observations=moved)


def test_the_house_figure_keeps_the_map_s_limits_and_marks_what_lies_off_it():
    house = _house_off_the_map()
    extent = map_extent(house.grid, *known_bounds(house.grid))  # (-4, 4, -3, 3)
    fig = house_figure(house)
    (ax,) = fig.axes
    np.testing.assert_allclose(_limits(ax), extent)
    marks = np.concatenate([at for at in _edge_marks(fig)])  # [3, 2]
    np.testing.assert_allclose(sorted(map(tuple, marks)), [(0.0, -3.0), (1.0, -3.0), (4.0, 1.0)])
    assert "off the map: 1 word and 2 images (at its edge)" in _legend(fig)
    assert "images (180)" in _legend(fig)  # every image still counted


def test_the_house_figure_of_many_words_counts_them_on_the_map_only():
    """Circles of area by count (too many to spread) are of the words on the map; the word off
    it is its triangle, and the axes stay on the map."""
    house = _house_off_the_map()
    obs = house.observations
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(obs.utterances), 5_000)
    xy = np.asarray(obs.word_xy)[pick] + rng.uniform(-0.2, 0.2, (5_000, 2))  # [U, 2]
    xy[0] = [-40.0, 0.0]  # west of the map
    many = dataclasses.replace(obs, utterances=[obs.utterances[k] for k in pick], word_xy=xy,
                               word_trial=np.asarray(obs.word_trial)[pick])  # fmt: skip
    fig = house_figure(dataclasses.replace(house, observations=many))
    np.testing.assert_allclose(_limits(fig.axes[0]), (-4.0, 4.0, -3.0, 3.0))
    words = [at for at in _edge_marks(fig) if (at[:, 0] == -4.0).any()]
    np.testing.assert_allclose(np.concatenate(words), [[-4.0, 0.0]])


def test_a_frequent_word_heard_only_off_the_map_is_in_the_legend_of_many_words():
    """With circles of area by count (5,000 utterances) the legend listed the words of the
    circles only: 'attic', said 600 times 30 m east of the map, was its triangles at the edge,
    in a colour no legend entry named (with few words, spread apart, it was listed)."""
    house = make_house(seed=0)
    obs = house.observations
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(obs.utterances), 5_000)
    xy = np.asarray(obs.word_xy)[pick] + rng.uniform(-0.2, 0.2, (5_000, 2))  # [5000, 2]
    xy = np.vstack([xy, np.tile([34.0, 1.0], (600, 1))])  # [5600, 2]
    trial = np.asarray(obs.word_trial)[np.r_[pick, np.zeros(600, dtype=np.int64)]]  # [5600]
    said = [*(obs.utterances[k] for k in pick), *[("attic",)] * 600]
    many = dataclasses.replace(obs, utterances=said, word_xy=xy, word_trial=trial)
    fig = house_figure(dataclasses.replace(house, observations=many))
    legend = fig.axes[0].get_legend()
    labels = [t.get_text() for t in legend.texts]
    assert "circle area by count" in legend.get_title().get_text()
    assert "attic" in labels and "off the map: 600 words (at its edge)" in labels
    (east,) = [  # attic's triangles at the map's east edge (x = 4 m)
        c
        for c in fig.axes[0].collections
        if c.get_sizes()[0] == EDGE_MARKER_AREA and (c.get_offsets()[:, 0] == 4.0).all()
    ]
    handle = legend.legend_handles[labels.index("attic")]
    np.testing.assert_allclose(east.get_facecolor()[0][:3], to_rgb(handle.get_markerfacecolor()))


def test_the_semantic_map_keeps_the_map_s_limits_and_marks_a_word_heard_off_it():
    result = two_rooms()  # 3.1 m x 1 m
    extent = map_extent(result.grid, *known_bounds(result.grid))
    obs = make_house(seed=0).observations
    xy = np.array([[0.3, 0.3], [0.8, 0.7], [9.0, 0.5], [1.0, -5.0]])  # [4, 2]: 2 off the map
    heard = dataclasses.replace(obs, utterances=obs.utterances[:4], word_xy=xy,
                                word_trial=np.asarray(obs.word_trial)[:4])  # fmt: skip
    plain = semantic_map_figure(result)
    fig = semantic_map_figure(result, observations=heard)
    np.testing.assert_allclose(_limits(fig.axes[0]), extent)
    np.testing.assert_allclose(_limits(fig.axes[0]), _limits(plain.axes[0]))
    marks = np.concatenate([at for at in _edge_marks(fig)])
    np.testing.assert_allclose(sorted(map(tuple, marks)), [(1.0, 0.0), (3.1, 0.5)])
    assert "2 utterances heard off the map (at its edge; fill as above)" in _legend(fig)
    assert any("(4 utterances; fill" in text for text in _legend(fig))


def test_a_long_map_s_strips_keep_their_limits():
    """Strips fix the limits along the map (x of a map long in x); across it they autoscaled."""
    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid

    house = _house_off_the_map()
    occupancy = np.full((44, 2004), OCCUPIED, dtype=np.int8)
    occupancy[2:-2, 2:-2] = FREE  # 100 m x 2 m inside, 0.05 m cells
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    obs = house.observations
    xy = np.asarray(obs.word_xy, dtype=np.float64) * 0.1 + [50.0, 1.0]  # [U, 2] on the map
    xy[0] = [50.0, 30.0]  # 28 m north of it
    moved = dataclasses.replace(obs, word_xy=xy, image_xy=np.asarray(obs.image_xy) * 0.1 + 1.0)
    fig = house_figure(dataclasses.replace(house, grid=grid, truth=None, observations=moved))
    assert len(fig.axes) == 7
    bottom, top = map_extent(grid, *known_bounds(grid))[2:]
    for ax in fig.axes:
        np.testing.assert_allclose(_limits(ax)[2:], (bottom, top))
    assert "off the map: 1 word and 2 images (at its edge)" in _legend(fig)  # images 2.3 m south


@pytest.mark.parametrize(
    ("point", "marker", "at"),
    [
        ((9.0, 0.5), ">", (3.0, 0.5)),
        ((-2.0, 0.2), "<", (0.0, 0.2)),
        ((1.0, 4.0), "^", (1.0, 1.0)),
        ((1.0, -4.0), "v", (1.0, 0.0)),
        ((9.0, 2.0), ">", (3.0, 1.0)),
    ],  # fmt: skip
)
def test_a_point_off_the_axes_points_its_way_from_the_nearest_edge(point, marker, at):
    from matplotlib.figure import Figure
    from matplotlib.markers import MarkerStyle

    ax = Figure().subplots()
    ax.set_xlim(0.0, 3.0)
    ax.set_ylim(0.0, 1.0)
    xy = np.array([point, (1.0, 0.5)])  # the second on the axes
    np.testing.assert_array_equal(off_axes([ax], xy), [True, False])
    draw_at_edge([ax], xy[:1], np.array([[1.0, 0.0, 0.0]]))
    (mark,) = ax.collections
    np.testing.assert_allclose(mark.get_offsets(), [at])
    expected = MarkerStyle(marker)
    path = mark.get_paths()[0]
    drawn = expected.get_path().transformed(expected.get_transform())
    np.testing.assert_allclose(path.vertices, drawn.vertices)
    assert _limits(ax) == (0.0, 3.0, 0.0, 1.0)


def test_the_map_s_axes_do_not_grow_for_anything_drawn_off_the_map():
    """Any artist off the map (a spread marker pushed past the edge, a figure's own point) is
    clipped, not given room: the axes keep the map's limits, one map or its strips."""
    from spcopyro.figures.map_axes import map_axes
    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid, render_labels

    house = make_house(seed=0)
    occupancy = np.full((44, 2004), OCCUPIED, dtype=np.int8)
    occupancy[2:-2, 2:-2] = FREE  # 100 m x 2 m: 7 strips
    for grid in (house.grid, OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))):
        _, axes, _, _ = map_axes(grid, render_labels(np.full(grid.shape, -1), grid), (8, 8))
        before = [_limits(ax) for ax in axes]
        for ax in axes:
            ax.scatter([500.0, -500.0], [40.0, -40.0])
            ax.plot([0.0, 500.0], [0.0, 40.0])
        assert [_limits(ax) for ax in axes] == before


def test_many_words_off_the_map_are_a_row_of_triangles_not_a_pile():
    """One triangle a square of a triangle's width along the edge (in the square's most common
    colour): 10^4 words heard east of the map, over its height, are tens of triangles (one per
    colour and square: 702); the legend counts them all."""
    house = make_house(seed=0)
    obs = house.observations
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(obs.utterances), 10_000)
    xy = np.column_stack([rng.uniform(10.0, 20.0, 10_000), rng.uniform(-3.0, 3.0, 10_000)])
    many = dataclasses.replace(obs, utterances=[obs.utterances[k] for k in pick], word_xy=xy,
                               word_trial=np.asarray(obs.word_trial)[pick])  # fmt: skip
    fig = house_figure(dataclasses.replace(house, observations=many))
    marks = np.concatenate(_edge_marks(fig))  # [n, 2]
    assert 10 <= len(marks) <= 60, len(marks)  # a 6 m edge of ~50 squares
    np.testing.assert_allclose(marks[:, 0], 4.0)
    assert "off the map: 10000 words (at its edge)" in _legend(fig)


def test_points_at_one_spot_off_the_map_are_one_triangle_of_their_most_common_colour():
    from matplotlib.figure import Figure

    ax = Figure().subplots()
    ax.set_xlim(0.0, 3.0)
    ax.set_ylim(0.0, 1.0)
    red, blue = [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]
    xy = np.array([[5.0, 0.5], [6.0, 0.5], [7.0, 0.5], [5.0, 0.1]])  # [4, 2]
    draw_at_edge([ax], xy, np.array([blue, red, red, blue]))
    (mark,) = ax.collections
    np.testing.assert_allclose(mark.get_offsets(), [[3.0, 0.5], [3.0, 0.1]])
    np.testing.assert_allclose(mark.get_facecolors()[:, :3], [red, blue])
