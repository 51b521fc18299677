"""Identical rows of sparse matrices, grouped without a per-row loop.

The grouping the factored counts use twice: the observations of one footprint
(:func:`~spcopyro.data.factored_counts.spread_sources`: identical rows of the footprints'
weights) and the observed cells of one footprint pattern
(:func:`spcopyro.gibbs.numba_background.row_classes`: identical rows of every modality's
weights). Rows are compared by their bits, as a dict keyed on the rows' bytes compares them, and
the groups are numbered by their first rows, as such a dict numbers its keys as they come.
"""

from __future__ import annotations

import numpy as np

__all__ = ["identical_rows"]


def identical_rows(
    *matrices: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """Rows m and m' of M share a group where every matrix's row m holds the same indices and the
    same values, in the same order and bit for bit, as its row m' (so 0.0 and -0.0 differ, a NaN
    matches a NaN of the same bits alone, and an empty row differs from a row of one stored 0).

    Each matrix is a CSR triple ``(indptr, indices, data)``: indptr [M + 1], row m's entries at
    indptr[m]:indptr[m + 1] of indices and data [nnz], values of at most 8 bytes. Returns
    ``(group, first)``: group [M] int64, each row's group, the groups numbered in the order of
    their first rows; first [U] int64, each group's first row, ascending (so group[first] =
    0, ..., U - 1).

    How: row m's key is its bits in every matrix side by side (``_padded_bits``); a stable sort of
    the keys' bytes puts equal keys next to each other, each run's first row first; runs start
    where adjacent keys differ, and are numbered in the order of their first rows. Memory: M
    sum_matrices (2 max row length + 1) 8 bytes for the keys."""
    if not matrices:
        raise ValueError("identical_rows needs at least one matrix, got none")
    M = len(matrices[0][0]) - 1
    for number, (indptr, _, _) in enumerate(matrices):
        if len(indptr) - 1 != M:
            raise ValueError(f"identical_rows: matrix {number} has {len(indptr) - 1} rows, "
                             f"matrix 0 has {M}")  # fmt: skip
    keys = np.concatenate([_padded_bits(*matrix) for matrix in matrices], axis=1)  # [M, W] uint64
    rows = keys.view(np.dtype((np.void, keys.shape[1] * keys.itemsize)))[:, 0]  # [M] W*8 bytes
    order = np.argsort(rows, kind="stable")  # [M] equal keys in runs, each by row
    ordered = keys[order]  # [M, W]
    starts = np.ones(M, dtype=bool)  # [M] where a run of equal keys starts in ``order``
    starts[1:] = (ordered[1:] != ordered[:-1]).any(axis=1)
    run_first = order[starts]  # [U] each run's first row
    by_first = np.argsort(run_first)  # [U] the runs by their first row
    number = np.empty(by_first.size, dtype=np.int64)  # [U] run -> group
    number[by_first] = np.arange(by_first.size, dtype=np.int64)
    group = np.empty(M, dtype=np.int64)  # [M]
    group[order] = number[np.cumsum(starts) - 1]
    first = run_first[by_first].astype(np.int64, copy=False)  # [U] ascending
    return group, first


def _padded_bits(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray) -> np.ndarray:
    """[M, 2 R + 1] uint64, R = the longest row's length: row m's length, then its indices' bits
    and its values' bits, each padded with zeros to R. Two rows' keys are equal exactly where
    the rows hold the same indices and values, bit for bit, in the same order."""
    indptr = np.asarray(indptr)
    lengths = np.diff(indptr)  # [M]
    R = int(lengths.max(initial=0))
    filled = np.arange(R) < lengths[:, None]  # [M, R] row m's first lengths[m] places
    entries = slice(indptr[0], indptr[-1])  # the rows' entries, row after row
    keys = np.zeros((lengths.size, 2 * R + 1), dtype=np.uint64)  # [M, 2 R + 1]
    keys[:, 0] = lengths
    keys[:, 1 : R + 1][filled] = _bits(np.asarray(indices)[entries])
    keys[:, R + 1 :][filled] = _bits(np.asarray(data)[entries])
    return keys


def _bits(values: np.ndarray) -> np.ndarray:
    """[n] uint64: each value's bit pattern (at most 8 bytes), zero-extended."""
    values = np.ascontiguousarray(values)
    if values.dtype.itemsize > 8 or values.dtype.hasobject:
        raise ValueError(f"identical_rows compares values of at most 8 bytes, got {values.dtype}")
    return values.view(np.dtype(f"u{values.dtype.itemsize}")).astype(np.uint64, copy=False)
