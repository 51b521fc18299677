r"""The split-merge move's launch and restricted scans, compiled (:mod:`spcopyro.gibbs.merge`).

The same proposal as the torch functions ``_launch`` and ``_restricted_scan`` of
:mod:`spcopyro.gibbs.merge` -- the launch state by breadth-first distances to i and j inside T
(ties, and cells that reach neither, by a fair coin), and restricted scans that redraw each cell
of T but i and j between the two sides, colour block by colour block, with the probabilities

.. math::

    q_k(s) \propto e^{\gamma n_s(k)} \, (a_\pi + m^{-k}_s)
        \prod_u \frac{B(a_u + n^{u,-k}_s + x^u_k)}{B(a_u + n^{u,-k}_s)}

(side totals taken at the block's start without k) -- as loops over T instead of tensors of it:
a move on two concepts of a settled public-house map cost ~38 ms in torch (most of the default
preset's time per sweep; issue 15) and costs a few here. Its random numbers come from the
compiled sampler's own stream (:mod:`spcopyro.gibbs.numba_random`, seeded from the move's
generator), so a chain on the numba backend makes other moves than one on torch, from the same
distribution: the enumerated-posterior tests run both.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spcopyro.gibbs.numba_random import bits_to_uniform, next_bits

UNREACHED = np.iinfo(np.int64).max


@njit(cache=True, nogil=True)
def _distances(neighbours: np.ndarray, source: int) -> np.ndarray:
    """[n] breadth-first distances inside T from ``source`` (UNREACHED where none)."""
    n = neighbours.shape[0]
    distance = np.full(n, UNREACHED, np.int64)
    queue = np.empty(n, np.int64)
    distance[source], queue[0] = 0, source
    head, tail = 0, 1
    while head < tail:
        k = queue[head]
        head += 1
        for s in range(neighbours.shape[1]):
            m = neighbours[k, s]
            if m >= 0 and distance[m] == UNREACHED:
                distance[m] = distance[k] + 1
                queue[tail] = m
                tail += 1
    return distance


@njit(cache=True, nogil=True)
def launch_sides(neighbours: np.ndarray, first: int, second: int, state: np.ndarray) -> np.ndarray:
    """[n_T] int64 launch sides: 0 nearer to ``first``, 1 nearer to ``second`` along the grid
    inside T (``neighbours`` [n_T, D] local indices, -1 outside T); ties by a fair coin."""
    near_first = _distances(neighbours, first)
    near_second = _distances(neighbours, second)
    n = neighbours.shape[0]
    side = np.empty(n, np.int64)
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for k in range(n):
        if near_first[k] < near_second[k]:
            side[k] = 0
        elif near_second[k] < near_first[k]:
            side[k] = 1
        else:
            bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
            side[k] = 1 if bits_to_uniform(bits) < 0.5 else 0
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    side[first], side[second] = 0, 1
    return side


@njit(cache=True, nogil=True)
def _side_terms(
    concentration: float, totals: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The per-block caches of :func:`_predictive_sides` for both sides' ``totals`` [2, K]:
    lgamma(a + totals) [2, K], the sums S [2] and lgamma(K a + S) [2]."""
    K = totals.shape[1]
    log_gammas = np.empty_like(totals)  # [2, K]
    sums = np.empty(2)  # [2]
    log_gamma_sums = np.empty(2)  # [2]
    for s in range(2):
        acc = 0.0
        for c in range(K):
            log_gammas[s, c] = math.lgamma(concentration + totals[s, c])
            acc += totals[s, c]
        sums[s] = acc
        log_gamma_sums[s] = math.lgamma(K * concentration + acc)
    return log_gammas, sums, log_gamma_sums


@njit(cache=True, nogil=True)
def _predictive_sides(
    concentration: float,
    totals: np.ndarray,
    log_gammas: np.ndarray,
    sums: np.ndarray,
    log_gamma_sums: np.ndarray,
    x: np.ndarray,
    own: int,
) -> tuple[float, float]:
    """(log B(a + n_0 + x) - log B(a + n_0), the same for side 1) of a cell on side ``own``:
    n_s = totals[s] - x on its own side (the totals without the cell), totals[s] on the other.
    Classes the cell has no count of cancel, so only its nonzero x_c cost anything, and the
    log-gammas of the totals come from :func:`_side_terms` (once a block): one log-gamma per
    nonzero class and side. (0, 0) for K = 0: a Dirichlet over no items is the point mass on
    the empty vector (the lgamma(0 a) of its caches is inf)."""
    if x.shape[0] == 0:
        return 0.0, 0.0
    other = 1 - own
    value_own = 0.0
    value_other = 0.0
    total_x = 0.0
    for c in range(x.shape[0]):
        xc = x[c]
        if xc != 0.0:
            value_own += log_gammas[own, c] - math.lgamma(concentration + totals[own, c] - xc)
            value_other += math.lgamma(concentration + totals[other, c] + xc) - log_gammas[other, c]
            total_x += xc
    K = x.shape[0]
    value_own -= log_gamma_sums[own] - math.lgamma(K * concentration + sums[own] - total_x)
    value_other -= math.lgamma(K * concentration + sums[other] + total_x) - log_gamma_sums[other]
    if own == 0:
        return value_own, value_other
    return value_other, value_own


@njit(cache=True, nogil=True, inline="always")
def _log_sides(logit0: float, logit1: float) -> tuple[float, float]:
    """(log q(0), log q(1)) of two logits (a two-way log-softmax)."""
    top = max(logit0, logit1)
    log_norm = top + math.log(math.exp(logit0 - top) + math.exp(logit1 - top))
    return logit0 - log_norm, logit1 - log_norm


@njit(cache=True, nogil=True, inline="always")
def _in_t(neighbours: np.ndarray, k: int) -> int:
    """How many of cell k's neighbours lie in T."""
    count = 0
    for t in range(neighbours.shape[1]):
        count += neighbours[k, t] >= 0
    return count


@njit(cache=True, nogil=True)
def restricted_scan(
    side: np.ndarray,
    neighbours: np.ndarray,
    block_cells: np.ndarray,
    block_starts: np.ndarray,
    observed: np.ndarray,
    counts: tuple,
    concentrations: np.ndarray,
    num_used: int,
    gamma: float,
    a_pi: float,
    forced: np.ndarray,
    use_forced: bool,
    state: np.ndarray,
) -> float:
    """One restricted scan of ``side`` [n_T] (in place); returns log q of its outcome.

    ``block_cells`` / ``block_starts`` [B + 1]: the local cells of each colour block, i and j
    left out; ``observed`` [M_T] local indices of T's observed cells, ``counts`` per modality in
    use [M_T, K_u], ``concentrations`` [U]; only the first ``num_used`` count (the tuple is
    never empty: with no modality in use it holds a placeholder). With ``use_forced`` nothing is
    drawn: the scan lands on ``forced`` and returns that outcome's log probability (the reverse
    of a merge).
    """
    n = side.shape[0]
    row_of = np.full(n, -1, np.int64)  # [n_T] row in ``observed``
    for r in range(observed.shape[0]):
        row_of[observed[r]] = r
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    log_q = 0.0
    for b in range(block_starts.shape[0] - 1):
        start, stop = block_starts[b], block_starts[b + 1]
        if start == stop:
            continue
        sizes = np.zeros(2)  # [2] cells on each side at the block's start
        for k in range(n):
            sizes[side[k]] += 1.0
        totals = [np.zeros((2, 0))]  # per modality [2, K_u] of each side at the block's start
        totals.clear()
        caches = [_side_terms(1.0, np.zeros((2, 1)))]  # per modality: _side_terms of totals
        caches.clear()
        for u in range(num_used):
            per = np.zeros((2, counts[u].shape[1]))
            for r in range(observed.shape[0]):
                s = side[observed[r]]
                for c in range(counts[u].shape[1]):
                    per[s, c] += counts[u][r, c]
            totals.append(per)
            caches.append(_side_terms(concentrations[u], per))
        new = np.empty(stop - start, np.int64)
        # Without observations the two logits differ by gamma (n_1 - n_0) + c_1 - c_0, with
        # c_s = log(a_pi + m_s - [own = s]): 2 (2D + 1) values, tabulated once a block.
        D = neighbours.shape[1]
        table = np.empty((2 * D + 1, 2, 3))  # [n_1 - n_0 + D, own] -> log q(0), log q(1), q(0)
        for own in range(2):
            c0 = math.log(a_pi + sizes[0] - (own == 0))
            c1 = math.log(a_pi + sizes[1] - (own == 1))
            for difference in range(-D, D + 1):
                log_p0, log_p1 = _log_sides(0.0, gamma * difference + c1 - c0)
                table[difference + D, own, 0] = log_p0
                table[difference + D, own, 1] = log_p1
                table[difference + D, own, 2] = math.exp(log_p0)
        for p in range(start, stop):
            k = block_cells[p]
            own = side[k]
            difference = 0
            for t in range(D):
                m = neighbours[k, t]
                if m >= 0:
                    difference += 2 * side[m] - 1  # +1 on side 1, -1 on side 0
            r = row_of[k]
            if r < 0:
                log_p0 = table[difference + D, own, 0]
                log_p1 = table[difference + D, own, 1]
                p0 = table[difference + D, own, 2]
            else:
                field1 = (difference + _in_t(neighbours, k)) // 2
                field0 = _in_t(neighbours, k) - field1
                logit0 = gamma * field0 + math.log(a_pi + sizes[0] - (own == 0))
                logit1 = gamma * field1 + math.log(a_pi + sizes[1] - (own == 1))
                for u in range(num_used):
                    log_gammas, sums, log_gamma_sums = caches[u]
                    term0, term1 = _predictive_sides(
                        concentrations[u], totals[u], log_gammas, sums, log_gamma_sums,
                        counts[u][r], own,
                    )  # fmt: skip
                    logit0 += term0
                    logit1 += term1
                log_p0, log_p1 = _log_sides(logit0, logit1)
                p0 = math.exp(log_p0)
            if use_forced:
                chosen = forced[k]
            else:
                bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                chosen = 1 if bits_to_uniform(bits) >= p0 else 0
            log_q += log_p1 if chosen == 1 else log_p0
            new[p - start] = chosen
        for p in range(start, stop):
            side[block_cells[p]] = new[p - start]
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    return log_q
