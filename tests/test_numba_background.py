"""The compiled sweep's background table (spcopyro.gibbs.numba_background): its centring of the
logits equals the numpy steps it replaced to the bit, and a non-finite row is named; built on one
row per footprint pattern (row_classes) it is the full table's rows to the bit, names the same
cell, and the compiled sweep draws the same labels and globals with it as without it; its
vectorised grouping gives the arrays of the per-cell dict loop it replaced, to the bit."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem, tiny_grid
from test_factored_counts import ROWS, observations

from spcopyro.data import cell_counts
from spcopyro.model import FactoredCounts, make_model_data

pytest.importorskip("numba")

from spcopyro.data.factored_counts import SpreadSources  # noqa: E402
from spcopyro.data.identical_rows import identical_rows  # noqa: E402
from spcopyro.gibbs import numba_sweep  # noqa: E402
from spcopyro.gibbs.numba_background import (  # noqa: E402
    RowClasses,
    _centre_rows,
    _row_classes,
    background_table,
    row_classes,
)
from spcopyro.gibbs.sampler import init  # noqa: E402
from spcopyro.gibbs.state import GibbsState  # noqa: E402

SPREADS = [{"footprint_radius": 0.35}, {"footprint_radius": 0.35, "footprint_reach_share": 0.5}]
"""Footprints whose weights repeat over the cells: without and with a reach share."""


def _spread_data(rng: np.random.Generator, **preparation: object):
    grid = tiny_grid(ROWS)
    return make_model_data(grid, cell_counts(grid, observations(grid, rng), snap_distance=0.0,
                                             **preparation))  # fmt: skip


def _bits(array) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(array, dtype=np.float64)).view(np.uint64)


def _numpy_centre(logits: np.ndarray, log_pi: np.ndarray) -> np.ndarray:
    """The table's steps as numpy wrote them before _centre_rows."""
    logits = logits.copy()
    logits[-1] = 0.0
    logits += log_pi
    logits -= logits.max(axis=1, keepdims=True)
    return logits


def test_centre_rows_is_the_numpy_steps_to_the_bit():
    rng = np.random.default_rng(0)
    for scale in (1e-3, 1.0, 1e3, 1e12):
        logits = rng.normal(size=(40, 120)) * scale  # [M + 1, L]
        logits[3, :7] = -np.inf  # a concept with zero probability in one row
        logits[5] = rng.normal(size=120) * 1e-300  # subnormal differences
        log_pi = rng.normal(size=120) * scale
        expected = _numpy_centre(logits, log_pi)
        out = logits.copy()
        assert _centre_rows(out, log_pi) == -1
        assert np.array_equal(out.view(np.uint64), expected.view(np.uint64)), scale


@pytest.mark.parametrize(
    ("row", "value"),
    [(2, np.nan), (2, np.inf), (0, np.nan), (4, -np.inf)],
)
def test_centre_rows_names_the_first_non_finite_row(row, value):
    logits = np.zeros((6, 5))  # [M + 1, L]
    log_pi = np.zeros(5)
    if value == -np.inf:
        logits[row] = value  # every concept impossible: no finite maximum
    else:
        logits[row, 3] = value
        logits[row + 1, 1] = value  # a later bad row is not the one named
    assert _centre_rows(logits, log_pi) == row


def test_background_table_names_the_row_a_nan_reaches():
    grid, data = random_problem(1)
    cfg = config()
    state = init(data, cfg, torch.Generator().manual_seed(2))
    table = background_table(state, data, cfg)  # [M + 1, L + D]
    assert np.isfinite(table).all() and (table[:, : cfg.num_concepts].max(axis=1) == 1.0).all()
    bad_counts = data.modality("images").counts.clone()
    bad_counts[3, 0] = np.nan
    with pytest.raises(ValueError, match="observed cell in row 3 of data.obs_cells"):
        background_table(state, data.with_counts("images", bad_counts), cfg)
    log_pi = state.log_pi.clone()
    log_pi[1] = np.nan
    nan_pi = GibbsState(state.labels, log_pi, state.log_emissions)
    with pytest.raises(ValueError, match="not finite for the observed cell in row 0"):
        background_table(nan_pi, data, cfg)  # every row holds pi: the first is named


@pytest.mark.parametrize("preparation", SPREADS)
def test_one_row_per_footprint_pattern_is_the_full_table_to_the_bit(rng, preparation):
    data = _spread_data(rng, **preparation)
    classes = row_classes(data)
    M, U = data.obs_cells.numel(), classes.first.size
    assert 1 < U < M  # the weights repeat: fewer rows to build
    assert classes.of.shape == (M + 1,) and classes.of[M] == U
    # numbered by first cell: classes 0..U-1, class u's first cell first[u], the firsts ascending
    numbers, firsts = np.unique(classes.of[:M], return_index=True)
    assert np.array_equal(numbers, np.arange(U)) and np.array_equal(firsts, classes.first)
    assert (np.diff(classes.first) > 0).all()
    for name in ("images", "words"):  # a class's cells hold the same weighted counts
        counts = data.modality(name).counts.numpy()
        assert np.array_equal(counts, counts[classes.first][classes.of[:M]])
    for cfg in (config(num_concepts=5), config(num_concepts=5, use_images=False)):
        state = init(data, cfg, torch.Generator().manual_seed(4))
        full = background_table(state, data, cfg)  # [M + 1, L + D]
        reduced = background_table(state, data, cfg, classes)  # [U + 1, L + D]
        assert reduced.shape == (U + 1, full.shape[1])
        assert np.array_equal(_bits(full), _bits(reduced[classes.of]))


def test_row_classes_only_where_every_modality_is_factored(rng):
    data = _spread_data(rng, **SPREADS[0])
    assert row_classes(data) is row_classes(data)  # cached per factored form
    words = data.modality("words").counts.clone()
    assert row_classes(data.with_counts("words", words)) is None  # a dense product's rows
    assert row_classes(_spread_data(rng)) is None  # no footprint


def test_one_row_per_pattern_names_the_same_cell(rng):
    """A footprint whose counts are NaN spoils the rows of the cells it reaches: both tables name
    the first of them (a class's first cell)."""
    data = _spread_data(rng, **SPREADS[1])
    images = data.modality("images")
    spread = images.factored()
    cell_of = np.repeat(np.arange(spread.indptr.size - 1), np.diff(spread.indptr))  # [nnz]
    reached = [cell_of[spread.indices == s].min() for s in range(spread.sources.shape[0])]
    spoilt_source = int(np.argmax(reached))  # the footprint whose first cell comes last
    row = int(reached[spoilt_source])
    sources = spread.sources.copy()
    sources[spoilt_source, 0] = np.nan
    spoilt = SpreadSources(spread.indptr, spread.indices, spread.weights, sources)
    bound = FactoredCounts(spoilt, images.counts, images.counts._version)
    modalities = tuple(m._replace(spread=bound) if m is images else m for m in data.modalities)
    data = data._replace(modalities=modalities)
    assert row > 0
    cfg = config(num_concepts=5)
    state = init(data, cfg, torch.Generator().manual_seed(4))
    for classes in (None, row_classes(data)):
        with pytest.raises(ValueError, match=f"observed cell in row {row} of data.obs_cells"):
            background_table(state, data, cfg, classes)


@pytest.mark.parametrize("preparation", SPREADS)
def test_the_compiled_sweep_is_the_same_with_one_row_per_pattern(rng, preparation, monkeypatch):
    from spcopyro.gibbs.numba_sweep import gibbs_sweep_numba

    data = _spread_data(rng, **preparation)
    cfg = config(num_concepts=5)
    runs = []
    for reduced in (True, False):
        if not reduced:
            monkeypatch.setattr(numba_sweep, "row_classes", lambda data: None)
        state = init(data, cfg, torch.Generator().manual_seed(4))
        generator = torch.Generator().manual_seed(7)
        states = []
        for _ in range(6):
            state = gibbs_sweep_numba(state, data, cfg, generator)
            states.append(state)
        runs.append(states)
    for with_classes, without in zip(*runs, strict=True):
        assert torch.equal(with_classes.labels, without.labels)
        assert np.array_equal(_bits(with_classes.log_pi), _bits(without.log_pi))
        for a, b in zip(with_classes.log_emissions, without.log_emissions, strict=True):
            assert np.array_equal(_bits(a), _bits(b))


def _dict_row_classes(spreads: tuple[SpreadSources, ...]) -> tuple[np.ndarray, np.ndarray]:
    """_row_classes' of [M + 1] int32 and first [U] int64 as it found them before its vectorised
    grouping: a per-cell loop over one dict keyed on the rows' bytes, each new key numbered as it
    comes (the reference)."""
    M = spreads[0].indptr.size - 1
    rows = [(spread.indptr.tolist(), spread.indices, spread.weights) for spread in spreads]
    class_of: dict[tuple[tuple[bytes, bytes], ...], int] = {}  # per modality: row m's entries
    of = np.empty(M + 1, dtype=np.int32)  # [M + 1]
    first: list[int] = []  # [U]
    for m in range(M):
        key = tuple(
            (indices[at[m] : at[m + 1]].tobytes(), weights[at[m] : at[m + 1]].tobytes())
            for at, indices, weights in rows
        )
        u = class_of.setdefault(key, len(class_of))
        if u == len(first):  # a new class: m is its first cell
            first.append(m)
        of[m] = u
    of[M] = len(first)
    return of, np.asarray(first, dtype=np.int64)  # [M + 1], [U] ascending


def _assert_same_classes(spreads: tuple[SpreadSources, ...]) -> RowClasses:
    """The vectorised grouping against the dict loop: _row_classes (uncached) and the helper it
    calls, identical_rows, give the same arrays and dtypes. (The classes' reduced spreads are
    _rows_of's of ``first``, checked by the tables and sweeps above.)"""
    got = _row_classes.__wrapped__(spreads)
    of, first = _dict_row_classes(spreads)
    group, first_rows = identical_rows(*((s.indptr, s.indices, s.weights) for s in spreads))
    for a, b, dtype in ((got.of, of, np.int32), (got.first, first, np.int64),
                        (group, of[:-1], np.int64), (first_rows, first, np.int64)):  # fmt: skip
        assert a.dtype == dtype and a.shape == b.shape and np.array_equal(a, b)
    return got


def _spread(rows: list[list[tuple[int, float]]], num_sources: int = 4) -> SpreadSources:
    """A SpreadSources of the given rows of (footprint, weight) entries, in their order."""
    lengths = [len(row) for row in rows]
    indptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)  # [M + 1]
    entries = [entry for row in rows for entry in row]
    indices = np.array([s for s, _ in entries], dtype=np.int64)  # [nnz]
    weights = np.array([w for _, w in entries], dtype=np.float64)  # [nnz]
    return SpreadSources(indptr, indices, weights, np.ones((num_sources, 3)))


_NAN = np.float64(np.nan)
_OTHER_NAN = np.uint64(0x7FF8000000000001).view(np.float64)  # a NaN of other bits
ROW_CASES = {
    "ties": [[(0, 0.5), (2, 0.25)], [(1, 1.0)], [(0, 0.5), (2, 0.25)], [(1, 1.0)], [(3, 0.1)],
             [(0, 0.5), (2, 0.25)], [(2, 0.25), (0, 0.5)]],  # the same entries in another order
    "all distinct": [[(s, 0.1 * (s + 1))] for s in range(4)] + [[(0, 0.1), (1, 0.2)]],
    "all identical": [[(1, 0.5), (3, 0.75)]] * 6,
    "one row": [[(2, 0.3)]],
    "no rows": [],
    "empty rows": [[], [(0, 0.0)], [], [(0, 0.0), (1, 0.5)], [(0, 0.0)]],  # padding is not a tie
    "signed zeros": [[(1, 0.0)], [(1, -0.0)], [(1, 0.0)], [(1, -0.0)], [(1, 0.0), (2, -0.0)]],
    "NaNs": [[(0, _NAN)], [(0, _OTHER_NAN)], [(0, _NAN)], [(0, 1.0)], [(0, _OTHER_NAN)],
             [(1, _NAN), (0, _NAN)]],
}  # fmt: skip
"""Rows for the grouping: the dict's keys are bytes, so 0.0 and -0.0 are two keys, and a NaN
ties with a NaN of the same bits alone (a float dict key would tie neither way)."""


@pytest.mark.parametrize("case", ROW_CASES)
def test_row_classes_are_the_dict_loops_to_the_bit(case):
    rows = ROW_CASES[case]
    classes = _assert_same_classes((_spread(rows),))
    assert classes.of.shape == (len(rows) + 1,)
    if case == "signed zeros":
        assert classes.of[:-1].tolist() == [0, 1, 0, 1, 2]
    if case == "NaNs":
        assert classes.of[:-1].tolist() == [0, 1, 0, 2, 1, 3]
    if case == "empty rows":
        assert classes.of[:-1].tolist() == [0, 1, 0, 2, 1]


def test_row_classes_of_two_modalities_are_the_dict_loops(rng):
    """Cells tie in one modality but not the other, and rows of many lengths: random rows over
    a few patterns each, so the keys of the two modalities' combinations repeat."""
    patterns = []  # 7 rows of 0 to 8 entries
    for n in (0, 1, 2, 3, 5, 8, 2):
        sources = rng.choice(9, size=n, replace=False).tolist()
        patterns.append(list(zip(sources, rng.choice([0.25, 0.5, 1.0], size=n), strict=True)))
    images = _spread([patterns[i] for i in rng.integers(0, 7, size=300)], num_sources=9)
    words = _spread([patterns[i] for i in rng.integers(0, 3, size=300)], num_sources=9)
    classes = _assert_same_classes((images, words))
    assert 7 < classes.first.size < 300


@pytest.mark.parametrize("preparation", SPREADS)
def test_row_classes_of_spread_data_are_the_dict_loops(rng, preparation):
    data = _spread_data(rng, **preparation)
    _assert_same_classes(tuple(modality.factored() for modality in data.modalities))


def test_row_classes_of_the_embedded_house_are_the_dict_loops():
    """The data of a real fit: the embedded house under the default preset (``coarse``)."""
    from spcopyro.config import DEFAULT_PRESET, preset
    from spcopyro.data.model_grid import model_house
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.synthetic import HouseSpec, make_house

    settings = preset(DEFAULT_PRESET)
    house = model_house(make_house(seed=0, spec=HouseSpec.embedded()), settings.data.cell_size)
    _, data = prepare_model_data(house, settings)
    spreads = tuple(modality.factored() for modality in data.modalities)
    assert all(spread is not None and spread.pays() for spread in spreads)
    classes = _assert_same_classes(spreads)
    assert 1 < classes.first.size < data.obs_cells.numel()  # some cells' rows repeat
