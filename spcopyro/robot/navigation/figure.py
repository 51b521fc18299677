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
from spcopyro.figures.map_axes import known_bounds, map_axes, shown_in
from spcopyro.figures.map_axes import map_extent as _extent
from spcopyro.figures.map_pieces import draw_outline, map_legend
from spcopyro.figures.plotting import semantic_colours
from spcopyro.figures.png import save_figure
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.maps.render import render_labels
from spcopyro.results.result import SpCoResult
from spcopyro.results.uncertainty import cell_probability_label
from spcopyro.robot.navigation.places import DOORWAY_WIDTH, PlaceGraph, telling_apart
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


def _showing(axes: list[Axes], x: float, y: float) -> Axes:
    """The axes of ``axes`` (one map, or its strips) that shows (x, y) farthest from the ends of
    its stretch: a label by a point on a cut goes on the strip that shows its marker whole."""
    best, depth = shown_in(axes, x, y), -np.inf
    for ax in axes:
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            continue
        inside = min(x - x0, x1 - x) if x1 - x0 >= y1 - y0 else min(y - y0, y1 - y)
        if inside > depth:
            best, depth = ax, inside
    return best


def plot_plan(plan: NavigationPlan, path: str | os.PathLike[str]) -> Path:
    """Draw ``plan`` (module docstring) into the PNG ``path``: :func:`plan_figure`."""
    return save_figure(plan_figure(plan), path)


def plan_figure(plan: NavigationPlan) -> Figure:
    """``plan`` (module docstring) as a figure. A map more than
    :data:`~spcopyro.figures.map_pieces.STRIP_ASPECT` times as long as wide (a 100 m corridor)
    is drawn in strips at one scale (:func:`~spcopyro.figures.map_axes.map_axes`): the
    probability, the route's outline, the path and the markers on every strip (each clipped to
    its own stretch, so the path runs on from one strip to the next), a stop's name on the strip
    showing it (:func:`_showing`), the colour bar beside the map (the last strip) and as tall,
    the legend below it."""
    grid = plan.planning.grid
    rgb = render_labels(np.full(grid.shape, -1), grid, np.zeros((1, 3), dtype=np.uint8))
    fig, axes, _, strips = map_axes(grid, rgb, (9, 8))
    rows, cols = known_bounds(grid)
    goal = plan.goal
    image = np.full(grid.shape, np.nan)  # [H, W]
    image[grid.free] = goal.probability
    extent = _extent(grid, rows, cols)
    kept = [leg.corridor for leg in plan.legs if leg.corridor is not None]
    region = None
    if kept:  # the cells a hierarchical plan was kept to: its routes' places, outlined
        cells = plan.planning.cells(np.flatnonzero(np.logical_or.reduce(kept)))
        region = np.zeros(grid.shape, dtype=bool)  # [H, W]
        region[cells[:, 0], cells[:, 1]] = True
    label = cell_probability_label(goal.shown, plan.off_map)  # as where's figures name it
    length = 0.3 * max(1.0, plan.radius * 4)
    for ax in axes:  # one map, or its strips: every artist clipped to the strip's stretch
        shown = ax.imshow(image[rows, cols], extent=extent, origin="upper",
                          cmap=PROBABILITY_CMAP, vmin=0.0, vmax=1.0,
                          interpolation="nearest")  # fmt: skip
        if region is not None:
            draw_outline(ax, grid, region, rows, cols, extent, colors=[ROUTE_RGB],
                         linewidths=2.0)  # fmt: skip
            ax.plot([], [], color=ROUTE_RGB, lw=2.0, label="route's places (outline)")
        ax.plot(plan.path_xy[:, 0], plan.path_xy[:, 1], color="C3", lw=2, label="path")
        ax.plot(*plan.start, marker="o", color="C2", ms=9, ls="", label="start")
        for k, stop in enumerate(plan.stops[:-1]):  # white, black-rimmed: not the route's orange
            ax.plot(*stop.xy, marker="s", ms=8, ls="", markerfacecolor="w", markeredgecolor="k",
                    markeredgewidth=1.5, label="" if k else "stop ('via' place)")  # fmt: skip
        ax.plot(*goal.xy, marker="*", color="C3", ms=16, ls="",
                label=f"goal: {goal.shown} (arrow: its heading)")  # fmt: skip
        # the goal pose's yaw in black: drawn in the path's red it read as the path running on
        # past the goal (room1ldk5, 'go to the bath via the kitchen')
        ax.arrow(goal.xy[0], goal.xy[1], length * np.cos(goal.yaw), length * np.sin(goal.yaw),
                 width=0.02, color="k", zorder=3)  # fmt: skip
        others = [c.xy for stop in plan.stops for c in stop.choice.candidates
                  if (c.xy != stop.xy) or not c.reachable]  # fmt: skip
        for k, xy in enumerate(others):
            ax.plot(*xy, marker="x", color="C4", ms=9, mew=2.0, ls="",
                    label="" if k else "other candidate goal (not taken)")  # fmt: skip
    for stop in plan.stops[:-1]:  # its name once, on the strip showing it (_showing)
        _showing(axes, *stop.xy).annotate(stop.shown, stop.xy, xytext=(5, 5),
                                          textcoords="offset points", fontsize=9)  # fmt: skip
    # beside the map or the last strip, as tall as it (shrink=0.8 of the figure stood above
    # and below a wide map)
    fig.colorbar(shown, cax=axes[-1].inset_axes((1.02, 0.0, 0.025, 1.0)), label=label)
    # below the map (the colour bar is beside it): loc="best" weighs the lines, not the map,
    # and put the legend over a room
    map_legend(axes[-1], axes[0].get_legend_handles_labels()[0], below=True, columns=2,
               fontsize=8)  # fmt: skip
    axes[0].set_title(f"navigate: {plan.instruction.text!r}\n{plan.length:.2f} m, "
                      f"radius {plan.radius:g} m{strips}")  # fmt: skip
    return fig


_CORNERS = ((6, 6, "left", "bottom"), (6, -6, "left", "top"), (-6, 6, "right", "bottom"),
            (-6, -6, "right", "top"), (0, 11, "center", "bottom"),
            (0, -11, "center", "top"))  # fmt: skip
"""Offsets (points) and alignments of a place's label from its centroid, in the order tried:
its corners, then above and below it (centred: in a narrow strip of a tall map no corner's
label fits)."""


def _place_texts(graph: PlaceGraph) -> list[str]:
    """Each place's label, by place id: its name and area, ``door (0.44 m²)``; where places
    would read the same, each adds its concept (``door (concept 38, 0.44 m²)``), or, where two
    of them are regions of one concept, each its place id (``door (place 17, 0.44 m²)``, the ids
    of ``show --graph``'s list), as a route tells places apart
    (:func:`~spcopyro.robot.navigation.places.told_apart`, whose decision it takes:
    :func:`~spcopyro.robot.navigation.places.telling_apart`). room1ldk5's CAVI fit has two
    places labelled ``door (0.44 m²)``."""
    texts = [f"{p.name} ({p.area_text} m²)" for p in graph.places]
    added = telling_apart(graph, [p.id for p in graph.places], texts)
    return [f"{p.name} ({how}, {p.area_text} m²)" if how else text
            for text, p, how in zip(texts, graph.places, added, strict=True)]  # fmt: skip


def _marker_boxes(fig: Figure, axes: list[Axes], xy: np.ndarray, size: np.ndarray) -> list[Bbox]:
    """The display box of each place's marker (``xy``: ``[N, 2]``, ``size``: ``[N]``, the
    scatter's area in points^2), on the strip showing it (:func:`_showing`)."""
    boxes = []
    for (x, y), s in zip(xy, size, strict=True):
        cx, cy = _showing(axes, x, y).transData.transform((x, y))
        r = np.sqrt(s) / 2 * fig.dpi / 72  # the marker's radius in pixels
        boxes.append(Bbox.from_extents(cx - r, cy - r, cx + r, cy + r))
    return boxes


def _label_places(
    fig: Figure, axes: list[Axes], graph: PlaceGraph, xy: np.ndarray, size: np.ndarray
) -> int:
    """Each place's name and area beside its marker (``xy``: ``[N, 2]``; ``size``: ``[N]``, the
    markers' areas in points^2), on the strip of ``axes`` showing it (:func:`_showing`),
    largest place first, at the first of :data:`_CORNERS` where it overlaps no label written
    before, stays inside its axes and covers no other place's marker (else the first that
    overlaps no label and stays inside, else the first that overlaps none; a label that would
    overlap one written before at every corner is left out, and the count returned): on a
    corridor's strip a label above a centroid ran over the title, and a label pushed off the
    map's edge to its marker's left sat on a smaller place's marker, which it then seemed to
    name (room1ldk5's words: ``washroom`` beside ``wall``'s marker); one with no free corner
    was drawn over another (room1ldk5's CAVI fit: "washroom (0.25 m²)" over "washroom (0.31
    m²)"), and neither could be read."""
    if fig.canvas is None or not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    renderer = fig.canvas.get_renderer()
    for ax in axes:
        ax.apply_aspect()  # the axes' box as drawn: label boxes measured where they will be
    markers = _marker_boxes(fig, axes, xy, size)  # [N] display boxes
    box = {"boxstyle": "round,pad=0.2", "fc": "white", "alpha": 0.8, "lw": 0}
    written: list[Bbox] = []
    left_out = 0
    texts = _place_texts(graph)  # [N] by place id
    for p in sorted(graph.places, key=lambda place: -place.area):
        at = tuple(xy[p.id])
        ax = _showing(axes, *at)
        frame = ax.get_window_extent(renderer=renderer)
        others = [m for q, m in enumerate(markers) if q != p.id]
        boxes = []
        for dx, dy, ha, va in _CORNERS:
            label = ax.annotate(texts[p.id], at, xytext=(dx, dy),
                                textcoords="offset points", ha=ha, va=va, fontsize=8, zorder=5,
                                bbox=box)  # fmt: skip
            boxes.append(label.get_window_extent(renderer=renderer))
            label.remove()
        free = [not any(b.overlaps(other) for other in written) for b in boxes]
        inside = [frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1
                  for b in boxes]  # fmt: skip
        clear = [not any(b.overlaps(m) for m in others) for b in boxes]
        order = [k for k in range(len(boxes)) if free[k] and inside[k] and clear[k]]
        order = order or [k for k in range(len(boxes)) if free[k] and inside[k]]
        order = order or [k for k in range(len(boxes)) if free[k]]
        if not order:  # drawn over a label written before, it hid that one and read as neither
            left_out += 1
            continue
        k = order[0]
        dx, dy, ha, va = _CORNERS[k]
        ax.annotate(texts[p.id], at, xytext=(dx, dy),
                    textcoords="offset points", ha=ha, va=va, fontsize=8, zorder=5,
                    bbox=box)  # fmt: skip
        written.append(boxes[k])
    return left_out


def place_points(grid: OccupancyGrid, graph: PlaceGraph) -> tuple[np.ndarray, np.ndarray]:
    """(``[N, 2]`` world x, y of each place's marker, ``[N, 2]`` its (row, col)): its centroid
    when that falls on one of its cells, else the centre of its cell nearest the centroid (a
    U-shaped place's centroid lies on the wall between its arms)."""
    xy = np.array([p.centroid for p in graph.places], dtype=np.float64).reshape(-1, 2)
    cells = grid.world_to_cell(xy).reshape(-1, 2)  # [N, 2]
    for k in range(len(xy)):
        r, c = cells[k]
        inside = 0 <= r < grid.height and 0 <= c < grid.width
        if inside and graph.regions[r, c] == k:
            continue
        own = np.argwhere(graph.regions == k)  # [M, 2]
        if not len(own):
            continue
        centres = grid.cell_to_world(own)  # [M, 2]
        cells[k] = own[np.argmin(((centres - xy[k]) ** 2).sum(axis=1))]
        xy[k] = grid.cell_to_world(cells[k])
    return xy, cells


def passage_lines(
    grid: OccupancyGrid, graph: PlaceGraph, xy: np.ndarray, cells: np.ndarray
) -> list[np.ndarray]:
    """``[K, 2]`` world points of each passage's line: from one place's marker (``xy``, on cell
    ``cells``: :func:`place_points`) to the other's over the centres of a shortest chain of the
    two places' cells (8-neighbours, no corner cut:
    :func:`~spcopyro.data.footprint.free_cell_graph`), so it crosses no wall; straight where
    their cells do not join on the fit's grid (a passage found on the robot's map only)."""
    from scipy.sparse.csgraph import dijkstra

    from spcopyro.data.footprint import free_cell_graph
    from spcopyro.robot.navigation.graph import trace_path

    lines = []
    for e in graph.passages:
        both = (graph.regions == e.a) | (graph.regions == e.b)  # [H, W]
        rows, cols = np.nonzero(both)  # a place has a cell at least
        corner = np.array([rows.min(), cols.min()])
        crop = both[corner[0] : rows.max() + 1, corner[1] : cols.max() + 1]
        pair = OccupancyGrid(np.where(crop, FREE, OCCUPIED).astype(np.int8), grid.resolution,
                             (0.0, 0.0, 0.0))  # fmt: skip  # the two places' box
        ends = [cells[e.a] - corner, cells[e.b] - corner]
        source, target = (int(pair.free_index[r, c]) if pair.in_bounds(np.array([r, c]))
                          else -1 for r, c in ends)  # fmt: skip
        line = np.array([xy[e.a], xy[e.b]])
        if source >= 0 and target >= 0:
            _, predecessors = dijkstra(free_cell_graph(pair), directed=False, indices=source,
                                       return_predecessors=True)  # fmt: skip
            if target == source or predecessors[target] >= 0:
                chain = pair.free_cells[trace_path(predecessors, target)] + corner  # [K, 2]
                line = np.concatenate([xy[e.a][None], grid.cell_to_world(chain), xy[e.b][None]])
        lines.append(line)
    return lines


def plot_place_graph(result: SpCoResult, graph: PlaceGraph, path: str | os.PathLike[str]) -> Path:
    """Write :func:`place_graph_figure` to ``path``."""
    return save_figure(place_graph_figure(result, graph), path)


def place_graph_figure(result: SpCoResult, graph: PlaceGraph) -> Figure:
    """The semantic map (the colours of ``spcopyro fit``'s map) with every place of ``graph`` at
    its centroid (marker area by the region's area, labelled with its top word and area; a
    concave place's centroid off its cells: on its cell nearest the centroid,
    :func:`place_points`) and its passages as lines between them along the two places' free
    cells (:func:`passage_lines`; straight, they crossed walls): doorways dashed, longer
    shared borders solid. A label that would overlap one written before (largest places first)
    moves to another corner of its marker (with none free, it is left out and counted in the
    title), and the legend stands beside the map (below a wide one): on a corridor's narrow
    places two labels ran into one ("concept 34 (0.8 m²).9 m²)") and the legend covered a room.
    A map more than :data:`~spcopyro.figures.map_pieces.STRIP_ASPECT` times as long as wide is
    drawn in strips at one scale (:func:`~spcopyro.figures.map_axes.map_axes`), the passages
    and markers on every strip, each label on the strip showing its place."""
    grid = result.grid
    colours = semantic_colours(result)  # [L, 3] uint8
    rgb = render_labels(result.label_image(), grid, colours)
    fig, axes, below, strips = map_axes(grid, rgb, (9, 8))
    xy, anchors = place_points(grid, graph)  # [N, 2] markers, [N, 2] their cells
    lines = passage_lines(grid, graph, xy, anchors)
    area = np.array([p.area for p in graph.places], dtype=float)  # [N] m^2
    size = 40 + 260 * area / area.max() if len(area) else area  # [N] marker areas, points^2
    for ax in axes:  # one map, or its strips: every line and marker clipped to its stretch
        for e, line in zip(graph.passages, lines, strict=True):
            ax.plot(*line.T, color="k", lw=1.5, ls="--" if e.doorway else "-", zorder=3)
        if len(xy):
            face = colours[[p.concept for p in graph.places]] / 255.0
            ax.scatter(*xy.T, s=size, c=face, edgecolors="k", linewidths=1.2, zorder=4)
    axes[0].plot([], [], color="k", ls="--", label=f"doorway (border <= {DOORWAY_WIDTH:g} m)")
    axes[0].plot([], [], color="k", ls="-", label="wider shared border")
    map_legend(axes[-1], axes[0].get_legend_handles_labels()[0], below=below, columns=2,
               fontsize=8)  # fmt: skip
    unlabelled = _label_places(fig, axes, graph, xy, size)
    dropped = graph.dropped_text("m²")  # as show --graph prints it
    dropped = f"; {dropped}" if dropped else ""
    # show --graph, which writes the figure, prints every place
    crowded = f", {unlabelled} left unlabelled (crowded)" if unlabelled else ""
    places, passages = plural(len(graph.places), "place"), plural(len(graph.passages), "passage")
    axes[0].set_title(f"place graph: {places}{crowded}, {passages}{dropped}{strips}")
    return fig
