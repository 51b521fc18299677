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
    _Pairs,
    _pairs,
    _sample_tables,
    _signature,
)
from spcopyro.results.point_estimate import _greedy, _prepare, compact


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
    assert np.array_equal(prepared.by_column, np.argsort(prepared.signature, kind="stable"))


def test_signature_folds_rows_as_the_keys_allow():
    """Many large labelings: several passes of a few rows each (the int64 key's limit)."""
    rng = np.random.default_rng(5)
    stacked = rng.integers(0, 3000, (14, 6000))
    stacked[:, :3000] = np.arange(3000)  # every label in use: J_s = 3000
    sizes = tuple(int(row.max()) + 1 for row in stacked)
    assert np.array_equal(_signature(stacked, sizes), _old_signature(stacked, sizes))


@pytest.mark.parametrize("seed", range(12))
def test_pairs_are_the_sort_of_the_keys(seed):
    rng = np.random.default_rng(100 + seed)
    prepared = _prepare(_random_samples(seed), "vi")
    n = prepared.signature.shape[0]
    for clusters in (1, 3, 300, 70000):  # uint8, uint16 and int64 clusters
        estimate, _ = compact(rng.integers(0, clusters, n))
        ours, theirs = _pairs(estimate, prepared), _old_pairs(estimate, prepared)
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
    joined = buffer[:, : k + 1]
    kept = {"same": np.arange(k), "emptied": np.array([0, 2, 3, 5, 6, 7]),
            "opened": np.arange(k + 1), "outgrown": np.arange(k + 1)}[case]  # fmt: skip
    expected = joined[:, kept].copy()  # the copy the search made before 2026-12-05
    moved = _kept_columns(joined, kept)
    assert moved.shape == (23, kept.shape[0] + 1)
    assert np.array_equal(moved[:, : kept.shape[0]], expected)
    assert (moved.base is buffer) == (case != "outgrown")  # in place where it fits


@pytest.mark.parametrize("loss", ["vi", "binder"])
def test_the_search_on_a_map_like_case_is_unchanged(loss, monkeypatch):
    """The search with small blocks (moves in place, new clusters, outgrown buffers) against
    the same search with the old tables and join terms: the same estimate and loss, bit for
    bit."""
    import spcopyro.results.point_estimate as module
    from tests.test_point_estimate import _map_like_samples

    prepared = _prepare(_map_like_samples(4, cells=1500), loss)
    monkeypatch.setattr(tables_module, "BLOCK", 64)
    ours = [_greedy(start, prepared, loss, None) for start in prepared.codes[:3]]

    def old_rows(tables, rows, prepared, loss, out=None):
        if out is None:
            return _old_joined_rows(tables, rows, prepared, loss)
        out = np.ascontiguousarray(out)
        out[:, rows] = _old_joined_rows(tables, rows, prepared, loss)
        return out

    def old_kept(joined, kept):
        grown = np.empty((joined.shape[0], kept.shape[0] + 1))
        grown[:, :-1] = joined[:, kept]
        return grown

    monkeypatch.setattr(module, "_joined_rows", old_rows)
    monkeypatch.setattr(module, "_kept_columns", old_kept)
    monkeypatch.setattr(module, "_pairs", _old_pairs)
    for (estimate, value), start in zip(ours, prepared.codes[:3], strict=True):
        theirs, their_value = _greedy(start, prepared, loss, None)
        assert np.array_equal(estimate, theirs) and value == their_value
