"""Open-plan synthetic houses (issue 21, item 1): HouseSpec.open_plan, categories_per_open_plan
and open_plan_share, where cutting the map at its doors cannot reach the truth."""

from __future__ import annotations

import numpy as np
import pytest

from spcopyro.baselines.geometry import geometry_semantic_map, room_segments
from spcopyro.baselines.nearest import nearest_word_map
from spcopyro.cli.main import main
from spcopyro.data import load_house
from spcopyro.experiments.ablation import SYNTHETIC_HOUSES, AblationSettings
from spcopyro.experiments.open_plan import (
    categories_in_segments,
    observation_oracle,
    open_plan_scores,
)
from spcopyro.metrics import adjusted_rand_index
from spcopyro.study.ablation import ablation_study, spec_options
from spcopyro.synthetic import HouseSpec, HouseSpecError, make_house
from spcopyro.synthetic.floor_plan import floor_plan

OPEN_PLAN = HouseSpec.open_plan()


@pytest.fixture(scope="module")
def house():
    return make_house(seed=0, spec=OPEN_PLAN, name="open-plan")


def test_the_spec_is_public_like_with_a_three_category_open_plan():
    public = HouseSpec.public_like()
    assert (OPEN_PLAN.height, OPEN_PLAN.width, OPEN_PLAN.resolution) == (160, 165, 0.05)
    assert OPEN_PLAN.revisit_waypoints and OPEN_PLAN.waypoint_radius == public.waypoint_radius
    assert OPEN_PLAN.num_rooms == 4 and OPEN_PLAN.num_open_plan == 1
    assert OPEN_PLAN.categories_per_open_plan == 3 and OPEN_PLAN.open_plan_share == 0.65
    assert OPEN_PLAN.num_regions == 6  # 3 walled rooms + living, dining, kitchen
    assert HouseSpec.open_plan(categories_per_open_plan=4, num_open_plan=2).num_regions == 10
    # The default stays two categories per open plan and the largest rooms.
    assert HouseSpec().categories_per_open_plan == 2 and HouseSpec().open_plan_share is None
    assert HouseSpec().num_regions == 6


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(categories_per_open_plan=1), "categories_per_open_plan must be an integer >= 2"),
        (dict(categories_per_open_plan=2.5), "categories_per_open_plan must be an integer"),
        (dict(categories_per_open_plan=4, category_names=("a", "b", "c")), "at least 4 category"),
        (dict(open_plan_share=1.0), r"open_plan_share must be None or lie in \(0, 1\)"),
        (dict(open_plan_share="half"), "open_plan_share must be a number"),
        (dict(num_open_plan=4), "open_plan_share needs 1 <= num_open_plan < num_rooms"),
        (dict(num_open_plan=0), "open_plan_share needs 1 <= num_open_plan < num_rooms"),
        (dict(open_plan_share=0.95), r"both must be at least min_room_size \(24\)"),
    ],
)
def test_invalid_open_plan_fields_are_refused(changes, message):
    with pytest.raises(HouseSpecError, match=message):
        HouseSpec.open_plan(**changes)


def test_three_categories_share_one_walled_space(house):
    assert house.category_names == ("living", "dining", "kitchen", "bedroom", "bathroom", "toilet")
    truth, free = house.truth, house.grid.free
    assert set(np.unique(truth[free])) == set(range(6))
    # Cutting at doors (1 m, the geometry baseline's width for synthetic houses): 4 segments,
    # one of them holding living, dining and kitchen.
    segments = room_segments(house.grid, door_width=1.0)
    counts = categories_in_segments(segments, truth)
    assert len(counts) == 4 and max(counts) == 3
    open_space = segments == int(np.argmax(counts))
    shares = np.bincount(truth[open_space], minlength=6) / open_space.sum()
    assert shares[:3].sum() > 0.95  # living, dining, kitchen
    assert open_space.sum() > 0.55 * free.sum()  # most of the house


def test_the_open_plan_parts_are_unwalled_rectangles_of_their_own():
    for seed in range(3):
        spec = HouseSpec.open_plan(categories_per_open_plan=4)
        plan = floor_plan(spec, np.random.default_rng(seed))
        assert plan.open_pairs == 1 and plan.open_size == 4 and plan.num_regions == 7
        house = make_house(seed=seed, spec=spec)
        # The four parts (regions 0-3) take four distinct categories, and cutting at doors
        # leaves them in one segment: no wall between them.
        parts = (plan.region >= 0) & (plan.region < 4)
        assert len(np.unique(house.truth[parts])) == 4
        segments = room_segments(house.grid, door_width=1.0)
        assert max(categories_in_segments(segments, house.truth)) == 4
        assert len(np.unique(segments[parts])) == 1


def test_every_category_has_its_own_images_and_utterances(house):
    grid, obs, truth = house.grid, house.observations, house.truth
    image_cells = grid.world_to_cell(obs.image_xy)  # [T, 2]
    word_cells = grid.world_to_cell(obs.word_xy)  # [U, 2]
    image_category = truth[image_cells[:, 0], image_cells[:, 1]]
    word_category = truth[word_cells[:, 0], word_cells[:, 1]]
    # 10 waypoints x 3 trials per region, 3 utterances per region and trial.
    np.testing.assert_array_equal(np.bincount(image_category, minlength=6), [30] * 6)
    np.testing.assert_array_equal(np.bincount(word_category, minlength=6), [9] * 6)
    # Each category's images lie around one spot of its own (waypoint_radius 0.25 m).
    for c in range(6):
        xy = obs.image_xy[image_category == c]
        assert np.ptp(xy, axis=0).max() < 0.6


def test_cutting_at_doors_scores_at_most_half(house):
    grid, obs, truth = house.grid, house.observations, house.truth
    for door_width in (1.0, 2.0):
        model = geometry_semantic_map(grid, obs, door_width=door_width)
        assert adjusted_rand_index(model.label_image(), truth) <= 0.5
    nearest = adjusted_rand_index(nearest_word_map(grid, obs).label_image(), truth)
    assert nearest > 0.15  # the words alone separate the categories better than chance
    scores = open_plan_scores(0)
    assert scores.geometry <= 0.5 and scores.geometry_wide <= 0.5
    assert scores.geometry_open == pytest.approx(0.0, abs=1e-9)  # one segment, 3 categories
    assert scores.nearest_open > 0.1
    assert scores.geometry + 0.2 < scores.oracle < 1.0


def test_the_observation_oracle_cuts_half_way_between_the_places(house):
    grid, obs, truth = house.grid, house.observations, house.truth
    oracle = observation_oracle(grid, obs, truth)  # [H, W]
    assert ((oracle >= 0) == grid.free).all()
    cells = np.concatenate([grid.world_to_cell(obs.image_xy), grid.world_to_cell(obs.word_xy)])
    on_free = cells[grid.free[cells[:, 0], cells[:, 1]]]
    # Every observation's cell keeps its own truth region.
    np.testing.assert_array_equal(
        oracle[on_free[:, 0], on_free[:, 1]], truth[on_free[:, 0], on_free[:, 1]]
    )
    # A walled room of one region is that region; the open plan's borders lie between spots,
    # not where the truth draws them (its parts are not in the data): the score is below 1.
    segments = room_segments(grid)
    for s in range(int(segments.max()) + 1):
        regions = np.unique(truth[segments == s])
        if regions.size == 1:
            assert (oracle[segments == s] == regions[0]).all()
    assert adjusted_rand_index(oracle, truth) == pytest.approx(0.835, abs=0.005)


def test_studies_and_the_cli_name_the_house(tmp_path, capsys):
    assert SYNTHETIC_HOUSES["open-plan"] == OPEN_PLAN
    settings = AblationSettings.quick(houses=dict(SYNTHETIC_HOUSES), synthetic=("open-plan",))
    study = ablation_study(settings)
    assert [(d.name, d.kind, d.options) for d in study.data] == [
        ("open-plan", "synthetic", spec_options(OPEN_PLAN))
    ]
    assert main(["simulate", "--out", str(tmp_path), "--density", "open-plan", "--seed", "1"]) == 0
    written = load_house(tmp_path / "synthetic")
    assert written.category_names == make_house(seed=1, spec=OPEN_PLAN).category_names
    np.testing.assert_array_equal(written.truth, make_house(seed=1, spec=OPEN_PLAN).truth)
    with pytest.raises(SystemExit):
        main(["simulate", "--out", str(tmp_path), "--density", "open"])
    assert "open-plan" in capsys.readouterr().err
