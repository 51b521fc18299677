r"""The contingency tables behind :mod:`spcopyro.results.point_estimate`'s greedy search.

The S samples' distinct columns (cells labelled alike in every sample), the (cluster, column)
pairs an estimate's cells take, the S tables of the estimate against the samples counted over
those pairs, their update when cells move, and the join and departure terms of a move read off
them; ``_f`` is the f of that module's doc (:math:`x^2` or :math:`x \log x`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


def _f(x: np.ndarray, loss: str) -> np.ndarray:
    """f of the module doc, elementwise: x^2 (Binder) or x log x (VI, 0 at 0)."""
    x = np.asarray(x, dtype=np.float64)
    if loss == "binder":
        return x * x
    return x * np.log(np.where(x > 0, x, 1.0))


def _codes_and_values(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """([N] int64 codes: each label's rank among the distinct values, [K] those values
    ascending), as np.unique(labels, return_inverse=True): for integer labels in
    [0, 4 N + 1024) by a table lookup, O(N), else by np.unique's one sort. At 2.9 million
    cells 0.02 s per labelling where np.unique's inverse took 0.34 s."""
    labels = np.asarray(labels)
    if labels.dtype.kind in "iu" and labels.size and labels.dtype != np.uint64:
        low, high = int(labels.min()), int(labels.max())
        if low >= 0 and high < 4 * labels.size + 1024:
            present = np.bincount(labels.ravel(), minlength=high + 1) > 0  # [max + 1]
            values = np.flatnonzero(present).astype(labels.dtype, copy=False)  # [K]
            rank = np.cumsum(present, dtype=np.int64) - 1  # [max + 1] value -> its code
            return rank[labels], values
    values, codes = np.unique(labels, return_inverse=True)
    return codes.astype(np.int64), values


class _Samples(NamedTuple):
    codes: np.ndarray  # [S, N] each sample's labels renamed 0..J_s-1 (uint8 to 256 labels)
    sizes: tuple[int, ...]  # J_s
    constant: float  # sum_s F(b^s) / S
    signatures: np.ndarray  # [S, U] the distinct columns of codes (cells labelled alike in all)
    signature: np.ndarray  # [N] each cell's column of signatures
    by_column: np.ndarray  # [N] the cells in order of their column, then of their index
    column_cells: np.ndarray  # [U] float64 cells of each column (one count for all samples)


class _Pairs(NamedTuple):
    """The (cluster of the estimate, distinct column of the samples) pairs that cells take: a
    contingency table of any sample is a sum over these P pairs (a few thousand on a settled
    map) rather than over the N cells."""

    cluster: np.ndarray  # [P] the estimate's cluster of each pair
    column: np.ndarray  # [P] its column of signatures
    cells: np.ndarray  # [P] float64 number of cells of each pair
    of_cell: np.ndarray  # [N] each cell's pair


def _radix_dtype(estimate: np.ndarray) -> type:
    """The narrowest dtype that holds the clusters ``estimate`` [N] (non-negative) for
    :func:`_pairs`' stable sort: uint8 up to 256 clusters, uint16 up to 65,536 (numpy's stable
    sort of these is a radix sort), else int64. Of any shape: the point estimate's ``_prepare``
    holds the samples' [S, N] codes in the dtype it gives for the samples' labels."""
    clusters = int(estimate.max()) + 1 if estimate.size else 1
    return np.uint8 if clusters <= 256 else np.uint16 if clusters <= 65536 else np.int64


def _pairs(estimate: np.ndarray, prepared: _Samples) -> _Pairs:
    """The pairs in order of cluster, then column, from a stable sort of the cells by their
    cluster in the samples' fixed column order (``by_column``): the order of a stable sort of
    the keys cluster * U + column, by a radix sort of 1- or 2-byte clusters (0.05 s at 3.07
    million cells where the keys' sort took 0.3 s)."""
    width = prepared.signatures.shape[1]  # U
    small = estimate.astype(_radix_dtype(estimate), copy=False)[prepared.by_column]  # [N]
    by_cluster = np.argsort(small, kind="stable")  # [N]
    order = prepared.by_column[by_cluster]  # [N] cells by (cluster, column, index)
    # [N] their keys, ascending; int64 whatever the estimate's dtype (a row of the samples'
    # uint8 codes times U wrapped round)
    ordered = estimate[order].astype(np.int64, copy=False) * width + prepared.signature[order]
    first = np.empty(ordered.shape[0], dtype=bool)  # [N] a cell opens a pair
    first[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    starts = np.flatnonzero(first)  # [P]
    present = ordered[starts]  # [P]
    of_cell = np.empty(ordered.shape[0], dtype=np.int64)
    of_cell[order] = np.cumsum(first) - 1
    cells = np.diff(np.append(starts, ordered.shape[0])).astype(np.float64)  # [P]
    return _Pairs(present // width, present % width, cells, of_cell)


def _sample_pairs(row: int, prepared: _Samples) -> _Pairs:
    """:func:`_pairs` of sample ``row``'s own codes (``prepared.codes[row]``) as the estimate,
    from a sort of the U columns instead of the N cells: a column of the samples holds one label
    of each, so each of the U columns is one pair, of the sample's label there (the 25 samples'
    losses sorted 3.07 million cells 25 times, ~0.1 s each, for 157,574 columns). The cells of
    each column are ``prepared.column_cells``, counted once for all samples."""
    clusters = prepared.signatures[row]  # [U] the sample's label on each column
    width = clusters.shape[0]  # U
    order = np.argsort(clusters, kind="stable")  # [U] the pairs: by cluster, then column
    rank = np.empty(width, dtype=np.int64)  # [U] each column's pair
    rank[order] = np.arange(width)
    cells = prepared.column_cells[order]  # [U] float64
    return _Pairs(clusters[order], order.astype(np.int64), cells, rank[prepared.signature])


def _moved_pairs(
    pairs: _Pairs, prepared: _Samples, movers: np.ndarray, codes: np.ndarray, rename: np.ndarray
) -> _Pairs:
    """:func:`_pairs` of ``codes`` [N]: the estimate of ``pairs`` with the cells ``movers`` [M]
    moved and its clusters renamed by ``rename`` [k + 1] (increasing on the clusters kept, so
    the kept pairs keep their order), from those pairs instead of a sort of the N cells: a sort
    of the P + M keys and gathers over the N cells (an accepted trial of the search sorted the
    3.07 million cells, 0.16 s, 58 times in one estimate)."""
    width = prepared.signatures.shape[1]  # U
    count = pairs.cells.shape[0]  # P
    remaining = pairs.cells - np.bincount(pairs.of_cell[movers], minlength=count)  # [P] exact
    alive = np.flatnonzero(remaining > 0)  # [P'] the pairs a cell still takes
    old_keys = rename[pairs.cluster[alive]] * width + pairs.column[alive]  # [P'] ascending
    mover_keys = codes[movers] * width + prepared.signature[movers]  # [M]
    present = np.union1d(old_keys, mover_keys)  # [Q] the new pairs' keys, ascending
    where = np.full(count, -1, dtype=np.int64)  # [P] each old pair's new pair (-1: none)
    where[alive] = np.searchsorted(present, old_keys)
    of_cell = where[pairs.of_cell]  # [N]; the movers' next
    of_cell[movers] = np.searchsorted(present, mover_keys)
    cells = np.bincount(of_cell[movers], minlength=present.shape[0]).astype(np.float64)  # [Q]
    cells[where[alive]] += remaining[alive]
    return _Pairs(present // width, present % width, cells, of_cell)


def _signature(stacked: np.ndarray, sizes: tuple[int, ...], bar=None) -> np.ndarray:
    """[N] each cell's rank among the distinct columns of ``stacked`` [S, N] (J_s labels in
    row s) in lexicographic order, row 0 first: np.unique(stacked, axis=1)'s inverse. A
    column's rank so far, refined by the next rows: as many rows at once as a mixed-radix
    int64 key holds (5 of 120 labels at 3 million cells), one renaming of the keys each (it
    refined by one row per sort of the N cells). ``bar.update()`` once per row."""
    signature = np.zeros(stacked.shape[1], dtype=np.int64)  # [N]
    distinct, row = 1, 0
    while row < len(sizes):
        key, bound = signature.copy(), distinct  # [N]; key < bound
        while row < len(sizes) and (bound == distinct or bound * sizes[row] < 2**62):
            key *= sizes[row]
            key += stacked[row]
            bound *= sizes[row]
            row += 1
            if bar is not None:
                bar.update()
        signature, values = _codes_and_values(key)
        distinct = int(values.shape[0])
    return signature


class _Tables(NamedTuple):
    """The S contingency tables of an estimate against the samples, in one flat array."""

    flat: np.ndarray  # [sum_s rows J_s] float64 the tables one after another
    offsets: np.ndarray  # [S + 1] where each starts in flat
    tables: list[np.ndarray]  # S x [rows, J_s] views of flat


def _sample_tables(pairs: _Pairs, rows: int, prepared: _Samples) -> _Tables:
    """The S tables [rows, J_s] float64 of the estimate (its clusters 0..rows-1) against each
    sample, from one bincount over the P pairs: integer counts, exact in float64, equal to
    :func:`contingency` of the cells."""
    widths = np.asarray(prepared.sizes, dtype=np.int64)  # [S] J_s
    offsets = np.concatenate([[0], np.cumsum(rows * widths)])  # [S + 1]
    index = prepared.signatures[:, pairs.column] + offsets[:-1, None]  # [S, P]
    index += pairs.cluster[None, :] * widths[:, None]
    weights = np.broadcast_to(pairs.cells, index.shape)
    flat = np.bincount(index.ravel(), weights=weights.ravel(), minlength=int(offsets[-1]))
    bounds = zip(offsets[:-1], offsets[1:], prepared.sizes, strict=True)
    tables = [flat[a:b].reshape(rows, j) for a, b, j in bounds]
    return _Tables(flat, offsets, tables)


BLOCK = 512
""":func:`_joined_rows` sums this many distinct columns at a time over the samples (a sum of
[BLOCK, R] that stays in cache: 4-5x faster than adding [U, R] gathers on 157,574 columns)."""


def _joined_rows(
    tables: list[np.ndarray],
    rows: np.ndarray | None,
    prepared: _Samples,
    loss: str,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """[U, R] sum_s f(n^s_{k' j_s(u)} + 1) - f(n^s_{k' j_s(u)}) for every distinct column u and
    the clusters k' in ``rows`` (None: all k + 1), summed in the samples' order from 0.0; a
    column's terms side by side (a row gather of each table's transpose, 4x faster than a
    column gather on a 64,319-cell map). A cluster's terms depend on its cells only, so the
    search keeps those of clusters a sweep left alone: with ``out`` [U, k + 1] it writes them
    into its columns ``rows`` (all where None) and returns ``out``."""
    count = tables[0].shape[0] if rows is None else rows.shape[0]  # R
    joins = []  # S x [J_s, R]
    for table in tables:
        part = table if rows is None else table[rows]  # [R, J]
        joins.append(np.ascontiguousarray((_f(part + 1, loss) - _f(part, loss)).T))
    width = prepared.signatures.shape[1]  # U
    joined = np.empty((width, count)) if out is None else out  # [U, R] or [U, k + 1]
    total, gathered = np.empty((BLOCK, count)), np.empty((BLOCK, count))  # in cache
    for start in range(0, width, BLOCK):
        stop = min(start + BLOCK, width)
        block, terms = total[: stop - start], gathered[: stop - start]
        block.fill(0.0)
        for join, columns in zip(joins, prepared.signatures, strict=True):
            np.take(join, columns[start:stop], axis=0, out=terms, mode="clip")  # valid: no clip
            block += terms
        if out is None or rows is None:
            joined[start:stop] = block
        else:
            joined[start:stop, rows] = block
    return joined


def _kept_columns(buffer: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """[U, width] the search's buffer of join terms after a move: ``buffer`` [U, width >= k + 1]
    holds those of the clusters 0..k in its first k + 1 columns; the returned buffer holds
    those of the clusters ``kept`` [kk] (old names, ascending) in its first kk columns and
    leaves column kk (the spare cluster's) to recompute. It is ``buffer`` itself, its columns
    moved a block of rows at a time, where it is wide enough; else a new buffer 8 columns wider
    than needed (kk + 9), for the new clusters to come."""
    count = kept.shape[0]  # kk
    grow = count + 1 > buffer.shape[1]
    if not grow and np.array_equal(kept, np.arange(count)):
        return buffer  # nothing moves
    target = np.empty((buffer.shape[0], count + 9)) if grow else buffer  # [U, width']
    for start in range(0, buffer.shape[0], BLOCK):
        block = buffer[start : start + BLOCK, kept]  # [<= BLOCK, kk] a copy: safe in place
        target[start : start + BLOCK, :count] = block
    return target


def _departed(pairs: _Pairs, tables: list[np.ndarray], prepared: _Samples, loss: str):
    """[P] sum_s f(n^s_{k j_s} - 1) - f(n^s_{k j_s}): a cell of each pair leaving its table
    entries, summed in the samples' order."""
    departed = np.zeros(pairs.cluster.shape[0])  # [P]
    for table, columns in zip(tables, prepared.signatures, strict=True):
        depart = _f(table - 1, loss) - _f(table, loss)  # [k + 1, J]
        departed += depart[pairs.cluster, columns[pairs.column]]
    return departed


def _trial_change(
    movers: np.ndarray,
    estimate: np.ndarray,
    target: np.ndarray,
    sizes: np.ndarray,
    tables: _Tables,
    prepared: _Samples,
    loss: str,
) -> float:
    """The change of the expected loss (times Z) when the cells ``movers`` go to ``target``,
    from the table entries they change only (at most 2 M per sample): equal to the difference
    of two :func:`_expected` to rounding (~1e-16 of the sums), not to the bit."""
    source, dest = estimate[movers], target[movers]  # [M]
    count = sizes.shape[0]  # k + 1
    grow = np.bincount(dest, minlength=count) - np.bincount(source, minlength=count)  # [k + 1]
    touched = np.flatnonzero(grow)
    total = float((_f(sizes[touched] + grow[touched], loss) - _f(sizes[touched], loss)).sum())
    widths = np.asarray(prepared.sizes, dtype=np.int64)[:, None]  # [S, 1]
    base = prepared.codes[:, movers] + tables.offsets[:-1, None]  # [S, M] flat index of column
    index = np.concatenate([(base + source * widths).ravel(), (base + dest * widths).ravel()])
    entries, inverse = np.unique(index, return_inverse=True)
    step = np.bincount(inverse.reshape(-1), weights=np.repeat([-1.0, 1.0], base.size))
    before = tables.flat[entries]
    shared = float((_f(before + step, loss) - _f(before, loss)).sum())
    return total - 2.0 * shared / len(prepared.sizes)


def _moved_tables(
    tables: _Tables,
    kept: np.ndarray,
    movers: np.ndarray,
    estimate: np.ndarray,
    target: np.ndarray,
    prepared: _Samples,
) -> _Tables:
    """The tables [kk + 1, J_s] after the cells ``movers`` went to ``target``, from ``tables``
    [k + 1, J_s]: the rows of the clusters ``kept`` [kk] (old names, in order: the renaming of
    :func:`compact`), a spare empty row, and the movers' counts moved. Integer counts: equal to
    :func:`_sample_tables` of the moved estimate, to the bit."""
    widths = np.asarray(prepared.sizes, dtype=np.int64)  # [S]
    rows = kept.shape[0] + 1  # kk + 1
    offsets = np.concatenate([[0], np.cumsum(rows * widths)])  # [S + 1]
    flat = np.zeros(int(offsets[-1]))
    for old, a, j in zip(tables.tables, offsets[:-1], prepared.sizes, strict=True):
        flat[a : a + (rows - 1) * j].reshape(rows - 1, j)[:] = old[kept]
    rename = np.full(tables.tables[0].shape[0], -1, dtype=np.int64)  # [k + 1] old -> new
    rename[kept] = np.arange(kept.shape[0])
    base = prepared.codes[:, movers] + offsets[:-1, None]  # [S, M]
    source = rename[estimate[movers]]  # [M] -1: a cluster the moves emptied, its row dropped
    left = (base + source * widths[:, None])[:, source >= 0]
    np.subtract.at(flat, left.ravel(), 1.0)
    np.add.at(flat, (base + rename[target[movers]] * widths[:, None]).ravel(), 1.0)
    bounds = zip(offsets[:-1], offsets[1:], prepared.sizes, strict=True)
    return _Tables(flat, offsets, [flat[a:b].reshape(rows, j) for a, b, j in bounds])
