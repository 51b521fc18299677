"""The pieces of the semantic-map and "where is X?" figures that a person reads (paper Fig. 10F):
the words written on the map itself with an outline that keeps them readable over any colour,
the legend of concepts with their words, the places where words were heard, and the outline of
a where-answer's region. :mod:`spcopyro.figures.plotting` assembles them into figures.

The words are the posterior means of w (:mod:`spcopyro.results.posterior_means`) with their
probability, and the lift p(word | concept) / p(word) next to the words that are distinctive
(:mod:`spcopyro.results.concept_words`); a concept whose region holds no observed word says
:data:`~spcopyro.results.concept_words.NO_WORDS` instead.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from typing import Any

import numpy as np
from matplotlib import patheffects
from matplotlib.axes import Axes
from matplotlib.backend_bases import RendererBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.text import Text
from matplotlib.transforms import Bbox, IdentityTransform, ScaledTranslation

from spcopyro._util.messages import plural
from spcopyro.data import House, Observations
from spcopyro.figures.off_map import draw_at_edge, edge_handle, off_axes
from spcopyro.maps import OCCUPIED, OccupancyGrid
from spcopyro.results.concept_names import concept_name
from spcopyro.results.concept_words import (
    MIN_LIFT,
    NO_WORDS,
    cells_range,
    format_words_heard,
    named_specks,
    shown_top_words,
    speck_line,
)
from spcopyro.results.result import SpCoResult
from spcopyro.results.specks import speck_concepts, support_text

__all__ = [
    "OFF_MAP_RGB",
    "OUTLINE",
    "concept_handles",
    "draw_counted_words",
    "draw_outline",
    "draw_utterances",
    "house_title",
    "is_wide",
    "legend_concepts",
    "map_legend",
    "markers_counted",
    "map_strips",
    "place_labels",
    "region_text",
    "rim_colours",
    "spread_markers",
    "utterance_concepts",
    "utterance_markers",
    "utterance_marks",
    "word_palette",
]

OUTLINE = [patheffects.withStroke(linewidth=2.5, foreground="white")]
"""Path effect drawn under every text on a map: a white halo that keeps it readable on any
concept colour or wall."""
OFF_MAP_RGB = (0.5, 0.5, 0.5)
"""Marker colour of an utterance heard off free space (no concept there)."""
WIDE_ASPECT = 2.5
"""A map shown more than this many times as wide as it is high gets its legend below it, in
columns (:func:`map_legend`): beside it, a legend taller than the map left most of the figure
blank and the map a strip."""
LEGEND_BELOW_INCHES = 0.55
"""Gap between the axes and a legend below them: clears the x tick labels and the x label."""
STRIP_ASPECT = 8.0
"""A map shown more than this many times as long as it is wide (a corridor of 100 m x 2 m) is
drawn in strips of at most this aspect (:func:`map_strips`), their margins
(:data:`STRIP_PAD`) included: whole, it was a line a few pixels high with its markers spilling
over the walls."""
STRIP_PAD = 0.03
"""Each strip of a long map shows this fraction of its stretch more at both ends, so a marker on
a cut shows whole (:func:`~spcopyro.figures.map_axes.strip_axes`)."""
MAX_LEGEND_CONCEPTS = 12
"""The legend lists this many of the largest concepts (the rest are counted in one line)."""
MARKER_AREA = 22.0
"""Area (points^2, as ``scatter``'s ``s``) of the circle marking one utterance on the semantic
map (:func:`utterance_markers`)."""
MAX_MARKER_COVER = 0.1
"""The semantic map's word circles cover at most about this share of the free space shown
(:func:`utterance_markers`; 10^4 utterances, one circle each, covered the default house)."""
MIN_MARKER_AREA = 3.0
"""Points^2 of the smallest circle of counted utterances: a lone word still shows."""
MAX_MARKER_AREA = 9 * MARKER_AREA
"""Points^2 of the largest circle of counted utterances (three circles wide)."""


def _word_line(word: str, p: float, lift: float) -> str:
    """``"kitchen .31 x4.2"``: a word, its probability, and its lift when it is distinctive."""
    text = f"{word} {p:.2f}"
    return text + (f" x{lift:.1f}" if lift > MIN_LIFT else "")


def region_text(
    result: SpCoResult,
    concept: int,
    n_words: int = 3,
    largest: bool = True,
    name: str | None = None,
) -> str:
    """The label of one region: ``[concept]`` then its ``n_words`` most probable words, one a
    line, each with its probability and, if distinctive, its lift (``"kitchen 0.31 x4.2"``);
    on a further region of the same concept, ``[concept]`` and its name on one line (the word
    ``where`` answers with it, :func:`~spcopyro.results.concept_names.concept_name`, as the place
    graph names it: the kitchen whose top word is "sink" reads ``[3] kitchen``). A concept where
    no word was heard: ``[concept]`` and ``"no words heard here"``; any other region of a fit
    that did not model its words: ``[concept]`` alone. ``name``: the concept's name when the
    caller has it (:func:`~spcopyro.results.concept_names.concept_names` once for every region
    of a map: each call without it ranks the whole vocabulary again); None: computed here."""
    if not largest:
        name = concept_name(result, concept) if name is None else name
        return f"[{concept}]" if name == f"concept {concept}" else f"[{concept}] {name}"
    if result.heard(concept) == 0:
        return f"[{concept}]\n{NO_WORDS}"
    lifts = result.lift()[concept]  # [V]
    index = {w: k for k, w in enumerate(result.vocabulary)}
    words = shown_top_words(result, concept, n_words)
    return "\n".join([f"[{concept}]"] + [_word_line(w, p, lifts[index[w]]) for w, p in words])


def house_title(house: House) -> str:
    """The title of a house's figure: its name and free cells at their size, and for a grid a
    fit coarsened (``fit``'s house.png) the map's own cells too, as ``fit`` prints them:
    "room1dk5: 700 free cells" beside ``show``'s "18622 free cells" of the same house read as
    a contradiction."""
    grid = house.grid
    title = f"{house.name}: {grid.num_free} free cells of {grid.resolution:g} m"
    source = grid.coarsened_from
    if source is not None:
        title += (f"\n(the model's cells; the map's: {source.num_free} free of "
                  f"{source.resolution:g} m)")  # fmt: skip
    return title


def is_wide(rows: slice, cols: slice) -> bool:
    """Whether the shown part of a map (``rows`` x ``cols`` cells) is wider than
    :data:`WIDE_ASPECT` times its height."""
    return (cols.stop - cols.start) > WIDE_ASPECT * (rows.stop - rows.start)


def map_strips(rows: slice, cols: slice) -> tuple[int, bool]:
    """How to cut the shown part of a map (``rows`` x ``cols`` cells) into strips of at most
    :data:`STRIP_ASPECT`: ``(strips, along_x)``; 1 strip for a map no longer than that, else
    enough that a strip's stretch with its margins (``1 + 2 * STRIP_PAD`` times it) keeps the
    bound (counted without them, a 100 m x 2 m corridor's 6 strips were 8.05:1);
    ``along_x`` for a wide map (strips stacked top to bottom), else a tall one (strips side by
    side, left to right)."""
    height, width = rows.stop - rows.start, cols.stop - cols.start
    long, short = max(height, width), max(min(height, width), 1)
    if long <= STRIP_ASPECT * short:
        return 1, width >= height
    return math.ceil(long * (1 + 2 * STRIP_PAD) / (STRIP_ASPECT * short)), width >= height


def map_legend(
    ax: Axes,
    handles: list,
    labels: list[str] | None = None,
    *,
    below: bool,
    columns: int = 1,
    below_inches: float = LEGEND_BELOW_INCHES,
    **kwargs,
) -> Legend:
    """The legend of a map figure: beside the map (upper left of the space to its right), or
    ``below`` it in ``columns`` columns, ``below_inches`` under the axes whatever the map's
    height (a fraction of a short map's height put it over the x label). Below suits a wide map
    (:func:`is_wide`) and a map with a colour bar beside it. ``kwargs`` go to
    :meth:`~matplotlib.axes.Axes.legend` (fontsize, title, ...); the entries and title are
    aligned left."""
    args = () if labels is None else (handles, labels)  # one positional argument means labels
    kwargs = kwargs if labels is not None else {**kwargs, "handles": handles}
    # entries under a wider title start at its left, not centred beneath it (house.png's words)
    kwargs.setdefault("alignment", "left")
    if not below:
        return ax.legend(*args, loc="upper left", bbox_to_anchor=(1.01, 1.0), **kwargs)
    offset = ax.transAxes + ScaledTranslation(0.0, -below_inches, ax.figure.dpi_scale_trans)
    return ax.legend(*args, loc="upper left", bbox_to_anchor=(0.0, 0.0), bbox_transform=offset,
                     borderaxespad=0.0, ncol=columns, **kwargs)  # fmt: skip


def concept_handles(
    result: SpCoResult, colours: np.ndarray, n_words: int = 3, limit: int = MAX_LEGEND_CONCEPTS
) -> list[Patch]:
    """Legend entries of the ``limit`` largest concepts: the colour, ``[concept]``, its cells,
    the words heard there, its top words and its distinctive words with their lifts
    (``colours``: ``[L, 3]`` uint8, :func:`spcopyro.figures.plotting.semantic_colours`)."""
    handles = []
    sizes = result.concept_sizes()
    used, specks = _legend_split(result)
    for concept in used[:limit]:
        c = int(concept)
        heard = result.heard(c)
        cells = int(sizes[c])
        if heard == 0:
            words = f": {NO_WORDS}"
        else:  # as fit prints: none where the fit did not model its words (the title says so)
            top = shown_top_words(result, c, n_words)
            words = ": " * bool(top) + ", ".join(f"{w} {p:.2f}" for w, p in top)
            distinctive = result.distinctive_words(c, n_words)
            if distinctive:
                words += "\n      distinctive: " + ", ".join(
                    f"{w} x{r:.1f}" for w, r, _ in distinctive
                )
        heard_text = "" if heard is None else format_words_heard(heard)
        noun = "word" if heard_text == "1" else "words"  # not "1 words heard"
        count = "" if heard is None or heard == 0 else f", {heard_text} {noun} heard"
        size = cells_range([cells])  # "1 cell", not "1 cells", as fit prints
        handles.append(Patch(color=colours[c] / 255.0, label=f"[{c}] {size}{count}{words}"))
    summaries = []  # (largest concept, entry): the two summary lines, larger concepts first
    if len(used) > limit:
        rest = [int(sizes[c]) for c in used[limit:]]
        summaries.append(
            (max(rest), f"... {len(rest)} smaller concepts of {cells_range(rest)} in concepts.json")
        )  # as fit's listing says: their words are there
    if specks:  # fit's listing's line, its share of the posterior under it
        speck_sizes = [int(sizes[c]) for c in specks]
        support = support_text(result, specks)
        support = "" if support is None else f"\n      {support}"
        summaries.append((max(speck_sizes), f"{speck_line(specks, speck_sizes)}{support}"))
    for _, label in sorted(summaries, key=lambda s: -s[0]):  # stable: equal sizes keep order
        handles.append(Patch(color="white", label=label))
    return handles


def _legend_split(result: SpCoResult) -> tuple[np.ndarray, list[int]]:
    """The concepts in use, largest first, that are not specks ``[L']``, and the specks:
    :func:`concept_handles` gives the first their own entries, the specks one line."""
    specks = speck_concepts(result)
    used = np.array([c for c in result.concepts_in_use() if int(c) not in specks], dtype=np.int64)
    return used, specks


def legend_concepts(result: SpCoResult, limit: int = MAX_LEGEND_CONCEPTS) -> set[int]:
    """The concepts :func:`concept_handles` names: the ``limit`` largest with their own entry
    and the specks its speck line names; a smaller concept is only counted there (its words
    are in concepts.json)."""
    used, specks = _legend_split(result)
    return {int(c) for c in used[:limit]} | set(named_specks(specks))


def utterance_marks(utterances: list[list[str]]) -> list[str]:
    """The word each utterance is marked by on a map of the words heard: its rarest word (in
    the fewest utterances) that is not a filler of a sentence ("here", "is", "the", "place",
    ...: :data:`~spcopyro.synthetic.lexicon.FILLER_WORDS`), the last of equally rare ones;
    ``""`` for an empty utterance. A one-word utterance is its word; "kitchen" marks "here is
    the kitchen", "living" marks "we are in the living room". The last word, marked before, was
    "here" in "the stove is here" and "room" in "this is the living room": on a house of
    sentences "here" took the first colour and "living" never showed."""
    from spcopyro.synthetic.lexicon import FILLER_WORDS

    counts = Counter(w for u in utterances for w in set(u))  # utterances holding each word
    return [
        min(reversed(u), key=lambda w: (w in FILLER_WORDS, counts[w])) if u else ""
        for u in utterances
    ]


def utterance_concepts(result: SpCoResult, xy: np.ndarray) -> np.ndarray:
    """[U] the concept of the cell each world point ``[U, 2]`` is placed in as the fit placed
    its observations (:func:`~spcopyro.data.place_observations` with the fit's snap distance:
    a word heard just off free space, e.g. in a doorway that a coarse grid's thickened wall
    covers, takes the cell it was counted in); -1 where it was left out."""
    from spcopyro.data import place_observations

    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)  # [U, 2]
    if len(xy) == 0:
        return np.zeros(0, dtype=np.int64)
    cells, _, _ = place_observations(result.grid, xy, result.preparation.snap_distance)  # [U]
    labels = np.asarray(result.labels)  # [N] concept of each free cell
    return np.where(cells >= 0, labels[np.maximum(cells, 0)], -1).astype(np.int64)


def _on_walls(grid: OccupancyGrid, xy: np.ndarray) -> np.ndarray:
    """[U] bool: the world point ``[U, 2]`` lies on an occupied cell (a black wall)."""
    cells = grid.world_to_cell(xy)  # [U, 2]
    inside = grid.in_bounds(cells)  # [U]
    walls = np.zeros(len(xy), dtype=bool)
    walls[inside] = grid.occupancy[cells[inside, 0], cells[inside, 1]] == OCCUPIED
    return walls


def rim_colours(grid: OccupancyGrid, xy: np.ndarray) -> np.ndarray:
    """``[U, 3]`` the rim of a marker at each world point ``[U, 2]``: black, white on a wall
    (a black rim on a black wall vanished and a dark marker there was hard to see)."""
    return np.repeat(np.where(_on_walls(grid, xy)[:, None], 1.0, 0.0), 3, axis=1)


def _free_area_shown(ax: Axes, grid: OccupancyGrid) -> float:
    """Pixels^2 of the free cells whose centres ``ax`` shows, as drawn (equal aspect applied)."""
    ax.apply_aspect()
    xy = grid.cell_to_world(grid.free_cells)  # [N, 2]
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    shown = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)  # [N]
    side = np.abs(np.diff(ax.transData.transform([[0.0, 0.0], [grid.resolution] * 2]), axis=0))
    return float(shown.sum() * side[0, 0] * side[0, 1])


def _crowding(ax: Axes, grid: OccupancyGrid, xy: np.ndarray) -> tuple[np.ndarray, int, float]:
    """``(pixels [U, 2], n, cover)``: the world points ``xy`` ``[U, 2]`` in ``ax``'s pixels, how
    many of them it shows, and the points^2 that ``MAX_MARKER_COVER`` of the free space shown
    makes (:func:`utterance_markers`)."""
    inch = ax.figure.dpi / 72.0  # pixels per point
    cover = MAX_MARKER_COVER * _free_area_shown(ax, grid) / inch**2  # points^2 (aspect applied)
    pixels = ax.transData.transform(xy)  # [U, 2]
    x0, y0, x1, y1 = ax.bbox.extents  # the axes in pixels
    in_view = (pixels[:, 0] >= x0) & (pixels[:, 0] <= x1) & (pixels[:, 1] >= y0) & (
        pixels[:, 1] <= y1)  # fmt: skip
    return pixels, int(in_view.sum()), cover


def markers_counted(ax: Axes, grid: OccupancyGrid, xy: np.ndarray) -> bool:
    """Whether :func:`utterance_markers` of the utterances at ``xy`` ``[U, 2]`` on ``ax`` draws
    circles of area by count (too many for one circle each), without grouping them."""
    _, n, cover = _crowding(ax, grid, xy)
    return n * MARKER_AREA > cover


def utterance_markers(
    ax: Axes, grid: OccupancyGrid, xy: np.ndarray, concepts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The circles that mark the utterances heard at world points ``xy`` ``[U, 2]`` (counted in
    ``concepts`` ``[U]``, -1 left out) on ``ax``: ``(xy [M, 2], concepts [M], areas [M] in
    points^2, counts [M] or None)``.

    One circle of ``MARKER_AREA`` per utterance, ``counts`` None, while those circles cover at
    most ``MAX_MARKER_COVER`` of the free space shown (up to ~1100 utterances on the default
    house's map, ~300-400 on room2ldk4's and room1ldk4's, which hold 76 and 45). Beyond it
    (10^4 utterances covered the default house's map) the utterances of one concept in one
    square of a circle's width are one circle at their mean point, of area proportional to
    their ``counts``, ``area = count * unit`` within ``[MIN_MARKER_AREA, MAX_MARKER_AREA]``,
    ``unit`` at most ``cover / U`` (``cover`` the points^2 that ``MAX_MARKER_COVER`` of the free
    space shown makes, ``U`` the utterances in view) and bisected so the areas sum to ``cover``
    where the floor allows: each lone word still shows (with a word in nearly every square the
    floor wins: 10^5 utterances spread over a 3.1 m x 1 m map cover 15% of it)."""
    inch = ax.figure.dpi / 72.0  # pixels per point
    pixels, n, cover = _crowding(ax, grid, xy)
    if n * MARKER_AREA <= cover:
        return xy, concepts, np.full(len(xy), MARKER_AREA), None
    width = np.sqrt(MARKER_AREA) * inch  # pixels: one circle's diameter
    keys = np.column_stack([np.floor(pixels / width).astype(np.int64), concepts])  # [U, 3]
    _, group, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    group = group.reshape(-1)  # [U] (numpy 2.0.x returns it [U, 1] with axis=0)
    mean = np.stack([np.bincount(group, weights=xy[:, k]) for k in (0, 1)], 1) / counts[:, None]
    first = np.zeros(len(counts), dtype=np.int64)  # [M] the concept of each circle
    first[group] = concepts
    low, high = 0.0, cover / max(n, 1)  # points^2 per utterance: bisected so the sum is cover
    for _ in range(40):  # the floor and the cap bend the sum, so area = count * cover / n is off
        unit = (low + high) / 2
        total = np.clip(counts * unit, MIN_MARKER_AREA, MAX_MARKER_AREA).sum()
        low, high = (unit, high) if total < cover else (low, unit)
    areas = np.clip(counts * low, MIN_MARKER_AREA, MAX_MARKER_AREA)  # [M]
    return mean, first, areas, counts


def draw_counted_words(
    ax: Axes,
    grid: OccupancyGrid,
    xy: np.ndarray,
    kind: np.ndarray,
    frequent: list[str],
    colours: np.ndarray,
    listed: np.ndarray,
    others: str = "other words",
) -> None:
    """house.png's words heard when too many to spread apart: the utterances at world points
    ``xy`` ``[U, 2]`` of each ``kind`` ``[U]`` (an index into ``frequent``, whose colours are
    ``colours`` ``[F, 3]`` in 0..1; ``len(frequent)``: other words, light grey, whose legend
    entry is ``others``) as circles of
    area by count (:func:`utterance_markers`), the smallest on top, and an empty scatter for
    the legend per kind in ``listed`` (the kinds of every utterance, those heard off the map
    and drawn at its edge too; other words last)."""
    at, kinds, areas, _ = utterance_markers(ax, grid, xy, kind)
    palette = word_palette(colours)  # [F + 1, 3]
    order = np.argsort(-areas, kind="stable")
    ax.scatter(*at[order].T, s=areas[order], c=palette[kinds[order]],
               edgecolors=rim_colours(grid, at[order]), linewidths=0.4, zorder=3)  # fmt: skip
    for k, word in [*enumerate(frequent), (len(frequent), others)]:
        if (np.asarray(listed) == k).any():
            ax.scatter([], [], s=MARKER_AREA, color=palette[k], label=word)


def draw_utterances(
    axes: list[Axes], result: SpCoResult, observations: Observations, colours: np.ndarray
) -> list[Line2D]:
    """Mark where each utterance was heard (Fig. 10F) on each of ``axes``: a circle in the
    colour of the concept of the cell it was counted in (:func:`utterance_concepts`; grey
    where it was left out, as the legend says) with a black rim, white on a wall (room1dk5's
    coarse walls cover two words heard by a door: their black rims vanished and they read as
    specks of paint); many utterances as circles of area by count
    (:func:`utterance_markers`), the largest drawn first; one circle each, those heard at one
    spot are spread apart (:func:`spread_markers`, as on house.png): each shows. A long map's
    strips are drawn at one scale and spread once, on the first: a word shown by two strips is
    at one place in both. One heard off the map shown is a triangle at its edge pointing its
    way (:mod:`~spcopyro.figures.off_map`; the axes keep the map's limits). Returns the
    legend's handles: the circles', and the triangles' where there are any (none when the
    observations hold no utterance)."""
    heard = np.asarray(observations.word_xy, dtype=np.float64).reshape(-1, 2)  # [U, 2]
    if len(heard) == 0:
        return []
    every = utterance_concepts(result, heard)  # [U]
    away = off_axes(axes, heard)  # [U] off the map: at its edge
    fill = _concept_rgb(every, colours)  # [U, 3]
    draw_at_edge(axes, heard[away], fill[away])  # fill: [U, 3], as the circles'
    xy, concepts = heard[~away], every[~away]  # [U', 2], [U'] on the map
    marks = [utterance_markers(ax, result.grid, xy, concepts) for ax in axes]
    one_each = [counts is None for *_, counts in marks]  # else circles of area by count
    # one circle each: those at one spot side by side, spread once for every strip (drawn at
    # one scale, strip_axes) as on house.png, so a word in two strips is at one place in both
    spread = spread_markers(axes[0], xy, MARKER_AREA) if any(one_each) else xy  # [U', 2]
    moved = not np.allclose(spread, xy)
    counted = not all(one_each)
    for ax, (at, concept, areas, counts) in zip(axes, marks, strict=True):
        at = spread if counts is None else at  # [M, 2]: one each, M = U' in xy's order
        order = np.argsort(-areas, kind="stable")  # a small circle over a large one
        at, concept, areas = at[order], concept[order], areas[order]
        rgb = _concept_rgb(concept, colours)  # [M, 3]
        rims = rim_colours(result.grid, at)
        ax.scatter(*at.T, s=areas, c=rgb, edgecolors=rims, linewidths=0.7 if counts is None
                   else 0.4, zorder=3)  # fmt: skip
    left_out = int((every < 0).sum())  # the fit printed them as "unplaced"
    grey = f", mid grey: {left_out} left out, off the free space" if left_out else ""
    many = ", circle area by count" if counted else ""
    many += ", those at one spot spread apart" if moved else ""
    handles = [Line2D(
        [], [], marker="o", ls="", markerfacecolor="0.8", markeredgecolor="black",
        label=f"where a word was heard ({len(heard)} utterances{many}; fill: the concept "
        f"there{grey})",
    )]  # fmt: skip
    if away.any():
        handles.append(edge_handle(f"{plural(int(away.sum()), 'utterance')} heard off the map "
                                   "(at its edge; fill as above)"))  # fmt: skip
    return handles


def _concept_rgb(concepts: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """``[n, 3]`` RGB in [0, 1] of each concept of ``concepts`` ``[n]`` (``colours`` ``[L, 3]``
    uint8); :data:`OFF_MAP_RGB` where it is -1 (an utterance the fit placed on no cell)."""
    return np.where(concepts[:, None] >= 0, colours[np.maximum(concepts, 0)] / 255.0, OFF_MAP_RGB)


def word_palette(colours: object) -> np.ndarray:
    """``[F + 1, 3]``: the word colours ``colours`` (``[F, 3]`` RGB in [0, 1]) and a last grey
    for the words past them."""
    return np.vstack([np.asarray(colours).reshape(-1, 3), [0.8, 0.8, 0.8]])


def draw_outline(
    ax: Axes,
    grid: OccupancyGrid,
    region: np.ndarray,
    rows: slice,
    cols: slice,
    extent: tuple[float, float, float, float],
    **style: object,
) -> None:
    """Draw the border of an ``[H, W]`` bool region (cropped to ``rows``, ``cols``, shown at
    ``extent``) as a contour line with ``style`` (colors, linewidths, linestyles)."""
    part = np.asarray(region, dtype=np.float64)[rows, cols]  # [h, w]
    if not part.any():
        return
    h, w = part.shape
    left, right, bottom, top = extent
    x = left + (np.arange(w) + 0.5) * (right - left) / w
    y = top - (np.arange(h) + 0.5) * (top - bottom) / h
    ax.contour(x, y, part, levels=[0.5], **style)


def place_labels(
    fig: Figure,
    ax: Axes,
    labels: list[tuple[float, float, str, dict[str, Any], list[tuple[float, float]]]],
) -> tuple[int, list[int]]:
    """Write each ``(x, y, text, style, spots)`` label centred at (x, y) with the white halo
    :data:`OUTLINE`, in the given order; a label whose box would overlap one already written
    is tried at each further ``(x, y)`` of ``spots`` in turn, and left out where every spot
    overlaps. Returns (how many were written, the indices of those left out). The boxes are
    measured by rendering the figure on an Agg canvas (no backend is selected for anything
    else), after the axes took the shape of an equal-aspect map: measured on the axes as made
    (the whole subplot), a tall map was drawn narrower than measured and two labels side by
    side ran into each other ("table 0.41 x15entrance 0.40 x7.0" on room1ldk4).

    A label is measured once (:func:`_label_box`): its box at a spot is that box moved to the
    spot, as :meth:`matplotlib.text.Text.get_window_extent` moves a text's layout to its
    position, the same numbers; only the text written is added to the axes. (A text made,
    measured and removed at every spot tried cost the semantic map of room2ldk4 242 texts
    for its 70 labels.)"""
    if fig.canvas is None or not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    renderer = fig.canvas.get_renderer()
    ax.apply_aspect()  # the axes' box as drawn (matplotlib applies the aspect only at draw)
    boxes = np.empty((len(labels), 4))  # [n, 4] x0, y0, x1, y1 of the labels written, in order
    written, skipped = 0, []
    for index, (x, y, text, style, spots) in enumerate(labels):
        layout = _label_box(fig, renderer, text, style)
        for at in [(x, y), *spots]:
            box = layout.translated(*ax.transData.transform(at)).expanded(1.15, 1.25)
            (x0, y0), (x1, y1) = np.sort(box.get_points(), axis=0)  # as Bbox.overlaps orders
            w = boxes[:written]  # Bbox.overlaps of each, at once
            if not ((x0 <= w[:, 2]) & (w[:, 0] <= x1) & (y0 <= w[:, 3]) & (w[:, 1] <= y1)).any():
                boxes[written], written = (x0, y0, x1, y1), written + 1
                ax.text(*at, text, ha="center", va="center", path_effects=OUTLINE, zorder=4,
                        **style)  # fmt: skip
                break
        else:
            skipped.append(index)
    return written, skipped


def _label_box(fig: Figure, renderer: RendererBase, text: str, style: dict[str, Any]) -> Bbox:
    """The display box of a :func:`place_labels` label centred at the display origin: a text
    of its style drawn at (0, 0) with no transform, which is not added to the figure (its
    box there is its layout, which :meth:`~matplotlib.text.Text.get_window_extent` translates
    to a text's position)."""
    probe = Text(0.0, 0.0, text, ha="center", va="center", transform=IdentityTransform(),
                 **style)  # fmt: skip
    probe.set_figure(fig)
    with warnings.catch_warnings():  # told once, in words, when saved (png.save_figure)
        warnings.filterwarnings("ignore", message="Glyph .* missing from font")
        return probe.get_window_extent(renderer=renderer)


def spread_markers(ax: Axes, xy: np.ndarray, size: float, spacing: float = 0.8) -> np.ndarray:
    """``[U, 2]`` world positions of markers of area ``size`` (points^2, as ``scatter``'s
    ``s``) moved, in the given order, just enough that no marker's centre lies within
    ``spacing`` diameters of one placed before it: each keeps its place if it is free, else
    takes the first free point on rings of ``spacing`` diameters around it (6, 12, 18 points,
    starting straight up). Deterministic; words heard at one spot (room1dk5: 'bedroom', 'shelf'
    and 'bed' three times at the same places) all show. Measured on the axes as drawn (equal
    aspect applied), so call it once the axes' limits are set."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)  # [U, 2]
    if len(xy) == 0:
        return xy.copy()
    ax.apply_aspect()
    pixels = ax.transData.transform(xy)  # [U, 2]
    gap = spacing * np.sqrt(size) * ax.figure.dpi / 72.0  # pixels
    if not gap > 0:  # markers of no size: each keeps its place
        return ax.transData.inverted().transform(pixels)
    placed = np.empty_like(pixels)
    # the markers placed so far by square buckets of side gap: a candidate is compared with those
    # of the buckets around it only (a marker farther away is more than gap from it), not with
    # every marker placed before it (quadratic: a 10^6-cell map's 11,799 words took minutes)
    buckets: dict[tuple[int, int], list[int]] = {}
    angles = [np.pi / 2 + 2 * np.pi * np.arange(6 * ring) / (6 * ring) for ring in range(1, 6)]
    rings = np.concatenate([ring * gap * np.stack([np.cos(a), np.sin(a)], 1)
                            for ring, a in enumerate(angles, 1)])  # fmt: skip  # [90, 2]
    for k, point in enumerate(pixels):
        placed[k] = point  # its own place if free (most markers: their rings are never built)
        if not _free(point[None, :], placed, buckets, gap)[0]:
            around = point + rings  # [90, 2]
            free = np.flatnonzero(_free(around, placed, buckets, gap))
            placed[k] = around[free[0]] if len(free) else around[-1]  # the first free, or last
        key = (int(np.floor(placed[k, 0] / gap)), int(np.floor(placed[k, 1] / gap)))
        buckets.setdefault(key, []).append(k)
    return ax.transData.inverted().transform(placed)


def _free(
    options: np.ndarray, placed: np.ndarray, buckets: dict[tuple[int, int], list[int]], gap: float
) -> np.ndarray:
    """``[M]`` bool: which points of ``options`` ``[M, 2]`` lie ``gap`` or more from every marker
    of ``buckets`` (:func:`spread_markers`; ``placed`` ``[U, 2]``: their positions)."""
    close = _placed_near(buckets, options, gap)
    if not close:
        return np.ones(len(options), dtype=bool)
    near = np.linalg.norm(options[:, None, :] - placed[None, close, :], axis=-1).min(1)  # [M]
    return near >= gap * (1 - 1e-9)


def _placed_near(
    buckets: dict[tuple[int, int], list[int]], options: np.ndarray, gap: float
) -> list[int]:
    """The markers of ``buckets`` (:func:`spread_markers`) that may lie within ``gap`` of a point
    of ``options`` ``[M, 2]``, in the order placed."""
    lo = np.floor((options.min(0) - gap) / gap).astype(np.int64) - 1  # [2] bucket range
    hi = np.floor((options.max(0) + gap) / gap).astype(np.int64) + 1
    return sorted(j for bx in range(int(lo[0]), int(hi[0]) + 1)
                  for by in range(int(lo[1]), int(hi[1]) + 1)
                  for j in buckets.get((bx, by), ()))  # fmt: skip
