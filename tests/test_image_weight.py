"""The two-stage image weight (spcopyro.fit.image_weight): the statistic against Dirichlet draws
of known concentration, the rule, the images' concepts and the two-stage fit's wiring."""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import pytest

from spcopyro.config import preset
from spcopyro.fit.image_weight import (
    HIGH,
    LOW,
    TOP,
    fit_two_stage,
    image_labels,
    image_separation,
    image_weight,
)
from spcopyro.synthetic import HouseSpec, make_house

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def dirichlet_images(rng, groups: int, per_group: int, kappa: float, classes: int = 10):
    """``[G * n, K]`` histograms ``f ~ Dir(kappa phi_g)`` around ``G`` random means, and ``[G * n]``
    their groups."""
    means = rng.dirichlet(np.ones(classes), size=groups)  # [G, K]
    features = np.concatenate([rng.dirichlet(kappa * m, size=per_group) for m in means])
    return features, np.repeat(np.arange(groups), per_group)


def test_separation_recovers_the_concentration_and_the_explained_share():
    """Within groups the moment estimate is the generator's kappa; the explained share is about
    ``1 - (kappa_whole + 1) / (kappa_within + 1)`` (exactly so were the groups' means as pure as
    the whole house's, ``||phi_g|| = ||phi||``)."""
    rng = np.random.default_rng(0)
    features, groups = dirichlet_images(rng, groups=6, per_group=800, kappa=30.0)
    s = image_separation(features, groups)
    assert s.kappa_within == pytest.approx(30.0, rel=0.1)
    assert s.kappa_whole < 15.0
    assert s.explained == pytest.approx(1 - (s.kappa_whole + 1) / (s.kappa_within + 1), abs=0.05)
    assert s.images == 4800 and s.concepts == 6


def test_labels_that_do_not_follow_the_images_explain_nothing():
    """Concepts drawn independently of the images (and 1,000 speck concepts of one image
    each, which explain their own image by construction) give about 0 after the adjustment."""
    rng = np.random.default_rng(1)
    features, groups = dirichlet_images(rng, groups=6, per_group=400, kappa=30.0)
    shuffled = rng.permutation(groups)
    assert abs(image_separation(features, shuffled).explained) < 0.02
    specks = np.full(groups.size, 5000)  # 1,000 random images alone, the rest in one concept
    alone = rng.choice(groups.size, size=1000, replace=False)
    specks[alone] = np.arange(1000)
    assert abs(image_separation(features, specks).explained) < 0.1
    true = image_separation(features, groups).explained
    assert true > 0.5


def test_unlabelled_images_are_left_out_and_too_few_images_give_zero():
    rng = np.random.default_rng(2)
    features, groups = dirichlet_images(rng, groups=3, per_group=50, kappa=30.0)
    labels = groups.copy()
    labels[:50] = -1
    s = image_separation(features, labels)
    assert s.images == 100 and s.concepts == 2
    assert image_separation(features[:2], np.array([0, 1])).explained == 0.0


def test_weight_rule():
    assert image_weight(0.0) == 1.0 and image_weight(LOW) == 1.0
    assert image_weight(HIGH) == pytest.approx(TOP) and image_weight(0.95) == pytest.approx(TOP)
    assert image_weight((LOW + HIGH) / 2) == pytest.approx(math.sqrt(TOP))
    with pytest.raises(ValueError, match="low must be below high"):
        image_weight(0.5, low=0.6, high=0.4)


@pytest.fixture(scope="module")
def two_stage_fit():
    house = make_house(seed=1, spec=HouseSpec(height=36, width=44, num_rooms=3, num_open_plan=1))
    logging.disable(logging.WARNING)
    try:
        fit = fit_two_stage(house, preset("coarse"), first_sweeps=20, second_sweeps=10, seed=3,
                            init="rooms", progress=False)  # fmt: skip
    finally:
        logging.disable(logging.NOTSET)
    return house, fit


def test_images_take_the_concept_of_their_model_cell(two_stage_fit):
    house, fit = two_stage_fit
    labels = image_labels(fit.first, house)  # [T]
    cells = fit.first.grid.world_to_cell(house.observations.image_xy)  # [T, 2]
    image = fit.first.label_image()
    for t in range(0, labels.size, 7):
        row, col = cells[t]
        if fit.first.grid.free[row, col]:  # on free space: that cell's concept
            assert labels[t] == image[row, col]
    assert (labels >= 0).mean() > 0.9  # images are taken on free space


def test_an_image_just_off_free_space_takes_the_concept_the_fit_snapped_it_to(two_stage_fit):
    """As the fit places it (eq. 11 with the snap distance), not -1 for the wall cell: every
    image moved onto a wall cell with one free 4-neighbour takes that neighbour's concept."""
    house, fit = two_stage_fit
    grid = fit.first.grid  # 0.3 m cells, the fit's snap distance 0.25 m
    free = np.pad(grid.free, 1)  # [h + 2, w + 2]
    neighbours = free[:-2, 1:-1] + free[2:, 1:-1] + free[1:-1, :-2] + free[1:-1, 2:]  # [h, w]
    row, col = np.argwhere(~grid.free & (neighbours == 1))[0]
    steps = [(-1, 0), (1, 0), (0, -1), (0, 1)]
    ((dr, dc),) = [(dr, dc) for dr, dc in steps if free[row + 1 + dr, col + 1 + dc]]
    xy = grid.cell_to_world(np.array([[row, col]]))  # [1, 2] the wall cell's centre
    observations = dataclasses.replace(
        house.observations, image_xy=np.repeat(xy, house.observations.num_images, axis=0)
    )
    moved = dataclasses.replace(house, observations=observations)
    labels = image_labels(fit.first, moved)  # 0.15 m from the free neighbour's square
    assert (labels == fit.first.label_image()[row + dr, col + dc]).all() and labels[0] >= 0


def test_two_stage_refits_with_the_rule_s_weight_from_the_first_fit(two_stage_fit):
    house, fit = two_stage_fit
    assert fit.first.preparation.feature_scaling == "probability"
    separation = image_separation(house.observations.image_features, image_labels(fit.first, house))
    assert fit.separation == separation
    assert fit.weight == pytest.approx(image_weight(separation.explained))
    assert fit.result.preparation.feature_scaling == pytest.approx(fit.weight)
    assert fit.result.inference["init"] == "result of gibbs"  # warm start from the first fit
    assert fit.result.grid.shape == fit.first.grid.shape  # both on the model grid
