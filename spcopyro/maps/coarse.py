r"""The model's grid when it is coarser than the map's: coarsening, and labels back on the map.

SpCoMapping's Potts prior couples neighbouring *cells*, so its answer depends on the cell size:
a border of length b metres costs gamma * b / resolution nats, and every unobserved cell votes in
the label prior, while the observations stay as many as they are. At 0.05 m (the public houses)
a 3 m border costs 180 nats at gamma 3, against about 10 nats that two places' words gain from
being told apart: the posterior puts the whole house in one concept (docs/real_houses.md).
Fitting on cells of about 0.25 m keeps the map's walls and doorways and makes the model's answer
a property of the house, not of the scanner's resolution.

Coarsening by an integer factor f (:func:`coarsen_grid`): the map is padded with UNKNOWN cells
at the top and on the right (so the origin, the lower-left corner, stays where it is) to a
multiple of f, and cut into f x f blocks. A block is

* OCCUPIED if any of its map cells is occupied (walls are never lost; they thicken to one
  model cell),
* FREE if at least half of its map cells are free and none is occupied,
* UNKNOWN otherwise.

A map cell (row r, col c) lies in model cell ``((r + pad) // f, c // f)`` with ``pad`` the
padding rows (:func:`model_cell_of`). The coarse grid keeps the map (``coarsened_from``), so
observations are placed as the map places them: a position on the map's free space (or
snapped to it) whose block a wall thickened over goes to the free block reached first through
the map's free cells (:func:`free_block_of_map_cells`), never through a wall.
:func:`refine_labels` takes a model label image back to the map: every free map cell takes its
block's label, or, where its block is not free (next to a wall), the label of the nearest free
block.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from spcopyro._util.number_checks import is_integer
from spcopyro.maps.grid import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    OccupancyGrid,
    same_origin,
    same_resolution,
)

__all__ = [
    "coarsen_grid",
    "coarsening_factor",
    "free_block_of_map_cells",
    "grow_labels",
    "is_coarsening",
    "labels_on_grid",
    "model_cell_of",
    "refine_labels",
]


def coarsening_factor(resolution: float, cell_size: float | None) -> int:
    """Map cells per model cell side: ``round(cell_size / resolution)``, at least 1 (None: 1)."""
    if cell_size is None:
        return 1
    if not (math.isfinite(cell_size) and cell_size > 0):
        raise ValueError(f"cell_size must be a positive number of metres, got {cell_size!r}")
    return max(1, int(math.floor(cell_size / resolution + 0.5)))


def _padding(grid: OccupancyGrid, factor: int) -> tuple[int, int]:
    return (-grid.height) % factor, (-grid.width) % factor


_T = TypeVar("_T")


def _kept_on(grid: OccupancyGrid, key: str, make: Callable[[], _T]) -> _T:
    """``make()``, made once per ``grid`` object and kept in its ``__dict__`` (as
    ``functools.cached_property`` keeps its values): a grid is frozen and its cells read-only,
    so what is computed from it cannot go stale, and it goes when the grid goes (no global
    cache to outlive a fit). A grid made anew (``dataclasses.replace``) starts without it."""
    kept = grid.__dict__
    if key not in kept:
        kept[key] = make()
    return kept[key]


def coarsen_grid(grid: OccupancyGrid, factor: int) -> OccupancyGrid:
    """The grid of ``factor x factor`` blocks of ``grid`` (module docstring); ``factor`` 1: the
    grid itself. While the coarse grid is alive, ``grid`` gives that same object again (held
    weakly, so no cycle keeps either alive): a fit asks for its model grid more than once (the
    command, the refinement's decision), and the coarse grid keeps what was computed on it
    (:func:`free_block_of_map_cells`)."""
    if not is_integer(factor) or factor < 1:
        raise ValueError(f"factor must be an integer >= 1, got {factor!r}")
    if factor == 1:
        return grid
    made: weakref.WeakValueDictionary[int, OccupancyGrid] = _kept_on(
        grid, "_coarsened", weakref.WeakValueDictionary
    )
    coarse = made.get(int(factor))
    if coarse is None:
        coarse = made[int(factor)] = _coarsen(grid, int(factor))
    return coarse


def _coarsen(grid: OccupancyGrid, factor: int) -> OccupancyGrid:
    """:func:`coarsen_grid` for ``factor`` >= 2, made anew."""
    pad_rows, pad_cols = _padding(grid, factor)
    occupancy = np.pad(
        np.asarray(grid.occupancy), ((pad_rows, 0), (0, pad_cols)), constant_values=UNKNOWN
    )  # [H', W'], multiples of factor
    h, w = occupancy.shape[0] // factor, occupancy.shape[1] // factor
    blocks = occupancy.reshape(h, factor, w, factor).swapaxes(1, 2)  # [h, w, f, f]
    occupied = (blocks == OCCUPIED).any(axis=(2, 3))  # [h, w]
    free = (blocks == FREE).sum(axis=(2, 3)) * 2 >= factor * factor  # [h, w]
    coarse = np.full((h, w), UNKNOWN, dtype=np.int8)
    coarse[free] = FREE
    coarse[occupied] = OCCUPIED
    resolution = round(grid.resolution * factor, 12)  # 0.1 * 3 -> 0.3, not 0.30000000000000004
    return OccupancyGrid(coarse, resolution, grid.origin, source=grid.source, coarsened_from=grid)


def is_coarsening(grid: OccupancyGrid, fine: OccupancyGrid) -> bool:
    """Whether ``grid`` is :func:`coarsen_grid` of ``fine`` by a whole factor f >= 1, as far as
    the geometry tells: its resolution f times ``fine``'s and its origin ``fine``'s in ``fine``'s
    cells, both within :data:`~spcopyro.maps.grid.MAP_TOLERANCE_CELLS` (the maps' one rule:
    :func:`coarsen_grid` keeps the origin exactly, but the two are compared after a trip through
    yaml files another tool, map_saver's ``%f``, may have written again), and its shape
    ``fine``'s in f x f blocks, padded up. The one check of :func:`free_block_of_map_cells`
    and of the robot's map in Nav2's export (:func:`spcopyro.robot.nav2.check_robot_map`)."""
    factor = round(grid.resolution / fine.resolution)
    return (
        factor >= 1
        and same_resolution(grid.resolution, factor * fine.resolution)
        and same_origin(grid.origin, fine.origin, fine.resolution)
        and tuple(-(-n // factor) for n in fine.shape) == grid.shape
    )


def model_cell_of(grid: OccupancyGrid, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """``(rows [H], cols [W])``: the model-grid row of every map row and column of every map
    column under :func:`coarsen_grid` with ``factor``."""
    pad_rows, _ = _padding(grid, factor)
    return (np.arange(grid.height) + pad_rows) // factor, np.arange(grid.width) // factor


def free_block_of_map_cells(grid: OccupancyGrid) -> np.ndarray:
    """``[H, W]`` of the map ``grid.coarsened_from``: for each free map cell, the free index
    (``grid.free_index``) of the free model cell it belongs to, or, where its block is not free
    (a wall thickened over it), of the free block reached first by growing through the map's
    free cells (:func:`grow_labels`: 4-neighbourhood, never through a wall); -1 off free space
    and where no free block is reached. Raises ValueError for a grid not made by
    :func:`coarsen_grid`.

    Computed once per ``grid`` object and kept on it (read-only): placing a fit's observations
    asks for it once per modality and placement, 13 times in a default fit of a public house
    (a 2000 x 2000-cell map: 0.3 s each)."""
    return _kept_on(grid, "_free_block_of_map_cells", lambda: _free_block_of_map_cells(grid))


def _free_block_of_map_cells(grid: OccupancyGrid) -> np.ndarray:
    """:func:`free_block_of_map_cells`, computed anew (read-only)."""
    fine = grid.coarsened_from
    if fine is None:
        raise ValueError("the grid was not coarsened from a map (grid.coarsened_from is None)")
    if not is_coarsening(grid, fine):
        raise ValueError(
            f"grid ({grid.shape} cells of {grid.resolution} m) is not a coarsening of its "
            f"coarsened_from ({fine.shape} cells of {fine.resolution} m): was it replaced?"
        )
    rows, cols = model_cell_of(fine, round(grid.resolution / fine.resolution))
    index = np.asarray(grid.free_index)[rows[:, None], cols[None, :]]  # [H, W] block's index
    free = np.asarray(fine.free)  # [H, W]
    block = grow_labels(np.where(free, index, -1), free)  # [H, W]
    block.setflags(write=False)  # kept on the grid: no caller may change it
    return block


def grow_labels(labels: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``[H, W]`` labels (>= 0; -1: none yet) grown over ``mask`` by a breadth-first wavefront
    (4-neighbourhood, one cell a step, all labels at once; ties go to the neighbour above,
    below, left, right in that order) until nothing changes. Cells of ``mask`` that no label
    reaches stay -1.

    Each step looks only at the cells labelled the step before (the wavefront) and at their
    unlabelled neighbours in ``mask``: an unlabelled cell next to an older label would have
    been labelled a step earlier. So the whole growth costs about one pass over the map plus
    the cells it labels, not a pass over the map per step (on a 2000 x 2000-cell map with 0.25
    m blocks, tens of steps of 4 x 10^6 cells each took 5-12 s)."""
    labels = np.asarray(labels, dtype=np.int64).copy()  # [H, W]
    mask = np.asarray(mask, dtype=bool)
    h, w = labels.shape
    flat = labels.reshape(-1)  # [H*W] a view: writes land in labels
    open_ = (mask & (labels < 0)).reshape(-1)  # [H*W] bool: may still be labelled
    if not open_.any():
        return labels
    # The first wavefront: the labelled cells next to an open cell (the others label nothing).
    near_open = np.zeros((h, w), dtype=bool)  # [H, W]
    grid_open = open_.reshape(h, w)
    near_open[1:, :] |= grid_open[:-1, :]
    near_open[:-1, :] |= grid_open[1:, :]
    near_open[:, 1:] |= grid_open[:, :-1]
    near_open[:, :-1] |= grid_open[:, 1:]
    front = np.flatnonzero((near_open & (labels >= 0)).reshape(-1))  # [F] flat indices
    last_row = (h - 1) * w
    while front.size:
        col = front % w  # [F]
        reach = np.concatenate(  # [<= 4F] the wavefront's neighbours on the map
            (front[front >= w] - w, front[front < last_row] + w,
             front[col > 0] - 1, front[col < w - 1] + 1)
        )  # fmt: skip
        grow = np.unique(reach[open_[reach]])  # [G] open cells the wavefront reaches
        if not grow.size:
            break
        grow_col = grow % w  # [G]
        new = np.full(grow.size, -1, dtype=np.int64)  # [G] labels before this step's
        sides = ((-w, grow >= w), (w, grow < last_row), (-1, grow_col > 0), (1, grow_col < w - 1))
        for step, valid in sides:  # above, below, left, right: an earlier direction wins ties
            take = valid & (new < 0)
            new[take] = flat[grow[take] + step]
        flat[grow] = new  # every cell of grow has a labelled neighbour: new >= 0
        open_[grow] = False
        front = grow
    return labels


def labels_on_grid(labels: np.ndarray, grid: OccupancyGrid, cell_size: float | None) -> np.ndarray:
    """``[H, W]`` a fit's ``labels`` on ``grid``'s own cells: refined
    (:func:`refine_labels`) from the model grid of ``cell_size`` that the fit ran on where their
    shapes differ, else as they are. How a fit left on its model grid is scored on the map's
    cells (``fit``'s ``ari_map_cells``, a study cell's label map)."""
    if labels.shape != grid.shape:
        labels = refine_labels(labels, grid, coarsening_factor(grid.resolution, cell_size))
    return labels


def refine_labels(labels: np.ndarray, grid: OccupancyGrid, factor: int) -> np.ndarray:
    """``[H, W]`` labels on ``grid`` (the map) from ``[h, w]`` labels on its coarsened grid
    (-1 off free): each free map cell in a labelled block takes the block's label; the others
    (in blocks that hold a wall) take the label that reaches them first by growing through the
    map's free cells (4-neighbourhood, never through a wall), and free cells no label reaches
    the nearest labelled block's. -1 off free."""
    labels = np.asarray(labels)
    if factor == 1:
        return np.where(grid.free, labels, -1)
    if not (labels >= 0).any():
        return np.full(grid.shape, -1, dtype=np.int64)
    rows, cols = model_cell_of(grid, factor)
    free = np.asarray(grid.free)  # [H, W]
    fine = np.where(free, labels[rows[:, None], cols[None, :]], -1).astype(np.int64)  # [H, W]
    fine = grow_labels(fine, free)  # through free map cells, never through a wall
    unreached = free & (fine < 0)  # [H, W]: free cells cut off from every labelled block
    if not unreached.any():
        return fine
    from scipy import ndimage  # here, not on the fit's import path

    nearest = ndimage.distance_transform_edt(
        labels < 0, return_distances=False, return_indices=True
    )  # [2, h, w]
    filled = labels[nearest[0], nearest[1]][rows[:, None], cols[None, :]]  # [H, W]
    return np.where(unreached, filled, fine).astype(np.int64)


def coarsen_labels(
    labels: np.ndarray, grid: OccupancyGrid, factor: int, *, fill: bool = True
) -> np.ndarray:
    """``[h, w]`` labels on :func:`coarsen_grid` ``(grid, factor)`` from ``[H, W]`` labels on the
    map ``grid`` (-1: none): each free model cell's most frequent label among its map cells'
    (the smallest on ties); -1 off free. A free model cell none of whose map cells is labelled
    takes the nearest labelled one's (:func:`grow_labels`) with ``fill``, else stays -1 (a
    truth's unnamed cells). The inverse direction of :func:`refine_labels`."""
    labels = np.asarray(labels, dtype=np.int64)  # [H, W]
    coarse_free = np.asarray(coarsen_grid(grid, factor).free)  # [h, w]
    rows, cols = model_cell_of(grid, factor)
    labelled = labels >= 0
    block = rows[:, None] * coarse_free.shape[1] + cols[None, :]  # [H, W] model cell id
    count = int(labels.max()) + 1 if labelled.any() else 1
    votes = np.zeros((coarse_free.size, count), dtype=np.int64)  # [h*w, K]
    np.add.at(votes, (block[labelled], labels[labelled]), 1)
    best = np.where(votes.any(axis=1), votes.argmax(axis=1), -1).reshape(coarse_free.shape)
    best = np.where(coarse_free, best, -1).astype(np.int64)
    return grow_labels(best, coarse_free) if fill else best
