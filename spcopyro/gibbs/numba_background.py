r"""The per-sweep background table of the compiled sweep (:mod:`spcopyro.gibbs.numba_sweep`).

For observed cell m (row m of ``data.obs_cells``) and concept l,

.. math::

    B_{ml} = \exp\bigl(\log\pi_l + \mathrm{loglik}_{ml} - \max_{l'}(\cdot)\bigr), \qquad
    \mathrm{loglik}_{ml} = \sum_{\text{modalities}} x_m \cdot \log\phi_l

(eqs. 5, 6: f_m . log theta_l + S_m . log w_l, and any further modality), and row M holds
exp(log pi - max), the background of every cell without observations (eq. 13).

Each modality's product ``x log(phi)^T`` [M, L] is the sweep's largest piece of arithmetic when
an observation footprint spreads a few dozen observations over hundreds of cells (preset
``coarse``: M = 686 observed cells on room2ldk4, K = 205 image classes, L = 120). There the
counts are a product themselves, ``x = A X`` with S distinct footprints
(:class:`~spcopyro.data.factored_counts.SpreadSources`, S = 75 on room2ldk4), and the table is built
as ``A (X log(phi)^T)``: S K L + nnz(A) L multiply-adds instead of M K L, a ninth there.
Both orders give the same table to rounding (about 1e-15 relative); a modality without a
footprint, or whose factored form would not pay, takes the dense product.

The products run on one BLAS thread (:func:`~spcopyro._util.threads.one_blas_thread`: MKL's
count for the calling thread only), whatever the fit's count, so the table, and the draws
against it, do not depend on the thread count by construction. A BLAS that splits a product
across threads sums it in another order, and MKL's split depends on its code path: on its
AVX-512 path (MKL 2024.2, torch 2.14.1) a contiguous copy of log(phi)^T gave the same bits on 1
and 2+ threads (the transposed view did not, from 86 rows on), but on its AVX2 path (what MKL
runs on AMD and pre-AVX-512 Intel; ``MKL_ENABLE_INSTRUCTIONS=AVX2``) the copy's product too
differed between thread counts at 60, 85, 86, 100 and 105 rows. Maps of fewer than
:data:`~spcopyro._util.threads.MIN_CELLS_FOR_MORE_THREADS` free cells run on one thread anyway
(docs/speed.md, "Threads"). Each product still takes log(phi)^T as a contiguous [K, L] copy (a
single row: the transposed view), the operand the fits since b98aaa2 were seeded with: on one
thread its bits differ from the view's (up to 1.4e-13), so the pinned outputs keep theirs.

**One row per footprint pattern** (:class:`RowClasses`). Where every modality takes the factored
product, a row of the table depends only on its cell's weights (which footprints, how much):
cells of the same weights in every modality get the same row, to the bit (the same entries added
in the same order, then the same centring and exp). A reach share (``footprint_reach_share``)
observes every cell of a Voronoi cell with the same small weight, so on the map's own cells its
rows repeat: 23,649 observed cells but 221 patterns on an open-plan synthetic house (seed 0,
0.05 m, share 0.2 in rooms), 887 cells and 224 patterns at the default's 0.25 m. The compiled
sweep (:mod:`~spcopyro.gibbs.numba_sweep`) therefore builds the table on one row per pattern
(:func:`row_classes`) and points each cell to its pattern's row: the label draws read the same
numbers, so the fit is the same bit for bit (docs/real_houses.md, "Voronoi cells within
rooms", the stage-two share's cost, 2026-12-06).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
import torch
from numba import njit

from spcopyro._util.threads import one_blas_thread
from spcopyro.config import SpCoConfig
from spcopyro.data.factored_counts import SpreadSources
from spcopyro.data.identical_rows import identical_rows
from spcopyro.gibbs.state import GibbsState
from spcopyro.model import ModelData

__all__ = ["RowClasses", "background_table", "row_classes"]


class RowClasses(NamedTuple):
    """The observed cells grouped by their weights (module docstring, "One row per footprint
    pattern"): U classes, numbered by their first cell."""

    of: np.ndarray  # [M + 1] int32: each observed cell's class; M (pi's row) -> U
    first: np.ndarray  # [U] int64: the first observed cell of each class, ascending
    spreads: tuple[SpreadSources, ...]  # per modality: the weights of the rows ``first`` alone


def row_classes(data: ModelData) -> RowClasses | None:
    """The :class:`RowClasses` of ``data``'s observed cells where every modality's counts have a
    factored form that pays (the table is then built from the weights alone); else None (a
    dense product's rows are left as they are). Cached per factored form (by identity)."""
    spreads = [modality.factored() for modality in data.modalities]
    if not spreads or any(spread is None or not spread.pays() for spread in spreads):
        return None
    return _row_classes(tuple(spreads))


@functools.lru_cache(maxsize=8)
def _row_classes(spreads: tuple[SpreadSources, ...]) -> RowClasses:
    """Cells m and m' share a class where every spread's row m holds the same footprints with
    the same weights, bit for bit, as row m' (:func:`~spcopyro.data.identical_rows.identical_rows`,
    the grouping :func:`~spcopyro.data.factored_counts.spread_sources` gives the observations'
    footprints): the classes come numbered by their first cell."""
    M = spreads[0].indptr.size - 1
    group, first = identical_rows(*((s.indptr, s.indices, s.weights) for s in spreads))  # [M], [U]
    of = np.empty(M + 1, dtype=np.int32)  # [M + 1]
    of[:M] = group
    of[M] = first.size
    return RowClasses(of, first, tuple(_rows_of(spread, first) for spread in spreads))


def _rows_of(spread: SpreadSources, rows: np.ndarray) -> SpreadSources:
    """``spread``'s rows ``rows`` [U] alone, each with its entries in their order."""
    lengths = np.diff(spread.indptr)[rows]  # [U]
    indptr = np.zeros(rows.size + 1, dtype=np.int64)  # [U + 1]
    np.cumsum(lengths, out=indptr[1:])
    take = np.repeat(spread.indptr[rows] - indptr[:-1], lengths) + np.arange(indptr[-1])  # [nnz']
    return SpreadSources(indptr, np.ascontiguousarray(spread.indices[take]),
                         np.ascontiguousarray(spread.weights[take]), spread.sources)  # fmt: skip


@njit(cache=True, nogil=True)
def _add_weighted_rows(
    indptr: np.ndarray,
    indices: np.ndarray,
    weights: np.ndarray,
    rows: np.ndarray,
    out: np.ndarray,
) -> None:
    """out[m] += sum_j weights[j] rows[indices[j]] over row m's entries j of the CSR matrix
    (indptr [M + 1], indices / weights [nnz]); rows [S, L], out [>= M, L]."""
    for m in range(indptr.shape[0] - 1):
        for j in range(indptr[m], indptr[m + 1]):
            weight = weights[j]
            source = indices[j]
            for column in range(rows.shape[1]):
                out[m, column] += weight * rows[source, column]


def write_log_likelihood(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    out: torch.Tensor,
    classes: RowClasses | None = None,
) -> None:
    """Write loglik [M, L] (module docstring) into ``out`` [M, L] (float64, contiguous), the
    modalities switched off in ``config`` left out; factored products where they pay. The
    products run on one thread: the same bits on any thread count (module docstring). With
    ``classes`` (:func:`row_classes` of ``data``): the rows of ``classes.first`` alone, ``out``
    [U, L]."""
    with one_blas_thread():
        _write_log_likelihood(state, data, config, out, classes)


def _write_log_likelihood(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    out: torch.Tensor,
    classes: RowClasses | None = None,
) -> None:
    out.zero_()
    for index, (modality, table) in enumerate(
        zip(data.modalities, state.log_emissions, strict=True)
    ):
        if not config.uses(modality.name):
            continue
        log_phi = table.detach().to(torch.float64)  # [L, K_m]
        factored = modality.factored()
        if factored is not None and factored.pays():
            if classes is not None:  # the same entries of the classes' first rows alone
                factored = classes.spreads[index]
            sources = torch.from_numpy(factored.sources)  # [S, K_m]
            per_source = torch.matmul(sources, _right_operand(log_phi, len(sources))).numpy()
            _add_weighted_rows(  # per_source [S, L]
                factored.indptr, factored.indices, factored.weights, per_source, out.numpy()
            )
        elif index == 0:
            counts = modality.counts.to(torch.float64)  # [M, K_m]
            torch.matmul(counts, _right_operand(log_phi, len(counts)), out=out)  # [M, L]
        else:
            counts = modality.counts.to(torch.float64)  # [M, K_m]
            out.addmm_(counts, _right_operand(log_phi, len(counts)))  # [M, K_m] @ [K_m, L]


def _right_operand(log_phi: torch.Tensor, rows: int) -> torch.Tensor:
    """log_phi [L, K] as the [K, L] right operand of a product with ``rows`` rows: a contiguous
    copy, or for one row the transposed view (the seeded fits' bits, module docstring)."""
    return log_phi.T if rows == 1 else log_phi.T.contiguous()


@njit(cache=True, nogil=True)
def _centre_rows(logits: np.ndarray, log_pi: np.ndarray) -> int:
    """logits [M + 1, L]: the last row set to 0, log_pi [L] added to every row, then each row's
    maximum subtracted from it; returns -1, or the first row whose maximum is not finite (NaN
    anywhere in it, +inf, or all -inf; that row and later ones are then left unfinished).

    The numpy steps' arithmetic to the bit (each entry one IEEE add and one subtract of the same
    values; a maximum is exact), in one pass instead of five array operations (~15 us a sweep).
    """
    R, L = logits.shape
    for l in range(L):
        logits[R - 1, l] = 0.0
    for r in range(R):
        top = -np.inf
        for l in range(L):
            value = logits[r, l] + log_pi[l]
            logits[r, l] = value
            if value > top or value != value:  # a NaN stays the maximum, as in numpy
                top = value
        if not -np.inf < top < np.inf:
            return r
        for l in range(L):
            logits[r, l] -= top
    return -1


def background_table(
    state: GibbsState, data: ModelData, config: SpCoConfig, classes: RowClasses | None = None
) -> np.ndarray:
    """[M + 1, L + D] the per-cell backgrounds B (module docstring), the D last columns 0: the
    sentinel labels of missing neighbours. With ``classes`` (:func:`row_classes` of ``data``):
    [U + 1, L + D], row u the rows of class u's cells (``classes.of`` points each observed cell
    to its row; the last row is pi's), the same numbers to the bit.

    Raises:
        ValueError: log pi + loglik not finite in some row (naming the first observed cell whose
            row it is).
    """
    L, D = config.num_concepts, data.neighbours.shape[1]
    M = data.obs_cells.shape[0] if classes is None else classes.first.shape[0]
    # The products run in torch (MKL), on one thread: numpy's OpenBLAS threads would fight
    # torch's OpenMP threads.
    logits_t = torch.empty(M + 1, L, dtype=torch.float64)  # [M + 1, L]
    write_log_likelihood(state, data, config, logits_t[:M], classes)
    logits = logits_t.numpy()
    log_pi = np.ascontiguousarray(state.log_pi.detach().cpu().numpy(), dtype=np.float64)  # [L]
    row = _centre_rows(logits, log_pi)  # row M: pi's; NaN or +inf anywhere shows in a maximum
    if row >= 0:  # a class's first cell: the first cell of any class after it comes later
        cell = row if classes is None or row >= M else int(classes.first[row])
        where = f"the observed cell in row {cell} of data.obs_cells" if row < M else "pi"
        raise ValueError(
            f"log pi + observation log-likelihood is not finite for {where}: NaN or infinite "
            "values in GibbsState.log_pi / log_emissions or in the data's counts"
        )
    table = np.zeros((M + 1, L + D))  # [M + 1, L + D]
    np.exp(logits, out=table[:, :L])
    return table
