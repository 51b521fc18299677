"""Metrics: exact values on tiny hand-made label images, models and samples."""

from __future__ import annotations

import numpy as np
import pytest

from spcopyro.config import SpCoConfig
from spcopyro.data import Observations
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.metrics import (
    LocalisationScores,
    SemanticMapModel,
    SpCoSemanticMap,
    TabularSemanticMap,
    WordPredictionScores,
    adjusted_rand_index,
    as_semantic_map,
    chain_ari,
    co_assignment,
    heldout_localisation,
    heldout_word_prediction,
    matching_rate,
    num_concepts,
    pairwise_chain_ari,
    rank_of_truth,
)
from spcopyro.results.result import EmissionTable, SpCoResult, Trace
from spcopyro.results.semantic_map import UnknownWordError


def free_grid(height: int, width: int, resolution: float = 1.0) -> OccupancyGrid:
    return OccupancyGrid(
        occupancy=np.full((height, width), FREE, dtype=np.int8),
        resolution=resolution,
        origin=(0.0, 0.0, 0.0),
    )


def observations(utterances, xy) -> Observations:
    """Held-out utterances at world positions (one dummy image, unused by the scores)."""
    return Observations(
        image_features=np.ones((1, 2)) / 2,
        image_xy=np.zeros((1, 2)),
        image_trial=np.zeros(1, dtype=np.int64),
        utterances=tuple(tuple(u) for u in utterances),
        word_xy=np.asarray(xy, dtype=np.float64),
        word_trial=np.zeros(len(utterances), dtype=np.int64),
    )


class FixedModel:
    """A hand-made SemanticMapModel on a 1 x 4 corridor at 0.5 m: labels 0 0 1 1."""

    vocabulary = ("x", "y", "z")

    def __init__(self) -> None:
        self.grid = free_grid(1, 4, resolution=0.5)
        self.table = np.array([[0.5, 0.25, 0.25], [0.2, 0.2, 0.6]])  # [label, V]
        self.labels = np.array([[0, 0, 1, 1]])
        self.regions = {"x": [0], "y": [3], "z": []}

    def label_image(self) -> np.ndarray:
        return self.labels.copy()

    def word_distribution(self, cells: np.ndarray) -> np.ndarray:
        return self.table[self.labels[0, cells]]

    def region(self, word: str) -> np.ndarray:
        mask = np.zeros((1, 4), dtype=bool)
        mask[0, self.regions[word]] = True
        return mask


# ---------------------------------------------------------------------------------- ARI


def test_adjusted_rand_index_by_hand():
    # Contingency [[2, 1, 0], [0, 1, 2]]: sum C(n_ij, 2) = 2, rows 2 C(3,2) = 6, columns
    # 3 C(2,2) = 3, C(6,2) = 15: expected 6 * 3 / 15 = 1.2, max 4.5 -> 0.8 / 3.3 = 8/33.
    truth = np.array([[0, 0, 0, -1], [1, 1, 1, -1]])
    labels = np.array([[5, 5, 7, 9], [7, 2, 2, 9]])
    assert adjusted_rand_index(labels, truth) == pytest.approx(8 / 33)
    assert adjusted_rand_index(truth * 3 + 1, truth) == pytest.approx(1.0)
    with pytest.raises(ValueError, match=r"differ in shape$"):
        adjusted_rand_index(labels[:, :3], truth)


def test_labels_of_a_coarser_model_grid_are_refused_with_the_way_to_score_them():
    truth = np.zeros((4, 6), dtype=np.int64)  # a map of 4 x 6 cells
    coarse = np.zeros((2, 3), dtype=np.int64)  # a fit on cells twice as large
    with pytest.raises(ValueError, match="coarser model grid.*model_house.*refine_labels"):
        adjusted_rand_index(coarse, truth)
    with pytest.raises(ValueError, match="coarser model grid"):
        matching_rate(lambda word: np.zeros((2, 3), dtype=bool), truth, ["a"])


# ---------------------------------------------------------------------------- matching rate

TRUTH = np.array([[0, 0, 1, 1], [0, 0, 1, 1], [-1, 2, 2, 2]])


def region_function(word: str) -> np.ndarray:
    cells = {"a": [(0, 0), (0, 1), (0, 2)], "b": [(1, 2), (1, 3), (2, 0)], "c": []}[word]
    mask = np.zeros(TRUTH.shape, dtype=bool)
    for cell in cells:
        mask[cell] = True
    return mask  # "d" raises KeyError: unknown to the method


def test_matching_rate_by_hand():
    words = {"a": 0, "b": 1, "c": 2, "d": 2}
    # a: region 3 cells, 2 in category 0 (4 cells): precision 2/3, recall 1/2, IoU 2/5.
    # b: (2, 0) is undefined in the truth -> region 2 cells, both in category 1:
    #    precision 1, recall 1/2, IoU 2/4. c: empty region; d: unknown word -> 0, 0, 0.
    precision = matching_rate(region_function, TRUTH, words)
    assert precision.kind == "precision"
    assert precision.value == pytest.approx((2 / 3 + 1 + 0 + 0) / 4)
    assert precision.per_word["a"] == pytest.approx((0, 2 / 3, 1 / 2, 2 / 5))
    assert precision.per_word["b"] == pytest.approx((1, 1.0, 1 / 2, 1 / 2))
    assert precision.unknown_words == ("d",)
    assert precision.empty_regions == ("c",)
    assert matching_rate(region_function, TRUTH, words, kind="recall").value == pytest.approx(0.25)
    assert matching_rate(region_function, TRUTH, words, kind="iou").value == pytest.approx(
        (0.4 + 0.5) / 4
    )


def test_matching_rate_takes_category_names_and_models():
    names = ("a", "b", "c")  # entry c names category c
    assert matching_rate(region_function, TRUTH, names).value == pytest.approx((2 / 3 + 1) / 3)
    grid = free_grid(3, 4)
    model = TabularSemanticMap(
        grid=grid,
        vocabulary=("a", "b", "c"),
        labels=TRUTH.clip(min=0),  # the truth itself, (2, 0) merged into category 0
        word_counts=np.eye(3),
    )
    perfect = matching_rate(model, TRUTH, names)
    assert perfect.value == pytest.approx(1.0)
    assert perfect.per_word["c"] == pytest.approx((2, 1.0, 1.0, 1.0))


def test_matching_rate_rejects_bad_input():
    with pytest.raises(ValueError, match="kind"):
        matching_rate(region_function, TRUTH, ("a",), kind="f1")
    with pytest.raises(ValueError, match="not a category"):
        matching_rate(region_function, TRUTH, {"a": 7})
    with pytest.raises(ValueError, match="twice"):
        matching_rate(region_function, TRUTH, ("a", "a"))


# ----------------------------------------------------------------- the model interface


def test_tabular_semantic_map_by_hand():
    grid = free_grid(2, 3)
    labels = np.array([[0, 0, 1], [1, 1, 2]])
    counts = np.array([[2.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.0, 1.0, 0.0]])  # [label, V]
    model = TabularSemanticMap(grid, ("a", "b", "c"), labels, counts, smoothing=0.5)
    assert isinstance(model, SemanticMapModel)
    # label 0: (2.5, .5, .5) / 3.5; label 1: (.5, 1.5, 1.5) / 3.5; label 2: (.5, 1.5, .5) / 2.5
    expected = np.array([[5, 1, 1], [1, 3, 3], [1, 3, 1]]) / np.array([[7], [7], [5]])
    np.testing.assert_allclose(model.word_distribution(np.array([0, 2, 5])), expected)
    np.testing.assert_array_equal(model.region("a"), labels == 0)
    # "b" is heard once under labels 1 and 2: the tie goes to the larger label (3 cells vs 1).
    assert model.region_label("b") == 1
    np.testing.assert_array_equal(model.region("c"), labels == 1)
    with pytest.raises(UnknownWordError, match="'d'"):
        model.region("d")
    with pytest.raises(ValueError, match="free-cell index"):
        model.word_distribution(np.array([6]))


def test_tabular_semantic_map_validates():
    grid = OccupancyGrid(np.array([[FREE, OCCUPIED]], dtype=np.int8), 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="-1 on every non-free"):
        TabularSemanticMap(grid, ("a",), np.array([[0, 0]]), np.ones((1, 1)))
    with pytest.raises(ValueError, match="needs a label"):
        TabularSemanticMap(grid, ("a",), np.array([[1, -1]]), np.ones((1, 1)))
    with pytest.raises(ValueError, match="shape"):
        TabularSemanticMap(grid, ("a", "b"), np.array([[0, -1]]), np.ones((1, 1)))
    never_heard = TabularSemanticMap(grid, ("a",), np.array([[0, -1]]), np.zeros((1, 1)))
    assert not never_heard.region("a").any()


def spco_result() -> SpCoResult:
    """A hand-made fitted result on a 1 x 3 corridor: concepts 0 1 1."""
    return SpCoResult(
        grid=free_grid(1, 3),
        config=SpCoConfig(num_concepts=2, prior="dirichlet"),
        labels=np.array([0, 1, 1]),  # [N]
        pi=np.array([0.5, 0.5]),  # [L]
        emissions=(
            EmissionTable("images", ("0", "1"), np.full((2, 2), 0.5)),  # theta [L, K]
            EmissionTable("words", ("a", "b"), np.array([[0.7, 0.3], [0.1, 0.9]])),  # w [L, V]
        ),
        trace=Trace(objective=np.zeros(1), num_concepts=np.array([2]), seconds=np.zeros(1)),
        best_iteration=0,
        labels_final=np.array([0, 1, 1]),
    )


def test_spco_semantic_map_point_estimate_and_samples():
    result = spco_result()
    point = as_semantic_map(result)
    assert isinstance(point, SpCoSemanticMap)
    np.testing.assert_allclose(point.word_distribution(np.array([0, 2])), [[0.7, 0.3], [0.1, 0.9]])
    np.testing.assert_array_equal(point.region("a"), [[True, False, False]])
    np.testing.assert_array_equal(point.label_image(), [[0, 1, 1]])
    # p(C = l) from two samples: cell 0 is 0 then 1, cell 2 is 1 then 0 -> both (w0 + w1) / 2.
    sampled = SpCoSemanticMap(result, label_samples=np.array([[0, 1, 1], [1, 1, 0]]))
    np.testing.assert_allclose(
        sampled.word_distribution(np.array([0, 1, 2])), [[0.4, 0.6], [0.1, 0.9], [0.4, 0.6]]
    )
    with pytest.raises(ValueError, match="label_samples"):
        SpCoSemanticMap(result, label_samples=np.array([[0, 1]]))
    with pytest.raises(TypeError, match="SemanticMapModel"):
        as_semantic_map(object())
    # The matching rate takes the result itself: truth = the result's map.
    assert matching_rate(result, np.array([[0, 1, 1]]), ("a", "b")).value == pytest.approx(1.0)


# ------------------------------------------------------------------------- held-out scores


def test_rank_of_truth_ties_at_expected_position():
    ranks, (top1, top3) = rank_of_truth(
        np.array([[0.25, 0.25, 0.25, 0.25], [0.1, 0.5, 0.2, 0.2]]), np.array([2, 3])
    )
    # Row 0: 3 others tied -> rank 1 + 3/2; top-1 1/4, top-3 3/4.
    # Row 1: one greater (0.5), one tied (0.2) -> rank 2.5; top-1 0, top-3 1.
    np.testing.assert_allclose(ranks, [2.5, 2.5])
    np.testing.assert_allclose(top1, [0.25, 0.0])
    np.testing.assert_allclose(top3, [0.75, 1.0])


def test_rank_of_truth_counts_scores_a_few_last_bits_apart_as_ties():
    """Scores equal in exact arithmetic come out of a vectorised sum a few ulps apart, in a
    way that depends on the CPU; ranked exactly, a held-out score differed between machines."""
    p = 0.2
    above, below = p * (1 + 4e-16), p * (1 - 4e-16)  # a few last bits either side
    rows = np.array([[p, above, 0.6], [p, below, 0.6], [p, p * 1.01, 0.6]])
    ranks, (top1,) = rank_of_truth(rows, np.array([0, 0, 0]), ks=(1,))
    # rows 0 and 1: the 0.2s tie behind 0.6 -> rank 2.5 on any CPU; row 2: 1 % apart, third
    np.testing.assert_allclose(ranks, [2.5, 2.5, 3.0])
    np.testing.assert_allclose(top1, [0.0, 0.0, 0.0])
    ranks, (top1,) = rank_of_truth(rows[:2, :2], np.array([0, 0]), ks=(1,))
    np.testing.assert_allclose(ranks, [1.5, 1.5])  # tied with the other, whichever is larger
    np.testing.assert_allclose(top1, [0.5, 0.5])


def test_heldout_word_prediction_by_hand():
    model = FixedModel()
    held_out = observations(
        [("x",), ("y", "q"), ("z",)],
        [(0.25, 0.25), (1.25, 0.25), (100.0, 0.25)],  # cells 0 and 2; the last is off the map
    )
    scores = heldout_word_prediction(model, held_out)
    # x at label 0: p = (.5, .25, .25): rank 1. y at label 1: p = (.2, .2, .6): one greater,
    # one tied -> rank 2.5, top-1 0, top-3 1. q: unknown. z: unplaced (100 m off the map).
    np.testing.assert_allclose(scores.ranks, [1.0, 2.5])
    assert scores.mean_rank == pytest.approx(1.75)
    assert scores.top1 == pytest.approx(0.5)
    assert scores.top3 == pytest.approx(1.0)
    assert (scores.unknown_tokens, scores.unknown_words) == (1, ("q",))
    assert scores.unplaced_utterances == 1
    assert scores.vocabulary_size == 3
    pooled = WordPredictionScores.pooled([scores, scores])
    assert (pooled.num_scored, pooled.unknown_tokens, pooled.mean_rank) == (4, 2, 1.75)


def test_heldout_localisation_by_hand():
    model = FixedModel()
    held_out = observations(
        [("x",), ("y",), ("z",), ("w",)],
        [(0.25, 0.25), (1.25, 0.25), (0.75, 0.25), (0.3, 0.3)],  # cells 0, 2, 1, 0
    )
    scores = heldout_localisation(model, held_out)
    # x said in its region: 0. y said at cell 2, region cell 3: one cell = 0.5 m.
    # z's region is empty: inf. w: unknown.
    np.testing.assert_allclose(scores.distances, [0.0, 0.5, np.inf])
    assert scores.words == ("x", "y", "z")
    assert scores.empty_regions == 1
    assert scores.mean_distance == pytest.approx(0.25)
    assert scores.median_distance == pytest.approx(0.5)
    assert scores.inside_rate == pytest.approx(1 / 3)
    assert (scores.unknown_tokens, scores.unknown_words) == (1, ("w",))
    # x's and y's regions are one of the four cells each, z's none
    np.testing.assert_allclose(scores.region_shares, [0.25, 0.25, 0.0])
    assert scores.mean_region_share == pytest.approx(1 / 6)
    pooled = LocalisationScores.pooled([scores, scores])
    assert pooled.num_scored == 6
    np.testing.assert_allclose(pooled.region_shares, [0.25, 0.25, 0.0] * 2)


def test_heldout_localisation_whole_map_region_is_read_by_its_share():
    """A map of one region names all of it: 0 m from everywhere, read against share 1."""
    grid = free_grid(2, 3, resolution=0.5)
    model = TabularSemanticMap(grid, ("a", "b"), np.zeros((2, 3), dtype=int), np.eye(2))
    scores = heldout_localisation(
        model, observations([("a",), ("a",)], [(0.25, 0.25), (1.25, 0.75)])
    )
    assert scores.mean_distance == 0.0
    assert scores.mean_region_share == pytest.approx(1.0)


def test_heldout_localisation_diagonal_distance():
    grid = free_grid(3, 3, resolution=0.1)
    labels = np.array([[0, 1, 1], [1, 1, 1], [1, 1, 1]])
    model = TabularSemanticMap(grid, ("a", "b"), labels, np.eye(2))
    # "a" said at the opposite corner, cell (2, 2) = world (0.25, 0.05): sqrt(8) cells away.
    scores = heldout_localisation(model, observations([("a",)], [(0.25, 0.05)]))
    np.testing.assert_allclose(scores.distances, [0.1 * np.sqrt(8.0)])


# ---------------------------------------------------------------- posterior summaries


def test_num_concepts_and_chain_ari():
    assert num_concepts(np.array([[-1, 3, 3], [5, -1, 0]])) == 3
    assert num_concepts(np.array([2, 2, 7])) == 2
    a = np.array([0, 0, 0, 1, 1, 1])
    b = np.array([5, 5, 7, 7, 2, 2])
    assert chain_ari(a, b) == pytest.approx(8 / 33)  # as in test_adjusted_rand_index_by_hand
    assert chain_ari(a, 1 - a) == pytest.approx(1.0)
    image = np.array([[0, 1], [-1, 1]])
    assert chain_ari(image, np.array([[4, 3], [-1, 3]])) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="different cells"):
        chain_ari(image, np.array([[4, -1], [3, 3]]))
    table = pairwise_chain_ari([a, b, 1 - a])
    np.testing.assert_allclose(table, [[1, 8 / 33, 1], [8 / 33, 1, 8 / 33], [1, 8 / 33, 1]])


def test_co_assignment_by_hand():
    samples = np.array([[0, 0, 1, 1], [0, 1, 1, 1], [2, 2, 2, 2]], dtype=np.int16)
    summary = co_assignment(samples, pairs=np.array([[0, 1], [1, 2], [0, 3]]))
    # (0, 1): together in samples 0 and 2; (1, 2): in 1 and 2; (0, 3): only in 2.
    np.testing.assert_allclose(summary.similarity, [2 / 3, 2 / 3, 1 / 3])
    assert summary.mean_similarity == pytest.approx(5 / 9)
    assert summary.uncertainty == pytest.approx(8 / 9)  # 4 s (1 - s) = 8/9 for s = 1/3, 2/3
    # ARI([0,0,1,1], [0,1,1,1]): index 1 = expected 2 * 3 / 6 -> 0; against one cluster: 0.
    np.testing.assert_allclose(summary.consecutive_ari, [0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(summary.num_concepts, [2, 2, 1])


def test_co_assignment_random_pairs_are_distinct_and_seeded():
    samples = np.zeros((2, 5), dtype=np.int64)
    first = co_assignment(samples, num_pairs=500, seed=3)
    again = co_assignment(samples, num_pairs=500, seed=3)
    np.testing.assert_array_equal(first.pairs, again.pairs)
    assert first.pairs.shape == (500, 2)
    assert (first.pairs[:, 0] != first.pairs[:, 1]).all()
    assert first.pairs.min() == 0 and first.pairs.max() == 4
    assert first.mean_similarity == 1.0 and first.uncertainty == 0.0
    # 500 uniform draws over the 20 ordered pairs of distinct cells reach all of them.
    codes = first.pairs[:, 0] * 5 + first.pairs[:, 1]
    assert np.unique(codes).size == 20
    with pytest.raises(ValueError, match="label_samples"):
        co_assignment(np.zeros((2, 1), dtype=np.int64))
