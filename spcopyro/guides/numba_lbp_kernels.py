"""The compiled kernels of the sparse loopy-BP backend (:mod:`spcopyro.guides.numba_lbp`, whose
docstring states the math) other than the pass (:mod:`spcopyro.guides.numba_lbp_pass`): the
beliefs' summaries (statistics, labels, Bethe terms), the warm start and the conversions to
dense tensors. Private to that module; helpers are written out in the loops (see the pass's
module for why), but for a pair's Bethe terms, shared with the cached summaries
(:func:`spcopyro.guides.numba_lbp_beliefs._pair_terms`).

Shapes: N cells, D neighbour slots, L concepts, K kept entries a message, M observed cells; the
base table ``beta [M + 1, L]`` holds exp(h - max h) of every observed cell's row and, in row M,
of the cells without observations (exp(E log pi - max)).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spcopyro.guides.numba_cavi_kernels import _select
from spcopyro.guides.numba_lbp_beliefs import _pair_terms


@njit(cache=True)
def _summaries(
    idx: np.ndarray,
    val: np.ndarray,
    lg: np.ndarray,
    cnt: np.ndarray,
    nb: np.ndarray,
    rows: np.ndarray,
    beta: np.ndarray,
    logbeta: np.ndarray,
    border: np.ndarray,
    bsum: np.ndarray,
    row_entropy: np.ndarray,
    pair_starts: np.ndarray,
    pair_b: np.ndarray,
    pair_slots: np.ndarray,
    gamma: float,
    marks: np.ndarray,
    fmarks: np.ndarray,
    scratch: np.ndarray,
    facs: np.ndarray,
    flogs: np.ndarray,
    tsets: np.ndarray,
    sizes: np.ndarray,
    observed_q: np.ndarray,
    labels: np.ndarray,
    totals: np.ndarray,
) -> None:
    """The beliefs q_i(l) = beta_l W_i(l) / Z_i read from the messages, summarised: ``sizes [L]``
    sum_i q_i, ``observed_q [M, L]`` the observed cells' q, ``labels [N]`` argmax (the smallest
    concept among ties), ``totals [3]``: sum_i (d_i - 1) H[q_i], the pairs' sum of E_{b_ab}[delta]
    and of H[b_ab] (module docstring). ``row_entropy [M + 1]`` sum_l beta log beta per row;
    the pairs (a, b) grouped by a (``pair_starts [N + 1]``, ``pair_b [P]``, ``pair_slots [P, 2]``
    b's slot in a's row and a's in b's). Scratch per side (a, b): marks [2, L], fmarks [2, D, L],
    scratch [4, L] (W, log W of a; of b), facs, flogs [2, D, L], tsets [2, L]."""
    N, D = nb.shape
    L = beta.shape[1]
    M = beta.shape[0] - 1
    tick = max(marks.max(), fmarks.max()) + 1
    mark_a, mark_b, fmark_a, fmark_b = marks[0], marks[1], fmarks[0], fmarks[1]
    prod_a, logprod_a, prod_b, logprod_b = scratch[0], scratch[1], scratch[2], scratch[3]
    fac_a, fac_b, flog_a, flog_b = facs[0], facs[1], flogs[0], flogs[1]
    tset_a, tset_b = tsets[0], tsets[1]
    ulist = np.empty(2 * L, np.int64)
    b2 = 0.0  # sum_l b_l^2 and sum_l b_l^2 log b_l of the background row
    a2 = 0.0
    for l in range(L):
        b2 += beta[M, l] * beta[M, l]
        a2 += beta[M, l] * beta[M, l] * logbeta[M, l]
    sizes[:] = 0.0
    invz = 0.0
    node, agree, pair_entropy = 0.0, 0.0, 0.0
    for a in range(N):
        ra = rows[a]
        sa = tick
        tick += 1
        na = 0  # gather (written out: see numba_lbp_pass) T, W = prod (1 + rho), log W
        for d in range(D):
            if nb[a, d] < 0:
                continue
            e = a * D + d
            for k in range(cnt[e]):
                l = idx[e, k]
                if mark_a[l] != sa:
                    mark_a[l] = sa
                    prod_a[l] = 1.0
                    logprod_a[l] = 0.0
                    tset_a[na] = l
                    na += 1
                f = 1.0 + val[e, k]
                prod_a[l] *= f
                logprod_a[l] += lg[e, k]
                fmark_a[d, l] = sa
                fac_a[d, l] = f
                flog_a[d, l] = lg[e, k]
        z = bsum[ra]
        for t in range(na):
            l = tset_a[t]
            z += beta[ra, l] * (prod_a[l] - 1.0)
        cross = row_entropy[ra]  # sum_l beta W log(beta W)
        best, best_l = -1.0, L
        for t in range(na):
            l = tset_a[t]
            w = beta[ra, l] * prod_a[l]
            cross += beta[ra, l] * (prod_a[l] - 1.0) * logbeta[ra, l] + w * logprod_a[l]
            if w > best or (w == best and l < best_l):
                best, best_l = w, l
        for o in range(L):  # outside T: the largest beta (row M: the first in border's order)
            l = border[o] if ra == M else o
            if mark_a[l] != sa:
                if beta[ra, l] > best or (beta[ra, l] == best and l < best_l):
                    best, best_l = beta[ra, l], l
                if ra == M:
                    break
        labels[a] = best_l
        degree = 0
        for d in range(D):
            if nb[a, d] >= 0:
                degree += 1
        node += (degree - 1) * (np.log(z) - cross / z)
        if ra == M:
            invz += 1.0 / z
            for t in range(na):
                l = tset_a[t]
                sizes[l] += beta[M, l] * (prod_a[l] - 1.0) / z
        else:
            for l in range(L):
                x = prod_a[l] if mark_a[l] == sa else 1.0
                observed_q[ra, l] = beta[ra, l] * x / z
                sizes[l] += observed_q[ra, l]
        for q in range(pair_starts[a], pair_starts[a + 1]):
            b = pair_b[q]
            rb = rows[b]
            da, db = pair_slots[q, 0], pair_slots[q, 1]
            sb = tick
            tick += 1
            nbb = 0  # gather (written out: see numba_lbp_pass) T, W = prod (1 + rho), log W
            for d in range(D):
                if nb[b, d] < 0:
                    continue
                e = b * D + d
                for k in range(cnt[e]):
                    l = idx[e, k]
                    if mark_b[l] != sb:
                        mark_b[l] = sb
                        prod_b[l] = 1.0
                        logprod_b[l] = 0.0
                        tset_b[nbb] = l
                        nbb += 1
                    f = 1.0 + val[e, k]
                    prod_b[l] *= f
                    logprod_b[l] += lg[e, k]
                    fmark_b[d, l] = sb
                    fac_b[d, l] = f
                    flog_b[d, l] = lg[e, k]
            # E[delta] and H of the pair's belief: one loop over the concepts where u or v differ
            # from the base row's (numba_lbp_beliefs._pair_terms, which the cached summaries use)
            agreement, entropy = _pair_terms(
                ra, rb, da, db, beta, logbeta, bsum, row_entropy, b2, a2, gamma,
                sa, mark_a, prod_a, logprod_a, tset_a, na, fmark_a, fac_a, flog_a,
                sb, mark_b, prod_b, logprod_b, tset_b, nbb, fmark_b, fac_b, flog_b, ulist,
            )  # fmt: skip
            agree += agreement
            pair_entropy += entropy
    for l in range(L):
        sizes[l] += beta[M, l] * invz
    totals[0] = node
    totals[1] = agree
    totals[2] = pair_entropy


@njit(cache=True)
def _start(
    q: np.ndarray, nb: np.ndarray, rev: np.ndarray, s: float, threshold: float,
    idx: np.ndarray, val: np.ndarray, lg: np.ndarray, cnt: np.ndarray, msum: np.ndarray,
) -> None:  # fmt: skip
    """Every message i -> j set to the one a cell whose cavity belief is q_i [N, L] sends:
    rho(l) = (e^gamma - 1) q_i(l), its K largest entries >= threshold."""
    N, D = nb.shape
    K = idx.shape[1]
    L = q.shape[1]
    top_l = np.empty(K, np.int64)
    top_w = np.empty(K)
    cand_l = np.empty(L, np.int64)
    cand_w = np.empty(L)
    for i in range(N):
        nc = 0
        for l in range(L):
            w = s * q[i, l]
            if w >= threshold and w > 0.0:
                cand_l[nc] = l
                cand_w[nc] = w
                nc += 1
        n = _select(cand_l, cand_w, nc, top_l, top_w)
        total = 0.0
        for k in range(n):
            total += top_w[k]
        for d in range(D):
            j = nb[i, d]
            if j < 0:
                continue
            e = j * D + rev[i, d]
            for k in range(n):
                idx[e, k] = top_l[k]
                val[e, k] = top_w[k]
                lg[e, k] = np.log1p(top_w[k])
            cnt[e] = n
            msum[e] = total


@njit(cache=True)
def _dense(
    idx: np.ndarray, val: np.ndarray, cnt: np.ndarray, msum: np.ndarray, nb: np.ndarray,
    rows: np.ndarray, beta: np.ndarray, log_messages: np.ndarray, beliefs: np.ndarray,
) -> None:  # fmt: skip
    """log_messages [N, D, L] (log m = log(1 + rho) - log(L + sum rho); 0 where no neighbour)
    and beliefs [N, L] (beta W / Z), dense."""
    N, D = nb.shape
    L = beta.shape[1]
    for i in range(N):
        for l in range(L):
            beliefs[i, l] = beta[rows[i], l]
        for d in range(D):
            if nb[i, d] < 0:
                continue
            e = i * D + d
            base = -np.log(L + msum[e])
            for l in range(L):
                log_messages[i, d, l] = base
            for k in range(cnt[e]):
                log_messages[i, d, idx[e, k]] += np.log1p(val[e, k])
                beliefs[i, idx[e, k]] *= 1.0 + val[e, k]
        z = 0.0
        for l in range(L):
            z += beliefs[i, l]
        for l in range(L):
            beliefs[i, l] /= z
