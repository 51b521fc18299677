"""The compiled message pass of the sparse loopy-BP backend (:mod:`spcopyro.guides.numba_lbp`,
whose docstring states the math). Private to that module.

Every helper is written out in the loop: a call with array arguments costs an atomic
increment and decrement of each array's reference count (numba's runtime), which took a third
of the pass when the gather, the top-K selection and the change measure were functions.

A sent cell's work, once each: the cavity's X(l) on T per message (kept for its candidates), the
concepts outside T per cell (listed in scan order, the same for its D messages), and per message
one loop over the undamped entries and one over the old ones giving the damped message with both
its change ranges (``residual``, ``moved``); the old message is read in place and overwritten
last. Only where the top-K cut drops entries after damping are the ranges measured again over
what is kept. The values are those of the earlier layout bit for bit (the ranges' min/max taken
in another order; its messages, ``moved`` and ``residual`` equal on 324 option combinations on
2026-12-06).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _message_pass(
    idx: np.ndarray,
    val: np.ndarray,
    lg: np.ndarray,
    cnt: np.ndarray,
    msum: np.ndarray,
    moved: np.ndarray,
    drift: np.ndarray,
    residual: np.ndarray,
    belief_drift: np.ndarray,
    order: np.ndarray,
    nb: np.ndarray,
    rev: np.ndarray,
    rows: np.ndarray,
    beta: np.ndarray,
    border: np.ndarray,
    bsum: np.ndarray,
    row_drift: np.ndarray,
    gamma: float,
    threshold: float,
    damping: float,
    tolerance: float,
    mark: np.ndarray,
    omark: np.ndarray,
    fmark: np.ndarray,
    prod: np.ndarray,
    oval: np.ndarray,
    fac: np.ndarray,
) -> int:
    """One message pass: every cell in ``order`` (colour class after colour class) sends its D
    messages, unless the active set skips it; returns how many cells sent.

    Message storage (row e = j * D + s: the message into j from its slot-s neighbour): ``idx,
    val, lg [N * D, K]`` the excess's concepts, rho and log(1 + rho); ``cnt [N * D]`` entries,
    ``msum [N * D]`` sum of rho, ``moved [N * D]`` half the log range of the message's change at
    its sender's latest visit (0 when skipped). Per cell: ``drift [N]`` the inputs' accumulated
    drift since its last send (inf: send), ``residual [N]`` how far (half log range) its stored
    messages lie from the undamped ones of its last send, ``belief_drift [N]`` the drift of its
    inputs since its cached belief was computed (each message sent into it adds its ``moved``).
    ``rows [N]`` base row (M: none),
    ``border [L]`` the concepts by descending beta of row M, ``bsum [M + 1]`` each row's sum,
    ``row_drift [M + 1]`` the base rows' drift this pass (plus the coupling's). Scratch (never
    reset: stamps only grow): mark, omark [L] int64, fmark [D, L] int64, prod, oval [L],
    fac [D, L]."""
    D = nb.shape[1]
    K = idx.shape[1]
    L = beta.shape[1]
    M = beta.shape[0] - 1
    s = np.expm1(gamma)
    tset = np.empty(L, np.int64)
    tbeta = np.empty(L)  # beta[r, tset[t]]
    xs = np.empty(L)  # the cavity's X(tset[t]) of the message being built
    outl = np.empty(L, np.int64)  # the concepts outside T in scan order
    top_l = np.empty(L + 2 * K, np.int64)  # the undamped candidates, the kept ones in front
    top_w = np.empty(L + 2 * K)
    new_l = np.empty(L + 2 * K, np.int64)  # the damped message's entries
    new_w = np.empty(L + 2 * K)
    tick = max(mark.max(), omark.max(), fmark.max()) + 1
    sent = 0
    for p in range(len(order)):  # N cells in a run (a test replays a pass cell by cell)
        i = order[p]
        r = rows[i]
        bound = drift[i] + row_drift[r]
        for d in range(D):
            if nb[i, d] >= 0:
                bound += moved[i * D + d]
        if 2.0 * bound + residual[i] <= tolerance:
            drift[i] = bound
            for d in range(D):
                if nb[i, d] >= 0:
                    moved[nb[i, d] * D + rev[i, d]] = 0.0
            continue
        sent += 1
        stamp = tick
        tick += 1
        # gather: T (tset[:nt]), W(l) = prod_r (1 + rho_r(l)) in prod, fac[d, l] = 1 + rho_d(l)
        nt = 0
        for d in range(D):
            if nb[i, d] < 0:
                continue
            e = i * D + d
            for k in range(cnt[e]):
                l = idx[e, k]
                f = 1.0 + val[e, k]
                if mark[l] != stamp:
                    mark[l] = stamp
                    prod[l] = f
                    tset[nt] = l
                    nt += 1
                else:
                    prod[l] *= f
                fmark[d, l] = stamp
                fac[d, l] = f
        for t in range(nt):
            tbeta[t] = beta[r, tset[t]]
        nout = 0  # outl[:nout]: the concepts outside T in scan order (the same for all d)
        for o in range(L):  # by descending beta of row M, else in concept order
            l = border[o] if r == M else o
            if mark[l] != stamp:
                outl[nout] = l
                nout += 1
        worst = 0.0
        for d in range(D):
            j = nb[i, d]
            if j < 0:
                continue
            # the cavity b_{i \ j}(l) = beta_l X(l) / Z, X = W / (1 + rho_{j -> i}) on T
            z = bsum[r]
            for t in range(nt):
                l = tset[t]
                x = prod[l] / fac[d, l] if fmark[d, l] == stamp else prod[l]
                xs[t] = x
                z += tbeta[t] * (x - 1.0)
            scale = s / z  # rho_new(l) = (e^gamma - 1) b_{i \ j}(l)
            nc = 0
            for t in range(nt):
                w = scale * tbeta[t] * xs[t]
                if w >= threshold and w > 0.0:
                    top_l[nc] = tset[t]
                    top_w[nc] = w
                    nc += 1
            taken = 0
            for q in range(nout):  # the concepts outside T, by descending beta (row M)
                l = outl[q]
                w = scale * beta[r, l]
                if r == M and (w < threshold or w <= 0.0 or taken == K):
                    break  # descending order: every later one is smaller
                if w >= threshold and w > 0.0:
                    top_l[nc] = l
                    top_w[nc] = w
                    nc += 1
                    taken += 1
            n = nc
            if nc > K:  # keep the K largest: partial selection sort
                for k in range(K):
                    best = k
                    for c in range(k + 1, nc):
                        if top_w[c] > top_w[best]:
                            best = c
                    top_l[k], top_l[best] = top_l[best], top_l[k]
                    top_w[k], top_w[best] = top_w[best], top_w[k]
                n = K
            e = j * D + rev[i, d]
            ce = cnt[e]
            # moved: half the log range of (1 + rho_new) / (1 + rho_old) over the concepts of
            # either; residual: of (1 + rho_stored) / (1 + rho_undamped). The old message is
            # read from idx, val (overwritten last); mlo < 0: moved still to be measured
            mlo, mhi = -1.0, -1.0
            if damping > 0.0:  # m = (1 - d) m_new + d m_old = a (1 + rho) (module docstring)
                ostamp = tick  # the old excess, scattered
                tick += 2
                for k in range(ce):
                    omark[idx[e, k]] = ostamp
                    oval[idx[e, k]] = val[e, k]
                mlo, mhi = 1.0, 1.0  # both ranges measured in one loop over each excess
                total = 0.0
                for k in range(n):
                    total += top_w[k]
                wa, wb = (1.0 - damping) / (L + total), damping / (L + msum[e])
                a = wa + wb
                rlo, rhi = 1.0, 1.0
                nn = 0
                for k in range(n):  # the undamped entries, with the old one where there is one
                    l = top_l[k]
                    u = top_w[k]
                    had = omark[l] == ostamp
                    old = oval[l] if had else 0.0
                    w = (wa * u + wb * old) / a
                    omark[l] = ostamp + 1
                    if w >= threshold and w > 0.0:
                        new_l[nn] = l
                        new_w[nn] = w
                        nn += 1
                        ratio = (1.0 + w) / (1.0 + u)
                        rlo, rhi = min(rlo, ratio), max(rhi, ratio)
                        ratio = (1.0 + w) / (1.0 + old)
                        mlo, mhi = min(mlo, ratio), max(mhi, ratio)
                    else:
                        ratio = 1.0 / (1.0 + u)
                        rlo, rhi = min(rlo, ratio), max(rhi, ratio)
                        if had:
                            ratio = 1.0 / (1.0 + old)
                            mlo, mhi = min(mlo, ratio), max(mhi, ratio)
                for k in range(ce):
                    l = idx[e, k]
                    if omark[l] == ostamp:  # in the old excess only
                        old = val[e, k]
                        w = wb * old / a
                        if w >= threshold and w > 0.0:
                            new_l[nn] = l
                            new_w[nn] = w
                            nn += 1
                            ratio = 1.0 + w  # over 1 + rho_undamped = 1
                            rlo, rhi = min(rlo, ratio), max(rhi, ratio)
                            ratio = (1.0 + w) / (1.0 + old)
                            mlo, mhi = min(mlo, ratio), max(mhi, ratio)
                        else:
                            ratio = 1.0 / (1.0 + old)
                            mlo, mhi = min(mlo, ratio), max(mhi, ratio)
                if nn > K:  # keep the K largest; the ranges over what is kept, recomputed
                    for k in range(K):
                        best = k
                        for c in range(k + 1, nn):
                            if new_w[c] > new_w[best]:
                                best = c
                        new_l[k], new_l[best] = new_l[best], new_l[k]
                        new_w[k], new_w[best] = new_w[best], new_w[k]
                    nn = K
                    ustamp = tick
                    tick += 2
                    for k in range(n):
                        omark[top_l[k]] = ustamp
                        oval[top_l[k]] = top_w[k]
                    rlo, rhi = 1.0, 1.0
                    for k in range(nn):
                        l = new_l[k]
                        u = oval[l] if omark[l] == ustamp else 0.0
                        ratio = (1.0 + new_w[k]) / (1.0 + u)
                        rlo, rhi = min(rlo, ratio), max(rhi, ratio)
                        omark[l] = ustamp + 1
                    for k in range(n):
                        if omark[top_l[k]] == ustamp:  # in the undamped excess only
                            ratio = 1.0 / (1.0 + top_w[k])
                            rlo, rhi = min(rlo, ratio), max(rhi, ratio)
                    mlo, mhi = -1.0, -1.0  # over what is kept: measured below
                worst = max(worst, 0.5 * np.log(rhi / rlo))
                n = nn
            else:
                for k in range(n):
                    new_l[k] = top_l[k]
                    new_w[k] = top_w[k]
            if mlo < 0.0:  # moved from the old excess, scattered (again)
                ostamp = tick
                tick += 2
                for k in range(ce):
                    omark[idx[e, k]] = ostamp
                    oval[idx[e, k]] = val[e, k]
                mlo, mhi = 1.0, 1.0
                for k in range(n):
                    l = new_l[k]
                    o = oval[l] if omark[l] == ostamp else 0.0
                    ratio = (1.0 + new_w[k]) / (1.0 + o)
                    mlo, mhi = min(mlo, ratio), max(mhi, ratio)
                    omark[l] = ostamp + 1
                for k in range(ce):
                    if omark[idx[e, k]] == ostamp:  # in the old excess only
                        ratio = 1.0 / (1.0 + val[e, k])
                        mlo, mhi = min(mlo, ratio), max(mhi, ratio)
            total = 0.0
            for k in range(n):
                w = new_w[k]
                idx[e, k] = new_l[k]
                val[e, k] = w
                lg[e, k] = np.log1p(w)
                total += w
            moved[e] = 0.5 * np.log(mhi / mlo)
            belief_drift[j] += moved[e]
            cnt[e] = n
            msum[e] = total
        drift[i] = 0.0
        residual[i] = worst
    return sent
