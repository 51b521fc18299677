r"""Spatial blocks of the free cells: square tiles of the grid, recovered from the model data.

Stochastic and memoized variational inference (:mod:`spcopyro.guides.memoized`) visit the
map one spatial block at a time. :class:`~spcopyro.model.ModelData` keeps the neighbour table but
not the cells' grid coordinates, so :func:`cell_coordinates` recovers them from the table: the
columns of :meth:`OccupancyGrid.neighbour_table <spcopyro.maps.grid.OccupancyGrid.neighbour_table>`
are fixed grid offsets (up, down, left, right, then the diagonals), so along a spanning tree of
each connected component a cell's coordinate is its parent's plus the edge's offset. The tree is
scipy's breadth-first tree and the sums along it are taken by pointer doubling (O(N log depth)
vectorised work, no per-cell Python loop). Coordinates are exact up to one shift per connected
component; a tile is a ``size x size`` square of those coordinates. Two disconnected components
may share a tile, which is harmless: a block need not be connected.

:func:`make_blocks` orders the cells by (block, colour) so that one block's cells of one colour
are a contiguous slice: the local step of a block is then a handful of slices, O(N) int64 in all.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch

from spcopyro._util.number_checks import is_integer
from spcopyro.model import ModelData

GRID_OFFSETS = ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1))
"""(row, col) offset of each column of the neighbour table (OccupancyGrid.neighbour_table's
order: up, down, left, right, up-left, up-right, down-left, down-right)."""


def cell_coordinates(neighbours: torch.Tensor | np.ndarray) -> np.ndarray:
    """[N, 2] int64 (row, col) of every free cell, from the ``[N, D]`` neighbour table.

    Exact up to a shift per connected component (each component's coordinates start at 0).
    Raises ValueError for a table whose offsets contradict each other (not a grid's table).
    """
    import scipy.sparse  # here, not at import: ``spcopyro fit`` imports this module's method
    import scipy.sparse.csgraph

    table = np.asarray(neighbours, dtype=np.int64)  # [N, D]
    if table.ndim != 2 or table.shape[1] not in (4, 8):
        raise ValueError(f"neighbours must be [N, 4] or [N, 8], got {table.shape}")
    n, d = table.shape
    offsets = np.asarray(GRID_OFFSETS[:d], dtype=np.int64)  # [D, 2]
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    # Each undirected edge once (the columns pointing forward in raster order), int32 indices.
    forward = [k for k in range(d) if GRID_OFFSETS[k] > (0, 0)]
    source = np.concatenate([np.flatnonzero(table[:, k] >= 0) for k in forward])  # [E]
    target = np.concatenate([table[table[:, k] >= 0, k] for k in forward])  # [E]
    source, target = source.astype(np.int32), target.astype(np.int32)

    def graph(size: int, a: np.ndarray, b: np.ndarray) -> scipy.sparse.csr_matrix:
        return scipy.sparse.csr_matrix((np.ones(a.size, dtype=np.float32), (a, b)), (size, size))

    _, labels = scipy.sparse.csgraph.connected_components(graph(n, source, target), directed=False)
    roots = np.unique(labels, return_index=True)[1]  # [K] first cell of each component
    # One compiled BFS from an extra node n joined to every component's root.
    source = np.concatenate([source, np.full(roots.size, n, dtype=np.int32)])
    target = np.concatenate([target, roots.astype(np.int32)])
    _, predecessors = scipy.sparse.csgraph.breadth_first_order(
        graph(n + 1, source, target), n, directed=False, return_predecessors=True
    )
    del source, target
    parent = predecessors[:n].astype(np.int64)  # [N]
    parent[roots] = roots
    # The edge parent -> child: the column d with table[parent, d] == child.
    child = np.flatnonzero(parent != np.arange(n))  # [N - K]
    column = (table[parent[child]] == child[:, None]).argmax(1)  # [N - K]
    step = np.zeros((n, 2), dtype=np.int64)
    step[child] = offsets[column]
    # Pointer doubling. Invariant: coordinate(i) = coordinate(jump[i]) + value[i]; a root is
    # its own jump with value 0, so once every jump is a root, value is the coordinate.
    value, jump = step, parent
    while not np.array_equal(jump[jump], jump):
        value, jump = value + value[jump], jump[jump]
    coordinate = value
    # Every edge of the table must agree with the coordinates.
    for k in range(d):
        cells = np.flatnonzero(table[:, k] >= 0)
        if not (coordinate[table[cells, k]] - coordinate[cells] == offsets[k]).all():
            raise ValueError(
                "the neighbour table is not a grid's: its offsets contradict each other"
            )
    # Shift each component to start at 0.
    if roots.size == 1:
        return coordinate - coordinate.min(0)
    by_component = np.argsort(labels, kind="stable")  # [N]
    first = np.searchsorted(labels[by_component], np.arange(roots.size))  # [K]
    lowest = np.minimum.reduceat(coordinate[by_component], first, axis=0)  # [K, 2]
    return coordinate - lowest[labels]


class Blocks(NamedTuple):
    """The free cells split into spatial blocks, ordered by (block, colour).

    ``order[starts[b, c] : starts[b, c + 1]]`` are block b's cells of colour c (ascending),
    with ``starts[b, num_colours] == starts[b + 1, 0]``.
    """

    order: torch.Tensor
    """[N] int64 free indices sorted by (block, colour, index)."""
    starts: torch.Tensor
    """[B, num_colours + 1] int64 slice bounds into ``order``."""
    block_of: torch.Tensor
    """[N] int64 each cell's block."""

    @property
    def num_blocks(self) -> int:
        return int(self.starts.shape[0])

    def cells(self, block: int) -> torch.Tensor:
        """The cells of ``block`` (sorted by colour)."""
        return self.order[int(self.starts[block, 0]) : int(self.starts[block, -1])]

    def sizes(self) -> torch.Tensor:
        """[B] cells per block."""
        return self.starts[:, -1] - self.starts[:, 0]


def tile_ids(coordinates: np.ndarray, size: int) -> np.ndarray:
    """[N] int64 block id of each cell: the ``size x size`` tile holding its coordinates, the
    non-empty tiles numbered in raster order from 0."""
    if not is_integer(size) or size < 1:
        raise ValueError(f"block size must be an integer >= 1, got {size!r}")
    tile = coordinates // size  # [N, 2]
    key = tile[:, 0] * (int(tile[:, 1].max(initial=0)) + 1) + tile[:, 1]  # [N]
    return np.unique(key, return_inverse=True)[1].astype(np.int64).ravel()


def make_blocks(data: ModelData, block_of: np.ndarray | torch.Tensor) -> Blocks:
    """The :class:`Blocks` of a given ``[N]`` block id per cell (ids 0..B-1, each used)."""
    block_of = np.asarray(block_of, dtype=np.int64).ravel()
    if block_of.shape != (data.num_free,):
        raise ValueError(f"block ids must be [{data.num_free}], got {block_of.shape}")
    if block_of.size and (block_of.min() < 0):
        raise ValueError("block ids must be >= 0")
    num_blocks = int(block_of.max(initial=-1)) + 1
    used = np.bincount(block_of, minlength=num_blocks) > 0
    if not used.all():
        raise ValueError(f"block ids must use every id in 0..{num_blocks - 1}; some are empty")
    colours = len(data.colours)
    colour = np.empty(data.num_free, dtype=np.int64)
    for c, cells in enumerate(data.colours):
        colour[np.asarray(cells)] = c
    key = block_of * colours + colour  # [N]
    order = np.argsort(key, kind="stable")  # [N] ascending free index within a key
    bounds = np.searchsorted(key[order], np.arange(num_blocks * colours + 1))  # [B*C + 1]
    starts = np.empty((num_blocks, colours + 1), dtype=np.int64)
    starts[:, :colours] = bounds[:-1].reshape(num_blocks, colours)
    starts[:, colours] = bounds[colours::colours]
    return Blocks(torch.from_numpy(order), torch.from_numpy(starts), torch.from_numpy(block_of))


def grid_blocks(data: ModelData, size: int) -> Blocks:
    """The free cells in ``size x size`` tiles of the grid (see the module docstring)."""
    return make_blocks(data, tile_ids(cell_coordinates(data.neighbours), size))
