"""Figures of a fit: the semantic map with words (paper Fig. 10F), the answer to "where is X?",
the per-cell maps of uncertainty and agreement. Everything is drawn in world metres, cropped to
the known part of the map. The house before a fit (:mod:`~spcopyro.figures.house`), the trace
(:mod:`~spcopyro.figures.trace`) and the PNG writer (:func:`~spcopyro.figures.png.save_figure`)
have modules of their own; their names are importable from here too.

The semantic map gives every concept in use its own colour, touching concepts the most different
ones (:func:`~spcopyro.maps.palette.concept_colours`), and writes a label on every connected region
of at least ``SMALL_REGION_FRACTION`` of the free cells (:func:`region_label_spots`), so a
concept split over two rooms is labelled in both.

Figures are built as :class:`matplotlib.figure.Figure` objects and written with
:meth:`~matplotlib.figure.Figure.savefig`: no pyplot, no window, and no backend is chosen on
import (a notebook keeps its inline figures; headless runs need no display).
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.transforms import ScaledTranslation
from scipy import ndimage

from spcopyro._util.messages import plural
from spcopyro.data import Observations
from spcopyro.figures.house import MAX_WORD_COLOURS, house_figure, plot_house  # noqa: F401
from spcopyro.figures.map_axes import known_bounds, map_axes, shown_in
from spcopyro.figures.map_axes import map_extent as _extent
from spcopyro.figures.map_pieces import (
    concept_handles,
    draw_outline,
    draw_utterances,
    legend_concepts,
    map_legend,
    place_labels,
    region_text,
)
from spcopyro.figures.png import DPI, PAD_INCHES, save_figure  # noqa: F401 (DPI, PAD_INCHES: re-exported)
from spcopyro.figures.trace import (  # noqa: F401 (plot_trace, trace_figure: re-exported)
    ESTIMATE_NAMES,
    _estimate_name,
    plot_trace,
    trace_figure,
)
from spcopyro.inference.names import SAMPLERS
from spcopyro.maps import (
    RGB_BACKGROUND,
    RGB_OCCUPIED,
    RGB_UNKNOWN,
    concept_colours,
    concept_regions,
    render_labels,
)
from spcopyro.results.concept_names import concept_names
from spcopyro.results.concept_words import (
    ESTIMATED_WORDS,
    NO_WORDS,
    WORDS_NOT_MODELLED,
    WORDS_NOT_MODELLED_NOTE,
    shown_top_words,
    words_modelled,
)
from spcopyro.results.result import SpCoResult
from spcopyro.results.specks import in_use_text
from spcopyro.results.uncertainty import (
    cell_entropy,
    cell_probability_label,
    free_cells_image,
    marginals_source,
    unmapped_note,
    where_probability,
)
from spcopyro.results.where import SMALL_REGION_FRACTION, WhereAnswer

ANSWER_RGB = (214, 0, 0)  # the answer's region in plot_where
RUNNER_UP_RGB = (0, 70, 200)  # the runner-up's region in plot_where
FREE_RGB = RGB_BACKGROUND  # plot_where's free cells: white, as in house.png and navigate.png
# (a light grey (225) was 7 delta-E from the unknown grey (205): the two read as one)


def semantic_colours(result: SpCoResult) -> np.ndarray:
    """[L, 3] uint8 colour of every concept id (white for concepts not in use): all concepts in
    use distinct, touching ones as different as the palette allows
    (:func:`~spcopyro.maps.palette.concept_colours`, largest region first)."""
    colours = np.full((result.config.num_concepts, 3), RGB_BACKGROUND, dtype=np.uint8)
    used = result.concepts_in_use()
    colours[used] = concept_colours(result.label_image(), used)
    return colours


def semantic_map_image(result: SpCoResult) -> np.ndarray:
    """[H, W, 3] uint8 what :func:`plot_semantic_map` draws: every concept in its
    :func:`semantic_colours` colour, walls black, unknown grey."""
    return render_labels(result.label_image(), result.grid, semantic_colours(result))


LABEL_SPOTS = 6
"""Spots a region's label may take (:func:`region_label_spots`): its most interior cell, then
others of the region, tried in turn where the label there would overlap one written before."""


def region_label_spots(
    image: np.ndarray, min_cells: float, spots: int = LABEL_SPOTS
) -> list[tuple[int, int, int, int, bool, list[tuple[int, int]]]]:
    """Where to write a label on every sizeable connected region of an ``[H, W]`` label image.

    Returns ``(concept, row, col, cells, largest, spots)`` for every 4-connected region of one
    concept with at least ``min_cells`` cells, concepts in ascending order and each concept's
    regions largest first (``largest`` marks its largest one). ``(row, col)`` is the region's
    cell farthest from its border (the maximum of the Euclidean distance transform), so the
    label sits inside the region even when the region is not convex. ``spots``
    ``[(row, col), ...]``: that cell first, then up to ``spots - 1`` further cells of the
    region at least half as far from its border as that one, each the farthest from those
    chosen before (spread over the region). A label that would overlap another at its first
    spot takes the next free one (:func:`~spcopyro.figures.map_pieces.place_labels`): on
    room1ldk5's CAVI fit the kitchen's concept, the fourth largest, was left unlabelled while
    its region had room to spare."""
    regions, concept_of = concept_regions(image)  # [H, W] region ids, [R] their concepts
    sizes = np.bincount(regions[regions >= 0], minlength=len(concept_of))  # [R]
    boxes = ndimage.find_objects(regions + 1)  # [R] each region's bounding box
    points = []
    for concept in np.unique(concept_of):
        ids = np.flatnonzero(concept_of == concept)  # the concept's regions, in raster order
        first = True
        for index in ids[np.argsort(-sizes[ids], kind="stable")]:
            if sizes[index] < min_cells:
                break
            box = boxes[index]
            inside = np.pad(regions[box] == index, 1)  # [h + 2, w + 2] bool
            distance = ndimage.distance_transform_edt(inside)
            r, c = np.unravel_index(int(np.argmax(distance)), distance.shape)
            cells = np.argwhere(distance >= 0.5 * distance[r, c])  # [K, 2] interior enough
            chosen = [np.array([r, c])]
            gap = np.linalg.norm(cells - chosen[0], axis=1)  # [K] to the nearest chosen
            while len(chosen) < spots and gap.max(initial=0.0) > 0:
                chosen.append(cells[int(np.argmax(gap))])
                gap = np.minimum(gap, np.linalg.norm(cells - chosen[-1], axis=1))
            at = [(box[0].start + int(a) - 1, box[1].start + int(b) - 1) for a, b in chosen]
            points.append((int(concept), *at[0], int(sizes[index]), first, at))
            first = False
    return points


def plot_semantic_map(
    result: SpCoResult,
    path: str | os.PathLike[str],
    n_words: int = 3,
    max_labelled: int | None = None,
    min_region_fraction: float = SMALL_REGION_FRACTION,
    observations: Observations | None = None,
) -> Path:
    """Write :func:`semantic_map_figure` to ``path``."""
    figure = semantic_map_figure(
        result, n_words, max_labelled, min_region_fraction, observations=observations
    )
    return save_figure(figure, path)


def semantic_map_figure(
    result: SpCoResult,
    n_words: int = 3,
    max_labelled: int | None = None,
    min_region_fraction: float = SMALL_REGION_FRACTION,
    observations: Observations | None = None,
) -> Figure:
    """Each concept its own colour, walls black, its words on the map itself (Fig. 10F).

    Every connected region holding at least ``min_region_fraction`` of the free cells gets a
    label at its most interior cell (:func:`region_label_spots`), in black with a white halo
    (a label whose box would overlap the label of a larger region there takes another spot of
    its region; where none is free it is left out and counted in
    the title, "6 labelled regions, 1 left unlabelled (legend)", or "... 8 left unlabelled (1 in
    the legend, 7 in concepts.json)" where some are of concepts the legend has no entry for,
    :func:`~spcopyro.figures.map_pieces.place_labels`):
    ``[concept]`` and its ``n_words`` most probable words with their probabilities (and the
    lift of the distinctive ones, ``x4.2``) on the concept's largest region, ``[concept]`` and
    its best word on each further one, "no words heard here" for a concept whose region holds
    no observed word (:func:`~spcopyro.figures.map_pieces.region_text`). A legend lists the largest
    concepts with their words (a fit that did not model its words: its title says so, and no
    entry or label lists any); ``observations`` given, a circle marks where each word was heard,
    filled with the colour of the concept there. ``max_labelled``: label only the regions of
    that many largest concepts (default: all).
    """
    grid = result.grid
    image = result.label_image()
    colours = semantic_colours(result)  # [L, 3]
    fig, axes, wide, strips = map_axes(grid, render_labels(image, grid, colours), (13, 9))
    labelled = set(result.concepts_in_use()[:max_labelled].tolist())
    points = region_label_spots(image, min_region_fraction * grid.num_free)
    points = [p for p in points if p[0] in labelled]
    points.sort(key=lambda p: -p[3])  # largest region first: its label wins a collision
    names = concept_names(result)  # once: a further region's label is its concept's name
    labels = []
    for concept, row, col, _, largest, spots in points:
        x, y = grid.cell_to_world(np.array([row, col]))
        others = [tuple(float(v) for v in grid.cell_to_world(np.array(cell)))
                  for cell in spots[1:]]  # fmt: skip
        silent = result.heard(concept) == 0
        text = region_text(result, concept, n_words, largest, names.get(int(concept)))
        labels.append((float(x), float(y), text,
                       {"fontsize": 6 if silent else 7, "style": "italic" if silent else
                        "normal", "color": "0.25" if silent else "black"}, others))  # fmt: skip
    regions = 0
    skipped = []  # [concept]: each region whose label was left out
    for ax in axes:  # each label on the strip that shows its point, and its spots there
        mine = [k for k, label in enumerate(labels) if shown_in(axes, *label[:2]) is ax]
        written, left_out = place_labels(fig, ax, [
            (*labels[k][:4], [at for at in labels[k][4] if shown_in(axes, *at) is ax])
            for k in mine])  # fmt: skip
        regions += written
        skipped += [points[mine[k]][0] for k in left_out]
    handles: list[Patch | Line2D] = list(concept_handles(result, colours, n_words))
    if observations is not None:
        handles += draw_utterances(axes, result, observations, colours)
    handles += [Patch(color=np.array(RGB_OCCUPIED) / 255.0, label="walls"),
                Patch(color=np.array(RGB_UNKNOWN) / 255.0, label="unknown")]  # fmt: skip
    # the words' p as fit's listing names it: a variational fit's are no posterior means
    words = ("words (posterior mean p; " if "parameters" in result.inference
             else f"{ESTIMATED_WORDS} (")  # fmt: skip
    words += "x lift = p(word | concept) / p(word))"
    if not words_modelled(result):  # said once, here: no entry or label lists words
        words = WORDS_NOT_MODELLED_NOTE
    map_legend(axes[-1], handles, below=wide, columns=2, fontsize=7, frameon=False,
               title=f"concepts, largest first: {words}", title_fontsize=7)  # fmt: skip
    crowded = (
        f", {len(skipped)} left unlabelled ({_unlabelled_text(result, skipped)})" if skipped else ""
    )
    axes[0].set_title(f"{result.name or 'semantic map'}: {in_use_text(result)}, "
                      f"{plural(regions, 'labelled region')}{crowded} (regions >= "
                      f"{min_region_fraction:.1%} of the free cells){strips}")  # fmt: skip
    return fig


def _unlabelled_text(result: SpCoResult, concepts: list[int]) -> str:
    """Where the concepts of regions left unlabelled (one entry a region) are described:
    "legend" when the legend has an entry for each (:func:`legend_concepts`), "concepts.json"
    when it has none, else how many regions each holds ("5 in the legend, 3 in
    concepts.json"): the legend lists only the largest concepts."""
    listed = legend_concepts(result)
    shown = sum(int(c) in listed for c in concepts)
    if shown == len(concepts):
        return "legend"
    if shown == 0:
        return "concepts.json"
    return f"{shown} in the legend, {len(concepts) - shown} in concepts.json"


def where_image(result: SpCoResult, answer: WhereAnswer) -> np.ndarray:
    """[H, W, 3] uint8 the map (free cells ``FREE_RGB``, white; walls black, unknown
    grey), the answer's region in ``ANSWER_RGB`` and the runner-up's in ``RUNNER_UP_RGB``: what
    :func:`plot_where` draws for a result without marginals."""
    image = result.label_image()  # [H, W]
    free = np.tile(np.array(FREE_RGB, dtype=np.uint8), (result.config.num_concepts, 1))
    rgb = render_labels(image, result.grid, free)  # [H, W, 3]
    if answer.runner_up is not None:
        rgb[image == answer.runner_up] = RUNNER_UP_RGB
    rgb[answer.region] = ANSWER_RGB
    return rgb


def plot_where(
    result: SpCoResult,
    answer: WhereAnswer,
    path: str | os.PathLike[str],
    probability: np.ndarray | None = None,
) -> Path:
    """Write :func:`where_figure` to ``path`` (``probability`` as there)."""
    return save_figure(where_figure(result, answer, probability), path)


BELOW_INCHES = (0.55, 1.0)  # where_figure: the legend below the map, then the warnings below it


def where_figure(
    result: SpCoResult, answer: WhereAnswer, probability: np.ndarray | None = None
) -> Figure:
    """The answer to "where is WORD?" over the map (free white, walls black, unknown grey, as
    the other map figures): with per-cell marginals, each cell's probability of lying in the
    word's place (:func:`~spcopyro.results.uncertainty.where_probability`, over the reported
    map's concepts: the colour bar says so where cells hold mass on others) as a colour scale,
    the answer's region outlined in red and the runner-up's in dashed blue; without them (a
    point estimate), the answer's region filled red and the runner-up's blue
    (:func:`where_image`). A title with the word, the concept, p(concept | word), the prior and
    the concept's words, a legend, and the answer's warnings under the map (the answer's p is
    p(concept | word), the colour bar's p(cell is the place), as ``where`` prints them). A
    region smaller than
    ``SMALL_REGION_FRACTION`` of the free cells is ringed, so a speck can be seen.
    ``probability``: [N] that :func:`~spcopyro.results.uncertainty.where_probability` of
    ``answer.word`` and ``answer.prior`` when the caller has it (``spcopyro where``), or None."""
    grid = result.grid
    area = grid.resolution**2
    cells = int(answer.region.sum())
    image = result.label_image()
    runner = image == answer.runner_up if answer.runner_up is not None else None
    handles: list[Patch | Line2D] = []
    if result.marginals is None:
        fig, axes, wide, strips = map_axes(grid, where_image(result, answer), (11, 9))
        answer_handle: Patch | Line2D = Patch(color=np.array(ANSWER_RGB) / 255.0, label="")
        runner_handle: Patch | Line2D = Patch(color=np.array(RUNNER_UP_RGB) / 255.0, label="")
    else:
        free = np.tile(np.array(FREE_RGB, dtype=np.uint8), (result.config.num_concepts, 1))
        fig, axes, wide, strips = map_axes(grid, render_labels(image, grid, free), (11, 9))
        rows, cols = known_bounds(grid)
        extent = _extent(grid, rows, cols)
        if probability is None:
            probability = where_probability(result, answer.word, answer.prior)  # [N]
        shown = free_cells_image(result, probability)[rows, cols]  # [h, w]
        shown = np.ma.masked_less(shown, 0.01)  # [h, w]: free white below 1%
        red, blue = np.array(ANSWER_RGB) / 255.0, np.array(RUNNER_UP_RGB) / 255.0
        for ax in axes:  # one map, or its strips
            scale = ax.imshow(shown, extent=extent, cmap="Reds", vmin=0.0, vmax=1.0,
                              interpolation="nearest", alpha=0.9)  # fmt: skip
            draw_outline(ax, grid, answer.region, rows, cols, extent, colors=[red],
                         linewidths=2.0)  # fmt: skip
            if runner is not None:
                draw_outline(ax, grid, runner, rows, cols, extent, colors=[blue],
                             linewidths=1.5, linestyles="dashed")  # fmt: skip
        label = cell_probability_label(answer.word, bool(unmapped_note(result)))
        fig.colorbar(scale, cax=axes[-1].inset_axes((1.02, 0.0, 0.025, 1.0)),  # the map's height
                     label=label)  # fmt: skip
        answer_handle = Line2D([], [], color=red, lw=2.0, label="")
        runner_handle = Line2D([], [], color=blue, lw=1.5, ls="--", label="")
    if 0 < cells < SMALL_REGION_FRACTION * grid.num_free:
        labels, _ = ndimage.label(answer.region)
        centres = ndimage.center_of_mass(answer.region, labels, range(1, int(labels.max()) + 1))
        xy = grid.cell_to_world(np.round(np.array(centres)).astype(np.int64))  # [n, 2]
        for ax in axes:
            ax.scatter(*xy.T, s=300, facecolors="none", edgecolors=np.array(ANSWER_RGB) / 255.0,
                       linewidths=1.5, zorder=3)  # fmt: skip

    def size(n: int) -> str:  # the answer's and the runner-up's: cells and their area
        return f"({plural(n, 'cell')}, {n * area:.2f} m²)"

    answer_handle.set_label(
        f"answer: concept {answer.concept}, p(concept | word) = {answer.probability:.3f} "
        f"{size(cells)}"
    )
    handles.append(answer_handle)
    if runner is not None:
        runner_handle.set_label(
            f"runner-up: concept {answer.runner_up}, "
            f"p(concept | word) = {answer.runner_up_probability:.3f} {size(int(runner.sum()))}"
        )
        handles.append(runner_handle)
    handles += [
        Patch(facecolor=np.array(FREE_RGB) / 255.0, edgecolor="0.5", lw=0.5, label="free space"),
        Patch(color=np.array(RGB_OCCUPIED) / 255.0, label="walls"),
        Patch(color=np.array(RGB_UNKNOWN) / 255.0, label="unknown"),
    ]
    # Below the map when the colour bar stands beside it, or below a wide map's strips (the
    # warnings go below the legend).
    below = result.marginals is not None or bool(strips and wide)
    map_legend(axes[-1], handles, below=below, below_inches=BELOW_INCHES[0], fontsize=8,
               frameon=False)  # fmt: skip
    if result.heard(answer.concept) == 0:
        words = NO_WORDS
    elif not words_modelled(result):  # its warnings say what the answer is then
        words = WORDS_NOT_MODELLED
    else:
        top = shown_top_words(result, answer.concept, 3)
        words = ", ".join(f"{w} {p:.2f}" for w, p in top)
    kind = marginals_source(result)  # as where's line and the probability figure name it
    kind = kind if result.marginals is None else f"per-cell probability: {kind}"
    axes[0].set_title(f"where is '{answer.word}'? concept {answer.concept}, "
                      f"p(concept | word) = {answer.probability:.3f} ({answer.prior} prior; "
                      f"{kind})\n"
                      f"its words: {words}{strips}")  # fmt: skip
    if answer.warnings:
        text = "\n".join(textwrap.fill(f"warning: {w}", 110) for w in answer.warnings)
        inches = BELOW_INCHES[0] + (BELOW_INCHES[1] if below else 0.0)
        at = axes[-1].transAxes + ScaledTranslation(0.0, -inches, fig.dpi_scale_trans)
        axes[-1].text(0.0, 0.0, text, transform=at, fontsize=7, color="#b00000", va="top",
                      ha="left")  # fmt: skip
    return fig


def _plot_cell_values(
    result: SpCoResult,
    values: np.ndarray,
    path: str | os.PathLike[str],
    *,
    title: str,
    label: str,
    vmax: float,
    cmap: str,
) -> Path:
    """Write :func:`_cell_values_figure` to ``path``."""
    figure = _cell_values_figure(result, values, title=title, label=label, vmax=vmax, cmap=cmap)
    return save_figure(figure, path)


CELL_VALUES_TOP = 0.75
"""The per-cell maps (uncertainty.png, agreement.png, where's probability) use their colour map
up to this fraction: its darkest colours (Greens' at 1.0 of L* 24) beside the black walls made a
map of agreement near 1 one dark mass (as navigate.png's PROBABILITY_CMAP, Blues up to 0.7)."""


def _cell_values_figure(
    result: SpCoResult, values: np.ndarray, *, title: str, label: str, vmax: float, cmap: str
) -> Figure:
    """``[N]`` per-free-cell ``values`` as a colour map over the grid (walls black, unknown
    grey), with a colour bar; ``cmap`` a matplotlib colour map's name, used up to
    :data:`CELL_VALUES_TOP`."""
    colours = colormaps[cmap](np.linspace(0.0, CELL_VALUES_TOP, 256))  # [256, 4]
    light = ListedColormap(colours, f"{cmap}_0_{round(100 * CELL_VALUES_TOP)}")
    grid = result.grid
    rgb = render_labels(np.full(grid.shape, -1), grid, np.zeros((1, 3), dtype=np.uint8))
    fig, axes, _, strips = map_axes(grid, rgb, (9, 8))  # a long map in strips
    rows, cols = known_bounds(grid)
    image = free_cells_image(result, values)[rows, cols]  # [h, w], NaN off free space
    for ax in axes:
        shown = ax.imshow(image, extent=_extent(grid, rows, cols), origin="upper", cmap=light,
                          vmin=0.0, vmax=vmax, interpolation="nearest")  # fmt: skip
    fig.colorbar(shown, cax=axes[-1].inset_axes((1.03, 0.0, 0.03, 1.0)),  # the map's height
                 label=label)  # fmt: skip
    axes[0].set_title(title + strips)
    return fig


def plot_uncertainty(result: SpCoResult, path: str | os.PathLike[str]) -> Path | None:
    """The uncertainty map: each free cell's entropy of p(C_i) in nats
    (:func:`~spcopyro.results.uncertainty.cell_entropy`); None (nothing drawn) for a result without
    marginals."""
    entropy = cell_entropy(result)
    if entropy is None:
        return None
    source = f"q(C) of {result.method}"
    if result.method in SAMPLERS:  # a Gibbs chain's samples (vi-gibbs: its Gibbs stage's)
        source = "Gibbs label frequencies" + ("" if result.method == "gibbs" else " (vi-gibbs)")
    title = (
        f"{result.name or 'uncertainty'}: entropy of p(C_i), {source}\nmean "
        f"{entropy.mean():.3f} nats (at most log L = {np.log(len(result.pi)):.2f})"
    )
    return _plot_cell_values(result, entropy, path, title=title, label="entropy (nats)",
                             vmax=max(float(entropy.max()), 1e-6), cmap="YlOrRd")  # fmt: skip


def plot_agreement(result: SpCoResult, path: str | os.PathLike[str]) -> Path | None:
    """Each free cell's probability of agreeing with the reported point estimate (the share of
    label samples, matched to it, that give the cell its label:
    :mod:`spcopyro.results.point_estimate`);
    None (nothing drawn) for a result that is not such an estimate."""
    if result.agreement is None:
        return None
    agreement = np.asarray(result.agreement)
    title = (
        f"{result.name or 'agreement'}: p(sample agrees with the {_estimate_name(result)})\n"
        f"mean {agreement.mean():.3f}, {plural(int((agreement < 0.5).sum()), 'cell')} below 0.5"
    )
    return _plot_cell_values(result, agreement, path, title=title, label="probability",
                             vmax=1.0, cmap="Greens")  # fmt: skip


def plot_where_probability(
    result: SpCoResult,
    word: str,
    path: str | os.PathLike[str],
    prior: str = "area",
    probability: np.ndarray | None = None,
) -> Path:
    """The answer to "where is WORD?" as a probability per cell: p(cell in the word's place)
    (:func:`~spcopyro.results.uncertainty.where_probability`; ``probability``: that [N] of
    ``word`` and ``prior`` when the caller has it, or None)."""
    if probability is None:
        probability = where_probability(result, word, prior)  # [N]
    kind = marginals_source(result)  # as where's line names it
    title = (
        f"where is '{word.lower()}'? p(cell is the place), {kind}, {prior} prior\n"
        f"{plural(int((probability > 0.5).sum()), 'cell')} above 0.5"
    )
    note = unmapped_note(result)
    if note:
        title += f"\n{note}"
    # named as `where` prints it and the answer's figure draws it (the title read "p(cell in
    # its place)", the colour bar "probability")
    label = cell_probability_label(word.lower(), bool(note))
    return _plot_cell_values(result, probability, path, title=title, label=label,
                             vmax=1.0, cmap="Blues")  # fmt: skip
