"""Growing labels through the map's free cells, once per grid (helper 227).

On a drawn 2000 x 2000-cell warehouse map at 0.05 m (3.07 million free cells, 0.25 m model
cells; ``spcopyro fit --sweeps 50``) a fit printed nothing for 83 s at its start: placing the
observations asked for :func:`~spcopyro.maps.coarse.free_block_of_map_cells` once per modality
and placement, each 4.9-12.7 s, all in :func:`~spcopyro.maps.coarse.grow_labels`, whose every
step went over the whole map. It now steps over the wavefront only (same labels), and the block
map is computed once per coarse grid and kept on it; ``coarsen_grid`` gives a fit's second ask
for its model grid the same grid.
"""

from __future__ import annotations

import dataclasses
import gc
import pickle
import weakref

import numpy as np
import pytest

import spcopyro.maps.coarse as coarse
from spcopyro.data import load_house
from spcopyro.maps.coarse import (
    coarsen_grid,
    free_block_of_map_cells,
    grow_labels,
    model_cell_of,
    refine_labels,
)
from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

HOUSES = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


def reference_grow(labels: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The wavefront as it was written before: a pass over the whole map per step."""
    labels = np.asarray(labels, dtype=np.int64).copy()  # [H, W]
    mask = np.asarray(mask, dtype=bool)
    h, w = labels.shape
    padded = np.full((h + 2, w + 2), -1, dtype=np.int64)
    while True:
        padded[1:-1, 1:-1] = labels
        candidate = np.full_like(labels, -1)  # [H, W]
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            shifted = padded[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]  # [H, W]
            candidate = np.where(candidate < 0, shifted, candidate)
        grow = mask & (labels < 0) & (candidate >= 0)  # [H, W]
        if not grow.any():
            return labels
        labels[grow] = candidate[grow]


def reference_free_block(grid: OccupancyGrid) -> np.ndarray:
    """free_block_of_map_cells as it was computed before, with the reference wavefront."""
    fine = grid.coarsened_from
    rows, cols = model_cell_of(fine, round(grid.resolution / fine.resolution))
    index = np.asarray(grid.free_index)[rows[:, None], cols[None, :]]  # [H, W]
    return reference_grow(np.where(fine.free, index, -1), fine.free)


def reference_refine(labels: np.ndarray, grid: OccupancyGrid, factor: int) -> np.ndarray:
    """refine_labels as it was computed before, with the reference wavefront."""
    from scipy import ndimage

    rows, cols = model_cell_of(grid, factor)
    fine = reference_grow(np.where(grid.free, labels[rows[:, None], cols[None, :]], -1), grid.free)
    nearest = ndimage.distance_transform_edt(
        labels < 0, return_distances=False, return_indices=True
    )  # [2, h, w]
    filled = labels[nearest[0], nearest[1]][rows[:, None], cols[None, :]]  # [H, W]
    return np.where(grid.free & (fine < 0), filled, fine)


def test_grow_labels_gives_the_labels_of_the_whole_map_wavefront():
    """Random masks and seeds, labels inside and outside the mask, one-row, one-column, empty
    and unseeded maps: the same labels (ties: above, below, left, right) and dtype."""
    rng = np.random.default_rng(11)
    shapes = [(1, 1), (1, 17), (17, 1), (0, 5), (5, 0), (2, 2), (31, 7)]
    shapes += [tuple(rng.integers(1, 30, 2)) for _ in range(400)]
    for h, w in shapes:
        mask = rng.random((h, w)) < rng.uniform(0.3, 1.0)
        seeds = rng.random((h, w)) < rng.uniform(0.0, 0.2)
        labels = np.where(seeds, rng.integers(0, 6, (h, w)), -1)
        if rng.random() < 0.5:
            labels = np.where(mask, labels, -1)
        grown = grow_labels(labels, mask)
        assert grown.dtype == np.int64
        np.testing.assert_array_equal(grown, reference_grow(labels, mask), err_msg=f"{h}x{w}")


def test_grow_labels_steps_over_the_wavefront_not_the_whole_map():
    """One seed in the corner of a 600 x 600 free square: 1200 steps. A pass over the whole map
    per step took 6-15 s (a 2-core machine, quiet and loaded); the wavefront's 0.3 s. No timing
    is asserted (these machines are shared): each step may look only at the cells the step
    before labelled (the wavefront) and their neighbours, so the cells reached over the whole
    growth stay within four times the map's, where a pass per step looks at 1200 maps' worth."""
    labels = np.full((600, 600), -1)
    labels[0, 0] = 3
    mask = np.ones((600, 600), dtype=bool)
    reached = []  # [steps] the size of each step's reach: 4 x its wavefront at most
    concatenate = np.concatenate

    def counting_concatenate(*args, **kwargs):
        out = concatenate(*args, **kwargs)
        reached.append(out.size)
        return out

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(coarse.np, "concatenate", counting_concatenate)
        grown = grow_labels(labels, mask)
    assert (grown == 3).all()
    assert len(reached) >= 1000  # one step a wavefront: the growth ran step by step
    # every cell is in the wavefront once: its four neighbours; a front of every labelled cell
    # (a pass over what is labelled each step) reaches ~1200 / 3 maps' worth
    assert sum(reached) <= 4 * mask.size, f"{sum(reached)} cells reached"


def _odd_maps() -> list[OccupancyGrid]:
    """Shapes that are no multiple of the block, walls one cell thick inside blocks, pockets of
    free cells walled off from every free block, unknown cells."""
    rng = np.random.default_rng(5)
    maps = []
    for h, w in ((23, 41), (40, 9), (1, 30), (57, 57)):
        occ = np.where(rng.random((h, w)) < 0.9, FREE, UNKNOWN).astype(np.int8)
        occ[:, w // 3] = OCCUPIED  # a wall down the map, a door in it
        occ[h // 2, w // 3] = FREE
        if h > 6 and w > 6:
            occ[1:4, -4:-1] = OCCUPIED  # a walled pocket of one free cell
            occ[2, -3] = FREE
        maps.append(OccupancyGrid(occ, 0.05, (1.0, -2.0, 0.0)))
    return maps


@pytest.mark.parametrize("factor", [2, 3, 5])
def test_free_block_of_map_cells_is_what_it_was_on_odd_maps(factor):
    for grid in _odd_maps():
        model = coarsen_grid(grid, factor)
        block = free_block_of_map_cells(model)
        np.testing.assert_array_equal(block, reference_free_block(model))
        assert block.dtype == np.int64 and not block.flags.writeable


@pytest.mark.dataset
@pytest.mark.parametrize("name", HOUSES)
def test_free_block_and_refined_labels_are_what_they_were_on_the_public_houses(dataset_root, name):
    grid = load_house(dataset_root / name).grid
    rng = np.random.default_rng(0)
    for factor in (3, 5):  # 0.15 m and the default 0.25 m model cells of the 0.05 m maps
        model = coarsen_grid(grid, factor)
        np.testing.assert_array_equal(free_block_of_map_cells(model), reference_free_block(model))
        labels = np.where(model.free, rng.integers(0, 8, model.shape), -1)  # [h, w]
        np.testing.assert_array_equal(
            refine_labels(labels, grid, factor), reference_refine(labels, grid, factor)
        )


def test_the_block_map_is_computed_once_per_coarse_grid(monkeypatch):
    """Asked again, the block map is the one kept on the grid; a grid made anew computes its
    own; the map gives the same coarse grid while it is alive, and keeps it no longer."""
    grid = _odd_maps()[0]
    checks = []
    check = coarse.is_coarsening  # the computation's first step
    monkeypatch.setattr(coarse, "is_coarsening", lambda *a: checks.append(1) or check(*a))
    model = coarsen_grid(grid, 3)
    assert coarsen_grid(grid, 3) is model
    first = free_block_of_map_cells(model)
    assert free_block_of_map_cells(coarsen_grid(grid, 3)) is first
    assert len(checks) == 1
    free_block_of_map_cells(dataclasses.replace(model))
    assert len(checks) == 2
    kept = weakref.ref(model)
    del model, first
    gc.collect()
    assert kept() is None  # the map holds its coarse grids weakly: nothing outlives a fit
    free_block_of_map_cells(coarsen_grid(grid, 3))  # made anew, so its block map is too
    assert len(checks) == 3


def test_a_grid_with_what_is_kept_on_it_pickles_without_it():
    """The coarse grids (held weakly) and the block map are left out of a pickle: a weak
    dictionary does not pickle, and the block map is as large as the map."""
    grid = _odd_maps()[3]
    model = coarsen_grid(grid, 3)
    block = free_block_of_map_cells(model)
    back = pickle.loads(pickle.dumps(model))
    assert back == model and back.coarsened_from == grid
    assert not any(key.startswith("_") for key in back.__dict__)
    assert not any(key.startswith("_") for key in back.coarsened_from.__dict__)
    np.testing.assert_array_equal(free_block_of_map_cells(back), block)


def test_a_pickled_grid_s_arrays_stay_read_only():
    """A pickle gave the cells back writeable, beside ``free`` and ``free_index`` kept from
    before: a write to the cells would have left those describing other cells."""
    grid = _odd_maps()[3]
    kept = (grid.free, grid.free_index, grid.free_cells)  # cached, so pickled with the grid
    back = pickle.loads(pickle.dumps(coarsen_grid(grid, 3))).coarsened_from
    assert back == grid and {"free", "free_index", "free_cells"} <= set(back.__dict__)
    for name, array in zip(("free", "free_index", "free_cells"), kept, strict=True):
        np.testing.assert_array_equal(back.__dict__[name], array)
    for name in ("occupancy", "free", "free_index", "free_cells"):
        array = back.__dict__[name]
        assert not array.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            array[0, 0] = array[0, 0]


@pytest.mark.dataset
def test_a_fit_computes_the_block_map_once(dataset_root, tmp_path, monkeypatch):
    """``spcopyro fit`` on a public house at its default 0.25 m model cells asks for the block
    map each time it places observations (13 times); it was computed each time."""
    from spcopyro.cli.main import main

    asks, checks = [], []
    ask, check = coarse.free_block_of_map_cells, coarse.is_coarsening
    monkeypatch.setattr(coarse, "free_block_of_map_cells", lambda g: asks.append(1) or ask(g))
    monkeypatch.setattr(coarse, "is_coarsening", lambda *a: checks.append(1) or check(*a))
    monkeypatch.setenv("CI", "1")  # no bars
    out = tmp_path / "fit"
    assert main(["fit", str(dataset_root / "room1dk5"), "--sweeps", "3", "--out", str(out)]) == 0
    assert len(asks) > 1
    assert len(checks) == 1
