"""Tests of the seeded synthetic house (spcopyro.synthetic)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import ndimage

from spcopyro.data import load_house
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN
from spcopyro.synthetic import (
    CATEGORY_LEXICON,
    DEFAULT_CATEGORY_NAMES,
    FILLER_WORDS,
    HouseSpec,
    HouseSpecError,
    make_house,
    write_synthetic,
)

SENTENCES = HouseSpec(sentence_fraction=0.5)


@pytest.fixture(scope="module")
def house():
    return make_house(seed=0)


@pytest.fixture(scope="module")
def sentence_house():
    return make_house(seed=1, spec=SENTENCES)


def _assert_same_house(a, b) -> None:
    np.testing.assert_array_equal(a.grid.occupancy, b.grid.occupancy)
    assert a.grid.resolution == b.grid.resolution
    assert a.grid.origin == b.grid.origin
    np.testing.assert_array_equal(a.truth, b.truth)
    assert a.category_names == b.category_names
    oa, ob = a.observations, b.observations
    np.testing.assert_array_equal(oa.image_features, ob.image_features)
    np.testing.assert_array_equal(oa.image_xy, ob.image_xy)
    np.testing.assert_array_equal(oa.image_trial, ob.image_trial)
    np.testing.assert_array_equal(oa.word_xy, ob.word_xy)
    np.testing.assert_array_equal(oa.word_trial, ob.word_trial)
    assert oa.utterances == ob.utterances


def _longest_open_boundary(free: np.ndarray, truth: np.ndarray) -> int:
    """Most 4-adjacent free pairs of different categories across one grid line.

    A doorway gives at most its width (<= 4) such pairs across a line; an open-plan split gives
    one per cell of the room's side.
    """
    across_cols = free[:, :-1] & free[:, 1:] & (truth[:, :-1] != truth[:, 1:])  # [H, W-1]
    across_rows = free[:-1, :] & free[1:, :] & (truth[:-1, :] != truth[1:, :])  # [H-1, W]
    return int(max(across_cols.sum(axis=0).max(), across_rows.sum(axis=1).max()))


# --- determinism --------------------------------------------------------------------------------


def test_same_seed_gives_identical_house(house):
    _assert_same_house(house, make_house(seed=0))
    _assert_same_house(make_house(seed=5, spec=SENTENCES), make_house(seed=5, spec=SENTENCES))


def test_different_seeds_give_different_houses(house):
    other = make_house(seed=1)
    assert not np.array_equal(house.truth, other.truth)
    assert not np.array_equal(house.observations.image_xy, other.observations.image_xy)
    assert house.observations.image_features.shape == other.observations.image_features.shape
    assert not np.array_equal(house.observations.image_features, other.observations.image_features)


# --- floor plan ---------------------------------------------------------------------------------


def test_default_house_shape_and_categories(house):
    grid = house.grid
    assert grid.shape == (60, 80)
    assert grid.resolution == 0.1
    # Centred on the world origin: the lower-left corner at (-W res / 2, -H res / 2).
    assert grid.origin == pytest.approx((-4.0, -3.0, 0.0))
    assert 2000 <= grid.num_free <= 4000
    assert house.category_names == (
        "kitchen",
        "living",
        "bedroom",
        "bathroom",
        "toilet",
        "entrance",
    )
    assert house.truth.dtype == np.int64
    np.testing.assert_array_equal(np.unique(house.truth), np.arange(-1, 6))


def test_unknown_margin_and_outer_wall(house):
    occ = house.grid.occupancy
    m = 3
    for border in (occ[:m], occ[-m:], occ[:, :m], occ[:, -m:]):
        assert (border == UNKNOWN).all()
    for wall in (occ[m, m:-m], occ[-m - 1, m:-m], occ[m:-m, m], occ[m:-m, -m - 1]):
        assert (wall == OCCUPIED).all()
    inside = occ[m + 1 : -m - 1, m + 1 : -m - 1]
    assert set(np.unique(inside).tolist()) == {FREE, OCCUPIED}


@pytest.mark.parametrize("seed", range(6))
def test_walls_are_one_cell_thick(seed):
    occ = make_house(seed=seed).grid.occupancy
    wall = occ == OCCUPIED
    block = wall[:-1, :-1] & wall[1:, :-1] & wall[:-1, 1:] & wall[1:, 1:]  # 2 x 2 wall blocks
    assert not block.any()
    # Walls split the inside into rooms: the default house has internal walls.
    assert wall[4:-4, 4:-4].sum() > 0


# Many small rooms with the narrowest doorways: the hardest case for reachability.
DENSE = HouseSpec(height=80, width=100, num_rooms=40, min_room_size=6, doorway_width=(2, 2))


@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("spec", [None, DENSE], ids=["default", "dense"])
def test_free_space_is_one_component(seed, spec):
    grid = make_house(seed=seed, spec=spec).grid
    _, count = ndimage.label(grid.free)  # 4-connectivity
    assert count == 1


@pytest.mark.parametrize("seed", range(5))
def test_the_embedded_house_has_doorways_a_robot_and_the_model_grid_keep_open(seed):
    """HouseSpec.embedded (the commands' default house): HouseSpec()'s rooms, categories and
    observations, with 0.7-0.9 m doorways that stay open on the default preset's 0.3 m model
    grid, where HouseSpec()'s 0.2-0.4 m ones close (issue 21's closing notes)."""
    from spcopyro.maps.coarse import coarsen_grid

    sealed, embedded = make_house(seed=seed), make_house(seed=seed, spec=HouseSpec.embedded())
    assert HouseSpec.embedded() == HouseSpec(doorway_width=(7, 9))
    assert embedded.category_names == sealed.category_names
    np.testing.assert_array_equal(np.unique(embedded.truth), np.unique(sealed.truth))
    assert embedded.observations.utterances == sealed.observations.utterances
    assert embedded.observations.num_images == sealed.observations.num_images
    _, on_map = ndimage.label(embedded.grid.free)
    _, on_model_grid = ndimage.label(coarsen_grid(embedded.grid, 3).free)
    _, sealed_on_model_grid = ndimage.label(coarsen_grid(sealed.grid, 3).free)
    assert on_map == on_model_grid == 1
    assert sealed_on_model_grid > 1  # what HouseSpec.embedded is for


def test_truth_is_defined_on_exactly_the_free_cells(house, sentence_house):
    for h in (house, sentence_house):
        assert h.truth.shape == h.grid.shape
        np.testing.assert_array_equal(h.truth >= 0, h.grid.occupancy == FREE)
        assert (h.truth[h.grid.occupancy != FREE] == -1).all()
        assert h.truth.max() == len(h.category_names) - 1


@pytest.mark.parametrize("seed", range(5))
def test_open_plan_gives_a_boundary_without_wall(seed):
    h = make_house(seed=seed)
    assert _longest_open_boundary(h.grid.free, h.truth) >= HouseSpec().min_room_size
    # Without open-plan rooms, categories touch only through doorways (at most 4 cells wide).
    walled = make_house(seed=seed, spec=HouseSpec(num_open_plan=0))
    assert _longest_open_boundary(walled.grid.free, walled.truth) <= 4


def test_default_open_plan_is_living_and_kitchen(house):
    free, truth = house.grid.free, house.truth
    # The open-plan line is the grid line crossed by the most free pairs of different categories.
    across_cols = free[:, :-1] & free[:, 1:] & (truth[:, :-1] != truth[:, 1:])  # [H, W-1]
    across_rows = free[:-1] & free[1:] & (truth[:-1] != truth[1:])  # [H-1, W]
    col, row = across_cols.sum(axis=0).argmax(), across_rows.sum(axis=1).argmax()
    if across_cols[:, col].sum() >= across_rows[row].sum():
        rows = np.flatnonzero(across_cols[:, col])
        pairs = np.stack([truth[rows, col], truth[rows, col + 1]], axis=1)
    else:
        cols = np.flatnonzero(across_rows[row])
        pairs = np.stack([truth[row, cols], truth[row + 1, cols]], axis=1)
    names = {frozenset(house.category_names[c] for c in pair) for pair in pairs.tolist()}
    assert names == {frozenset(("living", "kitchen"))}


def test_more_regions_than_names_reuses_names():
    spec = HouseSpec(category_names=("kitchen", "living", "bedroom"), num_rooms=6, num_open_plan=2)
    h = make_house(seed=3, spec=spec)
    assert h.category_names == ("kitchen", "living", "bedroom")
    np.testing.assert_array_equal(np.unique(h.truth), [-1, 0, 1, 2])
    # 8 regions over 3 names: names cover several rooms, so categories have >1 component
    # (at most 8: rooms of one name can touch through a doorway).
    components = [ndimage.label(h.truth == c)[1] for c in range(3)]
    assert 3 < sum(components) <= 8
    assert _longest_open_boundary(h.grid.free, h.truth) >= spec.min_room_size


def test_unlisted_category_names_are_their_own_word():
    spec = HouseSpec(category_names=("lab", "office"), num_rooms=2, num_open_plan=0)
    h = make_house(seed=0, spec=spec)
    assert h.category_names == ("lab", "office")
    words = {w for u in h.observations.utterances for w in u}
    assert words == {"lab", "office"}


def test_custom_origin_and_resolution():
    h = make_house(seed=4, spec=HouseSpec(origin=(-10.0, -10.0), resolution=0.05))
    assert h.grid.origin == (-10.0, -10.0, 0.0)
    assert h.grid.resolution == 0.05
    xy = h.observations.image_xy
    assert xy.min() >= -10.0
    assert xy[:, 0].max() <= -10.0 + 80 * 0.05
    assert xy[:, 1].max() <= -10.0 + 60 * 0.05
    assert h.grid.is_free(h.grid.world_to_cell(xy)).all()


def test_floor_plan_that_cannot_fit_raises():
    # 30 x 30 inside: passes the area check (6 x 144 <= 900) but walls leave room for 4 rooms
    # at most: refused by the spec itself, not by make_house for every seed (issue 24 item 7).
    with pytest.raises(HouseSpecError, match="fit at most 4 to the 30 x 30 inside"):
        HouseSpec(height=38, width=38, num_rooms=6, num_open_plan=0)
    with pytest.raises(HouseSpecError, match="fit at most 2"):
        HouseSpec(30, 40, num_rooms=3)  # the example
    for seed in range(3):  # what the spec accepts, make_house draws
        make_house(seed=seed, spec=HouseSpec(38, 38, num_rooms=4, num_open_plan=0))


def test_400_by_400_house():
    """A large house is drawn whole and connected (how long it takes belongs in a benchmark, not
    in a test: these machines are shared and noisy)."""
    spec = HouseSpec.scaled(400, 400, images_per_room_per_trial=2, utterances_per_room_per_trial=1)
    h = make_house(seed=0, spec=spec)
    assert h.grid.shape == (400, 400)
    assert spec.num_rooms == (392 * 392) // 900
    assert ndimage.label(h.grid.free)[1] == 1
    assert h.grid.is_free(h.grid.world_to_cell(h.observations.image_xy)).all()
    assert len(h.category_names) == len(DEFAULT_CATEGORY_NAMES)


# --- observations -------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(4))
def test_every_observation_lies_on_a_free_cell(seed):
    h = make_house(seed=seed, spec=SENTENCES)
    grid, obs = h.grid, h.observations
    assert grid.is_free(grid.world_to_cell(obs.image_xy)).all()
    assert grid.is_free(grid.world_to_cell(obs.word_xy)).all()


def test_observation_counts_and_trials(house):
    obs = house.observations
    # 6 regions x 3 trials x 10 images; 3 utterances per region and trial.
    assert obs.image_features.shape == (180, 205)
    assert obs.image_xy.shape == (180, 2)
    np.testing.assert_array_equal(np.bincount(obs.image_trial), [60, 60, 60])
    assert len(obs.utterances) == 54
    assert obs.word_xy.shape == (54, 2)
    np.testing.assert_array_equal(np.bincount(obs.word_trial), [18, 18, 18])
    # Images come in trial order; every region is visited with 10 images per trial.
    assert (np.diff(obs.image_trial) >= 0).all()
    cells = house.grid.world_to_cell(obs.image_xy)
    category = house.truth[cells[:, 0], cells[:, 1]]
    for t in range(3):
        counts = np.bincount(category[obs.image_trial == t], minlength=6)
        np.testing.assert_array_equal(counts, [10] * 6)


def test_utterances_are_spoken_at_image_positions(house):
    obs = house.observations
    matches = (obs.word_xy[:, None, :] == obs.image_xy[None, :, :]).all(axis=2)  # [U, T]
    assert matches.any(axis=1).all()
    first_image = matches.argmax(axis=1)
    np.testing.assert_array_equal(obs.image_trial[first_image], obs.word_trial)


def test_image_rows_are_probability_histograms(house, sentence_house):
    for h in (house, sentence_house):
        f = h.observations.image_features
        assert f.dtype == np.float64
        assert np.isfinite(f).all()
        assert (f >= 0).all()
        np.testing.assert_allclose(f.sum(axis=1), 1.0, rtol=0, atol=1e-12)


def test_tiny_concentration_still_gives_histograms():
    h = make_house(seed=0, spec=HouseSpec(feature_concentration=1e-6))
    f = h.observations.image_features
    assert np.isfinite(f).all()
    np.testing.assert_allclose(f.sum(axis=1), 1.0, rtol=0, atol=1e-12)


def test_image_features_identify_the_category(house):
    """Nearest class mean (by KL) from trial 0 classifies trials 1-2 almost perfectly."""
    obs = house.observations
    cells = house.grid.world_to_cell(obs.image_xy)
    category = house.truth[cells[:, 0], cells[:, 1]]
    train = obs.image_trial == 0
    means = np.stack([obs.image_features[train & (category == c)].mean(0) for c in range(6)])
    scores = obs.image_features[~train] @ np.log(means).T  # [T', C] cross-entropy scores
    accuracy = (scores.argmax(axis=1) == category[~train]).mean()
    assert accuracy >= 0.95
    # ... but no category owns its classes: the dominant classes overlap somewhat.
    top = np.argsort(-means, axis=1)[:, :5]
    shared = sum(len(set(top[c]) & set(top[d])) for c in range(6) for d in range(c + 1, 6))
    assert shared >= 1


def test_yaw_heads_towards_the_next_image(house):
    obs = house.observations
    yaw = obs.image_yaw
    assert yaw.shape == (180,)
    assert np.isfinite(yaw).all()
    assert (np.abs(yaw) <= math.pi).all()
    for i in range(len(yaw) - 1):
        if obs.image_trial[i + 1] == obs.image_trial[i]:
            dx, dy = obs.image_xy[i + 1] - obs.image_xy[i]
            assert yaw[i] == pytest.approx(math.atan2(dy, dx))
        else:
            assert yaw[i] == yaw[i - 1]  # last image of a trial keeps the previous heading
    assert yaw[-1] == yaw[-2]


def test_default_utterances_are_single_words(house):
    utterances = house.observations.utterances
    assert all(len(u) == 1 for u in utterances)
    words = {u[0] for u in utterances}
    names = set(house.category_names)
    assert names & words  # place names ...
    assert words - names  # ... and object words


def test_words_are_mostly_their_category_words(house, sentence_house):
    for h in (house, sentence_house):
        obs = h.observations
        cells = h.grid.world_to_cell(obs.word_xy)
        category = h.truth[cells[:, 0], cells[:, 1]]
        hits = total = 0
        for utterance, c in zip(obs.utterances, category.tolist(), strict=True):
            content = [w for w in utterance if w not in FILLER_WORDS]
            assert content, utterance
            own = CATEGORY_LEXICON[h.category_names[c]].words
            hits += sum(w in own for w in content)
            total += len(content)
        assert hits / total >= 0.85


def test_sentences_mix(sentence_house):
    utterances = sentence_house.observations.utterances
    sentences = [u for u in utterances if len(u) > 1]
    assert 0.3 <= len(sentences) / len(utterances) <= 0.7
    assert all(u[-1] != "the" for u in sentences)
    assert all(w == w.lower() and w.isalnum() for u in utterances for w in u)
    assert any(u[:3] in (("here", "is", "the"), ("this", "is", "the")) for u in sentences)


def test_some_words_are_shared_between_categories():
    shared = {
        word
        for a in CATEGORY_LEXICON.values()
        for b in CATEGORY_LEXICON.values()
        if a is not b
        for word in set(a.words) & set(b.words)
    }
    assert {"table", "room"} <= shared


# --- write / load -------------------------------------------------------------------------------


def test_write_load_round_trip(tmp_path):
    spec = HouseSpec(sentence_fraction=0.4, origin=(-2.5, 1.25))
    room = write_synthetic(tmp_path, seed=7, spec=spec, name="synth7")
    assert room == tmp_path / "synth7"
    assert (tmp_path / "map" / "synth7.yaml").is_file()
    assert (room / "truth.npy").is_file()
    expected = make_house(seed=7, spec=spec, name="synth7")
    assert json.loads((room / "categories.json").read_text()) == list(expected.category_names)
    loaded = load_house(room)
    assert loaded.name == "synth7"
    _assert_same_house(loaded, expected)
    np.testing.assert_allclose(
        loaded.observations.image_yaw, expected.observations.image_yaw, rtol=0, atol=1e-12
    )


# --- spec validation ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(height=10), "height x width 10 x 80"),
        (dict(width=2.5), "width must be an integer >= 1, got 2.5"),
        (dict(height=True), "height must be an integer >= 1, got True"),
        (dict(resolution=0.0), "resolution must be > 0, got 0.0"),
        (dict(resolution=float("nan")), "resolution must be finite, got nan"),
        (dict(origin=(1.0,)), r"origin must be None or two numbers \(x, y\), got \(1.0,\)"),
        (dict(origin=(1.0, "a")), "origin must be a number, got 'a'"),
        (dict(margin=-1), "margin must be an integer >= 0, got -1"),
        (dict(num_rooms=0), "num_rooms must be an integer >= 1, got 0"),
        (dict(num_rooms=30), "num_rooms 30: rooms of at least 12 cells a side"),
        (dict(num_open_plan=6), r"num_open_plan must be at most num_rooms \(5\), got 6"),
        (dict(doorway_width=(3, 2)), r"doorway_width .* got \(3, 2\)"),
        (dict(doorway_width=(1, 3)), r"2 <= lo <= hi, got \(1, 3\)"),
        (dict(min_room_size=5), "min_room_size must be an integer >= 6, got 5"),
        (dict(category_names=()), "category_names must not be empty"),
        (dict(category_names="kitchen"), "category_names must be a sequence"),
        (dict(category_names=("Kitchen", "living")), "got 'Kitchen'"),
        (dict(category_names=("living room", "x")), "got 'living room'"),
        (dict(category_names=("a", "b", "a")), "duplicates"),
        (dict(category_names=("kitchen",)), "at least two category_names"),
        (dict(num_feature_classes=0), "num_feature_classes must be an integer >= 1, got 0"),
        (dict(dominant_classes=300), r"dominant_classes must be at most .*\(205\), got 300"),
        (dict(shared_dominant_classes=5), r"less than dominant_classes \(5\), got 5"),
        (dict(dominant_mass=1.5), r"dominant_mass must lie in \[0, 1\], got 1.5"),
        (dict(feature_concentration=-1.0), "feature_concentration must be > 0, got -1.0"),
        (dict(num_trials=0), "num_trials must be an integer >= 1, got 0"),
        (dict(utterances_per_room_per_trial=11), "at most images_per_room_per_trial"),
        (dict(sentence_fraction=-0.1), r"sentence_fraction must lie in \[0, 1\], got -0.1"),
        (dict(word_noise=2), r"word_noise must lie in \[0, 1\], got 2"),
    ],
)
def test_spec_validation(changes, message):
    with pytest.raises(HouseSpecError, match=message):
        HouseSpec(**changes)


def test_spec_error_is_a_value_error():
    assert issubclass(HouseSpecError, ValueError)


def test_make_house_argument_errors():
    with pytest.raises(TypeError, match="HouseSpec"):
        make_house(seed=0, spec={"height": 60})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="seed must be a non-negative integer, got -1"):
        make_house(seed=-1)


def test_scaled_spec_keeps_room_size():
    spec = HouseSpec.scaled(1000, 1000)
    assert spec.num_rooms == (992 * 992) // 900
    assert spec.num_open_plan == spec.num_rooms // 5
    assert spec.min_room_size == HouseSpec().min_room_size
    assert HouseSpec.scaled(1000, 1000, num_rooms=10).num_rooms == 10
