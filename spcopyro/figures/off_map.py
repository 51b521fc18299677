"""Points beyond a map figure's axes: an utterance or image placed off the map shown (outside
the grid, or on unknown space beyond the crop of :func:`~spcopyro.figures.map_axes.known_bounds`;
fitting snaps it to the nearest free cell within the snap distance, or leaves it out:
:func:`~spcopyro.data.place_observations`).

The map's axes keep the map's limits (:func:`~spcopyro.figures.map_axes.show_map` turns
autoscaling off): a word heard 30 m off the default house's 8 m map grew its axes to 35 m, the map
a quarter of them. Such points are drawn instead at the edge nearest them as a triangle pointing
their way (:func:`draw_at_edge`), and each figure's legend counts them (:func:`edge_handle`).
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D

__all__ = ["EDGE_MARKER_AREA", "draw_at_edge", "edge_handle", "off_axes"]

EDGE_MARKER_AREA = 40.0
"""Points^2 of the triangle marking a point off the map, at the map's edge."""


def _limits(ax: Axes) -> tuple[np.ndarray, np.ndarray]:
    """``(low [2], high [2])``: the world x, y limits ``ax`` shows."""
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    return np.array([x0, y0]), np.array([x1, y1])


def off_axes(axes: list[Axes], xy: np.ndarray) -> np.ndarray:
    """[U] bool: the world point ``xy`` ``[U, 2]`` lies outside the limits of every one of
    ``axes`` (one map, or its strips: a point in any strip is on the map)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    inside = np.zeros(len(xy), dtype=bool)
    for ax in axes:
        low, high = _limits(ax)
        inside |= ((xy >= low) & (xy <= high)).all(axis=1)
    return ~inside


def draw_at_edge(
    axes: list[Axes], xy: np.ndarray, colours: np.ndarray, edgecolor: str = "black"
) -> None:
    """Mark each world point ``xy`` ``[U, 2]`` (off the map: :func:`off_axes`) at the nearest
    point of the nearest of ``axes``' limits, a triangle of ``EDGE_MARKER_AREA`` in its
    ``colours`` ``[U, 3]`` (0..1) pointing the way the point lies (across the longer of its
    x and y distances), drawn whole over the axes' frame. The points of one direction in one
    square of a triangle's width are one triangle, in their most common colour (10^4 words
    heard off the map are a row of triangles along the edge, not a pile of 10^4). The limits
    stay as they are."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    colours = np.asarray(colours, dtype=np.float64).reshape(-1, 3)
    if len(xy) == 0:
        return
    clamped = np.stack([np.clip(xy, *_limits(ax)) for ax in axes])  # [A, U, 2]
    distance = np.linalg.norm(xy[None] - clamped, axis=2)  # [A, U]
    nearest = np.argmin(distance, axis=0)  # [U] the first of the nearest axes
    at = clamped[nearest, np.arange(len(xy))]  # [U, 2] on that axes' edge
    away = xy - at  # [U, 2]
    across = np.argmax(np.abs(away), axis=1)  # [U] 0: beyond left or right, 1: below or above
    for k, ax in enumerate(axes):
        ax.apply_aspect()  # pixels as drawn
        for dim, (low, high) in enumerate((("<", ">"), ("v", "^"))):
            for sign, marker in ((-1.0, low), (1.0, high)):
                flip = ax.xaxis_inverted() if dim == 0 else ax.yaxis_inverted()
                pick = (nearest == k) & (across == dim) & (np.sign(away[:, dim]) == sign)
                if not pick.any():
                    continue
                points, fills = at[pick], colours[pick]  # [n, 2], [n, 3]
                width = np.sqrt(EDGE_MARKER_AREA) * ax.figure.dpi / 72.0  # pixels
                square = np.floor(ax.transData.transform(points) / width)  # [n, 2]
                first = _most_common(square, np.round(fills * 255.0))  # [m] one a square
                shown = marker if not flip else (high if marker == low else low)
                ax.scatter(*points[first].T, s=EDGE_MARKER_AREA, marker=shown, c=fills[first],
                           edgecolors=edgecolor, linewidths=0.6, zorder=5,
                           clip_on=False)  # fmt: skip


def _most_common(square: np.ndarray, colour: np.ndarray) -> np.ndarray:
    """[m] in ascending order, one index per distinct row of ``square`` ``[n, 2]``: the first
    point of that square whose ``colour`` ``[n, 3]`` is the square's most common."""
    group = np.unique(square, axis=0, return_inverse=True)[1].reshape(-1)  # [n]
    pairs = np.column_stack([group, colour])  # [n, 4]
    _, pair, counts = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    votes = counts[pair.reshape(-1)]  # [n] the points sharing each one's square and colour
    order = np.lexsort((-votes, group))  # by square, the most votes first, then the first point
    starts = np.r_[True, group[order][1:] != group[order][:-1]]  # [n] each square's first
    return np.sort(order[starts])


def edge_handle(label: str) -> Line2D:
    """The legend's entry for the triangles of :func:`draw_at_edge` (light grey: their fill
    is each point's own colour)."""
    return Line2D([], [], ls="", marker=">", ms=np.sqrt(EDGE_MARKER_AREA), mfc="0.8",
                  mec="black", mew=0.6, label=label)  # fmt: skip
