"""A compiled (numba) path for memoized VI's two dense loops (:mod:`spcopyro.guides.memoized`,
whose docstring states the math): a step's local mean-field sweeps over its blocks' cells, and
the ELBO's sums over neighbour pairs and cells. The memo, the global updates and the rest stay
in torch; the results equal the torch path's to rounding (tested).

The local update of cell i (eq. 13 in expectation) reads E log pi ``[L]``, its neighbours'
q and, for an observed cell, its row of the step's expected log-likelihoods (computed in torch
for the step's observed cells only, as the torch path does): one pass over the D neighbours'
rows and one softmax in float64, written back in q's dtype. Importing this module raises
:class:`ImportError` when numba is missing.
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from spcopyro.config import SpCoConfig
from spcopyro.guides.factors import GlobalFactors, expected_log_emissions, expected_log_pi
from spcopyro.model import DTYPE, ModelData

__all__ = ["local_step", "pair_and_entropy_sums"]


@njit(cache=True)
def _local_sweeps(
    q: np.ndarray,
    order: np.ndarray,
    starts: np.ndarray,
    batch: np.ndarray,
    neighbours: np.ndarray,
    local_rows: np.ndarray,
    loglik: np.ndarray,
    log_pi: np.ndarray,
    gamma: float,
    sweeps: int,
) -> None:
    """q [N, L] in place: ``sweeps`` times, colour class after colour class, every cell of the
    blocks ``batch [b]`` (``order[starts[b, c] : starts[b, c + 1]]``, blocks.Blocks) set to
    softmax(log_pi + gamma sum_{r ~ i} q_r + loglik[local_rows[i]]) (the last term only where
    local_rows[i] >= 0; loglik [m, L] float64)."""
    L = q.shape[1]
    D = neighbours.shape[1]
    colours = starts.shape[1] - 1
    around = np.empty(L, q.dtype)  # summed in q's dtype, as the torch path sums
    logits = np.empty(L)
    for _ in range(sweeps):
        for c in range(colours):
            for b in batch:
                for p in range(starts[b, c], starts[b, c + 1]):
                    i = order[p]
                    around[:] = 0.0
                    for d in range(D):
                        j = neighbours[i, d]
                        if j >= 0:
                            for l in range(L):
                                around[l] += q[j, l]
                    top = -np.inf
                    m = local_rows[i]
                    for l in range(L):
                        logits[l] = log_pi[l] + gamma * np.float64(around[l])
                        if m >= 0:
                            logits[l] += loglik[m, l]
                        top = max(top, logits[l])
                    total = 0.0
                    for l in range(L):
                        logits[l] = np.exp(logits[l] - top)
                        total += logits[l]
                    scale = 1.0 / total
                    for l in range(L):
                        q[i, l] = logits[l] * scale


@njit(cache=True)
def _pair_and_entropy(q: np.ndarray, pairs: np.ndarray) -> tuple[float, float]:
    """(sum over pairs (a, b) of q_a . q_b, sum_i H[q_i]) in float64 (q [N, L], pairs [P, 2])."""
    agreements = 0.0
    for p in range(pairs.shape[0]):
        a, b = pairs[p, 0], pairs[p, 1]
        for l in range(q.shape[1]):
            agreements += np.float64(q[a, l]) * np.float64(q[b, l])
    entropy = 0.0
    for i in range(q.shape[0]):
        for l in range(q.shape[1]):
            v = np.float64(q[i, l])
            if v > 0.0:
                entropy -= v * np.log(v)
    return agreements, entropy


def pair_and_entropy_sums(q: torch.Tensor, data: ModelData) -> tuple[float, float]:
    """(sum over neighbour pairs of q_a . q_b, sum_i H[q_i]) of q ``[N, L]``, compiled."""
    pairs = np.ascontiguousarray(data.pairs.numpy(), dtype=np.int64)
    return _pair_and_entropy(q.numpy(), pairs)


def local_step(
    q: torch.Tensor,
    factors: GlobalFactors,
    data: ModelData,
    config: SpCoConfig,
    blocks: tuple,
    batch: list[int],
    gamma: float,
    observed: tuple,
    local_rows: np.ndarray,
    sweeps: int = 1,
) -> None:
    """:func:`spcopyro.guides.memoized.local_step`, compiled: q ``[N, L]`` of the blocks in
    ``batch`` updated in place. ``observed``: the memo's observed cells grouped by block
    (``cells [M]``, ``rows [M]``, ``starts [B + 1]``); ``local_rows`` ``[N]`` int64 scratch, all
    -1 (left so)."""
    log_pi = expected_log_pi(factors)  # [L]
    log_phi = expected_log_emissions(factors)  # per modality [L, K_m]
    cells = [observed.cells[int(observed.starts[b]) : int(observed.starts[b + 1])] for b in batch]
    rows = [observed.rows[int(observed.starts[b]) : int(observed.starts[b + 1])] for b in batch]
    cells_t, rows_t = torch.cat(cells), torch.cat(rows)  # [m] the step's observed cells
    loglik = torch.zeros(cells_t.numel(), q.shape[1], dtype=DTYPE)  # [m, L]
    for modality, lphi in zip(data.modalities, log_phi, strict=True):
        if config.uses(modality.name) and cells_t.numel():
            loglik += modality.counts[rows_t] @ lphi.T  # [m, K_m] @ [K_m, L]
    observed_cells = cells_t.numpy()
    local_rows[observed_cells] = np.arange(observed_cells.size)
    try:
        _local_sweeps(
            q.numpy(), blocks.order.numpy(), blocks.starts.numpy(),
            np.asarray(batch, dtype=np.int64), data.neighbours.numpy(), local_rows,
            np.ascontiguousarray(loglik.numpy()), log_pi.numpy(), float(gamma), int(sweeps),
        )  # fmt: skip
    finally:
        local_rows[observed_cells] = -1
