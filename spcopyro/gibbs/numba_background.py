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
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from spcopyro._util.threads import one_blas_thread
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.state import GibbsState
from spcopyro.model import ModelData

__all__ = ["background_table"]


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
    state: GibbsState, data: ModelData, config: SpCoConfig, out: torch.Tensor
) -> None:
    """Write loglik [M, L] (module docstring) into ``out`` [M, L] (float64, contiguous), the
    modalities switched off in ``config`` left out; factored products where they pay. The
    products run on one thread: the same bits on any thread count (module docstring)."""
    with one_blas_thread():
        _write_log_likelihood(state, data, config, out)


def _write_log_likelihood(
    state: GibbsState, data: ModelData, config: SpCoConfig, out: torch.Tensor
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


def background_table(state: GibbsState, data: ModelData, config: SpCoConfig) -> np.ndarray:
    """[M + 1, L + D] the per-cell backgrounds B (module docstring), the D last columns 0: the
    sentinel labels of missing neighbours.

    Raises:
        ValueError: log pi + loglik not finite in some row (naming it).
    """
    L, D, M = config.num_concepts, data.neighbours.shape[1], data.obs_cells.shape[0]
    # The products run in torch (MKL), on one thread: numpy's OpenBLAS threads would fight
    # torch's OpenMP threads.
    logits_t = torch.empty(M + 1, L, dtype=torch.float64)  # [M + 1, L]
    write_log_likelihood(state, data, config, logits_t[:M])
    logits = logits_t.numpy()
    log_pi = np.ascontiguousarray(state.log_pi.detach().cpu().numpy(), dtype=np.float64)  # [L]
    row = _centre_rows(logits, log_pi)  # row M: pi's; NaN or +inf anywhere shows in a maximum
    if row >= 0:
        where = f"the observed cell in row {row} of data.obs_cells" if row < M else "pi"
        raise ValueError(
            f"log pi + observation log-likelihood is not finite for {where}: NaN or infinite "
            "values in GibbsState.log_pi / log_emissions or in the data's counts"
        )
    table = np.zeros((M + 1, L + D))  # [M + 1, L + D]
    np.exp(logits, out=table[:, :L])
    return table
