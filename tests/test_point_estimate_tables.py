"""The point estimate's tables, made faster on 2026-12-05 (a 3.07-million-cell map), against
the code they replaced (kept here as references): the same arrays, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

import spcopyro.results.estimate_tables as tables_module
from spcopyro.results.estimate_tables import (
    _f,
    _joined_rows,
    _kept_columns,
    _moved_pairs,
    _Pairs,
    _pairs,
    _sample_pairs,
    _sample_tables,
    _signature,
)
from spcopyro.results.point_estimate import _greedy, _prepare, _sample_start, compact


def _old_signature(stacked, sizes):
    """One np.unique of the N cells per sample (before 2026-12-05)."""
    signature = np.zeros(stacked.shape[1], dtype=np.int64)
    for row, size in zip(stacked, sizes, strict=True):
        _, signature = np.unique(signature * size + row, return_inverse=True)
        signature = signature.reshape(-1)
    return signature


def _old_pairs(estimate, prepared):
    """A stable sort of the keys cluster * U + column (before 2026-12-05)."""
    width = prepared.signatures.shape[1]
    key = estimate * width + prepared.signature
    order = np.argsort(key, kind="stable")
    ordered = key[order]
    first = np.empty(ordered.shape[0], dtype=bool)
    first[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    starts = np.flatnonzero(first)
    present = ordered[starts]
    of_cell = np.empty(key.shape[0], dtype=np.int64)
    of_cell[order] = np.cumsum(first) - 1
    cells = np.diff(np.append(starts, key.shape[0])).astype(np.float64)
    return _Pairs(present // width, present % width, cells, of_cell)


def _old_joined_rows(tables, rows, prepared, loss):
    """[U, R] by adding whole [U, R] gathers (before 2026-12-05)."""
    count = tables[0].shape[0] if rows is None else rows.shape[0]
    joined = np.zeros((prepared.signatures.shape[1], count))
    for table, columns in zip(tables, prepared.signatures, strict=True):
        part = table if rows is None else table[rows]
        join = np.ascontiguousarray((_f(part + 1, loss) - _f(part, loss)).T)
        joined += join[columns]
    return joined


def _random_samples(seed):
    """Samples of a few labels with blocks shared between samples and cells of noise."""
    rng = np.random.default_rng(seed)
    cells, count = int(rng.integers(1, 700)), int(rng.integers(1, 9))
    base = rng.integers(0, int(rng.integers(1, 12)), cells)
    samples = np.stack([np.where(rng.random(cells) < 0.2, rng.integers(0, 40, cells), base)
                        for _ in range(count)])  # fmt: skip
    return samples * int(rng.integers(1, 5))  # labels with gaps


@pytest.mark.parametrize("seed", range(12))
def test_signature_is_the_one_sort_per_sample_ranking(seed):
    prepared = _prepare(_random_samples(seed), "vi")
    assert np.array_equal(prepared.signature, _old_signature(prepared.codes, prepared.sizes))
    by_column, n = prepared.by_column, prepared.signature.shape[0]
    assert np.array_equal(np.sort(by_column), np.arange(n))  # a permutation of the cells
    keys = prepared.signature[by_column] * n + by_column  # (column, index), strictly rising
    assert (np.diff(keys) > 0).all()


def test_signature_folds_rows_as_the_keys_allow():
    """Many large labelings: several passes of a few rows each (the int64 key's limit)."""
    rng = np.random.default_rng(5)
    stacked = rng.integers(0, 3000, (14, 6000))
    stacked[:, :3000] = np.arange(3000)  # every label in use: J_s = 3000
    sizes = tuple(int(row.max()) + 1 for row in stacked)
    assert np.array_equal(_signature(stacked, sizes), _old_signature(stacked, sizes))


RADIX_CASES = [(1, np.uint8), (3, np.uint8), (256, np.uint8), (257, np.uint16), (300, np.uint16),
               (65536, np.uint16), (65537, np.int64), (70000, np.int64)]  # fmt: skip


@pytest.mark.parametrize("seed", range(12))
def test_pairs_are_the_sort_of_the_keys(seed, monkeypatch):
    """Any non-negative cluster numbers (not compacted: a few hundred cells reach 70,000
    clusters), their largest set so that each dtype of the sort is the one chosen."""
    chosen = []  # the dtype of each sort

    def radix_dtype(estimate, real=tables_module._radix_dtype):
        chosen.append(real(estimate))
        return chosen[-1]

    monkeypatch.setattr(tables_module, "_radix_dtype", radix_dtype)
    rng = np.random.default_rng(100 + seed)
    prepared = _prepare(_random_samples(seed), "vi")
    n = prepared.signature.shape[0]
    for clusters, dtype in RADIX_CASES:
        estimate = rng.integers(0, clusters, n)
        estimate[rng.integers(n)] = clusters - 1
        ours, theirs = _pairs(estimate, prepared), _old_pairs(estimate, prepared)
        assert chosen.pop() is dtype
        for a, b in zip(ours, theirs, strict=True):
            assert a.dtype == b.dtype and np.array_equal(a, b)


@pytest.mark.parametrize("seed", range(12))
def test_a_samples_own_pairs_are_the_sort_of_its_keys(seed):
    """The samples' losses take each sample's pairs from its U columns (_sample_pairs), not
    from a sort of the N cells: the same arrays, dtypes included, as both sorts of the cells;
    and the same expected loss as before, to the bit."""
    from spcopyro.results.point_estimate import _expected

    samples = _random_samples(seed)
    samples[-1] = 0  # a sample of one cluster: one pair per column, all in cluster 0
    for loss in ("vi", "binder"):
        prepared = _prepare(samples, loss)
        for s, (codes, size) in enumerate(zip(prepared.codes, prepared.sizes, strict=True)):
            ours = _sample_pairs(s, prepared)
            # the old sort of the keys took int64 codes (the samples' are uint8 since 2026-12-06)
            for theirs in (_pairs(codes, prepared), _old_pairs(codes.astype(np.int64), prepared)):
                for a, b in zip(ours, theirs, strict=True):
                    assert a.dtype == b.dtype and np.array_equal(a, b)
            tables = _sample_tables(ours, size, prepared)
            assert _expected(codes, size, prepared, loss, tables) == _expected(
                codes, size, prepared, loss
            )


def test_the_samples_losses_count_the_cells_of_each_column_once(monkeypatch):
    """The samples' pairs share one count of each column's cells: the samples' losses made one
    O(N) bincount of the cells' columns per sample (25 at 3 million cells) for the same [U]."""
    import spcopyro.results.point_estimate as module

    seen = []  # the _Samples the estimate prepared
    prepare, bincount = module._prepare, np.bincount

    def kept_prepare(*args, **kwargs):
        seen.append(prepare(*args, **kwargs))
        return seen[-1]

    counted = []  # every array bincount was given (told apart after the run)

    def counting_bincount(x, *args, **kwargs):
        counted.append(x)
        return bincount(x, *args, **kwargs)

    monkeypatch.setattr(module, "_prepare", kept_prepare)
    monkeypatch.setattr(np, "bincount", counting_bincount)
    samples = np.random.default_rng(5).integers(0, 6, (7, 300))  # [S, N]
    module.point_estimate(samples, "vi", starts=1)
    (prepared,) = seen
    assert [x.shape[0] for x in counted if x is prepared.signature] == [300]
    cells = bincount(prepared.signature, minlength=prepared.signatures.shape[1])  # [U]
    assert prepared.column_cells.dtype == np.float64
    assert np.array_equal(prepared.column_cells, cells)


@pytest.mark.parametrize("seed", range(12))
def test_moved_pairs_are_the_sort_of_the_moved_keys(seed):
    """An accepted trial's pairs from the estimate's pairs (_moved_pairs) against both sorts of
    the N cells: movers into other clusters, into a new one (k), clusters emptied and renamed
    (compact's renaming, as the search makes it), and all cells moving; dtypes included."""
    rng = np.random.default_rng(200 + seed)
    prepared = _prepare(_random_samples(seed), "vi")
    n = prepared.signature.shape[0]
    for case in range(6):
        k = int(rng.integers(1, 9))
        estimate = compact(rng.integers(0, k, n))[0]
        k = int(estimate.max()) + 1
        pairs = _pairs(estimate, prepared)
        share = (0.02, 0.3, 1.0)[case % 3]
        movers = np.flatnonzero(rng.random(n) < share) if case < 5 else np.arange(n)
        target = rng.integers(0, k + 1, n)  # k: a new cluster
        if case == 4:
            target[:] = k  # every mover into the new cluster
        trial = estimate.copy()
        trial[movers] = target[movers]
        kept = np.flatnonzero(np.bincount(trial, minlength=k + 1))
        rename = np.full(k + 1, -1, dtype=np.int64)
        rename[kept] = np.arange(kept.shape[0])
        codes = rename[trial]
        ours = _moved_pairs(pairs, prepared, movers, codes, rename)
        for theirs in (_pairs(codes, prepared), _old_pairs(codes, prepared)):
            for a, b in zip(ours, theirs, strict=True):
                assert a.dtype == b.dtype and np.array_equal(a, b)


@pytest.mark.parametrize("loss", ["vi", "binder"])
@pytest.mark.parametrize("seed", range(6))
def test_joined_rows_in_blocks_are_the_whole_sums(loss, seed, monkeypatch):
    monkeypatch.setattr(tables_module, "BLOCK", 7)  # many blocks, a short last one
    rng = np.random.default_rng(200 + seed)
    prepared = _prepare(_random_samples(seed), loss)
    estimate, k = compact(rng.integers(0, 5, prepared.signature.shape[0]))
    tables = _sample_tables(_pairs(estimate, prepared), k + 1, prepared).tables
    whole = _old_joined_rows(tables, None, prepared, loss)
    assert np.array_equal(_joined_rows(tables, None, prepared, loss), whole)
    rows = np.flatnonzero(rng.random(k + 1) < 0.5)
    part = _old_joined_rows(tables, rows, prepared, loss)
    assert np.array_equal(_joined_rows(tables, rows, prepared, loss), part)
    out = np.full_like(whole, np.nan)
    assert _joined_rows(tables, rows, prepared, loss, out) is out
    assert np.array_equal(out[:, rows], part)
    assert np.isnan(np.delete(out, rows, axis=1)).all()  # the other columns left alone


@pytest.mark.parametrize("case", ["same", "emptied", "opened", "outgrown"])
def test_kept_columns_are_the_copied_columns(case, monkeypatch):
    monkeypatch.setattr(tables_module, "BLOCK", 5)
    rng = np.random.default_rng(7)
    buffer = rng.random((23, 12))  # [U, width]
    k = {"outgrown": 11}.get(case, 8)
    kept = {"same": np.arange(k), "emptied": np.array([0, 2, 3, 5, 6, 7]),
            "opened": np.arange(k + 1), "outgrown": np.arange(k + 1)}[case]  # fmt: skip
    expected = buffer[:, kept].copy()  # the copy the search made before 2026-12-05
    moved = _kept_columns(buffer, kept)
    assert moved.shape == (23, 12 if case != "outgrown" else kept.shape[0] + 9)
    assert np.array_equal(moved[:, : kept.shape[0]], expected)
    assert (moved is buffer) == (case != "outgrown")  # in place where it fits


@pytest.mark.parametrize("loss", ["vi", "binder"])
def test_the_search_on_a_map_like_case_is_unchanged(loss, monkeypatch):
    """The search with small blocks (columns moved in place, new clusters, outgrown buffers)
    against the same search with the old tables and join terms: the same estimate and loss, bit
    for bit. The samples' own labellings as starts move columns in place; one cluster for all
    cells (all zeros) as a start opens clusters and outgrows its buffer (VI: once, to 3
    clusters; Binder: twice, to 18)."""
    import spcopyro.results.point_estimate as module
    from tests.test_point_estimate import _label_start, _map_like_samples

    prepared = _prepare(_map_like_samples(4, cells=1500), loss)
    starts = [*prepared.codes[:3], np.zeros(prepared.codes.shape[1], dtype=np.int64)]
    monkeypatch.setattr(tables_module, "BLOCK", 64)
    calls = []  # (start, in place, grown) of each _kept_columns

    def counted_kept(buffer, kept):
        moved = tables_module._kept_columns(buffer, kept)
        inplace = moved is buffer and not np.array_equal(kept, np.arange(kept.shape[0]))
        calls.append((len(ours), inplace, moved is not buffer))
        return moved

    monkeypatch.setattr(module, "_kept_columns", counted_kept)
    ours = []
    for start in starts:
        ours.append(_greedy(_label_start(start, prepared, loss), prepared, loss, None))
    assert any(inplace for s, inplace, _ in calls if s < 3)  # columns moved in place
    growths = sum(grown for s, _, grown in calls if s == 3)  # buffers outgrown from zeros
    assert growths >= {"vi": 1, "binder": 2}[loss]  # binder: 8 spare columns used up, too
    assert ours[3][0].max() >= 2  # new clusters opened

    def old_rows(tables, rows, prepared, loss, out=None):
        if out is None:
            return _old_joined_rows(tables, rows, prepared, loss)
        out[:, rows] = _old_joined_rows(tables, rows, prepared, loss)
        return out

    def old_kept(buffer, kept):  # [U, kk + 1]: the copy the search made before 2026-12-05
        grown = np.empty((buffer.shape[0], kept.shape[0] + 1))
        grown[:, :-1] = buffer[:, kept]
        return grown

    monkeypatch.setattr(module, "_joined_rows", old_rows)
    monkeypatch.setattr(module, "_kept_columns", old_kept)
    monkeypatch.setattr(
        module, "_moved_pairs", lambda p, prepared, m, codes, r: _old_pairs(codes, prepared)
    )
    for (estimate, value), start in zip(ours, starts, strict=True):
        old_start = _label_start(start, prepared, loss, _old_pairs)
        theirs, their_value = _greedy(old_start, prepared, loss, None)
        assert np.array_equal(estimate, theirs) and value == their_value


@pytest.mark.parametrize("loss", ["vi", "binder"])
def test_the_searches_start_from_a_samples_own_pairs(loss, monkeypatch):
    """A search's start is one of the samples: its pairs are its U columns (_sample_pairs), not
    a sort of the N cells (each of the 3 starts sorted them before 2026-12-05); the same search,
    estimate and loss to the bit, as from the sample's labels."""
    import spcopyro.results.point_estimate as module
    from tests.test_point_estimate import _label_start, _map_like_samples

    samples = _map_like_samples(6, cells=1500, count=8)
    prepared = _prepare(samples, loss)
    theirs = [  # from the codes [N] as labels: their pairs from a sort of the N cells
        _greedy(_label_start(codes, prepared, loss), prepared, loss, None)
        for codes in prepared.codes
    ]

    def from_labels(row, prepared, loss):  # the starts as before: from the codes [N]
        return _label_start(prepared.codes[row], prepared, loss)

    monkeypatch.setattr(module, "_sample_start", from_labels)
    old = module.point_estimate(samples, loss)
    monkeypatch.setattr(module, "_sample_start", _sample_start)

    def no_sort(estimate, prepared):
        raise AssertionError("the pairs of a sample from a sort of the N cells")

    monkeypatch.setattr(module, "_pairs", no_sort)
    for s, (estimate, value) in enumerate(theirs):
        ours, our_value = _greedy(_sample_start(s, prepared, loss), prepared, loss, None)
        assert np.array_equal(ours, estimate) and our_value == value
    new = module.point_estimate(samples, loss)  # no sort of the N cells anywhere
    assert np.array_equal(new.labels, old.labels)
    assert (new.expected_loss, new.best_sample_loss) == (old.expected_loss, old.best_sample_loss)
