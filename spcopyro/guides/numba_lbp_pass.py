"""The compiled message pass of the sparse loopy-BP backend (:mod:`spcopyro.guides.numba_lbp`,
whose docstring states the math). Private to that module.

Every helper is written out in the loop: a call with array arguments costs an atomic
increment and decrement of each array's reference count (numba's runtime), which took a third
of the pass when the gather, the top-K selection and the change measure were functions.
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
    N, D = nb.shape
    K = idx.shape[1]
    L = beta.shape[1]
    M = beta.shape[0] - 1
    s = np.expm1(gamma)
    tset = np.empty(L, np.int64)
    top_l = np.empty(L + 2 * K, np.int64)  # the candidates, then the kept ones in front
    top_w = np.empty(L + 2 * K)
    und_l = np.empty(K, np.int64)
    und_w = np.empty(K)
    old_l = np.empty(K, np.int64)
    old_w = np.empty(K)
    tick = max(mark.max(), omark.max(), fmark.max()) + 1
    sent = 0
    for p in range(N):
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
                z += beta[r, l] * (x - 1.0)
            scale = s / z  # rho_new(l) = (e^gamma - 1) b_{i \ j}(l)
            nc = 0
            for t in range(nt):
                l = tset[t]
                x = prod[l] / fac[d, l] if fmark[d, l] == stamp else prod[l]
                w = scale * beta[r, l] * x
                if w >= threshold and w > 0.0:
                    top_l[nc] = l
                    top_w[nc] = w
                    nc += 1
            taken = 0
            for o in range(L):  # the concepts outside T, by descending beta
                l = border[o] if r == M else o
                if mark[l] != stamp:
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
            for k in range(ce):
                old_l[k] = idx[e, k]
                old_w[k] = val[e, k]
            if damping > 0.0:  # m = (1 - d) m_new + d m_old = a (1 + rho) (module docstring)
                n_und = n
                total = 0.0
                for k in range(n):
                    und_l[k] = top_l[k]
                    und_w[k] = top_w[k]
                    total += top_w[k]
                wa, wb = (1.0 - damping) / (L + total), damping / (L + msum[e])
                a = wa + wb
                ostamp = tick
                tick += 2
                for k in range(ce):  # the old excess, scattered
                    omark[old_l[k]] = ostamp
                    oval[old_l[k]] = old_w[k]
                nc = 0
                for k in range(n):
                    l = und_l[k]
                    old = oval[l] if omark[l] == ostamp else 0.0
                    w = (wa * und_w[k] + wb * old) / a
                    omark[l] = ostamp + 1
                    if w >= threshold and w > 0.0:
                        top_l[nc] = l
                        top_w[nc] = w
                        nc += 1
                for k in range(ce):
                    l = old_l[k]
                    if omark[l] == ostamp:  # in the old excess only
                        w = wb * old_w[k] / a
                        if w >= threshold and w > 0.0:
                            top_l[nc] = l
                            top_w[nc] = w
                            nc += 1
                n = nc
                if nc > K:
                    for k in range(K):
                        best = k
                        for c in range(k + 1, nc):
                            if top_w[c] > top_w[best]:
                                best = c
                        top_l[k], top_l[best] = top_l[best], top_l[k]
                        top_w[k], top_w[best] = top_w[best], top_w[k]
                    n = K
                # residual: half the log range of (1 + rho_stored) / (1 + rho_undamped)
                ustamp = tick
                tick += 2
                for k in range(n_und):
                    omark[und_l[k]] = ustamp
                    oval[und_l[k]] = und_w[k]
                lo, hi = 1.0, 1.0
                for k in range(n):
                    l = top_l[k]
                    u = oval[l] if omark[l] == ustamp else 0.0
                    ratio = (1.0 + top_w[k]) / (1.0 + u)
                    lo, hi = min(lo, ratio), max(hi, ratio)
                    omark[l] = ustamp + 1
                for k in range(n_und):
                    if omark[und_l[k]] == ustamp:  # in the undamped excess only
                        ratio = 1.0 / (1.0 + und_w[k])
                        lo, hi = min(lo, ratio), max(hi, ratio)
                worst = max(worst, 0.5 * np.log(hi / lo))
            # moved: half the log range of (1 + rho_new) / (1 + rho_old)
            ostamp = tick
            tick += 2
            for k in range(ce):
                omark[old_l[k]] = ostamp
                oval[old_l[k]] = old_w[k]
            lo, hi = 1.0, 1.0
            total = 0.0
            for k in range(n):
                l = top_l[k]
                w = top_w[k]
                o = oval[l] if omark[l] == ostamp else 0.0
                ratio = (1.0 + w) / (1.0 + o)
                lo, hi = min(lo, ratio), max(hi, ratio)
                omark[l] = ostamp + 1
                idx[e, k] = l
                val[e, k] = w
                lg[e, k] = np.log1p(w)
                total += w
            for k in range(ce):
                if omark[old_l[k]] == ostamp:  # in the old excess only
                    ratio = 1.0 / (1.0 + old_w[k])
                    lo, hi = min(lo, ratio), max(hi, ratio)
            moved[e] = 0.5 * np.log(hi / lo)
            belief_drift[j] += moved[e]
            cnt[e] = n
            msum[e] = total
        drift[i] = 0.0
        residual[i] = worst
    return sent
