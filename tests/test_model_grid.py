"""The model's grid (``cell_size``), word scaling and the public houses' region truth (issue 21)."""

from __future__ import annotations

import numpy as np
import pytest

from spcopyro.config import DataPreparation, preset
from spcopyro.data import cell_counts, find_dataset_root, load_house
from spcopyro.data.model_grid import model_house
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.maps.coarse import (
    coarsen_grid,
    coarsen_labels,
    coarsening_factor,
    model_cell_of,
    refine_labels,
)
from spcopyro.synthetic import HouseSpec, make_house


def _two_rooms() -> OccupancyGrid:
    """9 x 10 cells at 0.05 m: two rooms split by a one-cell wall at column 4 with a door."""
    occ = np.full((9, 10), FREE, dtype=np.int8)
    occ[:, 4] = OCCUPIED
    occ[4, 4] = FREE  # the door
    return OccupancyGrid(occ, 0.05, (-1.0, -2.0, 0.0))


def test_coarsening_factor_rounds_and_is_at_least_one():
    assert coarsening_factor(0.05, None) == 1
    assert coarsening_factor(0.05, 0.25) == 5
    assert coarsening_factor(0.1, 0.25) == 3  # 2.5 rounds up
    assert coarsening_factor(0.5, 0.25) == 1
    with pytest.raises(ValueError, match="cell_size"):
        coarsening_factor(0.05, -1.0)


def test_coarse_grid_keeps_walls_origin_and_world_positions():
    grid = _two_rooms()
    coarse = coarsen_grid(grid, 2)
    assert coarse.resolution == 0.1 and coarse.origin == grid.origin
    assert coarse.shape == (5, 5)  # 9 rows padded on top to 10, 10 columns
    # Every block holding a wall cell is occupied: the wall is never lost.
    rows, cols = model_cell_of(grid, 2)
    wall = np.asarray(grid.occupancy) == OCCUPIED
    assert np.all(np.asarray(coarse.occupancy)[rows[:, None], cols[None, :]][wall] == OCCUPIED)
    # The padded top row's blocks hold 2 free map cells of 4: free (at least half), but the
    # wall's column stays occupied.
    assert list(np.asarray(coarse.occupancy)[0]) == [FREE, FREE, OCCUPIED, FREE, FREE]
    # A world point lands in the model cell that holds its map cell.
    xy = grid.cell_to_world(grid.free_cells)  # [N, 2] centres
    fine = grid.world_to_cell(xy)
    assert np.array_equal(
        coarse.world_to_cell(xy), np.stack([rows[fine[:, 0]], cols[fine[:, 1]]], 1)
    )


def test_observations_go_on_the_model_grid_as_the_map_places_them():
    """A position on the map's free space inside a block that a wall thickened over takes the
    free block its map cell reaches through the map's free cells -- the room it was taken in,
    never across the wall, and never lost -- where the model grid's own snapping would take the
    nearer block across the wall, or none within a small snap distance."""
    from spcopyro.data import place_observations
    from spcopyro.maps.coarse import free_block_of_map_cells

    occ = np.full((3, 9), FREE, dtype=np.int8)  # 0.1 m cells; blocks of 3: cols 0-2, 3-5, 6-8
    occ[:, 5] = OCCUPIED  # a thin wall in the middle block, 0.1 m right of centre
    grid = OccupancyGrid(occ, 0.1, (0.0, 0.0, 0.0))
    coarse = coarsen_grid(grid, 3)
    np.testing.assert_array_equal(coarse.free[0], [True, False, True])
    assert coarse.coarsened_from is grid
    assert coarse == OccupancyGrid(coarse.occupancy, 0.3, (0.0, 0.0, 0.0))  # not in equality
    np.testing.assert_array_equal(free_block_of_map_cells(coarse)[1], [0, 0, 0, 0, 0, -1, 1, 1, 1])
    xy = [[0.48, 0.15], [0.62, 0.15], [0.55, 0.15], [0.15, 0.15]]  # left of the wall (in the
    # wall's block), right of it (in a free block), on the wall (0.05 m from free map cells on
    # both sides), in a free block
    index, snapped, unplaced = place_observations(coarse, xy, snap_distance=0.25)
    np.testing.assert_array_equal(index[[0, 1, 3]], [0, 1, 0])
    assert index[2] in (0, 1)  # on the wall: a tie between the map cells on its two sides
    np.testing.assert_array_equal(snapped, [True, False, True, False])
    # The model grid alone: the first point's nearest free square is across the wall (0.12 m
    # against 0.18 m), and at 0.1 m of snap none is near enough.
    alone = OccupancyGrid(coarse.occupancy, 0.3, (0.0, 0.0, 0.0))
    assert place_observations(alone, xy[:1], 0.25)[0][0] == 1
    assert place_observations(alone, xy[:1], 0.1)[2][0]
    index, _, unplaced = place_observations(coarse, xy[:2], snap_distance=0.1)
    np.testing.assert_array_equal(index, [0, 1])
    assert not unplaced.any()
    # A grid whose cells were replaced no longer matches the map it keeps: a named error.
    import dataclasses

    replaced = dataclasses.replace(coarse, occupancy=np.full((2, 2), FREE, dtype=np.int8))
    with pytest.raises(ValueError, match="not a coarsening of its coarsened_from"):
        place_observations(replaced, [[0.65, 0.15]], snap_distance=0.25)  # off its cells


@pytest.mark.dataset
def test_the_public_houses_model_grids_keep_what_their_maps_place(dataset_root, caplog):
    """Before placement went through the map, room1dk5's 0.25 m model grid lost 6 images and
    room1ldk4's 3 images and a word that the map places; now only room1ldk4's 2 images and 1
    word remain out: the map snaps them into a pocket of 40 free cells inside a wall band, which
    reaches no free model cell."""
    for name, lost in (("room1dk5", (0, 0)), ("room1ldk4", (2, 1)), ("room2ldk4", (0, 0))):
        house = load_house(dataset_root / name)
        report = cell_counts(model_house(house, 0.25).grid, house.observations).placement
        assert (report.images_unplaced, report.words_unplaced) == lost, name
    # the warning says why on a model grid: the map places them, no free model cell is reached
    assert "in free space that reaches no free 0.25 m model cell" in caplog.text


def test_refine_labels_gives_every_free_map_cell_a_label():
    grid = _two_rooms()
    coarse = coarsen_grid(grid, 2)
    labels = np.where(
        coarse.free, np.arange(coarse.height * coarse.width).reshape(coarse.shape), -1
    )
    fine = refine_labels(labels, grid, 2)
    assert np.all(fine[grid.free] >= 0) and np.all(fine[~grid.free] == -1)
    rows, cols = model_cell_of(grid, 2)
    block = labels[rows[:, None], cols[None, :]]
    keep = grid.free & (block >= 0)
    assert np.array_equal(fine[keep], block[keep])  # a free block's cells keep its label


def test_coarsen_labels_takes_each_model_cells_majority_and_refine_labels_inverts_it():
    grid = _two_rooms()  # 9 x 10 -> 5 x 5 model cells (one padding row on top)
    labels = np.where(grid.free, 0, -1)
    labels[:, 5:] = np.where(grid.free[:, 5:], 1, -1)  # the right room
    labels[8, 0] = 2  # one map cell of a block of four: outvoted
    coarse = coarsen_labels(labels, grid, 2)
    free = coarsen_grid(grid, 2).free
    assert np.all(coarse[~free] == -1) and np.all(coarse[free] >= 0)
    assert 2 not in coarse
    np.testing.assert_array_equal(refine_labels(coarse, grid, 2)[grid.free & (labels != 2)],
                                  labels[grid.free & (labels != 2)])  # fmt: skip
    # Unlabelled map cells: filled from the nearest labelled model cell through free model
    # cells (the left room here; the right one, behind the wall, is reached by none), or -1
    # without fill.
    some = np.where(np.arange(10)[None, :] < 2, labels, -1)
    left = free & (np.arange(5)[None, :] < 2)
    filled = coarsen_labels(some, grid, 2)
    assert np.all(filled[left] >= 0) and np.all(filled[free & ~left] == -1)
    assert (coarsen_labels(some, grid, 2, fill=False)[left] == -1).any()


def test_a_fit_on_the_maps_cells_starts_a_fit_on_the_model_grid():
    """`fit --init-from OUT` of a refined fit (the default on the embedded house: the map's
    0.1 m cells) into a fit on the 0.3 m model grid was refused as another map."""
    from spcopyro.fit.house import fit_house
    from spcopyro.fit.starts import result_labels

    house = make_house(seed=0, spec=HouseSpec(height=30, width=36, num_rooms=2))
    fine = fit_house(house, preset("coarse").replace(cell_size=None), sweeps=3,
                     progress=False)  # fmt: skip
    assert fine.grid.shape == house.grid.shape
    coarse_house = model_house(house, 0.25)
    start = result_labels(fine, coarse_house, preset("coarse").model)  # [n]
    expected = coarsen_labels(fine.label_image(), house.grid, 3)
    cells = np.asarray(coarse_house.grid.free_cells)
    np.testing.assert_array_equal(start.numpy(), expected[cells[:, 0], cells[:, 1]])
    fit_house(house, preset("coarse"), init=fine, sweeps=2, progress=False, refine="never")


def test_model_house_is_idempotent_and_coarsens_the_truth():
    house = make_house(seed=0, spec=HouseSpec())
    assert model_house(house, None) is house
    coarse = model_house(house, 0.25)
    assert coarse.grid.resolution == pytest.approx(0.3)
    assert model_house(coarse, 0.25) is coarse
    assert coarse.truth.shape == coarse.grid.shape
    assert np.all(coarse.truth[~coarse.grid.free] == -1)
    assert set(np.unique(coarse.truth[coarse.grid.free])) <= set(range(len(house.category_names)))
    assert coarse.observations is house.observations


def test_a_map_too_thin_for_model_cells_keeps_its_own_cells_and_says_so_once(caplog):
    """A corridor one map cell wide leaves no free 0.3 m cell: the house keeps the map's own
    cells, with one warning however often a fit asks for its model grid (it was printed twice,
    once by the command and once by the refinement's check)."""
    import dataclasses

    house = make_house(seed=0, spec=HouseSpec())
    occupancy = np.full(house.grid.shape, OCCUPIED, dtype=house.grid.occupancy.dtype)
    occupancy[5, 2:40] = FREE  # [H, W] one row of free cells
    thin = dataclasses.replace(house, name="thin", truth=None,
                               grid=OccupancyGrid(occupancy, house.grid.resolution,
                                                  house.grid.origin))  # fmt: skip
    for _ in range(3):
        assert model_house(thin, 0.25) is thin
    said = [r for r in caplog.records if "leave no free cell" in r.getMessage()]
    assert len(said) == 1


def test_cells_finer_than_the_map_are_the_maps_own_and_said_so(caplog):
    house = make_house(seed=0, spec=HouseSpec())
    assert model_house(house, 0.01) is house and model_house(house, 0.01) is house
    said = [r.getMessage() for r in caplog.records if "are finer than map" in r.getMessage()]
    assert len(said) == 1 and "cells of 0.01 m" in said[0]
    caplog.clear()
    assert model_house(house, 0.12) is house  # rounds to the map's 0.1 m: nothing to say
    assert not [r for r in caplog.records if "finer than map" in r.getMessage()]


def test_word_scaling_multiplies_word_counts_only():
    house = make_house(seed=1, spec=HouseSpec())
    plain = cell_counts(house.grid, house.observations)
    scaled = cell_counts(house.grid, house.observations, word_scaling=10.0)
    np.testing.assert_allclose(scaled.word_counts, 10.0 * plain.word_counts)
    np.testing.assert_array_equal(scaled.image_counts, plain.image_counts)
    with pytest.raises(ValueError, match="word_scaling"):
        DataPreparation(word_scaling=0.0)
    with pytest.raises(ValueError, match="cell_size"):
        DataPreparation(cell_size=float("nan"))


def test_cell_size_map_over_a_preset_means_the_maps_own_cells():
    assert preset("coarse").data.cell_size == 0.25
    assert preset("coarse", cell_size="map").data.cell_size is None


def test_default_fit_on_the_model_grid_scores_against_the_truth():
    from spcopyro.fit.house import fit_house
    from spcopyro.gibbs import GibbsOptions
    from spcopyro.metrics import adjusted_rand_index

    house = make_house(seed=0, spec=HouseSpec())
    result = fit_house(house, preset(), options=GibbsOptions(merge_moves=0.2, region_moves=0.2),
                       sweeps=300,
                       init="rooms", progress=False, marginal_samples=50,
                       point_estimate="vi")  # fmt: skip
    assert result.grid.resolution == pytest.approx(0.3)
    fine = refine_labels(result.label_image(), house.grid, 3)
    assert adjusted_rand_index(fine, house.truth) > 0.8


@pytest.mark.dataset
def test_public_truth_has_a_category_per_place_word_and_labels_every_reached_cell():
    from spcopyro.experiments.public_truth import PLACE_CATEGORIES, public_truth

    root = find_dataset_root()
    if root is None:
        pytest.skip("public dataset not found ($SPCOPYRO_DATA or ../shared/data/spcomapping)")
    house = load_house(root / "room1ldk4")
    truth = public_truth(house)
    words = {tokens[-1] for tokens in house.observations.utterances}
    said = {PLACE_CATEGORIES[w] for w in words if w in PLACE_CATEGORIES}
    assert set(truth.categories) | set(truth.vanished) == said
    # 'shower' was said only at the two spots where 'washroom' was said twice each: it has no
    # cell, so it is no category (it was one without cells: matching_rate refused the truth)
    assert truth.vanished == ("shower",) and "shower" not in truth.categories
    assert truth.category_of_word("shower") is None
    cells = np.bincount(truth.labels[truth.labels >= 0], minlength=len(truth.categories))
    assert cells.size == len(truth.categories) and np.all(cells > 0), cells
    from spcopyro.metrics import matching_rate

    everywhere = matching_rate(lambda word: house.grid.free, truth.labels, truth.categories)
    assert 0 < everywhere.value < 1
    assert np.all(truth.labels[~house.grid.free] == -1)
    assert (truth.labels[house.grid.free] >= 0).mean() > 0.99
    assert 0 < len(truth.strays) < truth.num_place_utterances / 4
    # The same evidence gives the same truth (a reproducible method).
    np.testing.assert_array_equal(public_truth(house).labels, truth.labels)


def test_gibbs_conditionals_on_the_model_grid_equal_the_pyro_models_density_differences():
    """The default's model (0.3 m model cells on the 0.1 m house, words x10 over a 0.75 m
    footprint, images as probabilities) is the Pyro model on the coarse grid's counts: the
    sampler's enumerated conditionals (eq. 13) equal the model's log-density differences."""
    import torch
    from statistical_checks import assert_conditionals_match_model

    from spcopyro.fit.house import prepare_model_data
    from spcopyro.gibbs.sampler import init

    settings = preset(num_concepts=4)
    house = model_house(make_house(seed=2, spec=HouseSpec()), settings.data.cell_size)
    _, data = prepare_model_data(house, settings)
    state = init(data, settings.model, torch.Generator().manual_seed(0))
    rng = np.random.default_rng(0)
    cells = np.sort(rng.choice(data.obs_cells.numpy(), 6, replace=False))
    assert_conditionals_match_model(state, data, settings.model, torch.as_tensor(cells))


def test_fit_init_from_a_coarse_fits_folder_starts_a_fit_on_the_maps_cells(tmp_path, capsys):
    """`fit --init-from OUT` of a coarse fit (the default: the 0.3 m model grid) into a fit on
    the map's own cells: the loaded result's grid did not know the map it was coarsened from
    (robot_map.yaml), so its labels were refused as another map's instead of refined."""
    from spcopyro.cli.main import main

    coarse, fine = tmp_path / "coarse", tmp_path / "fine"
    args = ["fit", "--sweeps", "2", "--no-figures", "--method", "cavi"]
    assert main([*args, "--out", str(coarse)]) == 0
    capsys.readouterr()
    assert main([*args, "--out", str(fine), "--cell-size", "map", "--init-from", str(coarse)]) == 0
    assert "starting from    the cavi fit" in capsys.readouterr().out
    assert np.load(coarse / "labels.npy").shape == (20, 27)  # the 0.3 m model grid
    assert np.load(fine / "labels.npy").shape == (60, 80)  # the map's 0.1 m cells


def test_prepare_model_data_on_the_maps_cells_with_a_cell_size_names_model_house(tmp_path, caplog):
    """A library caller's prepare_model_data(house, preset("coarse")) fitted the map's own
    cells without a word: only fit_house applies model_house for the cell size. It warns now;
    fit_house and `spcopyro fit` (model_house first) do not."""
    from spcopyro.cli.main import main
    from spcopyro.fit.house import fit_house, prepare_model_data

    said = "prepare_model_data fits the cells it is given"
    house = make_house(seed=0, spec=HouseSpec(height=30, width=36, num_rooms=2))
    caplog.set_level("WARNING", logger="spcopyro")
    _, data = prepare_model_data(house, preset("coarse"))
    assert data.num_free == house.grid.num_free  # the map's own cells, as it says
    warned = [r.getMessage() for r in caplog.records if said in r.getMessage()]
    assert len(warned) == 1
    assert "settings cell_size 0.25 m" in warned[0] and "own 0.1 m cells" in warned[0]
    assert "model_house(house, settings.data.cell_size) (spcopyro.data.model_grid)" in warned[0]
    caplog.clear()
    prepare_model_data(model_house(house, 0.25), preset("coarse"))  # the model's grid
    prepare_model_data(house, preset("coarse", cell_size="map"))  # the map's cells asked for
    fit_house(house, preset("coarse"), sweeps=2, progress=False)
    assert main(["fit", "--sweeps", "2", "--no-figures", "--out", str(tmp_path / "fit")]) == 0
    assert not [r for r in caplog.records if said in r.getMessage()]
