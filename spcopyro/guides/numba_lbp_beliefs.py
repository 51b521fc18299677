"""The cached beliefs of the sparse loopy-BP backend (:mod:`spcopyro.guides.numba_lbp`, whose
docstring states the math and the error bound, "Cached beliefs"): each cell's belief summary and
each pair's Bethe terms, kept with running sums and recomputed only for the cells whose inputs
drifted past the tolerance (and the pairs touching them). Private to that module.

Shapes: N cells, D neighbour slots, L concepts, K kept entries a message, M observed cells, P
pairs, E epochs (the background rows the cached beliefs were computed under); the base table
``beta [M + 1, L]`` as in :mod:`spcopyro.guides.numba_lbp_kernels`.

Unlike the pass, these helpers are functions: the refresh runs on the few cells that drifted,
where the calls' reference counting does not matter. The from-scratch
:func:`~spcopyro.guides.numba_lbp_kernels._summaries` calls the same :func:`_pair_terms`, so a
pair's Bethe terms have one implementation; what checks that formula is the torch reference
(equal to it without truncation), and what the cache tests check is which cells and pairs are
refreshed.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _gather(
    i: int, idx: np.ndarray, val: np.ndarray, lg: np.ndarray, cnt: np.ndarray, nb: np.ndarray,
    stamp: int, mark: np.ndarray, prod: np.ndarray, logprod: np.ndarray, tset: np.ndarray,
    fmark: np.ndarray, fac: np.ndarray, flog: np.ndarray,
) -> int:  # fmt: skip
    """Cell i's union T of incoming supports (``tset[:n]``, marked ``stamp``), W = prod (1 + rho)
    and log W on T, and each slot's factor and log factor; returns n = |T|."""
    D = nb.shape[1]
    n = 0
    for d in range(D):
        if nb[i, d] < 0:
            continue
        e = i * D + d
        for k in range(cnt[e]):
            l = idx[e, k]
            if mark[l] != stamp:
                mark[l] = stamp
                prod[l] = 1.0
                logprod[l] = 0.0
                tset[n] = l
                n += 1
            f = 1.0 + val[e, k]
            prod[l] *= f
            logprod[l] += lg[e, k]
            fmark[d, l] = stamp
            fac[d, l] = f
            flog[d, l] = lg[e, k]
    return n


@njit(cache=True)
def _pair_terms(
    ra: int, rb: int, da: int, db: int, beta: np.ndarray, logbeta: np.ndarray,
    bsum: np.ndarray, row_entropy: np.ndarray, b2: float, a2: float, gamma: float,
    sa: int, mark_a: np.ndarray, prod_a: np.ndarray, logprod_a: np.ndarray, tset_a: np.ndarray,
    na: int, fmark_a: np.ndarray, fac_a: np.ndarray, flog_a: np.ndarray,
    sb: int, mark_b: np.ndarray, prod_b: np.ndarray, logprod_b: np.ndarray, tset_b: np.ndarray,
    nbb: int, fmark_b: np.ndarray, fac_b: np.ndarray, flog_b: np.ndarray, ulist: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    """(E_{b_ab}[delta], H[b_ab]) of the pair whose ends were gathered (a's side, b's side; da
    b's slot in a's row, db a's in b's), as in ``_summaries``."""
    L = beta.shape[1]
    M = beta.shape[0] - 1
    s = np.expm1(gamma)
    both = ra == M and rb == M
    nu = 0
    if both:
        for t in range(na):
            ulist[nu] = tset_a[t]
            nu += 1
        for t in range(nbb):
            if mark_a[tset_b[t]] != sa:
                ulist[nu] = tset_b[t]
                nu += 1
        zu, zv, s_uv = bsum[M], bsum[M], b2
        s1u, s1v, s2u, s2v = row_entropy[M], row_entropy[M], a2, a2
    else:
        for l in range(L):
            ulist[l] = l
        nu = L
        zu, zv, s_uv, s1u, s1v, s2u, s2v = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for t in range(nu):
        l = ulist[t]
        if mark_a[l] != sa:
            x, lx = 1.0, 0.0
        elif fmark_a[da, l] == sa:
            x, lx = prod_a[l] / fac_a[da, l], logprod_a[l] - flog_a[da, l]
        else:
            x, lx = prod_a[l], logprod_a[l]
        if mark_b[l] != sb:
            y, ly = 1.0, 0.0
        elif fmark_b[db, l] == sb:
            y, ly = prod_b[l] / fac_b[db, l], logprod_b[l] - flog_b[db, l]
        else:
            y, ly = prod_b[l], logprod_b[l]
        ba, bb = beta[ra, l], beta[rb, l]
        la, lb = logbeta[ra, l], logbeta[rb, l]
        if both:  # corrections to the dense sums
            bab = ba * bb * (x * y - 1.0)
            zu += ba * (x - 1.0)
            zv += bb * (y - 1.0)
            s_uv += bab
            s1u += ba * (x - 1.0) * la + ba * x * lx
            s1v += bb * (y - 1.0) * lb + bb * y * ly
            s2u += bab * la + ba * bb * x * y * lx
            s2v += bab * lb + ba * bb * x * y * ly
        else:
            uv = ba * x * bb * y
            zu += ba * x
            zv += bb * y
            s_uv += uv
            s1u += ba * x * (la + lx)
            s1v += bb * y * (lb + ly)
            s2u += uv * (la + lx)
            s2v += uv * (lb + ly)
    log_zu, log_zv = np.log(zu), np.log(zv)
    overlap = s_uv / (zu * zv)
    s1u = s1u / zu - log_zu
    s1v = s1v / zv - log_zv
    s2u = s2u / (zu * zv) - overlap * log_zu
    s2v = s2v / (zu * zv) - overlap * log_zv
    zp = 1.0 + s * overlap
    agreement = (1.0 + s) * overlap / zp
    e_log_u = (s1u + s * s2u) / zp
    e_log_v = (s1v + s * s2v) / zp
    return agreement, -e_log_u - e_log_v - gamma * agreement + np.log(zp)


@njit(cache=True)
def _refresh(
    idx: np.ndarray, val: np.ndarray, lg: np.ndarray, cnt: np.ndarray, nb: np.ndarray,
    rows: np.ndarray, beta: np.ndarray, logbeta: np.ndarray, border: np.ndarray,
    bsum: np.ndarray, row_entropy: np.ndarray, b2: float, a2: float, gamma: float,
    tolerance: float, epoch: int, pair_a: np.ndarray, pair_b: np.ndarray,
    pair_slots: np.ndarray, incident: np.ndarray, drift: np.ndarray, cell_epoch: np.ndarray,
    cell_invz: np.ndarray, cell_node: np.ndarray, bidx: np.ndarray, bval: np.ndarray,
    bcnt: np.ndarray, labels: np.ndarray, observed_q: np.ndarray, pair_agree: np.ndarray,
    pair_entropy: np.ndarray, pair_mark: np.ndarray, epoch_invz: np.ndarray,
    epoch_count: np.ndarray, sizes_rest: np.ndarray, totals: np.ndarray, marks: np.ndarray,
    fmarks: np.ndarray, scratch: np.ndarray, facs: np.ndarray, flogs: np.ndarray,
    tsets: np.ndarray,
) -> int:  # fmt: skip
    """Recompute the cached belief of every cell whose inputs drifted by ``drift [N]`` with 2
    drift > ``tolerance`` (inf: never computed), and the Bethe terms of every pair touching one;
    the running sums follow. Returns how many cells were recomputed.

    Per cell: ``cell_epoch [N]`` the epoch (slot of ``epoch_invz, epoch_count [E]``) of the base
    row its background belief was computed under (-1: none, or an observed cell),
    ``cell_invz [N]`` 1/Z, ``cell_node [N]`` (d - 1) H[q], ``bidx, bval [N, Kb], bcnt [N]`` the
    excess beta (W - 1) / Z on T of a background cell, ``labels [N]``; an observed cell's belief
    is its row of ``observed_q [M, L]``. Per pair: ``pair_agree, pair_entropy [P]``,
    ``pair_mark [P]`` (scratch stamps). Running sums: ``sizes_rest [L]`` (the background cells'
    excesses and the observed rows; the dense part is sum_e epoch_invz[e] beta_e, summed by the
    caller), ``totals [3]`` as ``_summaries``'. The current base row M is epoch ``epoch``.
    ``incident [N, D]`` the pair of each slot (-1: none); ``pair_a, pair_b [P]``, ``pair_slots
    [P, 2]`` b's slot in a's row and a's in b's.

    A cell whose gather the b side still holds (the last pair's other end: on a grid, the next
    cell of its row) takes it over (the two sides' scratch swap roles) instead of gathering again:
    the messages do not change during the refresh."""
    N, D = nb.shape
    L = beta.shape[1]
    M = beta.shape[0] - 1
    tick = max(marks.max(), fmarks.max()) + 1
    ptick = pair_mark.max() + 1
    mark_a, mark_b, fmark_a, fmark_b = marks[0], marks[1], fmarks[0], fmarks[1]
    prod_a, logprod_a, prod_b, logprod_b = scratch[0], scratch[1], scratch[2], scratch[3]
    fac_a, fac_b, flog_a, flog_b = facs[0], facs[1], flogs[0], flogs[1]
    tset_a, tset_b = tsets[0], tsets[1]
    ulist = np.empty(2 * L, np.int64)
    refreshed = 0
    cell_b, sa, sb, na, nbb = -1, 0, 0, 0, 0  # cell_b: whose gather the b side holds (-1: none)
    for a in range(N):
        if not 2.0 * drift[a] > tolerance:
            continue
        refreshed += 1
        drift[a] = 0.0
        ra = rows[a]
        if a == cell_b:  # gathered as the last pair's other end (the messages are unchanged)
            mark_a, mark_b, fmark_a, fmark_b = mark_b, mark_a, fmark_b, fmark_a
            prod_a, prod_b, logprod_a, logprod_b = prod_b, prod_a, logprod_b, logprod_a
            fac_a, fac_b, flog_a, flog_b = fac_b, fac_a, flog_b, flog_a
            tset_a, tset_b = tset_b, tset_a
            sa, sb, na, nbb = sb, sa, nbb, na
            cell_b = -1  # the b side now holds an earlier cell's gather: a only grows
        else:
            sa = tick
            tick += 1
            na = _gather(a, idx, val, lg, cnt, nb, sa, mark_a, prod_a, logprod_a, tset_a,
                         fmark_a, fac_a, flog_a)  # fmt: skip
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
        node = (degree - 1) * (np.log(z) - cross / z)
        totals[0] += node - cell_node[a]
        cell_node[a] = node
        if ra == M:  # the old belief out of the running sums, the new one in
            old = cell_epoch[a]
            if old >= 0:
                epoch_invz[old] -= cell_invz[a]
                epoch_count[old] -= 1
                if epoch_count[old] == 0:
                    epoch_invz[old] = 0.0  # no rounding left behind
            for k in range(bcnt[a]):
                sizes_rest[bidx[a, k]] -= bval[a, k]
            cell_epoch[a] = epoch
            cell_invz[a] = 1.0 / z
            epoch_invz[epoch] += 1.0 / z
            epoch_count[epoch] += 1
            for t in range(na):
                l = tset_a[t]
                v = beta[M, l] * (prod_a[l] - 1.0) / z
                bidx[a, t] = l
                bval[a, t] = v
                sizes_rest[l] += v
            bcnt[a] = na
        else:
            for l in range(L):
                x = prod_a[l] if mark_a[l] == sa else 1.0
                v = beta[ra, l] * x / z
                sizes_rest[l] += v - observed_q[ra, l]
                observed_q[ra, l] = v
        for d in range(D):
            p = incident[a, d]
            if p < 0 or pair_mark[p] == ptick:
                continue
            pair_mark[p] = ptick
            b = nb[a, d]
            rb = rows[b]
            sb = tick
            tick += 1
            nbb = _gather(b, idx, val, lg, cnt, nb, sb, mark_b, prod_b, logprod_b, tset_b,
                          fmark_b, fac_b, flog_b)  # fmt: skip
            cell_b = b
            db = pair_slots[p, 1] if pair_a[p] == a else pair_slots[p, 0]
            agreement, entropy = _pair_terms(
                ra, rb, d, db, beta, logbeta, bsum, row_entropy, b2, a2, gamma,
                sa, mark_a, prod_a, logprod_a, tset_a, na, fmark_a, fac_a, flog_a,
                sb, mark_b, prod_b, logprod_b, tset_b, nbb, fmark_b, fac_b, flog_b, ulist,
            )  # fmt: skip
            totals[1] += agreement - pair_agree[p]
            totals[2] += entropy - pair_entropy[p]
            pair_agree[p] = agreement
            pair_entropy[p] = entropy
    return refreshed


@njit(cache=True)
def _recount(
    rows: np.ndarray, cell_epoch: np.ndarray, cell_invz: np.ndarray, cell_node: np.ndarray,
    bidx: np.ndarray, bval: np.ndarray, bcnt: np.ndarray, observed_q: np.ndarray,
    pair_agree: np.ndarray, pair_entropy: np.ndarray, epoch_invz: np.ndarray,
    epoch_count: np.ndarray, sizes_rest: np.ndarray, totals: np.ndarray,
) -> None:  # fmt: skip
    """The running sums re-added from the cached per-cell and per-pair values (clears the
    rounding of the subtractions; the values themselves are unchanged)."""
    M = observed_q.shape[0]
    epoch_invz[:] = 0.0
    epoch_count[:] = 0
    sizes_rest[:] = 0.0
    node = 0.0
    for a in range(rows.shape[0]):
        node += cell_node[a]
        if rows[a] == M:
            if cell_epoch[a] >= 0:
                epoch_invz[cell_epoch[a]] += cell_invz[a]
                epoch_count[cell_epoch[a]] += 1
            for k in range(bcnt[a]):
                sizes_rest[bidx[a, k]] += bval[a, k]
    for r in range(M):
        for l in range(observed_q.shape[1]):
            sizes_rest[l] += observed_q[r, l]
    totals[0] = node
    totals[1] = pair_agree.sum()
    totals[2] = pair_entropy.sum()


@njit(cache=True)
def _bound(
    drift: np.ndarray, pair_a: np.ndarray, pair_b: np.ndarray, degree: np.ndarray,
    log_l: float, out: np.ndarray,
) -> None:  # fmt: skip
    """``out [4]``: bounds on how far the cached sizes (L1), sum (d - 1) H[q], the agreements and
    sum H[b_ab] lie from the exact ones of the current messages (module docstring of
    :mod:`spcopyro.guides.numba_lbp`): a cached belief within e^(+-delta), delta = 2 drift, a
    cached pair's within e^(+-2 (drift_a + drift_b))."""
    sizes, node, agree, pair = 0.0, 0.0, 0.0, 0.0
    for a in range(drift.shape[0]):
        delta = 2.0 * drift[a]
        grow = np.expm1(delta)
        sizes += grow
        node += abs(degree[a] - 1) * (delta + grow * log_l)
    for p in range(pair_a.shape[0]):
        delta = 2.0 * (drift[pair_a[p]] + drift[pair_b[p]])
        grow = np.expm1(delta)
        agree += grow
        pair += delta + grow * 2.0 * log_l
    out[0], out[1], out[2], out[3] = sizes, node, agree, pair
