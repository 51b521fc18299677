"""Occupancy grids: cell codes, world <-> cell geometry, neighbourhoods and colour classes.

Conventions
-----------
All ``[H, W]`` arrays are in the map IMAGE's row order: row 0 is the TOP of the map (largest world
y), exactly as the pgm is stored on disk. A cell is addressed as ``(row, col)``.

A world point ``(x, y)`` in metres falls in the cell (paper eq. 11, plus map_server's image
convention that the last image row is grid row 0)::

    col    = floor((x - origin_x) / resolution)
    grid_j = floor((y - origin_y) / resolution)
    row    = H - 1 - grid_j

``origin`` is the world pose of the lower-left corner of the lower-left cell (map_server
semantics). Rotated maps (``origin`` yaw != 0) are not supported: map_server itself ignores the yaw
for most consumers, and silently ignoring it here would misplace every observation, so a non-zero
yaw is an error.

Cell codes are map_server's trinary ``int8`` values ``FREE = 0``, ``OCCUPIED = 100``,
``UNKNOWN = -1``. Every FREE cell carries a latent spatial concept in SpCoMapping; free cells are
numbered ``0 .. N-1`` in raster (row-major image) order by :attr:`OccupancyGrid.free_index`, and
all per-free-cell arrays elsewhere in the package use that order.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "FREE",
    "MAP_TOLERANCE_CELLS",
    "OCCUPIED",
    "UNKNOWN",
    "OccupancyGrid",
    "cells_on_map",
    "describe_map",
    "frame_differences",
    "same_frame",
    "same_free_cells",
    "same_origin",
    "same_resolution",
]

FREE, OCCUPIED, UNKNOWN = 0, 100, -1  # map_server trinary values (int8)

_CONNECTIVITIES = (4, 8)
# (d_row, d_col) of the neighbour columns of neighbour_table: up, down, left, right, then
# up-left, up-right, down-left, down-right.
_OFFSETS = ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1))


MAP_TOLERANCE_CELLS = 1e-3
"""The one rule by which two maps' resolutions and origins are the same (:func:`same_frame`):
resolutions within a relative thousandth, origins within a thousandth of a cell along x and y.
Maps are compared after a trip through yaml files another tool may have written again: ROS 1's
``map_saver`` writes both with 6 decimals (``%f``), 0.05 / 3 m as 0.016667 (relative 2e-5 off)
and an origin up to 5e-7 m off, which an exact comparison refused. A thousandth of a cell moves
nothing placed on the map visibly (50 um at 0.05 m; 1 um at the smallest plausible resolution,
1 mm); a map of another resolution or origin (another SLAM run, a map of other cells) is off by
far more. A cell size off by the whole tolerance moves the far edge of a map N cells wide by N
thousandths of a cell (a cell at 1000 cells); the 6-decimal rounding it admits, by at most
N x 5e-7 m (0.5 mm at 1000 cells)."""


def same_resolution(a: float, b: float) -> bool:
    """Whether ``a`` and ``b``, metres per cell, are one resolution
    (:data:`MAP_TOLERANCE_CELLS`)."""
    return math.isclose(a, b, rel_tol=MAP_TOLERANCE_CELLS)


def same_origin(a: tuple[float, ...], b: tuple[float, ...], resolution: float) -> bool:
    """Whether origins ``a`` and ``b`` (x, y, yaw) are one, x and y within
    :data:`MAP_TOLERANCE_CELLS` of a cell of ``resolution`` metres (yaw: equal)."""
    tolerance = MAP_TOLERANCE_CELLS * resolution
    return all(math.isclose(a[i], b[i], abs_tol=tolerance) for i in (0, 1)) and a[2:] == b[2:]


def frame_differences(a: OccupancyGrid, b: OccupancyGrid) -> tuple[bool, bool]:
    """(the resolutions differ, the origins differ) of ``a`` and ``b``: :func:`same_resolution`,
    :func:`same_origin` in the finer one's cells. The one rule of :func:`same_frame` and of an
    update's check (:func:`spcopyro.robot.online.check_compatible`, which names each)."""
    return (
        not same_resolution(a.resolution, b.resolution),
        not same_origin(a.origin, b.origin, min(a.resolution, b.resolution)),
    )


def same_frame(a: OccupancyGrid, b: OccupancyGrid) -> bool:
    """Whether ``a`` and ``b`` have one resolution and origin (:func:`frame_differences`):
    their cells lie on each other."""
    return not any(frame_differences(a, b))


def same_free_cells(a: OccupancyGrid, b: OccupancyGrid) -> bool:
    """Whether a per-free-cell array of ``a`` (labels, counts: indexed by free cell) means the
    same on ``b``: the same shape and free cells (the mask, not only their count) in one frame
    (:func:`same_frame`)."""
    return a.shape == b.shape and same_frame(a, b) and np.array_equal(a.free, b.free)


def describe_map(grid: OccupancyGrid) -> str:
    """``"a (40, 50) map with 1200 free cells of 0.05 m, origin (0.0, 0.0, 0.0)"``: numbers as
    Python writes them back (``repr``), so two maps refused as different never read the same."""
    return (
        f"a {grid.shape} map with {grid.num_free} free cells of {grid.resolution!r} m, "
        f"origin {grid.origin!r}"
    )


def cells_on_map(grid: OccupancyGrid, xy: Any) -> np.ndarray:
    """``[n', 2]`` int64 (row, col), on the map ``grid`` was coarsened from (``grid`` itself if
    it was not: that map's walls are not thickened), of the points ``xy`` ``[n, 2]`` (metres)
    that fall inside its bounds, in their order; points not finite, or too far away for
    :meth:`OccupancyGrid.world_to_cell` (2**40 cells), are dropped with those off the map."""
    fine = grid.coarsened_from if grid.coarsened_from is not None else grid
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)  # [n, 2]
    xy = xy[np.isfinite(xy).all(axis=1) & (np.abs(xy) < 2.0**40 * fine.resolution).all(axis=1)]
    cells = np.asarray(fine.world_to_cell(xy), dtype=np.int64).reshape(-1, 2)  # [n, 2]
    return cells[np.asarray(fine.in_bounds(cells), dtype=bool)]  # [n', 2]


def _check_connectivity(connectivity: int) -> None:
    if connectivity not in _CONNECTIVITIES:
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")


def _as_cells(cells: Any, what: str = "cells") -> np.ndarray:
    """``[..., 2]`` integer (row, col) array as int64; raises ValueError otherwise."""
    arr = np.asarray(cells)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{what} must have shape [..., 2] (row, col), got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        raise ValueError(f"{what} must be an integer array, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=False)


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A map_server occupancy grid in image row order (row 0 = top = largest world y).

    Attributes:
        occupancy: ``[H, W]`` int8 in ``{FREE, OCCUPIED, UNKNOWN}``; stored as a read-only copy.
        resolution: metres per cell, > 0.
        origin: world pose ``(x, y, yaw)`` of the lower-left cell's lower-left corner (yaw 0).
        source: the yaml the grid was loaded from, if any (not part of equality).
        coarsened_from: the map this grid was coarsened from
            (:func:`spcopyro.maps.coarse.coarsen_grid`), if any: observations are placed on the
            map first and then on its blocks (:func:`spcopyro.data.place_observations`). Not
            part of equality, not saved with the grid.

    Two grids are equal when their cells, resolution and origin are equal.
    """

    occupancy: np.ndarray  # [H, W] int8
    resolution: float
    origin: tuple[float, float, float]
    source: Path | None = None
    coarsened_from: OccupancyGrid | None = None

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.ndim != 2:
            raise ValueError(f"occupancy must be a 2-D [H, W] array, got shape {occ.shape}")
        if occ.dtype.kind not in "iu":
            raise ValueError(f"occupancy must be an integer array, got dtype {occ.dtype}")
        bad = ~np.isin(occ, (FREE, OCCUPIED, UNKNOWN))  # [H, W] bool
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise ValueError(
                f"occupancy values must be FREE (0), OCCUPIED (100) or UNKNOWN (-1); "
                f"cell (row {row}, col {col}) is {occ[row, col]} ({int(bad.sum())} bad cells)"
            )
        object.__setattr__(self, "occupancy", _readonly(occ.astype(np.int8, copy=True)))

        if isinstance(self.resolution, bool) or not isinstance(
            self.resolution, (int, float, np.integer, np.floating)
        ):
            raise ValueError(f"resolution must be a number, got {self.resolution!r}")
        resolution = float(self.resolution)
        if not (math.isfinite(resolution) and resolution > 0):
            raise ValueError(f"resolution must be positive and finite, got {resolution!r}")
        object.__setattr__(self, "resolution", resolution)

        try:
            origin = tuple(float(v) for v in self.origin)
        except (TypeError, ValueError) as err:
            raise ValueError(f"origin must be 3 numbers (x, y, yaw), got {self.origin!r}") from err
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise ValueError(f"origin must be 3 finite numbers (x, y, yaw), got {self.origin!r}")
        if origin[2] != 0.0:
            raise ValueError(f"rotated maps are not supported: origin yaw is {origin[2]!r}")
        object.__setattr__(self, "origin", origin)

        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))

    def __eq__(self, other: object) -> bool:
        """The same cells, resolution and origin, the latter two by :func:`same_frame` (a map
        saved again with 6 decimals is the same map)."""
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return same_frame(self, other) and np.array_equal(self.occupancy, other.occupancy)

    __hash__ = None  # type: ignore[assignment]  # holds an ndarray

    def __getstate__(self) -> dict[str, Any]:
        """The fields and cached properties, less what other modules keep on the grid under a
        ``_`` name (:mod:`spcopyro.maps.coarse`'s coarse grids, held weakly, and block map):
        a copy or pickle computes them again."""
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_")}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """The fields and cached properties back, their arrays read-only again: a pickle
        gives them back writeable, and a write to ``occupancy`` would leave ``free`` and
        ``free_index``, kept from before, describing other cells."""
        self.__dict__.update(state)
        for value in state.values():
            if isinstance(value, np.ndarray):
                _readonly(value)

    def __repr__(self) -> str:
        return (
            f"OccupancyGrid(shape={self.shape}, resolution={self.resolution}, "
            f"origin={self.origin}, num_free={self.num_free}, source={self.source})"
        )

    # ------------------------------------------------------------------ shape and free cells
    @property
    def height(self) -> int:
        return int(self.occupancy.shape[0])

    @property
    def width(self) -> int:
        return int(self.occupancy.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    @property
    def cell_area(self) -> float:
        """Square metres of one cell: ``resolution ** 2`` (a speck's area bound,
        :func:`~spcopyro.results.concept_words.is_speck`)."""
        return self.resolution**2

    @cached_property
    def free(self) -> np.ndarray:
        """``[H, W]`` bool, True on FREE cells (read-only)."""
        return _readonly(self.occupancy == FREE)

    @cached_property
    def num_free(self) -> int:
        return int(np.count_nonzero(self.free))

    @cached_property
    def free_index(self) -> np.ndarray:
        """``[H, W]`` int64: raster-order index ``0..N-1`` of each free cell, -1 elsewhere."""
        index = np.full(self.shape, -1, dtype=np.int64)  # [H, W]
        index[self.free] = np.arange(self.num_free, dtype=np.int64)
        return _readonly(index)

    @cached_property
    def free_cells(self) -> np.ndarray:
        """``[N, 2]`` int64 (row, col) of the free cells in :attr:`free_index` order."""
        return _readonly(np.argwhere(self.free).astype(np.int64))

    # ------------------------------------------------------------------ geometry
    def world_to_cell(self, xy: Any) -> np.ndarray:
        """World points ``[..., 2]`` (x, y) in metres -> ``[..., 2]`` int64 (row, col).

        ``col = floor((x - ox) / res)``, ``row = H - 1 - floor((y - oy) / res)`` (paper eq. 11).
        No clipping: points off the map give indices outside ``[0, H) x [0, W)`` (see
        :meth:`in_bounds`). Raises ValueError on NaN/inf input.
        """
        pts = np.asarray(xy, dtype=np.float64)
        if pts.ndim == 0 or pts.shape[-1] != 2:
            raise ValueError(f"xy must have shape [..., 2] (x, y), got shape {pts.shape}")
        finite = np.isfinite(pts).all(axis=-1)  # [...] bool
        if not finite.all():
            first = np.argwhere(~finite)[0]
            raise ValueError(
                f"xy must be finite; point at index {tuple(int(i) for i in first)} is "
                f"{pts[tuple(first)].tolist()}"
            )
        ox, oy, _ = self.origin
        grid = np.floor((pts - np.array([ox, oy])) / self.resolution)  # [..., 2] (i, j) float
        if pts.size and np.abs(grid).max() >= 2.0**62:
            raise ValueError("xy is too far from the map origin to index a cell")
        grid = grid.astype(np.int64)
        cells = np.empty_like(grid)  # [..., 2] (row, col)
        cells[..., 0] = self.height - 1 - grid[..., 1]
        cells[..., 1] = grid[..., 0]
        return cells

    def cell_to_world(self, cells: Any) -> np.ndarray:
        """Cells ``[..., 2]`` int (row, col) -> ``[..., 2]`` float64 world (x, y) of the centre.

        ``x = ox + (col + 1/2) res``, ``y = oy + (H - 1 - row + 1/2) res``; so
        ``world_to_cell(cell_to_world(c)) == c`` exactly. Cells off the map are allowed.
        """
        c = _as_cells(cells)
        ox, oy, _ = self.origin
        xy = np.empty(c.shape, dtype=np.float64)  # [..., 2]
        xy[..., 0] = ox + (c[..., 1] + 0.5) * self.resolution
        xy[..., 1] = oy + (self.height - 1 - c[..., 0] + 0.5) * self.resolution
        return xy

    def in_bounds(self, cells: Any) -> np.ndarray:
        """``[...]`` bool: the (row, col) lies inside ``[0, H) x [0, W)``."""
        c = _as_cells(cells)
        return (
            (c[..., 0] >= 0)
            & (c[..., 0] < self.height)
            & (c[..., 1] >= 0)
            & (c[..., 1] < self.width)
        )

    def is_free(self, cells: Any) -> np.ndarray:
        """``[...]`` bool: the (row, col) is on the map and FREE (False when out of bounds)."""
        c = _as_cells(cells)
        inside = self.in_bounds(c)  # [...] bool
        rows = np.where(inside, c[..., 0], 0)
        cols = np.where(inside, c[..., 1], 0)
        return inside & self.free[rows, cols]

    # ------------------------------------------------------------------ neighbourhoods
    def _neighbours_at(self, offsets: Sequence[tuple[int, int]]) -> np.ndarray:
        """``[N, len(offsets)]`` int64 free-cell index of each free cell's neighbour at each
        ``(dr, dc)`` of ``offsets``, -1 where it is off the map or not free: one gather from the
        free index padded by a ring of -1, at the free cells' flat positions plus each offset's
        step (the pairs' lexsort it replaced took 2 s on a 3-million-cell map)."""
        width = self.width + 2
        padded = np.pad(self.free_index, 1, constant_values=-1).ravel()  # [(H+2) (W+2)]
        at = np.flatnonzero(np.pad(self.free, 1).ravel())  # [N] raster = free index order
        steps = np.array([dr * width + dc for dr, dc in offsets], dtype=np.int64)  # [K]
        return padded[at[:, None] + steps]  # [N, K]

    def neighbour_table(self, connectivity: int = 4) -> np.ndarray:
        """``[N, connectivity]`` int64 free-cell indices of each free cell's neighbours.

        Columns: up, down, left, right (row-1, row+1, col-1, col+1); for 8-connectivity then
        up-left, up-right, down-left, down-right. -1 where the neighbour is off the map or not free.
        """
        _check_connectivity(connectivity)
        return self._neighbours_at(_OFFSETS[:connectivity])

    def neighbour_pairs(self, connectivity: int = 4) -> np.ndarray:
        """``[P, 2]`` int64 unordered free-neighbour pairs ``(a, b)``, ``a < b``, each once.

        Sorted lexicographically by ``(a, b)``.
        """
        _check_connectivity(connectivity)
        # The neighbours later in raster order (right, then down-left, down, down-right: so
        # each pair appears once), in the order of their (dr, dc), which is their free index's
        # order: read row by row, [a, its neighbours] comes out sorted, without a sort.
        forward = sorted(offset for offset in _OFFSETS[:connectivity] if offset > (0, 0))
        later = self._neighbours_at(forward)  # [N, F]
        has = later >= 0  # [N, F] bool
        pairs = np.empty((int(np.count_nonzero(has)), 2), dtype=np.int64)  # [P, 2]
        pairs[:, 0] = np.repeat(np.arange(self.num_free, dtype=np.int64), has.sum(axis=1))
        pairs[:, 1] = later[has]
        return pairs

    def colour_classes(self, connectivity: int = 4) -> list[np.ndarray]:
        """Graph colouring of the free cells into blocks with no neighbours inside a block.

        4-connectivity: 2 classes by ``(row + col) % 2`` (checkerboard); 8-connectivity: 4
        classes by ``2 * (row % 2) + col % 2``. Each entry is an ascending int64 array of free-cell
        indices (possibly empty); given the other classes, the cells of one class are
        conditionally independent under a pairwise MRF, so they can be Gibbs-updated together.
        """
        _check_connectivity(connectivity)
        rows, cols = self.free_cells[:, 0], self.free_cells[:, 1]  # [N]
        if connectivity == 4:
            colour, num_colours = (rows + cols) % 2, 2
        else:
            colour, num_colours = 2 * (rows % 2) + cols % 2, 4
        return [np.flatnonzero(colour == k).astype(np.int64) for k in range(num_colours)]

    def with_occupancy(self, occupancy: Any) -> OccupancyGrid:
        """The same geometry (resolution, origin, source) with new ``[H, W]`` cells."""
        occ = np.asarray(occupancy)
        if occ.shape != self.shape:
            raise ValueError(f"occupancy must have shape {self.shape}, got {occ.shape}")
        return dataclasses.replace(self, occupancy=occ)
