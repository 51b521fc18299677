"""The compiled kernels of the sparse mean-field backend (:mod:`spcopyro.guides.numba_cavi`,
whose docstring states the math): the colour-block cell update over the sparse q, the running
sums' recount, the observed cells' rows, entropies, and conversion to and from a dense q.
Private to that module; numba compiles them on first use and caches them on disk.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _insert(top_l, top_w, size, capacity, label, weight):  # noqa: ANN001, ANN202
    """Insert (label, weight) into the descending top list of length ``size`` <= capacity;
    returns the new size."""
    if size == capacity and weight <= top_w[size - 1]:
        return size
    pos = size if size < capacity else capacity - 1
    while pos > 0 and top_w[pos - 1] < weight:
        top_w[pos] = top_w[pos - 1]
        top_l[pos] = top_l[pos - 1]
        pos -= 1
    top_w[pos] = weight
    top_l[pos] = label
    return size + 1 if size < capacity else size


@njit(cache=True)
def _select(cand_l, cand_w, nc, top_l, top_w):  # noqa: ANN001, ANN202
    """The (at most K = len(top_l)) largest of the nc candidates into top_l, top_w, the largest
    first (the rest unordered when all fit, else descending); returns how many."""
    K = top_l.shape[0]
    if nc > K:
        size = 0
        for c in range(nc):
            size = _insert(top_l, top_w, size, K, cand_l[c], cand_w[c])
        return size
    best = 0
    for c in range(nc):
        top_l[c] = cand_l[c]
        top_w[c] = cand_w[c]
        if cand_w[c] > cand_w[best]:
            best = c
    top_l[0], top_l[best] = top_l[best], top_l[0]
    top_w[0], top_w[best] = top_w[best], top_w[0]
    return nc


@njit(cache=True)
def _update_cells(
    index: np.ndarray,
    value: np.ndarray,
    count: np.ndarray,
    cells: np.ndarray,
    neighbours: np.ndarray,
    rows: np.ndarray,
    log_pi: np.ndarray,
    order: np.ndarray,
    background: np.ndarray,
    background_total: float,
    observed_logits: np.ndarray,
    gamma: float,
    threshold: float,
    damping: float,
    mark: np.ndarray,
    field: np.ndarray,
    touched: np.ndarray,
    weight: np.ndarray,
    entropy: np.ndarray,
    moved: np.ndarray,
    drift: np.ndarray,
    row_drift: np.ndarray,
    tolerance: float,
    sizes: np.ndarray,
    argmax_cells: np.ndarray,
    totals: np.ndarray,
) -> tuple[float, int]:
    """Every cell of the plan (block after block) set to its truncated mean-field update in
    place, except the cells the active set skips; returns (sum_i -log(kept mass fraction), the
    bound on the ELBO lost to the threshold; the number of cells updated).

    log_pi [L] (minus its max), order [L] concepts by descending log_pi, background [L]
    exp(log_pi), observed_logits [M, L] E log pi + loglik (row-wise max subtracted);
    mark [L] int64, field [L], touched [L], weight [L] scratch. Per cell (N + D rows):
    entropy H[q_i] (kept up to date), moved max_l |change of q_i(l)| at its last visit (0 when
    skipped), drift the bound on how far its logits moved since its last update (inf: update).
    row_drift [M + 1] the bound for this pass's change of the logits shared by a background row
    (row M: the cells without observations). A cell is skipped when drift + row_drift +
    gamma * sum of its neighbours' moved <= tolerance (module docstring, "Active set").
    sizes [L] sum_i q_i, argmax_cells [L] and totals [2] (sum_i H[q_i], sum over pairs of
    q_a . q_b) are kept up to date cell by cell (the change of the pairs' term is
    (q_i new - q_i old) . n(i), the field the update read); not the pairs' term with damping.
    """
    K = index.shape[1]
    D = neighbours.shape[1]
    L = log_pi.shape[0]
    M = observed_logits.shape[0]
    top_l = np.empty(K, np.int64)
    top_w = np.empty(K)
    cand_l = np.empty(L + K, np.int64)
    cand_w = np.empty(L + K)
    stamp = mark.max()
    lost = 0.0
    updated = 0
    for p in range(cells.shape[0]):
        i = cells[p]
        r = rows[p]
        bound = drift[i] + row_drift[r]
        for s in range(D):
            bound += gamma * moved[neighbours[p, s]]
        if bound <= tolerance and damping == 0.0:
            drift[i] = bound
            moved[i] = 0.0
            continue
        updated += 1
        stamp += 1
        nt = 0
        for s in range(D):
            j = neighbours[p, s]
            for k in range(count[j]):
                l = index[j, k]
                if mark[l] != stamp:
                    mark[l] = stamp
                    field[l] = 0.0
                    touched[nt] = l
                    nt += 1
                field[l] += value[j, k]
        nc = 0
        if r == M:  # no observations: background B plus the neighbours' correction
            shift = 0.0
            for t in range(nt):
                l = touched[t]
                shift = max(shift, log_pi[l] + gamma * field[l])
            below = np.exp(-shift)
            total = background_total * below
            for t in range(nt):
                l = touched[t]
                w = np.exp(log_pi[l] + gamma * field[l] - shift)
                weight[l] = w
                total += w - background[l] * below
            floor = threshold * total  # candidates below it are dropped anyway: skip them
            for t in range(nt):
                l = touched[t]
                if weight[l] >= floor or nc == 0:
                    cand_l[nc] = l
                    cand_w[nc] = weight[l]
                    nc += 1
            taken = 0
            for o in range(L):
                l = order[o]
                if mark[l] != stamp:
                    w = background[l] * below
                    if (w < floor and nc > 0) or taken == K:
                        break  # descending order: every later one is smaller still
                    cand_l[nc] = l
                    cand_w[nc] = w
                    nc += 1
                    taken += 1
        else:  # observed: every concept from the cell's row
            shift = -np.inf
            for l in range(L):
                extra = gamma * field[l] if mark[l] == stamp else 0.0
                shift = max(shift, observed_logits[r, l] + extra)
            total = 0.0
            for l in range(L):
                extra = gamma * field[l] if mark[l] == stamp else 0.0
                w = np.exp(observed_logits[r, l] + extra - shift)
                total += w
                cand_l[nc] = l
                cand_w[nc] = w
                nc += 1
        size = _select(cand_l, cand_w, nc, top_l, top_w)
        if damping > 0.0:  # mix with the old q_i, then truncate the union again
            stamp += 1
            for k in range(size):
                l = top_l[k]
                mark[l] = stamp
                field[l] = (1.0 - damping) * top_w[k] / total
            nt = size
            for k in range(size):
                touched[k] = top_l[k]
            for k in range(count[i]):
                l = index[i, k]
                if mark[l] != stamp:
                    mark[l] = stamp
                    field[l] = 0.0
                    touched[nt] = l
                    nt += 1
                field[l] += damping * value[i, k]
            total = 1.0
            for t in range(nt):
                cand_l[t] = touched[t]
                cand_w[t] = field[touched[t]]
            size = _select(cand_l, cand_w, nt, top_l, top_w)
        kept = top_w[0]
        n = 1
        for k in range(1, size):
            if top_w[k] >= threshold * total:
                top_l[n] = top_l[k]
                top_w[n] = top_w[k]
                kept += top_w[k]
                n += 1
        # H[q_i] = log kept - sum_k v_k log w_k (v_k = w_k / kept): one log per cell, the log
        # weights being the logits minus the shift (read from the field while it is stamped)
        h = 0.0
        if damping == 0.0:
            logits_stamp = stamp
            for k in range(n):
                l = top_l[k]
                extra = gamma * field[l] if mark[l] == logits_stamp else 0.0
                base = log_pi[l] if r == M else observed_logits[r, l]
                h -= top_w[k] * (base + extra - shift)
            h = h / kept + np.log(kept)
        else:
            for k in range(n):
                v = top_w[k] / kept
                h -= v * np.log(v)
        if damping == 0.0:  # the pairs' term: (q_i new - q_i old) . n(i)
            delta = 0.0
            for k in range(n):
                l = top_l[k]
                if mark[l] == stamp:
                    delta += top_w[k] * field[l]
            delta /= kept
            for k in range(count[i]):
                l = index[i, k]
                if mark[l] == stamp:
                    delta -= value[i, k] * field[l]
            totals[1] += delta
        totals[0] += h - entropy[i]
        argmax_cells[index[i, 0]] -= 1
        argmax_cells[top_l[0]] += 1
        for k in range(count[i]):
            sizes[index[i, k]] -= value[i, k]
        for k in range(n):
            sizes[top_l[k]] += top_w[k] / kept
        # how far q_i moved (max over concepts), for its neighbours' active-set test
        stamp += 1
        for k in range(n):
            mark[top_l[k]] = stamp
            weight[top_l[k]] = top_w[k] / kept
        change = 0.0
        for k in range(count[i]):
            l = index[i, k]
            if mark[l] == stamp:
                change = max(change, abs(weight[l] - value[i, k]))
                weight[l] = -1.0  # seen
            else:
                change = max(change, value[i, k])
        for k in range(n):
            l = top_l[k]
            if weight[l] >= 0.0:
                change = max(change, weight[l])
        for k in range(n):
            index[i, k] = top_l[k]
            value[i, k] = top_w[k] / kept
        count[i] = n
        entropy[i] = h
        moved[i] = change
        drift[i] = 0.0
        if kept < total:
            lost -= np.log(kept / total)
    return lost, updated


@njit(cache=True)
def _recount(
    index: np.ndarray,
    value: np.ndarray,
    count: np.ndarray,
    num_cells: int,
    entropy: np.ndarray,
    pair_starts: np.ndarray,
    pair_partners: np.ndarray,
    sizes: np.ndarray,
    argmax_cells: np.ndarray,
    totals: np.ndarray,
    row: np.ndarray,
) -> None:
    """Recompute from scratch what :func:`_update_cells` keeps up to date: sizes [L]
    (sum_i q_i), argmax_cells [L] (cells whose most probable concept each is), totals [2]
    (H[q(C)] = sum of the per-cell entropies, E_q[E(C)] = sum over pairs of q_a . q_b).

    The pairs (a, b) are grouped by a (pair_starts [N + 1] into pair_partners [P]); q_a is
    scattered into row [L] (zeros), so a pair costs O(count[b]). row is left zero."""
    sizes[:] = 0.0
    argmax_cells[:] = 0
    total_entropy = 0.0
    agreements = 0.0
    for a in range(num_cells):
        argmax_cells[index[a, 0]] += 1
        total_entropy += entropy[a]
        for k in range(count[a]):
            v = value[a, k]
            sizes[index[a, k]] += v
            row[index[a, k]] = v
        for e in range(pair_starts[a], pair_starts[a + 1]):
            b = pair_partners[e]
            for kb in range(count[b]):
                agreements += row[index[b, kb]] * value[b, kb]
        for k in range(count[a]):
            row[index[a, k]] = 0.0
    totals[0] = total_entropy
    totals[1] = agreements


@njit(cache=True)
def _observed(
    index: np.ndarray, value: np.ndarray, count: np.ndarray, obs_cells: np.ndarray, out: np.ndarray
) -> None:
    """out [M, L] (zeros): the observed cells' q."""
    for m in range(obs_cells.shape[0]):
        i = obs_cells[m]
        for k in range(count[i]):
            out[m, index[i, k]] += value[i, k]


@njit(cache=True)
def _entropies(value: np.ndarray, count: np.ndarray, out: np.ndarray) -> None:
    """out[i] = H[q_i] = -sum_k v log v over each row's entries."""
    for i in range(count.shape[0]):
        h = 0.0
        for k in range(count[i]):
            v = value[i, k]
            if v > 0.0:
                h -= v * np.log(v)
        out[i] = h


@njit(cache=True)
def _from_dense(q: np.ndarray, index: np.ndarray, value: np.ndarray, count: np.ndarray) -> None:
    """The top-K entries (K = index.shape[1]) of each row of q [N, L], renormalised."""
    K = index.shape[1]
    top_l = np.empty(K, np.int64)
    top_w = np.empty(K)
    cand_l = np.empty(q.shape[1], np.int64)
    cand_w = np.empty(q.shape[1])
    for i in range(q.shape[0]):
        nc = 0
        for l in range(q.shape[1]):
            if q[i, l] > 0.0:
                cand_l[nc] = l
                cand_w[nc] = q[i, l]
                nc += 1
        size = _select(cand_l, cand_w, nc, top_l, top_w)
        kept = 0.0
        for k in range(size):
            kept += top_w[k]
        for k in range(size):
            index[i, k] = top_l[k]
            value[i, k] = top_w[k] / kept
        count[i] = size


@njit(cache=True)
def _to_dense(index: np.ndarray, value: np.ndarray, count: np.ndarray, out: np.ndarray) -> None:
    for i in range(out.shape[0]):
        for k in range(count[i]):
            out[i, index[i, k]] = value[i, k]


# ---------------------------------------------------------------------------------- python side
