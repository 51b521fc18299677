"""The axes of a map figure: the known part of the map drawn in world metres
(:func:`show_map`), and a long map cut into strips at one scale (:func:`strip_axes`)."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from spcopyro.figures.map_pieces import STRIP_PAD, is_wide, map_strips
from spcopyro.maps import UNKNOWN, OccupancyGrid

__all__ = [
    "draw_map_image", "known_bounds", "map_axes", "map_extent", "opaque", "shown_in", "show_map",
    "strip_axes",
]  # fmt: skip


def known_bounds(grid: OccupancyGrid, margin: int = 3) -> tuple[slice, slice]:
    """Row and column slices of the map's known (not UNKNOWN) cells, plus a margin."""
    rows, cols = np.nonzero(grid.occupancy != UNKNOWN)
    if rows.size == 0:
        return slice(0, grid.height), slice(0, grid.width)
    return (
        slice(max(rows.min() - margin, 0), min(rows.max() + margin + 1, grid.height)),
        slice(max(cols.min() - margin, 0), min(cols.max() + margin + 1, grid.width)),
    )


def map_extent(grid: OccupancyGrid, rows: slice, cols: slice) -> tuple[float, float, float, float]:
    """imshow extent (left, right, bottom, top) in world metres of a cropped image."""
    ox, oy, _ = grid.origin
    res = grid.resolution
    top = oy + (grid.height - rows.start) * res
    bottom = oy + (grid.height - rows.stop) * res
    return ox + cols.start * res, ox + cols.stop * res, bottom, top


def draw_map_image(
    ax: Axes, grid: OccupancyGrid, rgb: np.ndarray, rows: slice, cols: slice
) -> tuple[float, float, float, float]:
    """Draw ``rgb[rows, cols]`` of the map image ``rgb`` (``[H, W, 3]`` uint8, or ``[H, W, 4]``
    already :func:`opaque`) on ``ax`` in world metres (:func:`map_extent`), pixel for pixel
    (``nearest``), as opaque RGBA; returns the extent (left, right, bottom, top). The one way
    a map's image is drawn: :func:`show_map`, and a study's maps
    (:func:`spcopyro.study.maps.plot_label_maps`)."""
    extent = map_extent(grid, rows, cols)
    ax.imshow(opaque(rgb[rows, cols]), extent=extent, interpolation="nearest")
    return extent


def show_map(ax: Axes, grid: OccupancyGrid, rgb: np.ndarray) -> tuple[slice, slice]:
    """Draw the known part of the map image ``rgb`` (``[H, W, 3]`` uint8, or ``[H, W, 4]``
    already :func:`opaque`, as :func:`strip_axes` hands it) on ``ax`` in world metres, at equal
    aspect (:func:`draw_map_image`); returns the rows and columns shown (:func:`known_bounds`).
    The axes keep the map's limits (autoscaling off): a point drawn off the map does not grow
    them and shrink the map (:mod:`~spcopyro.figures.off_map` marks such points at the edge)."""
    rows, cols = known_bounds(grid)
    left, right, bottom, top = draw_map_image(ax, grid, rgb, rows, cols)
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
    ax.set_autoscale_on(False)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    return rows, cols


def opaque(rgb: np.ndarray) -> np.ndarray:
    """``[h, w, 4]`` uint8: the ``[h, w, 3]`` uint8 image ``rgb`` with an opaque alpha (any other
    image as it is), the same pixels for :meth:`~matplotlib.axes.Axes.imshow`, drawn faster.

    matplotlib resamples an RGB image as float64 RGBA (its float32 RGB stacked with float64
    ones) and an RGBA one as float32; at ``nearest`` both copy the pixels, and x / 255 in float32
    times 255 gives x back in either precision, so the PNG is the same byte for byte, while the
    semantic map's image (its screen size, 1.5 million pixels on the embedded house) takes less
    CPU, nearly all of it the system time of the float64 arrays' fresh pages, which varies with
    the machine: 0.25 s less (sys 0.30 -> 0.05 s, ce52184, one core at load 4), 0.06 s less in a
    re-measure (sys 0.07-0.115 -> 0.03 s, load 3); medians of 12 (docs/speed.md)."""
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        return rgb
    rgba = np.empty((*rgb.shape[:2], 4), dtype=np.uint8)  # [h, w, 4]
    rgba[..., :3] = rgb
    rgba[..., 3] = 255
    return rgba


def strip_axes(
    grid: OccupancyGrid, rgb: np.ndarray, strips: int, along_x: bool
) -> tuple[Figure, list[Axes]]:
    """A figure of ``strips`` axes, each showing the map ``rgb`` at one scale over its own
    stretch of x (``along_x``: stacked top to bottom) or y (side by side, the top stretch on
    the left), each stretch :data:`~spcopyro.figures.map_pieces.STRIP_PAD` (3%) longer at both
    ends so a marker on a cut shows whole, the first and last moved inside the map; ``strips``
    from :func:`~spcopyro.figures.map_pieces.map_strips` keeps each at most
    :data:`~spcopyro.figures.map_pieces.STRIP_ASPECT`, margins included."""
    rows, cols = known_bounds(grid)
    left, right, bottom, top = map_extent(grid, rows, cols)
    rgb = opaque(rgb)  # [H, W, 4]: once, not once a strip (show_map passes it through)
    long, short = (right - left, top - bottom) if along_x else (top - bottom, right - left)
    length = long / strips
    pad = STRIP_PAD * length
    across = 11.0 * short / (length + 2 * pad)  # inches of a strip across, 11 along
    if along_x:
        fig = Figure(figsize=(11.5, strips * (across + 0.7) + 0.8))
        axes = list(fig.subplots(strips, 1))
    else:
        fig = Figure(figsize=(strips * (across + 0.9) + 0.8, 11.5))
        axes = list(fig.subplots(1, strips))
    for k, ax in enumerate(axes):
        show_map(ax, grid, rgb)
        start = min(max(k * length - pad, 0.0), long - length - 2 * pad)  # inside the map
        if along_x:
            ax.set_xlim(left + start, left + start + length + 2 * pad)
            if k < strips - 1:
                ax.set_xlabel("")
        else:
            ax.set_ylim(top - start - length - 2 * pad, top - start)
            if k:
                ax.set_ylabel("")
    return fig, axes


def map_axes(
    grid: OccupancyGrid, rgb: np.ndarray, figsize: tuple[float, float]
) -> tuple[Figure, list[Axes], bool, str]:
    """The figure of a map: one axes of ``figsize`` showing ``rgb``, or, for a map longer than
    :data:`~spcopyro.figures.map_pieces.STRIP_ASPECT`, its strips (:func:`strip_axes`).
    Returns the figure, its axes, whether its legend goes below (a wide map, or a wide map's
    strips: :func:`~spcopyro.figures.map_pieces.map_legend`) and a line for the title that
    names the strips (empty for one axes)."""
    rows, cols = known_bounds(grid)
    strips, along_x = map_strips(rows, cols)
    if strips == 1:
        fig = Figure(figsize=figsize)
        ax = fig.subplots()
        show_map(ax, grid, rgb)
        return fig, [ax], is_wide(rows, cols), ""
    fig, axes = strip_axes(grid, rgb, strips, along_x)
    order = "top to bottom" if along_x else "left to right"
    return fig, axes, along_x, f"\n(the map in {strips} strips, {order})"


def shown_in(axes: list[Axes], x: float, y: float) -> Axes:
    """The first of ``axes`` whose limits hold the world point (x, y) (the first, if none)."""
    if len(axes) == 1:  # a map in one axes: the first, whatever its limits
        return axes[0]
    for ax in axes:
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        if x0 <= x <= x1 and y0 <= y <= y1:
            return ax
    return axes[0]
