r"""A compiled (numba) loopy-BP backend with sparse messages: the outer iteration of
:mod:`spcopyro.guides.lbp_method` (message passes, beliefs, globals, Bethe objective) at the cost
of a few Gibbs sweeps.

**Sparse messages.** A normalised Potts message (:mod:`spcopyro.guides.lbp`) is
:math:`m_{i\to j}(l) = (1 + s\,b_{i\setminus j}(l)) / (L + s)`, s = e^gamma - 1: a constant
plus an excess that is large only where the cavity belief is. Every message is stored as

.. math::

    m(l) = \frac{1 + \rho(l)}{L + \sum_k \rho(k)}, \qquad \rho \ge 0 \text{ sparse},

(``rho = s b_{i \ j}`` undamped), at most ``support`` = K entries a message: ``idx, val, lg
[N * D, K]`` (concept, rho, log(1 + rho)), ``cnt``, ``msum`` (sum of rho) ``[N * D]``; row
j * D + s holds the message into j from its slot-s neighbour, as the torch reference's
``log_messages[j, s]``. The mixture of two messages is again of this form (with
:math:`a = (1-d)/(L+S_{new}) + d/(L+S_{old})`, :math:`\rho = [(1-d)\rho_{new}/(L+S_{new}) +
d\rho_{old}/(L+S_{old})]/a`), so damping (in probability space, as the reference) stays sparse.

**A cell's products.** With the node potential's base :math:`\beta_l = e^{h_i(l) - \max h_i}`
(eq. 13's node terms: E log pi for a cell without observations, shared by all of them; plus the
E-log-likelihood for an observed one, a row each) and :math:`W_i(l) = \prod_{r\sim i} (1 +
\rho_{r\to i}(l))`, 1 outside the union T_i of the incoming supports (at most D K concepts), the
belief and the cavity without j are

.. math::

    q_i(l) = \beta_l W_i(l) / Z_i, \quad Z_i = \textstyle\sum_l \beta_l + \sum_{l\in T_i}
    \beta_l (W_i(l) - 1); \qquad b_{i\setminus j}(l) \propto \beta_l W_i(l) / (1 +
    \rho_{j\to i}(l)),

so a message costs :math:`O(|T_i|)` plus the concepts of beta's descending order that are not
in T_i and pass the threshold (as the sparse CAVI's background,
:mod:`spcopyro.guides.numba_cavi`); no exp or log in the pass but log(1 + rho) of the entries
written. Products stay finite while gamma D <= 300 (else the torch reference runs: :func:`usable`).

**Truncation.** A new message keeps its K largest excess entries with rho >= ``threshold``: a
dropped entry changes log m(l) by at most log(1 + threshold) against the others. ``support=0``
(K = L) and ``threshold=0``: no truncation; equal to the reference to rounding (tested).

**Active set** (``active_tolerance`` = tau), as CAVI's. When a cell sends, each of its messages
records ``moved``, half the log range over l of its change (up to a constant, which the
normalisation removes). A cell's inputs are its base row and its incoming messages; their drift
since its last send is bounded by the sum of the base row's half log range of change (per iteration,
plus :math:`|\Delta\gamma|` for the coupling) and its incoming messages' ``moved``. If the inputs'
logs moved by at most epsilon up to a constant, the cavity's logs move by at most 2 epsilon, and so
do log(1 + s b) and the messages. Damping leaves a stored message at ``residual`` (half log range)
from its undamped update. A cell is skipped (its messages kept, their ``moved`` set to 0) while 2
drift + residual <= tau: its messages then lie within a factor e^(+-tau) of a fresh send's undamped
messages. The pass visits every cell once in a fixed order, so a neighbour's latest ``moved`` is its
change since the cell's last visit. tau = 0 skips only cells whose inputs did not change and whose
messages are undamped fixed points.

**Beliefs and the Bethe objective** are functions of the stored messages: the sizes
sum_i q_i, the observed cells' q ``[M, L]``, the argmax labels, and the terms of
:func:`spcopyro.guides.lbp.bethe_label_objective`: node entropies
:math:`H_i = \log Z_i - Z_i^{-1} \sum_l \beta_l W_i \log(\beta_l W_i)` and, per pair, the
overlap :math:`\sum_l u(l) v(l)` of the two cavities and the pairwise belief's entropy, each a
dense sum over L (sum beta^2, sum beta log beta, ... once per iteration) plus corrections on
T_a and T_b. :func:`~spcopyro.guides.numba_lbp_kernels._summaries` computes them all from the
messages (:meth:`SparseLoopyBP.exact_summaries`); a run keeps them cached instead.

**Cached beliefs** (:mod:`spcopyro.guides.numba_lbp_beliefs`), with the active set's tolerance
semantics. Each cell keeps its belief as computed at its last refresh: a cell without
observations as 1/Z_i, the epoch e of the base row beta_e it was computed under (its dense part
is beta_e / Z_i) and its excess :math:`\beta_{e,l}(W_i(l) - 1)/Z_i` on T_i (at most
min(L, D K) entries); an observed cell as its row of ``observed_q``; and its label and
:math:`(d_i - 1) H_i`. Each pair keeps E_{b_ab}[delta] and H[b_ab]. Running sums: the sizes
(the excesses and observed rows, plus :math:`\sum_e \beta_e \sum_{i \in e} 1/Z_i` over the
epochs still in use) and the three Bethe totals; re-added from the cached values every
``RECOUNT_EVERY`` iterations (their rounding), and a cell's old contribution is subtracted
when it is refreshed. Each cell carries the drift of its belief's inputs since its refresh,
``belief_drift``: the base row's half log range of change per iteration (plus
:math:`|\Delta\gamma|`) and the ``moved`` of every message sent into it (the pass adds it). After
the passes, a cell is refreshed when 2 drift > tau, and then every pair touching it. Since
log q_i is log beta_l plus the incoming log messages, normalised:

* a cached belief is within a factor :math:`e^{\pm\delta_i}`, :math:`\delta_i = 2\,
  \mathrm{drift}_i \le \tau`, of the exact belief of the current messages, concept by concept;
  a cached pair belief (whose cavities exclude one message each, and whose coupling's change is
  counted in both ends' drift) within :math:`e^{\pm\delta_{ab}}`, :math:`\delta_{ab} =
  2(\mathrm{drift}_a + \mathrm{drift}_b) \le 2\tau`;
* so (:meth:`SparseLoopyBP.cache_bound`): the sizes lie within :math:`\sum_i (e^{\delta_i} - 1)`
  in L1 norm of the exact ones; with :math:`|H[\tilde p] - H[p]| \le \delta + (e^\delta - 1)
  H[p]` for a pointwise log ratio within delta, the node total within :math:`\sum_i |d_i - 1|
  (\delta_i + (e^{\delta_i} - 1)\log L)`, the agreements within :math:`\sum_{ab}
  (e^{\delta_{ab}} - 1)`, the pairs' entropies within :math:`\sum_{ab} (\delta_{ab} +
  (e^{\delta_{ab}} - 1)\, 2\log L)` (tested, cell by cell and pair by pair);
* tau = 0 refreshes every cell whose inputs changed at all: the cached summaries equal
  ``_summaries`` to rounding (tested), and so does :meth:`SparseLoopyBP.refresh_all` at any tau.

The Bethe objective is assembled from them (its energy under the new globals), so its trace moves
only with the refreshed cells. Nothing of size N x L exists in a run but at K = L the cached
excesses (N x min(L, D K), as the messages); the dense beliefs are written once at the end.

**Cost.** A cell that sends costs :math:`O(D |T_i|)`; a refreshed belief O(D K) plus, for each of
its pairs, the other end's gather and :math:`O(|T_a| + |T_b|)`; a skipped cell O(D) in each
pass and in the refresh. Against O(D L) for the dense reference, the backend is as fast as the
messages are sparse and as few cells move; they are sparse only where the beliefs have ordered:
in a disordered field every concept keeps an excess of about s / L, above any useful threshold
(paper-dp, L = 120: 115-119 of 120 entries a message). Measured by ``benchmarks/variational.py``
(one thread, load average 4-9, ratios within a run): where no cell moves once converged
(original-code, L = 120) an iteration now costs 0.6-2.3x a CAVI iteration (before the cached
beliefs: 8-176x, the summaries read every message); elsewhere 6-320x on room2ldk4 and the
embedded house (before: 8-508x), because 8-63 % of the cells still send in iterations 30-50,
where loopy BP is still converging and CAVI has settled (``docs/variational.md``).

The kernels compile on first use in a process (``cache=True`` keeps them for later processes on
the same machine; the results do not depend on it). Importing this module raises
:class:`ImportError` when numba is missing.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
import torch

from spcopyro._util.number_checks import is_finite_number, is_int, is_number
from spcopyro.config import SpCoConfig
from spcopyro.guides.factors import (
    GlobalFactors,
    expected_log_emissions,
    expected_log_pi,
    update_factors,
)
from spcopyro.guides.lbp import message_graph
from spcopyro.guides.numba_cavi import PriorKL
from spcopyro.guides.numba_lbp_beliefs import _bound, _recount, _refresh
from spcopyro.guides.numba_lbp_kernels import _dense, _start, _summaries
from spcopyro.guides.numba_lbp_pass import _message_pass
from spcopyro.likelihood import (
    ConceptStatistics,
    multinomial_coefficients,
    observation_log_likelihood,
)
from spcopyro.model import DTYPE, ModelData

__all__ = ["SparseLBPState", "SparseLoopyBP", "init", "step", "usable", "usable_at"]

RECOUNT_EVERY = 50
"""Outer iterations between re-additions of the cached beliefs' running sums (bounds their
rounding; the cached values themselves are kept)."""

MAX_GAMMA_DEGREE = 300.0
"""gamma D at most this: the pairs' products of two cavities (2 D - 2 messages) stay below e^600
(float64 holds e^709)."""


def usable(config: SpCoConfig, data: ModelData) -> bool:
    """Whether the compiled backend's products stay finite: gamma D <= 300."""
    return usable_at(config.gamma, data.neighbours.shape[1])


def usable_at(gamma: float, degree: int) -> bool:
    """:func:`usable` for a coupling ``gamma`` and ``degree`` neighbours a cell (before the
    model data exist: ``fit`` names the backend it will run)."""
    return gamma * degree <= MAX_GAMMA_DEGREE


class SparseLoopyBP:
    """The messages of loopy BP as sparse excesses (module docstring), and their updates.

    What :func:`step` calls: :meth:`run` (the passes and the summaries), :meth:`statistics`,
    :meth:`objective`, :meth:`num_used`, :meth:`labels`; :meth:`beliefs` and
    :meth:`log_messages` give the dense tensors of the torch reference's
    :class:`~spcopyro.guides.lbp.LoopyBP`.
    """

    def __init__(
        self,
        data: ModelData,
        config: SpCoConfig,
        damping: float = 0.5,
        passes: int = 1,
        *,
        support: int = 0,
        threshold: float = 0.0,
        active_tolerance: float = 0.0,
    ) -> None:
        if not (is_number(damping) and 0 <= damping < 1):
            raise ValueError(f"damping must lie in [0, 1), got {damping!r}")
        if not is_int(passes) or passes < 1:
            raise ValueError(f"passes must be an integer >= 1, got {passes!r}")
        if not is_int(support) or support < 0:
            raise ValueError(f"support must be an integer >= 0 (0: all L), got {support!r}")
        if not (is_finite_number(threshold) and threshold >= 0):
            raise ValueError(f"threshold must be a finite number >= 0, got {threshold!r}")
        if not (is_finite_number(active_tolerance) and active_tolerance >= 0):
            raise ValueError(
                f"active_tolerance must be a finite number >= 0, got {active_tolerance!r}"
            )
        if not usable(config, data):
            raise ValueError(f"gamma * D = {config.gamma * data.neighbours.shape[1]:g} > "
                             f"{MAX_GAMMA_DEGREE:g}: use the torch backend")  # fmt: skip
        self.data, self.config = data, config
        self.damping, self.passes = float(damping), passes
        self.threshold, self.active_tolerance = float(threshold), float(active_tolerance)
        graph = message_graph(data)
        N, D = data.neighbours.shape
        L = config.num_concepts
        K = min(support, L) if support > 0 else L
        self.nb = np.ascontiguousarray(graph.neighbours.numpy(), dtype=np.int64)  # [N, D]
        self.rev = np.ascontiguousarray(graph.reverse.numpy(), dtype=np.int64)  # [N, D]
        self.order = np.ascontiguousarray(torch.cat(list(data.colours)).numpy(), np.int64)  # [N]
        M = int(data.obs_cells.shape[0])
        rows = np.full(N, M, dtype=np.int64)  # [N] row of the base table (M: no observation)
        rows[data.obs_cells.numpy()] = np.arange(M)
        self.rows = rows
        pairs = data.pairs.numpy()
        by_a = np.argsort(pairs[:, 0], kind="stable") if len(pairs) else np.zeros(0, np.int64)
        self.pair_a = np.ascontiguousarray(pairs[by_a, 0], dtype=np.int64)  # [P]
        self.pair_b = np.ascontiguousarray(pairs[by_a, 1], dtype=np.int64)  # [P]
        self.pair_slots = np.ascontiguousarray(graph.pair_slots.numpy()[by_a], np.int64)  # [P, 2]
        P = len(self.pair_b)
        self.incident = np.full((N, D), -1, dtype=np.int64)  # [N, D] the pair of each slot
        self.incident[self.pair_a, self.pair_slots[:, 0]] = np.arange(P)
        self.incident[self.pair_b, self.pair_slots[:, 1]] = np.arange(P)
        self.pair_starts = np.zeros(N + 1, dtype=np.int64)  # [N + 1]
        np.cumsum(np.bincount(pairs[:, 0], minlength=N), out=self.pair_starts[1:])
        self.degree = graph.degree
        E = N * D
        self.idx = np.zeros((E, K), dtype=np.int32)  # [N * D, K] message excesses
        self.val = np.zeros((E, K))
        self.lg = np.zeros((E, K))
        self.cnt = np.zeros(E, dtype=np.int64)  # [N * D] (0: the uniform message)
        self.msum = np.zeros(E)
        self.moved = np.zeros(E)
        self.drift = np.full(N, np.inf)  # [N] every cell sends on the first pass
        self.residual = np.zeros(N)
        self._marks = np.zeros((2, L), dtype=np.int64)  # scratch of the kernels
        self._fmarks = np.zeros((2, D, L), dtype=np.int64)
        self._scratch = np.zeros((4, L))
        self._facs = np.ones((2, D, L))
        self._flogs = np.zeros((2, D, L))
        self._tsets = np.zeros((2, L), dtype=np.int64)
        self.sizes = np.zeros(L)  # [L] sum_i q_i (of the cached beliefs)
        self.observed_q = np.zeros((M, L))  # [M, L] the observed cells' cached beliefs
        self._labels = np.zeros(N, dtype=np.int64)  # [N]
        self.totals = np.zeros(3)  # [3] sum (d_i - 1) H_i, sum E[delta], sum H[b_ab]
        # the cached beliefs (module docstring): per cell, per pair, per epoch of base row M
        self.belief_drift = np.full(N, np.inf)  # [N] inputs' drift since the cell's belief
        self.cell_epoch = np.full(N, -1, dtype=np.int64)  # [N]
        self.cell_invz = np.zeros(N)  # [N] 1 / Z_i
        self.cell_node = np.zeros(N)  # [N] (d_i - 1) H_i
        Kb = min(L, D * K)
        self.bidx = np.zeros((N, Kb), dtype=np.int32)  # [N, Kb] excess beta (W - 1) / Z on T_i
        self.bval = np.zeros((N, Kb))
        self.bcnt = np.zeros(N, dtype=np.int64)  # [N]
        self.pair_agree = np.zeros(P)  # [P] E_{b_ab}[delta]
        self.pair_entropy = np.zeros(P)  # [P] H[b_ab]
        self._pair_mark = np.zeros(P, dtype=np.int64)
        self.epoch_beta = np.zeros((8, L))  # [E, L] the base rows M the beliefs were cached at
        self.epoch_invz = np.zeros(8)  # [E] sum of 1 / Z_i of the cells cached at each
        self.epoch_count = np.zeros(8, dtype=np.int64)  # [E]
        self.sizes_rest = np.zeros(L)  # [L] sizes but the epochs' dense parts
        self._degree = (self.nb >= 0).sum(1)  # [N]
        self.refreshed_cells = 0
        """Cells whose cached belief the last :meth:`run` recomputed."""
        self._runs_since_recount = 0
        self.gamma: float | None = None  # the coupling of the last pass (None: not started)
        self.sent_cells = 0
        """Cells that sent in the last :meth:`run` (over its passes; the others were skipped)."""
        self._tables: tuple[np.ndarray, ...] | None = None
        self._previous: tuple[np.ndarray, float] | None = None  # (log base rows, gamma)
        self._constant = float(multinomial_coefficients(data, config))
        self._cached: tuple | None = None  # (factors, h, loglik, E log phi) of the last factors
        self._prior: PriorKL | None = None

    @property
    def started(self) -> bool:
        return self.gamma is not None

    def start_from(self, q: torch.Tensor, gamma: float) -> None:
        """Every message i -> j set to the one a cell whose cavity belief is q_i ``[N, L]`` would
        send (as :meth:`spcopyro.guides.lbp.LoopyBP.start_from`), truncated."""
        dense = np.ascontiguousarray(q.detach().numpy(), dtype=np.float64)
        _start(dense, self.nb, self.rev, math.expm1(gamma), self.threshold, self.idx, self.val,
               self.lg, self.cnt, self.msum)  # fmt: skip
        self.drift[:] = np.inf
        self.belief_drift[:] = np.inf
        self.gamma = float(gamma)

    def _base(self, factors: GlobalFactors) -> tuple[np.ndarray, np.ndarray]:
        """(h rows [M + 1, L]: the observed cells' E log pi + loglik, then E log pi; the
        loglik [M, L]), cached for the last factors (the objective's are the next pass's)."""
        if self._cached is None or self._cached[0] is not factors:
            log_pi = expected_log_pi(factors)  # [L]
            log_phi = expected_log_emissions(factors)
            loglik = observation_log_likelihood(log_phi, self.data, self.config)  # [M, L]
            h = torch.cat([loglik + log_pi, log_pi[None]]).numpy()  # [M + 1, L]
            self._cached = (factors, h, loglik.numpy(), log_phi)
        return self._cached[1], self._cached[2]

    def run(self, factors: GlobalFactors, gamma: float) -> None:
        """``passes`` message passes under the node potentials of ``factors`` at coupling
        ``gamma``, then the beliefs' summaries."""
        h, _ = self._base(factors)
        shifted = h - h.max(1, keepdims=True)  # [M + 1, L]
        beta = np.exp(shifted)
        logbeta = np.where(beta > 0, shifted, 0.0)  # beta log beta = 0 where beta underflows
        border = np.argsort(-shifted[-1], kind="stable")  # [L] row M's concepts, descending
        bsum = beta.sum(1)  # [M + 1]
        row_entropy = (beta * logbeta).sum(1)  # [M + 1]
        M = beta.shape[0] - 1
        row_drift = np.full(M + 1, np.inf)  # [M + 1]
        if self._previous is not None:
            before, before_gamma = self._previous
            change = h - before  # a constant shift of a row changes nothing: half its range
            row_drift = 0.5 * (change.max(1) - change.min(1)) + abs(gamma - before_gamma)
        self._previous = (h, float(gamma))
        self.belief_drift += row_drift[self.rows]
        no_drift = np.zeros(M + 1)
        self.sent_cells = 0
        for p in range(self.passes):
            self.sent_cells += _message_pass(
                self.idx, self.val, self.lg, self.cnt, self.msum, self.moved, self.drift,
                self.residual, self.belief_drift, self.order, self.nb, self.rev, self.rows, beta,
                border, bsum, row_drift if p == 0 else no_drift, float(gamma), self.threshold,
                self.damping, self.active_tolerance, self._marks[0], self._marks[1],
                self._fmarks[0], self._scratch[0], self._scratch[2], self._facs[0],
            )  # fmt: skip
        self.gamma = float(gamma)
        self._tables = (beta, logbeta, border, bsum, row_entropy)
        self._refresh_cached(self.active_tolerance)
        self._runs_since_recount += 1
        if self._runs_since_recount >= RECOUNT_EVERY:
            self._recount()
        self.sizes[:] = self.sizes_rest + self.epoch_invz @ self.epoch_beta

    def _recount(self) -> None:
        """The running sums re-added from the cached values (clears their rounding)."""
        _recount(
            self.rows, self.cell_epoch, self.cell_invz, self.cell_node, self.bidx, self.bval,
            self.bcnt, self.observed_q, self.pair_agree, self.pair_entropy, self.epoch_invz,
            self.epoch_count, self.sizes_rest, self.totals,
        )  # fmt: skip
        self._runs_since_recount = 0

    def _refresh_cached(self, tolerance: float) -> None:
        """The cached beliefs of the cells whose inputs drifted past ``tolerance`` (and the pair
        terms touching them) recomputed under the last pass's base rows, at its coupling."""
        beta, logbeta, border, bsum, row_entropy = self._tables
        M = beta.shape[0] - 1
        epoch = self._free_epoch(beta[M])
        background = beta[M] * beta[M]  # [L]
        self.refreshed_cells = _refresh(
            self.idx, self.val, self.lg, self.cnt, self.nb, self.rows, beta, logbeta, border,
            bsum, row_entropy, float(background.sum()), float((background * logbeta[M]).sum()),
            self.gamma, tolerance, epoch, self.pair_a, self.pair_b, self.pair_slots,
            self.incident, self.belief_drift, self.cell_epoch, self.cell_invz, self.cell_node,
            self.bidx, self.bval, self.bcnt, self._labels, self.observed_q, self.pair_agree,
            self.pair_entropy, self._pair_mark, self.epoch_invz, self.epoch_count,
            self.sizes_rest, self.totals, self._marks, self._fmarks, self._scratch, self._facs,
            self._flogs, self._tsets,
        )  # fmt: skip

    def refresh_all(self) -> None:
        """Every cached belief and pair term recomputed from the current messages under the
        last pass's base rows, and the running sums re-added: the summaries become exact."""
        self.belief_drift[:] = np.inf
        self._refresh_cached(0.0)
        self._recount()
        self.sizes[:] = self.sizes_rest + self.epoch_invz @ self.epoch_beta

    def _free_epoch(self, row: np.ndarray) -> int:
        """A slot of the epoch tables no cached belief refers to, holding base row M ``row``
        [L] (the tables doubled when every slot is taken)."""
        free = np.flatnonzero(self.epoch_count == 0)
        if free.size == 0:
            E = self.epoch_count.shape[0]
            self.epoch_beta = np.concatenate([self.epoch_beta, np.zeros_like(self.epoch_beta)])
            self.epoch_invz = np.concatenate([self.epoch_invz, np.zeros(E)])
            self.epoch_count = np.concatenate([self.epoch_count, np.zeros(E, dtype=np.int64)])
            free = np.arange(E, 2 * E)
        epoch = int(free[0])
        self.epoch_beta[epoch] = row
        self.epoch_invz[epoch] = 0.0
        return epoch

    def exact_summaries(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(sizes [L], observed q [M, L], labels [N], totals [3]) recomputed from all the
        messages under the last pass's base rows (what the cached ones approximate; equal to
        them when no belief was kept stale)."""
        beta, logbeta, border, bsum, row_entropy = self._tables
        sizes, observed = np.zeros_like(self.sizes), np.zeros_like(self.observed_q)
        labels, totals = np.zeros_like(self._labels), np.zeros(3)
        _summaries(
            self.idx, self.val, self.lg, self.cnt, self.nb, self.rows, beta, logbeta, border,
            bsum, row_entropy, self.pair_starts, self.pair_b, self.pair_slots, self.gamma,
            self._marks, self._fmarks, self._scratch, self._facs, self._flogs, self._tsets,
            sizes, observed, labels, totals,
        )  # fmt: skip
        return sizes, observed, labels, totals

    def cache_bound(self) -> np.ndarray:
        """[4] bounds on how far the cached sizes (L1 norm), sum (d_i - 1) H_i, sum E[delta]
        and sum H[b_ab] lie from :meth:`exact_summaries` (module docstring)."""
        out = np.zeros(4)
        _bound(self.belief_drift, self.pair_a, self.pair_b, self._degree,
               math.log(self.config.num_concepts), out)  # fmt: skip
        return out

    def cached_beliefs(self) -> np.ndarray:
        """[N, L] the cached beliefs, dense (for tests)."""
        M = self.observed_q.shape[0]
        q = np.zeros((self.nb.shape[0], self.config.num_concepts))
        background = self.rows == M
        q[background] = self.epoch_beta[self.cell_epoch[background]] * self.cell_invz[
            background, None]  # fmt: skip
        for i in np.flatnonzero(background):
            q[i, self.bidx[i, : self.bcnt[i]]] += self.bval[i, : self.bcnt[i]]
        q[~background] = self.observed_q[self.rows[~background]]
        return q

    def statistics(self) -> ConceptStatistics:
        """Expected concept sizes and per-concept counts under the beliefs (as
        :func:`spcopyro.likelihood.concept_statistics` of the dense beliefs)."""
        L = self.config.num_concepts
        observed = torch.from_numpy(self.observed_q)  # [M, L]
        counts = []
        for modality in self.data.modalities:
            per_concept = torch.zeros(L, modality.counts.shape[-1], dtype=DTYPE)  # [L, K_m]
            if self.config.uses(modality.name):
                per_concept = observed.T @ modality.counts.to(DTYPE)
            counts.append(per_concept)
        return ConceptStatistics(torch.from_numpy(self.sizes.copy()), tuple(counts))

    def objective(self, factors: GlobalFactors, gamma: float | None = None) -> float:
        """:func:`spcopyro.guides.lbp.bethe_objective` of the current beliefs: the energy under
        ``factors`` at coupling ``gamma`` (default: the model's)."""
        gamma = self.config.gamma if gamma is None else gamma
        h, loglik = self._base(factors)
        energy = float(self.sizes @ h[-1]) + float((self.observed_q * loglik).sum())
        node, agreements, pair_entropy = (float(t) for t in self.totals)
        labels = energy + gamma * agreements + pair_entropy - node
        if self._prior is None:
            self._prior = PriorKL(self.data, self.config, factors.pi_family)
        return labels + self._constant - self._prior(factors, self._cached[3])

    def labels(self) -> torch.Tensor:
        """[N] int64 every cell's most probable concept."""
        return torch.from_numpy(self._labels.copy())

    def num_used(self) -> int:
        """How many concepts are some cell's most probable one."""
        return int(np.count_nonzero(np.bincount(self._labels)))

    def _dense(self) -> tuple[torch.Tensor, torch.Tensor]:
        N, D = self.nb.shape
        L = self.config.num_concepts
        log_messages, beliefs = np.zeros((N, D, L)), np.zeros((N, L))
        beta = self._tables[0] if self._tables is not None else np.ones((self.rows.max() + 1, L))
        _dense(self.idx, self.val, self.cnt, self.msum, self.nb, self.rows, beta, log_messages,
               beliefs)  # fmt: skip
        return torch.from_numpy(log_messages), torch.from_numpy(beliefs)

    @property
    def log_messages(self) -> torch.Tensor:
        """[N, D, L] the dense log messages (0 where no neighbour), as the reference's."""
        return self._dense()[0]

    def beliefs(self) -> torch.Tensor:
        """[N, L] float64 the beliefs under the node potentials of the last pass."""
        return self._dense()[1]


class SparseLBPState(NamedTuple):
    """The compiled backend's LBP state: the sparse messages (updated in place by :func:`step`)
    and the global factors optimal given the beliefs."""

    bp: SparseLoopyBP
    q: torch.Tensor
    """[N, L] the starting beliefs (read by the first step only; the final ones are
    :meth:`SparseLoopyBP.beliefs`)."""
    factors: GlobalFactors


def init(q: torch.Tensor, data: ModelData, config: SpCoConfig, options: Any) -> SparseLBPState:
    """The state at beliefs ``q`` ``[N, L]``: the globals from them; the messages start from q
    at the first step's coupling. ``options``: an
    :class:`~spcopyro.guides.lbp_method.LBPOptions`."""
    from spcopyro.guides.cavi import update_globals

    bp = SparseLoopyBP(
        data, config, options.damping, options.passes, support=options.support,
        threshold=options.threshold, active_tolerance=options.active_tolerance,
    )  # fmt: skip
    return SparseLBPState(bp, q, update_globals(q, data, config, options.pi_family))


def step(
    state: SparseLBPState,
    data: ModelData,
    config: SpCoConfig,
    gamma: float,
    options: Any,
) -> tuple[SparseLBPState, float, int]:
    """One outer iteration, as :func:`spcopyro.guides.lbp_method.step`: the passes under the
    globals' node potentials, the globals from the beliefs; returns the new state, the Bethe
    objective (NaN where not finite) and the concepts in use."""
    bp = state.bp
    if not bp.started:  # the first step: messages a cell with belief q would send
        bp.start_from(state.q, gamma)
    bp.run(state.factors, gamma)
    factors = update_factors(bp.statistics(), data, config, options.pi_family)
    value = bp.objective(factors)
    value = value if math.isfinite(value) else float("nan")
    return SparseLBPState(bp, state.q, factors), value, bp.num_used()
