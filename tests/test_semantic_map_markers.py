"""The semantic map's word circles stay a small part of the map however many utterances were
heard: 10^4 utterances, one circle of 22 points^2 each, covered the default house's map."""

from __future__ import annotations

import dataclasses

import numpy as np
from hand_results import two_rooms
from matplotlib.collections import PathCollection

from spcopyro.figures.map_pieces import MARKER_AREA, MAX_MARKER_COVER, MIN_MARKER_AREA
from spcopyro.figures.plotting import semantic_map_figure
from spcopyro.synthetic import make_house

SPOTS = np.array([[0.3, 0.3], [0.8, 0.7], [1.2, 0.5], [2.0, 0.3], [2.5, 0.8], [2.9, 0.5]])


def _figure(num_utterances: int, spread: float, xy: np.ndarray | None = None):
    """The semantic map of :func:`two_rooms` (3.1 x 1 m, 300 free cells of 0.1 m) with
    ``num_utterances`` utterances around 6 spots, ``spread`` metres apart at most (or at
    ``xy`` [U, 2])."""
    obs = make_house(seed=0).observations
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(obs.utterances), num_utterances)
    if xy is None:
        xy = SPOTS[rng.integers(0, len(SPOTS), num_utterances)]
        xy = xy + rng.uniform(-spread / 2, spread / 2, xy.shape)  # [U, 2]
    many = dataclasses.replace(
        obs,
        utterances=[obs.utterances[k] for k in pick],
        word_xy=xy,
        word_trial=np.asarray(obs.word_trial)[pick],
    )
    fig = semantic_map_figure(two_rooms(), observations=many)
    (markers,) = [
        c for c in fig.axes[0].collections if isinstance(c, PathCollection) and c.get_clip_on()
    ]  # not those off the map
    ax = fig.axes[0]
    corners = ax.transData.transform([[0.0, 0.0], [0.1, 0.1]])  # one 0.1 m cell, pixels
    cell = np.prod(np.abs(np.diff(corners, axis=0))) / (fig.dpi / 72.0) ** 2  # points^2
    free = two_rooms().grid.num_free * cell  # points^2 of the free space drawn
    legend = [t.get_text() for t in ax.get_legend().get_texts()] if ax.get_legend() else []
    legend += [t.get_text() for a in fig.axes if a.get_legend() for t in a.get_legend().texts]
    (entry,) = {t for t in legend if t.startswith("where a word was heard")}
    return markers, free, entry


def test_many_utterances_cover_a_bounded_share_of_the_map():
    markers, free, entry = _figure(10_000, spread=0.6)
    sizes = markers.get_sizes()  # [M] points^2
    assert len(sizes) < 10_000  # counted in circles, not drawn one by one
    assert sizes.min() >= MIN_MARKER_AREA
    # every circle at its least area makes the floor of the bound: MIN_MARKER_AREA each
    assert sizes.sum() <= MAX_MARKER_COVER * free + MIN_MARKER_AREA * len(sizes)
    assert sizes.sum() <= 0.2 * free, (sizes.sum(), free)
    assert "10000 utterances, circle area by count" in entry


def test_counted_circles_sum_to_the_share_of_the_map_aimed_at():
    """area = count * cover / U, then the 3 pt^2 floor: 10^4 utterances spread over the map
    covered 12.3% of it where 10% is aimed at."""
    rng = np.random.default_rng(0)
    xy = np.column_stack([rng.uniform(0, 3.1, 10_000), rng.uniform(0, 1.0, 10_000)])
    markers, free, _ = _figure(10_000, 0.0, xy)
    share = markers.get_sizes().sum() / free
    assert abs(share - MAX_MARKER_COVER) < 0.005, share


def test_utterances_at_few_spots_are_circles_of_area_by_count():
    counts = np.array([9_000, 900, 90, 9, 1])  # utterances heard at SPOTS[0], ..., SPOTS[4]
    xy = np.repeat(SPOTS[:5], counts, axis=0)  # [U, 2]
    markers, _, _ = _figure(int(counts.sum()), 0.0, xy)
    sizes = markers.get_sizes()  # [5], the largest first
    assert len(sizes) == 5
    at = markers.get_offsets()  # [5, 2] world points
    by_spot = [sizes[np.argmin(np.linalg.norm(at - spot, axis=1))] for spot in SPOTS[:5]]
    assert all(a > b for a, b in zip(by_spot[1:-1], by_spot[2:], strict=False)), by_spot
    assert by_spot[0] >= by_spot[1] and by_spot[-1] >= MIN_MARKER_AREA


def test_a_few_utterances_keep_one_circle_each():
    markers, _, entry = _figure(20, spread=0.6)
    # one of the 20 (y 1.03) lies off the 1 m high map: a triangle at its edge (test_off_map_*)
    assert len(markers.get_offsets()) == 19
    np.testing.assert_array_equal(np.broadcast_to(markers.get_sizes(), (19,)), MARKER_AREA)
    assert "area by count" not in entry
    assert "(20 utterances; fill: the concept there" in entry


def test_utterances_heard_at_one_spot_are_spread_apart():
    """room1ldk5's semantic map said "66 utterances" and showed about 30 circles: those heard
    at one spot were drawn on top of each other. Now spread apart as on house.png
    (spread_markers): 3 utterances at each of 5 spots are 15 circles, no two closer than 0.8 of
    a circle's width, each near its spot, and the legend still counts 15."""
    xy = np.repeat(SPOTS[:5], 3, axis=0)  # [15, 2]
    markers, _, entry = _figure(15, 0.0, xy)
    at = markers.get_offsets()  # [15, 2] world points
    assert len(at) == 15
    ax = markers.axes
    pixels = ax.transData.transform(at)  # [15, 2]
    apart = np.linalg.norm(pixels[:, None] - pixels[None], axis=-1)[np.triu_indices(15, 1)]
    width = np.sqrt(MARKER_AREA) * ax.figure.dpi / 72.0  # pixels: one circle's diameter
    assert apart.min() >= 0.8 * width * (1 - 1e-6), apart.min() / width
    near = np.linalg.norm(at[:, None] - SPOTS[None, :5], axis=-1).argmin(1)  # [15]
    np.testing.assert_array_equal(np.bincount(near), [3] * 5)
    assert "(15 utterances, those at one spot spread apart; fill: the concept there" in entry


def test_a_word_shown_by_two_strips_is_at_one_place_in_both():
    """A long map's strips each spread the words in reach of their own view (7 strips of a 100 m
    map), so a word where two strips overlap could be drawn at one place in one strip and
    another in the next. Now spread once, on one scale, as house.png does: every strip that
    shows a word draws it at one place, and the circles in each strip are apart.

    Two rows of words 0.54 circle widths apart, from 2.4 m (22 widths) before strip 2's view
    into the overlap of strips 1 and 2, placed in order: every other one moves up a ring, so
    spreading from another first word (strip 2 spreading only those in reach) flips the
    pattern of one row (they start a word apart) in the overlap. Two words at each of 10 spots
    along the map besides."""
    from hand_results import one_word_per_concept

    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid

    occupancy = np.full((44, 2004), OCCUPIED, dtype=np.int8)
    occupancy[2:-2, 2:-2] = FREE  # 100 m x 2 m inside, 0.05 m cells: 7 strips
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    labels = np.arange(grid.num_free) * 4 // grid.num_free  # [N] 4 concepts along the map
    result = one_word_per_concept(grid, labels, ("a", "b", "c", "d"))
    obs = make_house(seed=0).observations
    rows = [np.stack(np.broadcast_arrays(np.arange(x, 14.5, 0.06), y), 1)  # [~50, 2] each
            for x, y in ((11.5, 0.6), (11.56, 1.5))]  # fmt: skip
    pairs = np.column_stack([np.repeat(np.arange(5.0, 100.0, 10.0), 2), np.ones(20)])  # [20, 2]
    xy = np.concatenate([*rows, pairs])  # [U, 2]
    pick = np.arange(len(xy)) % len(obs.utterances)
    words = dataclasses.replace(obs, utterances=[obs.utterances[k] for k in pick], word_xy=xy,
                                word_trial=np.asarray(obs.word_trial)[pick])  # fmt: skip
    fig = semantic_map_figure(result, observations=words)
    assert len(fig.axes) == 7
    width = np.sqrt(MARKER_AREA) * fig.dpi / 72.0  # pixels: one circle's diameter
    views, drawn = [], []
    for ax in fig.axes:
        (markers,) = [c for c in ax.collections if isinstance(c, PathCollection)]
        assert markers.get_offsets().shape == xy.shape  # one circle each, in xy's order
        drawn.append(np.asarray(markers.get_offsets()))  # [U, 2]
        views.append(sorted(ax.get_xlim()))
        scale = np.diff(ax.transData.transform([[0.0, 0.0], [0.06, 0.0]]), axis=0)[0, 0] / width
        assert 0.5 <= scale < 0.8, scale  # the rows' spacing in circle widths, as drawn
        shown = drawn[-1][(xy[:, 0] > views[-1][0]) & (xy[:, 0] < views[-1][1])]  # [S, 2]
        pixels = ax.transData.transform(shown)  # [S, 2]
        pairs_of = np.triu_indices(len(shown), 1)
        apart = np.linalg.norm(pixels[:, None] - pixels[None], axis=-1)[pairs_of]
        assert len(shown) and apart.min() >= 0.8 * width * (1 - 1e-6), apart.min() / width
    twice = 0
    for k, (x, _) in enumerate(xy):  # each word at one place in every strip that shows it
        at = [strip[k] for strip, (x0, x1) in zip(drawn, views, strict=True) if x0 < x < x1]
        twice += len(at) > 1
        np.testing.assert_allclose(at, np.broadcast_to(at[0], np.shape(at)), atol=1e-9,
                                   err_msg=f"word {k} heard at {xy[k]}")  # fmt: skip
    assert twice >= 20  # the rows' words in the overlap of strips 1 and 2


def _house_with(num_utterances: int):
    house = make_house(seed=0)
    obs = house.observations
    rng = np.random.default_rng(1)
    pick = rng.integers(0, len(obs.utterances), num_utterances)
    xy = np.asarray(obs.word_xy)[pick] + rng.uniform(-0.2, 0.2, (num_utterances, 2))  # [U, 2]
    many = dataclasses.replace(
        obs,
        utterances=[obs.utterances[k] for k in pick],
        word_xy=xy,
        word_trial=np.asarray(obs.word_trial)[pick],
    )
    return dataclasses.replace(house, observations=many)


def test_the_house_figure_counts_many_words_instead_of_spreading_them():
    """house.png of 10^4 utterances spread its markers in rings over the whole map (and took
    15 s): now circles of area by count, every word still in the legend."""
    from spcopyro.figures.plotting import house_figure

    house = _house_with(10_000)
    fig = house_figure(house)
    ax = fig.axes[0]
    circles = [c for c in ax.collections if isinstance(c, PathCollection) and len(c.get_offsets())]
    sizes = np.concatenate(
        [np.broadcast_to(c.get_sizes(), (len(c.get_offsets()),)) for c in circles[1:]]
    )  # circles[0]: the images
    corners = ax.transData.transform([[0.0, 0.0], [0.1, 0.1]])  # one 0.1 m cell, pixels
    cell = np.prod(np.abs(np.diff(corners, axis=0))) / (fig.dpi / 72.0) ** 2  # points^2
    assert len(sizes) < 10_000
    assert sizes.sum() <= 0.2 * house.grid.num_free * cell
    legend = fig.axes[-1].get_legend()
    assert "circle area by count" in legend.get_title().get_text()
    words = [t.get_text() for t in legend.get_texts()]
    assert words[-1].startswith("other words: ") and len(words) == 1 + 12 + 1  # images, 12, rest


def test_the_house_figure_of_a_few_words_spreads_them():
    from spcopyro.figures.plotting import house_figure

    legend = house_figure(_house_with(50)).axes[-1].get_legend()
    assert "markers at one spot spread apart" in legend.get_title().get_text()
