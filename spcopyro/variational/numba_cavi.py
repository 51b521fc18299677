r"""A compiled (numba) mean-field CAVI backend with a sparse q(C): the update of
:mod:`spcopyro.variational.cavi`, at the cost of a Gibbs sweep.

**Sparse q.** Each cell keeps at most ``support`` = K concepts: ``index [N + D, K]`` (int64),
``value [N + D, K]`` (float64; entry 0 is the largest, so ``index[i, 0]`` is the argmax label) and
``count [N + D]`` entries in use; the D rows after the N cells are the empty sentinels of the
:class:`~spcopyro.gibbs.numba_plan.FlatPlan`'s missing neighbours (N + s). Nothing of size
N x L exists during a run: the globals' statistics, the ELBO and the labels are read from the
sparse state, and a dense ``[N, L]`` q is written once, at the end (:meth:`SparseMeanField.dense`;
27,746 x 120 float64 is 27 MB on room2ldk4).

**Shared structure** (as the compiled Gibbs sweep's background tables,
:mod:`spcopyro.gibbs.numba_sweep`). The update of a cell without observations is
:math:`q_i(l) \propto \exp(E\log\pi_l + \gamma n_l(i))`, and :math:`n_l(i) = \sum_{r\sim i}
q_r(l)` is non-zero only for the at most D K concepts its neighbours carry (the set T_i). With
:math:`b_l = \exp(E\log\pi_l - \max E\log\pi)` and :math:`B = \sum_l b_l`, computed once per
iteration, its normaliser is

.. math::

    Z_i = B + \sum_{l \in T_i} b_l \,(e^{\gamma n_l(i)} - 1),

so the cell costs O(D K) plus the top-K selection, which reads T_i and the first K concepts of
pi's descending order that are not in T_i. An observed cell (M of them, few) reads its row of the
[M, L] table :math:`E\log\pi + \ell_{m\cdot}`: O(L).

**Truncation.** The new q_i keeps the K most probable concepts of the exact update, then drops
those with mass below ``threshold`` (keeping at least one), and renormalises what it keeps (the
remainder's mass is given to the kept concepts in proportion). Given the other cells the ELBO is
:math:`f(q_i) = \sum_l q_i(l)\,\mathrm{logit}_l + H[q_i]`, whose maximum over q_i supported on a
set S is :math:`\log\sum_{l\in S} e^{\mathrm{logit}_l}`; the top-K set maximises that over every
set of K concepts, the old q_i's support included. So:

* ``threshold = 0`` (top-K only): every cell update is the exact optimum over "q_i with at most K
  concepts", and the ELBO of the sparse q **never decreases** (the globals' update is exact).
* ``threshold > 0``: dropping the small masses d_i of a cell loses at most
  :math:`-\log(1 - d_i)` of that bound, so an iteration can lower the ELBO by at most
  :math:`\sum_i -\log(1 - d_i)`; each update returns that bound
  (:attr:`SparseMeanField.truncation_bound`) and the tests check it.
* ``support >= L`` and ``threshold = 0``: no truncation; equal to the dense torch reference up
  to rounding (tested).

The ELBO traced is the exact ELBO of the sparse q (zero mass outside the support), a valid lower
bound of the same evidence as the reference's.

**What truncation does to the fit** (measured on the synthetic house, ``paper-dp``, README notes):
a cell near disorder spreads its mass over all L concepts, and a top-K cap renormalises it onto K
of them, which behaves like a K-state Potts model: it orders at a much lower gamma (a cap of 8
made mean field form regions from gamma 1.5 instead of staying disordered) and it changed the
default fit (ARI 0.09 with 90 concepts instead of the exact update's 0.23 with 49). The default is
therefore no cap (``support=0``) and a threshold of 1e-4: a disordered cell keeps all its
concepts (1/L > 1e-4 for L < 10^4), an ordered one its few non-negligible ones. On the synthetic
house a threshold of 1e-6 kept ~50 concepts a cell (at gamma = 4 a cell with 3 agreeing
neighbours still gives the others e^-12 = 6e-6) and cost 7x the time of 1e-4, for the same map
(ARI 0.231, 49 concepts) and an ELBO 18 nats (0.3%) higher; 1e-3 keeps 1.1 concepts a cell and
loses 120 nats. The ELBO lost is at most the reported bound (``benchmarks/variational.py``
counts the decreases).

The first call compiles the kernels (seconds; ``cache=True`` keeps them for later processes).
Importing this module raises :class:`ImportError` when numba is missing.
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.numba_plan import flat_plan
from spcopyro.gibbs.state import SweepPlan
from spcopyro.likelihood import (
    ConceptStatistics,
    multinomial_coefficients,
    observation_log_likelihood,
)
from spcopyro.model import DTYPE, ModelData
from spcopyro.variational.factors import (
    GlobalFactors,
    expected_log_emissions,
    expected_log_pi,
    kl_to_prior,
)

__all__ = ["SparseMeanField", "sparse_from_dense"]

# ------------------------------------------------------------------------------------ kernels


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
) -> float:
    """Every cell of the plan (block after block) set to its truncated mean-field update in
    place; returns sum_i -log(kept mass fraction), the bound on the ELBO lost to the threshold.

    log_pi [L] (minus its max), order [L] concepts by descending log_pi, background [L]
    exp(log_pi), observed_logits [M, L] E log pi + loglik (row-wise max subtracted);
    mark [L] int64, field [L], touched [L] scratch.
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
    for p in range(cells.shape[0]):
        i = cells[p]
        r = rows[p]
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
                field[l] = w  # from here on, field holds the weight
                total += w - background[l] * below
            floor = threshold * total  # candidates below it are dropped anyway: skip them
            for t in range(nt):
                l = touched[t]
                if field[l] >= floor or nc == 0:
                    cand_l[nc] = l
                    cand_w[nc] = field[l]
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
        for k in range(n):
            index[i, k] = top_l[k]
            value[i, k] = top_w[k] / kept
        count[i] = n
        if kept < total:
            lost -= np.log(kept / total)
    return lost


@njit(cache=True)
def _summaries(
    index: np.ndarray,
    value: np.ndarray,
    count: np.ndarray,
    num_cells: int,
    obs_cells: np.ndarray,
    pairs: np.ndarray,
    sizes: np.ndarray,
    observed_q: np.ndarray,
    argmax_cells: np.ndarray,
) -> tuple[float, float]:
    """Fill sizes [L] (sum_i q_i), observed_q [M, L] (zeroed, the observed cells' q) and
    argmax_cells [L] (zeroed, cells whose most probable concept each is); return
    (H[q(C)], E_q[E(C)] = sum over pairs of q_a . q_b)."""
    entropy = 0.0
    for i in range(num_cells):
        argmax_cells[index[i, 0]] += 1
        for k in range(count[i]):
            v = value[i, k]
            sizes[index[i, k]] += v
            if v > 0.0:
                entropy -= v * np.log(v)
    for m in range(obs_cells.shape[0]):
        i = obs_cells[m]
        for k in range(count[i]):
            observed_q[m, index[i, k]] += value[i, k]
    agreements = 0.0
    for p in range(pairs.shape[0]):
        a = pairs[p, 0]
        b = pairs[p, 1]
        for ka in range(count[a]):
            la = index[a, ka]
            for kb in range(count[b]):
                if index[b, kb] == la:
                    agreements += value[a, ka] * value[b, kb]
    return entropy, agreements


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


def sparse_from_dense(
    q: torch.Tensor, support: int, num_neighbours: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(index [N + D, K], value [N + D, K], count [N + D]): the top-``support`` entries of each
    row of q ``[N, L]``, renormalised, followed by D empty sentinel rows."""
    N, L = q.shape
    K = min(support, L) if support > 0 else L
    index = np.zeros((N + num_neighbours, K), dtype=np.int64)
    value = np.zeros((N + num_neighbours, K))
    count = np.zeros(N + num_neighbours, dtype=np.int64)
    dense = np.ascontiguousarray(q.detach().cpu().numpy(), dtype=np.float64)
    if N and (not np.isfinite(dense).all() or (dense < 0).any() or (dense.sum(1) <= 0).any()):
        raise ValueError("q must be [N, L] finite, non-negative rows with positive sums")
    _from_dense(dense, index[:N], value[:N], count[:N])
    return index, value, count


class SparseMeanField:
    """The numba backend's label field: a sparse q(C) (module docstring) and its updates.

    The methods the run loop (:func:`spcopyro.variational.run.run_variational`) calls:
    :meth:`update` (one colour-block pass at a coupling), :meth:`statistics` (for the globals),
    :meth:`elbo`, :meth:`labels`, and :meth:`dense` at the end.
    """

    def __init__(
        self,
        q: torch.Tensor,
        data: ModelData,
        config: SpCoConfig,
        *,
        support: int = 0,
        threshold: float = 0.0,
        damping: float = 0.0,
        plan: SweepPlan | None = None,
    ) -> None:
        N, L = data.num_free, config.num_concepts
        if tuple(q.shape) != (N, L):
            raise ValueError(f"q must be [{N}, {L}], got {tuple(q.shape)}")
        if support < 0:
            raise ValueError(f"support must be >= 0 (0: all L concepts), got {support}")
        if not 0.0 <= threshold < 1.0:
            raise ValueError(f"threshold must lie in [0, 1), got {threshold}")
        self.data, self.config = data, config
        self.threshold, self.damping = float(threshold), float(damping)
        self.flat = flat_plan(plan, data)
        D = data.neighbours.shape[1]
        self.index, self.value, self.count = sparse_from_dense(q, support, D)
        self.obs_cells = np.ascontiguousarray(data.obs_cells.numpy(), dtype=np.int64)
        self.pairs = np.ascontiguousarray(data.pairs.numpy(), dtype=np.int64)
        self.mark = np.zeros(L, dtype=np.int64)
        self.field = np.zeros(L)
        self.touched = np.zeros(L, dtype=np.int64)
        self.truncation_bound = 0.0
        """sum_i -log(kept fraction) of the last update: the most it can have lowered the ELBO
        (0 without a threshold)."""
        self._constant = float(multinomial_coefficients(data, config))
        self._summary: tuple[ConceptStatistics, np.ndarray, float, float] | None = None
        self._loglik: tuple[GlobalFactors, torch.Tensor, torch.Tensor] | None = None

    # -- expectations of the globals, once per factors object
    def _expectations(self, factors: GlobalFactors) -> tuple[torch.Tensor, torch.Tensor]:
        """(E log pi [L], loglik [M, L]) of ``factors`` (cached for the last factors)."""
        if self._loglik is None or self._loglik[0] is not factors:
            log_pi = expected_log_pi(factors)  # [L]
            log_phi = expected_log_emissions(factors)
            loglik = observation_log_likelihood(log_phi, self.data, self.config)  # [M, L]
            self._loglik = (factors, log_pi, loglik)
        return self._loglik[1], self._loglik[2]

    def update(self, factors: GlobalFactors, gamma: float) -> None:
        """One pass over every cell, colour block by colour block, at coupling ``gamma``."""
        log_pi_t, loglik = self._expectations(factors)
        log_pi = log_pi_t.numpy()
        log_pi = log_pi - log_pi.max()  # [L]
        order = np.argsort(-log_pi, kind="stable")  # [L]
        background = np.exp(log_pi)  # [L]
        observed = (loglik + log_pi_t).numpy()  # [M, L]
        observed = observed - observed.max(axis=1, keepdims=True) if observed.size else observed
        self.truncation_bound = _update_cells(
            self.index, self.value, self.count, self.flat.cells, self.flat.neighbours,
            self.flat.background_rows, log_pi, order, background, float(background.sum()),
            np.ascontiguousarray(observed), float(gamma), self.threshold, self.damping,
            self.mark, self.field, self.touched,
        )  # fmt: skip
        self._summary = None

    def _summaries(self) -> tuple[ConceptStatistics, np.ndarray, float, float]:
        """(statistics, observed q [M, L], entropy, expected agreements) of the current q."""
        if self._summary is None:
            N, L = self.data.num_free, self.config.num_concepts
            sizes = np.zeros(L)
            observed_q = np.zeros((self.obs_cells.shape[0], L))
            self._argmax_cells = np.zeros(L, dtype=np.int64)
            entropy, agreements = _summaries(
                self.index, self.value, self.count, N, self.obs_cells, self.pairs, sizes,
                observed_q, self._argmax_cells,
            )  # fmt: skip
            observed_t = torch.from_numpy(observed_q)  # [M, L]
            counts = []
            for modality in self.data.modalities:
                per_concept = torch.zeros(L, modality.counts.shape[-1], dtype=DTYPE)
                if self.config.uses(modality.name):
                    per_concept = observed_t.T @ modality.counts.to(DTYPE)  # [L, K_m]
                counts.append(per_concept)
            statistics = ConceptStatistics(torch.from_numpy(sizes), tuple(counts))
            self._summary = (statistics, observed_q, entropy, agreements)
        return self._summary

    def statistics(self) -> ConceptStatistics:
        """Expected concept sizes and per-concept counts under the sparse q."""
        return self._summaries()[0]

    def elbo(self, factors: GlobalFactors, gamma: float | None = None) -> float:
        """The ELBO of :mod:`spcopyro.variational.elbo`, from the sparse state."""
        gamma = self.config.gamma if gamma is None else gamma
        statistics, observed_q, entropy, agreements = self._summaries()
        log_pi, loglik = self._expectations(factors)
        expected = float((statistics.cells * log_pi).sum()) + gamma * agreements
        expected += float((loglik.numpy() * observed_q).sum()) + self._constant
        return expected - float(kl_to_prior(factors, self.data, self.config)) + entropy

    def labels(self) -> torch.Tensor:
        """[N] int64 every cell's most probable concept (its first sparse entry)."""
        return torch.from_numpy(self.index[: self.data.num_free, 0].copy())

    def num_used(self) -> int:
        """How many concepts are some cell's most probable one."""
        self._summaries()
        return int((self._argmax_cells > 0).sum())

    def support_sizes(self) -> np.ndarray:
        """[N] how many concepts each cell keeps."""
        return self.count[: self.data.num_free].copy()

    def dense(self, out: torch.Tensor | None = None) -> torch.Tensor:
        """q as a dense ``[N, L]`` float64 tensor (written into ``out`` when given)."""
        N, L = self.data.num_free, self.config.num_concepts
        q = np.zeros((N, L))
        _to_dense(self.index, self.value, self.count, q)
        if out is None:
            return torch.from_numpy(q)
        return out.copy_(torch.from_numpy(q))
