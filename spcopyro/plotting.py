"""Figures: a house and its observations, the semantic map with words (paper Fig. 10F), traces
(paper Figs. 5-6). Everything is drawn in world metres, cropped to the known part of the map.

Figures are built as :class:`matplotlib.figure.Figure` objects and written with
:meth:`~matplotlib.figure.Figure.savefig`: no pyplot, no window, and no backend is chosen on
import (a notebook keeps its inline figures; headless runs need no display).
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from scipy import ndimage

from spcopyro.data import House
from spcopyro.maps import UNKNOWN, OccupancyGrid, label_colours, render_labels
from spcopyro.results import SpCoResult

MAX_WORD_COLOURS = 12  # words beyond the most frequent ones are drawn as "other"


def known_bounds(grid: OccupancyGrid, margin: int = 3) -> tuple[slice, slice]:
    """Row and column slices of the map's known (not UNKNOWN) cells, plus a margin."""
    rows, cols = np.nonzero(grid.occupancy != UNKNOWN)
    if rows.size == 0:
        return slice(0, grid.height), slice(0, grid.width)
    return (
        slice(max(rows.min() - margin, 0), min(rows.max() + margin + 1, grid.height)),
        slice(max(cols.min() - margin, 0), min(cols.max() + margin + 1, grid.width)),
    )


def _extent(grid: OccupancyGrid, rows: slice, cols: slice) -> tuple[float, float, float, float]:
    """imshow extent (left, right, bottom, top) in world metres of a cropped image."""
    ox, oy, _ = grid.origin
    res = grid.resolution
    top = oy + (grid.height - rows.start) * res
    bottom = oy + (grid.height - rows.stop) * res
    return ox + cols.start * res, ox + cols.stop * res, bottom, top


def _show_image(ax: Axes, grid: OccupancyGrid, rgb: np.ndarray) -> tuple[slice, slice]:
    rows, cols = known_bounds(grid)
    ax.imshow(rgb[rows, cols], extent=_extent(grid, rows, cols), interpolation="nearest")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    return rows, cols


def _save(fig: Figure, path: str | os.PathLike[str]) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=150, bbox_inches="tight")
    return path


def plot_house(house: House, path: str | os.PathLike[str], title: str | None = None) -> Path:
    """The map (free white, walls black, unknown grey), image positions and words by colour."""
    grid, obs = house.grid, house.observations
    fig = Figure(figsize=(8, 8))
    ax = fig.subplots()
    _show_image(ax, grid, render_labels(np.full(grid.shape, -1), grid))
    ax.scatter(*obs.image_xy.T, s=6, c="0.45", marker="s", label=f"images ({obs.num_images})")
    first_words = [u[-1] if u else "" for u in obs.utterances]  # a sentence's last word
    frequent = [w for w, _ in Counter(first_words).most_common(MAX_WORD_COLOURS)]
    colours = label_colours(len(frequent) + 1) / 255.0
    for k, word in enumerate(frequent):
        mask = np.array([w == word for w in first_words])
        ax.scatter(*obs.word_xy[mask].T, s=28, color=colours[k], edgecolors="k", linewidths=0.4,
                   label=word)  # fmt: skip
    rest = np.array([w not in frequent for w in first_words])
    if rest.any():
        ax.scatter(*obs.word_xy[rest].T, s=28, color=colours[-1], edgecolors="k",
                   linewidths=0.4, label="other words")  # fmt: skip
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.set_title(title or f"{house.name}: {grid.num_free} free cells")
    return _save(fig, path)


def ranked_label_image(result: SpCoResult) -> np.ndarray:
    """[H, W] labels renumbered by region size (0 = largest), so big regions get strong colours."""
    image = result.label_image()
    order = result.concepts_in_use()
    rank = np.full(result.config.num_concepts, -1)
    rank[order] = np.arange(order.size)
    return np.where(image >= 0, rank[np.maximum(image, 0)], -1)


def plot_semantic_map(
    result: SpCoResult,
    path: str | os.PathLike[str],
    n_words: int = 3,
    max_labelled: int = 20,
    min_region_fraction: float = 0.005,
) -> Path:
    """Each concept a colour, walls black, its best words beside its largest region (Fig. 10F).

    Words are written for the ``max_labelled`` largest concepts whose largest region holds at
    least ``min_region_fraction`` of the free cells (tiny specks would only clutter the map).
    """
    grid = result.grid
    fig = Figure(figsize=(9, 9))
    ax = fig.subplots()
    rows, cols = _show_image(ax, grid, render_labels(ranked_label_image(result), grid))
    image = result.label_image()
    for concept in result.concepts_in_use()[:max_labelled]:
        regions, count = ndimage.label(image == concept)
        if count == 0:
            continue
        sizes = np.bincount(regions.ravel())[1:]
        if sizes.max() < min_region_fraction * grid.num_free:
            continue
        r, c = np.argwhere(regions == 1 + int(np.argmax(sizes))).mean(0)
        x, y = grid.cell_to_world(np.array([round(r), round(c)]))
        words = "\n".join(f"{w} {p:.2f}" for w, p in result.top_words(int(concept), n_words))
        ax.text(x, y, f"[{concept}]\n{words}", fontsize=6, ha="center", va="center",
                bbox=dict(boxstyle="round,pad=0.2", fc="white", alpha=0.75, lw=0))  # fmt: skip
    used = len(result.concepts_in_use())
    ax.set_title(f"{result.name or 'semantic map'}: {used} concepts in use")
    return _save(fig, path)


def plot_trace(result: SpCoResult, path: str | os.PathLike[str]) -> Path:
    """The objective (log joint or ELBO) and the number of concepts per iteration (paper
    Figs. 5-6), the point estimate's iteration marked."""
    trace = result.trace
    sweeps = np.arange(1, len(trace.objective) + 1)
    fig = Figure(figsize=(7, 5))
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(sweeps, trace.objective, lw=0.8)
    top.axvline(result.best_iteration + 1, color="C3", lw=0.6, ls="--", label="point estimate")
    top.set_ylabel(trace.objective_name)
    top.legend(fontsize=8)
    bottom.plot(sweeps, trace.num_concepts, lw=0.8, color="C1")
    bottom.set_ylabel("concepts in use")
    bottom.set_xlabel("sweep" if result.method == "gibbs" else "iteration")
    for ax in (top, bottom):
        ax.set_xscale("log")
    fig.suptitle(f"{result.name or 'trace'} ({result.method})")
    return _save(fig, path)
