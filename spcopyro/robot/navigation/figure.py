"""``navigate.png``: the map, the destination word's probability map, the route's places (the
cells a hierarchical plan was kept to), the path, start and stops;
``graph.png`` (``spcopyro show OUT --graph``): the place graph over the semantic map."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from spcopyro._util.messages import plural
from spcopyro.figures.map_pieces import draw_outline, is_wide, map_legend
from spcopyro.figures.plotting import _extent, _save, _show_image, semantic_colours
from spcopyro.maps.render import render_labels
from spcopyro.results.result import SpCoResult
from spcopyro.robot.navigation.places import DOORWAY_WIDTH, PlaceGraph
from spcopyro.robot.navigation.planning import NavigationPlan

__all__ = [
    "PROBABILITY_CMAP",
    "ROUTE_RGB",
    "place_graph_figure",
    "plan_figure",
    "plot_place_graph",
    "plot_plan",
]

PROBABILITY_CMAP = ListedColormap(colormaps["Blues"](np.linspace(0.0, 0.7, 256)), "Blues_0_70")
"""The destination's probability: matplotlib's Blues up to 70%, its darkest a mid blue that
walls (black) do not pass for (the full Blues under a 25% orange overlay drew the destination
dark slate grey)."""
ROUTE_RGB = (1.0, 0.6, 0.0)
"""The outline of the route's places (drawn over the probability, not blended with it)."""


def plot_plan(plan: NavigationPlan, path: str | os.PathLike[str]) -> Path:
    """Draw ``plan`` (module docstring) into the PNG ``path``: :func:`plan_figure`."""
    return _save(plan_figure(plan), path)


def plan_figure(plan: NavigationPlan) -> Figure:
    """``plan`` (module docstring) as a figure."""
    grid = plan.planning.grid
    fig = Figure(figsize=(9, 8))
    ax = fig.subplots()
    rgb = render_labels(np.full(grid.shape, -1), grid, np.zeros((1, 3), dtype=np.uint8))
    rows, cols = _show_image(ax, grid, rgb)
    goal = plan.goal
    image = np.full(grid.shape, np.nan)  # [H, W]
    image[grid.free] = goal.probability
    extent = _extent(grid, rows, cols)
    shown = ax.imshow(image[rows, cols], extent=extent, origin="upper", cmap=PROBABILITY_CMAP,
                      vmin=0.0, vmax=1.0, interpolation="nearest")  # fmt: skip
    fig.colorbar(shown, ax=ax, label=f"p(cell in the place of '{goal.shown}')", shrink=0.8)
    kept = [leg.corridor for leg in plan.legs if leg.corridor is not None]
    if kept:  # the cells a hierarchical plan was kept to: its routes' places, outlined
        cells = plan.planning.cells(np.flatnonzero(np.logical_or.reduce(kept)))
        region = np.zeros(grid.shape, dtype=bool)  # [H, W]
        region[cells[:, 0], cells[:, 1]] = True
        draw_outline(ax, grid, region, rows, cols, extent, colors=[ROUTE_RGB], linewidths=2.0)
        ax.plot([], [], color=ROUTE_RGB, lw=2.0, label="route's places (outline)")
    ax.plot(plan.path_xy[:, 0], plan.path_xy[:, 1], color="C3", lw=2, label="path")
    ax.plot(*plan.start, marker="o", color="C2", ms=9, ls="", label="start")
    for stop in plan.stops[:-1]:
        ax.plot(*stop.xy, marker="s", color="C1", ms=8, ls="")
        ax.annotate(stop.shown, stop.xy, xytext=(5, 5), textcoords="offset points", fontsize=9)
    ax.plot(*goal.xy, marker="*", color="C3", ms=16, ls="", label=f"goal: {goal.shown}")
    length = 0.3 * max(1.0, plan.radius * 4)
    ax.arrow(goal.xy[0], goal.xy[1], length * np.cos(goal.yaw), length * np.sin(goal.yaw),
             width=0.02, color="C3")  # fmt: skip
    for stop in plan.stops:
        for c in stop.choice.candidates:
            if (c.xy != stop.xy) or not c.reachable:
                ax.plot(*c.xy, marker="x", color="C4", ms=8, ls="")
    # below the map (the colour bar is beside it): loc="best" weighs the lines, not the map,
    # and put the legend over a room
    map_legend(ax, ax.get_legend_handles_labels()[0], below=True, columns=2, fontsize=8)
    ax.set_title(f"navigate: {plan.instruction.text!r}\n{plan.length:.2f} m, "
                 f"radius {plan.radius:g} m")  # fmt: skip
    return fig


_CORNERS = ((6, 6, "left", "bottom"), (6, -6, "left", "top"), (-6, 6, "right", "bottom"),
            (-6, -6, "right", "top"))  # fmt: skip
"""Offsets (points) and alignments of a place's label from its centroid, in the order tried."""


def _label_places(fig: Figure, ax: Axes, graph: PlaceGraph) -> None:
    """Each place's name and area beside its centroid, largest place first, at the first of
    :data:`_CORNERS` where it overlaps no label written before (else at the first corner)."""
    if fig.canvas is None or not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    renderer = fig.canvas.get_renderer()
    ax.apply_aspect()  # the axes' box as drawn: label boxes measured where they will be
    box = {"boxstyle": "round,pad=0.2", "fc": "white", "alpha": 0.8, "lw": 0}
    written: list[Bbox] = []
    for p in sorted(graph.places, key=lambda place: -place.area):
        tries = (*_CORNERS, _CORNERS[0])  # every corner taken: the first
        for k, (dx, dy, ha, va) in enumerate(tries):
            label = ax.annotate(f"{p.name} ({p.area:.1f} m²)", p.centroid, xytext=(dx, dy),
                                textcoords="offset points", ha=ha, va=va, fontsize=8, zorder=5,
                                bbox=box)  # fmt: skip
            extent = label.get_window_extent(renderer=renderer)
            if k == len(tries) - 1 or not any(extent.overlaps(other) for other in written):
                break
            label.remove()
        written.append(extent)


def plot_place_graph(result: SpCoResult, graph: PlaceGraph, path: str | os.PathLike[str]) -> Path:
    """Write :func:`place_graph_figure` to ``path``."""
    return _save(place_graph_figure(result, graph), path)


def place_graph_figure(result: SpCoResult, graph: PlaceGraph) -> Figure:
    """The semantic map (the colours of ``spcopyro fit``'s map) with every place of ``graph`` at
    its centroid (marker area by the region's area, labelled with its top word and area) and its
    passages as lines between them: doorways dashed, longer shared borders solid. A label that
    would overlap one written before (largest places first) moves to another corner of its
    marker, and the legend stands beside the map (below a wide one): on a corridor's narrow
    places two labels ran into one ("concept 34 (0.8 m²).9 m²)") and the legend covered a room."""
    grid = result.grid
    colours = semantic_colours(result)  # [L, 3] uint8
    rgb = render_labels(result.label_image(), grid, colours)
    fig = Figure(figsize=(9, 8))
    ax = fig.subplots()
    rows, cols = _show_image(ax, grid, rgb)
    xy = np.array([p.centroid for p in graph.places]).reshape(-1, 2)  # [N, 2]
    for e in graph.passages:
        (x0, y0), (x1, y1) = xy[e.a], xy[e.b]
        ax.plot([x0, x1], [y0, y1], color="k", lw=1.5, ls="--" if e.doorway else "-", zorder=3)
    if len(xy):
        area = np.array([p.area for p in graph.places])
        size = 40 + 260 * area / area.max()
        face = colours[[p.concept for p in graph.places]] / 255.0
        ax.scatter(*xy.T, s=size, c=face, edgecolors="k", linewidths=1.2, zorder=4)
    ax.plot([], [], color="k", ls="--", label=f"doorway (border <= {DOORWAY_WIDTH:g} m)")
    ax.plot([], [], color="k", ls="-", label="wider shared border")
    map_legend(ax, ax.get_legend_handles_labels()[0], below=is_wide(rows, cols), columns=2,
               fontsize=8)  # fmt: skip
    _label_places(fig, ax, graph)
    dropped = ""
    if graph.dropped:
        dropped = f"; {plural(graph.dropped, 'region')} under {graph.min_area:g} m² left out"
    places, passages = plural(len(graph.places), "place"), plural(len(graph.passages), "passage")
    ax.set_title(f"place graph: {places}, {passages}{dropped}")
    return fig
