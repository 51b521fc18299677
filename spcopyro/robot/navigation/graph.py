r"""Where the robot may drive: the clearance of every free cell and the graph paths run over.

**Clearance.** A free cell's clearance is the Euclidean distance from its centre to the centre
of the nearest cell that is not free (occupied, unknown, or beyond the map's edge), less half a
cell: the distance to that cell's near side along a row or column
(``scipy.ndimage.distance_transform_edt``). A cell next to a wall has half a cell of clearance.

**Hard exclusion.** The robot, a disc of radius ``radius`` metres, may stand on a free cell whose
clearance is at least ``radius``; every other cell is left out of the planning graph. There is
no soft cost near walls: a path is the shortest one through the cells the robot fits on, and it
may run along the edge of that set (exactly ``radius`` from a wall), which is what Nav2's
inflation layer is for once the robot drives.

**The graph** is :func:`spcopyro.data.footprint.free_cell_graph` of the map with the excluded
cells made occupied: 8-connected, steps of one cell or sqrt(2) cells (in metres), a diagonal step
only where both cells beside it are allowed (no corner cutting), so a path never crosses or
touches a cell the robot does not fit on. Shortest paths: ``scipy.sparse.csgraph.dijkstra``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from spcopyro.data.footprint import free_cell_graph
from spcopyro.maps import OCCUPIED, OccupancyGrid

if TYPE_CHECKING:
    from scipy import sparse

__all__ = ["PlanningGrid", "clearance_map", "planning_grid", "shortest_paths", "trace_path"]


def clearance_map(grid: OccupancyGrid) -> np.ndarray:
    """``[H, W]`` float64 metres: each free cell's clearance (module docstring), 0 elsewhere."""
    from scipy.ndimage import distance_transform_edt

    free = np.pad(np.asarray(grid.free, dtype=bool), 1, constant_values=False)  # edge: not free
    distance = distance_transform_edt(free)[1:-1, 1:-1] * grid.resolution  # [H, W] to a centre
    return np.where(grid.free, np.maximum(distance - grid.resolution / 2, 0.0), 0.0)


@dataclass(frozen=True)
class PlanningGrid:
    """The cells a robot of ``radius`` fits on and the graph between them.

    ``allowed`` is a copy of the fit's grid whose free cells are the allowed ones (the others
    made occupied); its ``free_index`` numbers the graph's nodes ("allowed index")."""

    grid: OccupancyGrid
    """The fit's grid."""
    radius: float
    clearance: np.ndarray
    """[H, W] metres (:func:`clearance_map`)."""
    allowed: OccupancyGrid
    graph: sparse.csr_matrix
    """[M, M] edge lengths in metres between allowed cells."""

    @property
    def num_allowed(self) -> int:
        return int(self.allowed.num_free)

    def node_of(self, cell: tuple[int, int] | np.ndarray) -> int:
        """The allowed index of a (row, col) cell, -1 when the robot does not fit there."""
        row, col = int(cell[0]), int(cell[1])
        if not (0 <= row < self.grid.height and 0 <= col < self.grid.width):
            return -1
        return int(self.allowed.free_index[row, col])

    def cells(self, nodes: np.ndarray) -> np.ndarray:
        """``[K, 2]`` (row, col) of allowed indices ``nodes`` ``[K]``."""
        return self.allowed.free_cells[np.asarray(nodes, dtype=np.int64)]

    def free_index_of(self, nodes: np.ndarray) -> np.ndarray:
        """``[K]`` the fit's free index (its labels' order) of allowed indices ``nodes``."""
        cells = self.cells(nodes)
        return self.grid.free_index[cells[:, 0], cells[:, 1]]


def planning_grid(grid: OccupancyGrid, radius: float) -> PlanningGrid:
    """The :class:`PlanningGrid` of a robot of ``radius`` metres (>= 0) on ``grid``."""
    if not (np.isfinite(radius) and radius >= 0):
        raise ValueError(f"the robot's radius must be a finite number of metres >= 0, got {radius}")
    clearance = clearance_map(grid)  # [H, W]
    ok = grid.free & (clearance >= radius - 1e-9)  # [H, W]
    occupancy = np.where(grid.free & ~ok, OCCUPIED, grid.occupancy).astype(grid.occupancy.dtype)
    allowed = OccupancyGrid(occupancy, grid.resolution, grid.origin, source=grid.source)
    return PlanningGrid(grid, float(radius), clearance, allowed, free_cell_graph(allowed))


def shortest_paths(planning: PlanningGrid, source: int) -> tuple[np.ndarray, np.ndarray]:
    """(``[M]`` metres from allowed cell ``source`` to every allowed cell, inf where unreachable;
    ``[M]`` predecessors, -9999 at the source and where unreachable)."""
    from scipy.sparse.csgraph import dijkstra

    distance, predecessors = dijkstra(
        planning.graph, directed=False, indices=int(source), return_predecessors=True
    )
    return distance, predecessors


def trace_path(predecessors: np.ndarray, target: int) -> np.ndarray:
    """``[K]`` allowed indices from the source of ``predecessors`` to ``target`` (inclusive)."""
    path = [int(target)]
    while predecessors[path[-1]] >= 0:
        path.append(int(predecessors[path[-1]]))
    return np.array(path[::-1], dtype=np.int64)


MAP_COVERAGE = 0.8
"""The least share of a fit's free cells that a map given for planning must cover
(:func:`check_same_map`): its own map covers all of them (the coarse cells are made of its
cells), another house's map in the same frame about 0.6 (room1dk5's of a room2ldk4 fit)."""


def map_coverage(fit_grid: OccupancyGrid, grid: OccupancyGrid) -> float:
    """The share of ``fit_grid``'s free cells that hold the centre of a free cell of ``grid`` (a
    finer map) or whose centre lies on one (a coarser map: it was counted as a quarter of a map
    twice as coarse, and refused as another house)."""
    cells = fit_grid.world_to_cell(grid.cell_to_world(grid.free_cells))  # [N_map, 2]
    inside = np.asarray(fit_grid.in_bounds(cells), dtype=bool)  # [N_map]
    covered = np.zeros(fit_grid.free.shape, dtype=bool)  # [H, W]
    covered[cells[inside, 0], cells[inside, 1]] = True
    on_map = grid.world_to_cell(fit_grid.cell_to_world(fit_grid.free_cells))  # [N, 2]
    covered[fit_grid.free] |= np.asarray(grid.is_free(on_map), dtype=bool)
    return float((covered & fit_grid.free).sum() / max(fit_grid.num_free, 1))


def check_same_map(fit_grid: OccupancyGrid, grid: OccupancyGrid) -> None:
    """Refuse a planning map that is not the fit's: one whose free cells cover less than
    :data:`MAP_COVERAGE` of the fit's free cells (another house, another origin or resolution):
    the fit's places carried onto it would lie across its walls.

    Raises:
        ValueError: naming the map and both maps' extents.
    """
    coverage = map_coverage(fit_grid, grid)
    if coverage >= MAP_COVERAGE:
        return

    def extent(g: OccupancyGrid) -> str:
        (x0, y0), (x1, y1) = g.cell_to_world(np.array([[g.height - 1, 0], [0, g.width - 1]]))
        return f"x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f} m at {g.resolution:g} m"

    raise ValueError(
        f"map {grid.source or '(given)'} is not the fit's map: its free space covers "
        f"{coverage:.0%} of the fit's {fit_grid.num_free} free cells (at least "
        f"{MAP_COVERAGE:.0%} expected; the map spans {extent(grid)}, the fit {extent(fit_grid)}): "
        "pass the map the fit was made on, in the same frame"
    )


def fit_cells_on(fit_grid: OccupancyGrid, grid: OccupancyGrid) -> np.ndarray:
    """``[N]`` for every free cell of ``grid`` (a map in the same frame, e.g. the finer map a
    coarse fit was made from), the free index in ``fit_grid`` of the fit cell holding its centre,
    or, where that cell is not free in the fit (a wall thickened by coarsening, or off the fit's
    map), of the nearest free fit cell (Euclidean, in fit cells)."""
    from scipy.ndimage import distance_transform_edt

    if fit_grid.num_free == 0:
        raise ValueError("the fit's map has no free cell")
    centres = grid.cell_to_world(grid.free_cells)  # [N, 2]
    cells = fit_grid.world_to_cell(centres)  # [N, 2] may lie off the fit's map
    rows = np.clip(cells[:, 0], 0, fit_grid.height - 1)
    cols = np.clip(cells[:, 1], 0, fit_grid.width - 1)
    _, (near_r, near_c) = distance_transform_edt(~np.asarray(fit_grid.free), return_indices=True)
    return fit_grid.free_index[near_r[rows, cols], near_c[rows, cols]]
