"""The footprint's factored counts (spcopyro.data.footprint.SpreadSources): the weighted per-cell
counts as the product of the footprints' weights and the summed counts of the observations
sharing a footprint, and the compiled sweep's background table built through it.

Checked: the product equals the dense counts; observations at one cell share a footprint (unless
a field of view tells them apart) and unplaced ones have none; the model data carries it for
exactly the counts tensor it equals (replaced or changed counts drop it); the compiled sweep's
background table is the dense one's to rounding, on a map where the factored product pays.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from gibbs_problems import config, tiny_grid

from spcopyro.data import Observations, cell_counts, place_observations
from spcopyro.data.footprint import (
    SpreadSources,
    footprint_weights,
    spread_counts,
    spread_sources,
)
from spcopyro.gibbs.sampler import init
from spcopyro.model import make_model_data

ROWS = [
    "............",
    "............",
    "......#.....",
    "......#.....",
    "......#.....",
    "............",
]
SPOTS = [(0, 1), (0, 1), (0, 1), (3, 3), (3, 3), (4, 9), (1, 10)]  # three images share (0, 1)
NUM_CLASSES = 40


def observations(grid, rng: np.random.Generator) -> Observations:
    """Seven images at four spots (three at one, two at another) and three utterances, two of
    them at one spot; 40 feature classes, so the footprints' product pays."""

    def centre(row: int, col: int) -> list[float]:
        return grid.cell_to_world(np.array([[row, col]]))[0].tolist()

    return Observations(
        image_features=rng.dirichlet(np.full(NUM_CLASSES, 0.5), len(SPOTS)),
        image_xy=[centre(*s) for s in SPOTS],
        image_trial=[0] * len(SPOTS),
        utterances=(("kitchen",), ("sofa", "kitchen"), ("bed",)),
        word_xy=[centre(0, 1), centre(0, 1), centre(4, 9)],
        word_trial=[0, 0, 0],
        image_yaw=[0.0, math.pi / 2, math.pi, 0.0, 0.0, 1.0, 2.0],
    )


@pytest.fixture
def problem(rng):
    grid = tiny_grid(ROWS)
    return grid, observations(grid, rng)


@pytest.mark.parametrize("kernel", ["uniform", "gaussian"])
def test_factored_counts_equal_the_dense_counts(problem, kernel):
    grid, obs = problem
    counts = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.35,
                         footprint_kernel=kernel)  # fmt: skip
    assert set(counts.spread) == {"images", "words"}
    for name, dense in (("images", counts.image_counts), ("words", counts.word_counts)):
        factored = counts.spread[name]
        assert factored.shape == dense.shape
        np.testing.assert_allclose(factored.dense(), dense, rtol=1e-12, atol=1e-15)
    assert counts.spread["images"].sources.shape[0] == 4  # seven images, four spots
    assert counts.spread["words"].sources.shape[0] == 2  # three utterances, two spots
    np.testing.assert_allclose(  # the three images at (0, 1): one source, their summed counts
        counts.spread["images"].sources.sum(0), obs.image_features.sum(0), rtol=1e-12
    )
    assert counts.spread["images"].pays()


def test_a_field_of_view_and_unplaced_observations(problem):
    """Images at one cell facing different ways have different footprints; an unplaced
    observation (an empty row) has none."""
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    cells = np.append(cells, -1)  # [T + 1]
    features = np.vstack([obs.image_features, np.ones(NUM_CLASSES)])  # [T + 1, K]
    yaw = np.append(obs.image_yaw, 0.0)
    weights = footprint_weights(grid, cells, 0.35, yaw=yaw, fov=90.0)
    reached = np.unique(weights.indices)
    factored = spread_sources(weights, features, reached)
    assert factored.sources.shape[0] == 6  # (0, 1) three ways, (3, 3) once (yaw 0 twice), 2 more
    np.testing.assert_allclose(
        factored.dense(), spread_counts(weights, features, reached), rtol=1e-12, atol=1e-15
    )
    assert factored.sources.sum() == pytest.approx(obs.image_features.sum())  # no unplaced row


def _dict_spread_sources(weights, counts: np.ndarray, cells: np.ndarray) -> SpreadSources:
    """spread_sources as it was before identical_rows grouped its rows: a per-observation loop
    over one dict keyed on the rows' bytes, each new key numbered as it comes (the reference)."""
    counts = np.asarray(counts, dtype=np.float64)  # [T, K]
    weights = weights.tocsr()
    footprint: dict[tuple[bytes, bytes], int] = {}
    members: list[int] = []  # [T'] the observations with a footprint
    groups: list[int] = []  # [T'] the footprint of each
    for t in range(weights.shape[0]):
        start, stop = weights.indptr[t], weights.indptr[t + 1]
        if start == stop:
            continue
        key = (weights.indices[start:stop].tobytes(), weights.data[start:stop].tobytes())
        members.append(t)
        groups.append(footprint.setdefault(key, len(footprint)))
    group = np.asarray(groups, dtype=np.int64)  # [T']
    member = np.asarray(members, dtype=np.int64)  # [T']
    first = np.zeros(len(footprint), dtype=np.int64)  # [S] an observation of each footprint
    first[group] = member
    sources = np.zeros((len(footprint), counts.shape[1]))  # [S, K]
    np.add.at(sources, group, counts[member])
    on_cells = weights[first].tocsc()[:, np.asarray(cells, dtype=np.int64)].T.tocsr()  # [M, S]
    on_cells.sort_indices()
    return SpreadSources(
        indptr=on_cells.indptr.astype(np.int64),
        indices=on_cells.indices.astype(np.int64),
        weights=on_cells.data.astype(np.float64),
        sources=sources,
    )


def _random_weights(rng: np.random.Generator, num_obs: int, num_cells: int):
    """[T, N] CSR weights: each row one of a few patterns, drawn at random (so the patterns'
    first rows come in another order than their bytes sort), or empty (unplaced); two patterns
    differ in a zero's sign alone, one holds a stored 0."""
    from scipy import sparse

    patterns = [([2, 5, 7], [0.5, 0.25, 0.25]), ([1], [1.0]), ([0, 3], [0.0, 1.0]),
                ([0, 3], [-0.0, 1.0]), ([4, 5, 6, 9], [0.1, 0.2, 0.3, 0.4]), ([9], [1.0]),
                ([], [])]  # fmt: skip
    rows = [patterns[i] for i in rng.integers(0, len(patterns), size=num_obs)]
    indptr = np.cumsum([0] + [len(cols) for cols, _ in rows])  # [T + 1]
    indices = np.array([c for cols, _ in rows for c in cols], dtype=np.int32)  # [nnz]
    data = np.array([w for _, ws in rows for w in ws], dtype=np.float64)  # [nnz]
    return sparse.csr_matrix((data, indices, indptr), shape=(num_obs, num_cells))


def test_spread_sources_groups_as_the_dict_loop_did(problem, rng):
    """spread_sources' footprints (identical_rows on the placed observations' rows) are the old
    dict loop's, numbered alike: the same arrays to the bit, on the problem's fields of view and
    unplaced image, and on random rows of a few patterns."""
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    cells = np.append(cells, [-1, cells[0]])  # [T + 2] an unplaced image, then one more
    features = rng.dirichlet(np.full(NUM_CLASSES, 0.5), cells.size)  # [T + 2, K]
    yaw = np.append(obs.image_yaw, [0.0, 0.0])
    cases = [(footprint_weights(grid, cells, 0.35, yaw=yaw, fov=90.0), features)]
    for num_obs in (1, 60):
        cases.append((_random_weights(rng, num_obs, 10), rng.random((num_obs, 5))))
    cases.append((_random_weights(rng, 4, 10)[[]], np.zeros((0, 5))))  # no observation
    num_sources = []
    for weights, counts in cases:
        reached = np.unique(weights.indices)
        got = spread_sources(weights, counts, reached)
        expected = _dict_spread_sources(weights, counts, reached)
        for name in ("indptr", "indices", "weights", "sources"):
            a, b = getattr(got, name), getattr(expected, name)
            assert a.dtype == b.dtype and a.shape == b.shape, name
            assert a.tobytes() == b.tobytes(), name
        num_sources.append(got.sources.shape[0])
    assert num_sources == [6, 1, 6, 0]  # the 60 random rows: six placed patterns, tied


def test_model_data_drops_a_product_whose_counts_changed(problem):
    grid, obs = problem
    counts = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.35)
    data = make_model_data(grid, counts)
    images, words = data.modality("images"), data.modality("words")
    assert images.factored() is counts.spread["images"]
    assert words.factored() is counts.spread["words"]
    assert data.with_counts("images", images.counts.clone()).modality("images").factored() is None
    assert images._replace(counts=images.counts * 2).factored() is None  # bound to its tensor
    words.counts.mul_(2.0)  # changed in place: the product no longer equals them
    assert words.factored() is None
    plain = make_model_data(grid, cell_counts(grid, obs, snap_distance=0.0))
    assert all(m.factored() is None for m in plain.modalities)  # no footprint, no product


def test_compiled_background_table_is_the_dense_products(problem, monkeypatch):
    """The background table built through the factored counts equals the one the dense counts
    give, with all modalities in use and with the images switched off."""
    pytest.importorskip("numba")
    from spcopyro.gibbs import numba_background
    from spcopyro.gibbs.numba_background import background_table

    products = []
    kernel = numba_background._add_weighted_rows
    monkeypatch.setattr(numba_background, "_add_weighted_rows",
                        lambda *args: products.append(1) or kernel(*args))  # fmt: skip

    grid, obs = problem
    data = make_model_data(grid, cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.35))
    dense = data
    for name in ("images", "words"):
        dense = dense.with_counts(name, data.modality(name).counts.clone())
    assert all(m.factored() is not None for m in data.modalities)
    assert all(m.factored() is None for m in dense.modalities)
    for cfg in (config(num_concepts=5), config(num_concepts=5, use_images=False)):
        state = init(data, cfg, torch.Generator().manual_seed(4))
        products.clear()
        factored_table = background_table(state, data, cfg)  # [M + 1, L + D]
        assert len(products) == (1 if cfg.use_images is False else 2)  # the factored path ran
        dense_table = background_table(state, dense, cfg)
        assert len(products) == (1 if cfg.use_images is False else 2)  # and not here
        assert factored_table.shape == (data.obs_cells.numel() + 1, 5 + 4)
        np.testing.assert_allclose(factored_table, dense_table, rtol=1e-12, atol=1e-300)
