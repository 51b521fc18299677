"""house.png: a house's map with where its images were taken and its words were heard
(:func:`house_figure`), before any fit. Re-exported by :mod:`spcopyro.figures.plotting`."""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from spcopyro._util.messages import plural, shown_count
from spcopyro.data import House
from spcopyro.figures.map_axes import map_axes
from spcopyro.figures.map_pieces import (
    draw_counted_words,
    house_title,
    map_legend,
    markers_counted,
    rim_colours,
    spread_markers,
    utterance_marks,
    word_palette,
)
from spcopyro.figures.off_map import draw_at_edge, edge_handle, off_axes
from spcopyro.figures.png import save_figure
from spcopyro.maps import distinct_colours, render_labels

MAX_WORD_COLOURS = 12  # words beyond the most frequent ones are drawn as "other"
OTHER_WORDS_NAMED = 6  # "other words: ..." names this many, then "and N more" (one over: named)


def plot_house(house: House, path: str | os.PathLike[str], title: str | None = None) -> Path:
    """Write :func:`house_figure` to ``path``."""
    return save_figure(house_figure(house, title), path)


def other_words_label(counts: Mapping[str, int], frequent: list[str]) -> str:
    """The legend's entry for the grey circles: "other words: " and the words they stand for,
    the most heard first (ties alphabetically), at most ``OTHER_WORDS_NAMED`` and "and N more"
    (all of them where one is over: :func:`~spcopyro._util.messages.shown_count`).
    ``counts``: how many utterances each word marks (a ``Counter`` of
    :func:`~spcopyro.figures.map_pieces.utterance_marks`, counted once by the figure; an
    empty utterance's "" is not named), ``frequent``: the words that have a colour. Before,
    the entry read "other words" alone: room1ldk5's 'bedroom', 'bath' and 'chair' were grey
    circles no figure named."""
    named = set(frequent)
    others = [(w, n) for w, n in counts.items() if w and w not in named and n > 0]
    rest = [w for w, _ in sorted(others, key=lambda item: (-item[1], item[0]))]
    shown = shown_count(len(rest), OTHER_WORDS_NAMED)
    more = len(rest) - shown
    return "other words" + (f": {', '.join(rest[:shown])}" if rest else "") + (
        f" and {more} more" if more > 0 else "")  # fmt: skip


def house_figure(house: House, title: str | None = None) -> Figure:
    """The map (free white, walls black, unknown grey), image positions and words by colour.

    Each utterance is marked by its rarest word (the place's name in a sentence such as "here
    is the kitchen": :func:`~spcopyro.figures.map_pieces.utterance_marks`); the
    ``MAX_WORD_COLOURS`` most frequent words each take a colour of
    :func:`~spcopyro.maps.palette.distinct_colours` (near-twins such as tv/kitchen came from
    ``label_colours``), the rest are "other words" in grey, named in the legend
    (:func:`other_words_label`). Markers at one spot are spread
    apart (:func:`~spcopyro.figures.map_pieces.spread_markers`): every word in the legend shows.
    A marker on a wall has a white rim (:func:`~spcopyro.figures.map_pieces.rim_colours`).
    A word or image off the map shown is a triangle at its edge pointing its way, counted in
    the legend (:mod:`~spcopyro.figures.off_map`): the axes keep the map's limits.
    """
    grid, obs = house.grid, house.observations
    rgb = render_labels(np.full(grid.shape, -1), grid)
    fig, axes, wide, strips = map_axes(grid, rgb, (8, 8))
    marks = utterance_marks(obs.utterances)  # [U] a sentence's rarest word: the place named
    counts = Counter(marks)  # utterances per word, counted once for the colours and the legend
    frequent = [w for w, _ in counts.most_common(MAX_WORD_COLOURS)]
    colours = distinct_colours(len(frequent)) / 255.0  # [F, 3]
    rank = {w: k for k, w in enumerate(frequent)}
    kind = np.array([rank.get(w, len(frequent)) for w in marks], dtype=np.int64)  # [U]
    size = 28.0
    heard = np.asarray(obs.word_xy, dtype=np.float64).reshape(-1, 2)  # [U, 2]
    away = off_axes(axes, heard)  # [U] off the map: at its edge
    images = np.asarray(obs.image_xy, dtype=np.float64).reshape(-1, 2)  # [I, 2]
    images_away = off_axes(axes, images)  # [I]
    palette = word_palette(colours)  # [F + 1, 3]
    draw_at_edge(axes, heard[away], palette[kind[away]])
    draw_at_edge(axes, images[images_away], np.full((int(images_away.sum()), 3), 0.45))
    every = kind  # [U] the legend lists each word, on the map or off (its triangle's colour)
    others = (kind == len(frequent)).any()  # "other words" in the legend, on the map or off
    others_label = other_words_label(counts, frequent)
    xy, kind = heard[~away], kind[~away]  # [U', 2], [U'] the words on the map
    order = np.argsort(kind, kind="stable")  # named words keep their places first
    counted = markers_counted(axes[0], grid, xy)  # too many to spread
    shown = np.empty_like(xy)
    shown[order] = xy[order] if counted else spread_markers(axes[0], xy[order], size)
    rest = kind == len(frequent)
    rims = rim_colours(grid, shown)  # [U, 3] white on a wall, as on the semantic map
    for ax in axes:
        if obs.num_images:  # a house of words only has none: no "images (0)" in the legend
            ax.scatter(*images[~images_away].T, s=6, c="0.45", marker="s",
                       label=f"images ({obs.num_images})")  # fmt: skip
        if counted:  # circles of area by count, the smallest on top; the legend's from empties
            draw_counted_words(ax, grid, xy, kind, frequent, colours, every, others_label)
            continue
        if others:  # drawn first (under the named words), listed last in the legend
            ax.scatter(*shown[rest].T, s=size, color="0.8", edgecolors=rims[rest],
                       linewidths=0.4, zorder=2, label=others_label)  # fmt: skip
        for k, word in enumerate(frequent):
            ax.scatter(*shown[kind == k].T, s=size, color=colours[k], edgecolors=rims[kind == k],
                       linewidths=0.4, zorder=3, label=word)  # fmt: skip
    handles, labels = axes[0].get_legend_handles_labels()
    marker = np.sqrt(size)  # the legend's word markers rimmed black, wherever their first one is
    handles = [h if label.startswith("images (") else Line2D(
        [], [], ls="", marker="o", ms=marker, mfc=h.get_facecolor()[0], mec="k", mew=0.4)
        for h, label in zip(handles, labels, strict=True)]  # fmt: skip
    if others_label in labels:
        k = labels.index(others_label)
        handles.append(handles.pop(k))
        labels.append(labels.pop(k))
    off = [plural(int(n), what) for n, what in ((away.sum(), "word"),
                                                (images_away.sum(), "image")) if n]  # fmt: skip
    if off:  # drawn at the edge, pointing their way
        handles.append(edge_handle(f"off the map: {' and '.join(off)} (at its edge)"))
        labels.append(handles[-1].get_label())
    spread = "circle area by count" if counted else "markers at one spot spread apart"
    map_legend(axes[-1], handles, labels, below=wide, columns=4, fontsize=8, frameon=False,
               title=f"words heard (rarest word of each utterance;\n{spread})",
               title_fontsize=8)  # fmt: skip
    axes[0].set_title((title or house_title(house)) + strips)
    return fig
