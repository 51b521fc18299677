r"""A compiled (numba) mean-field CAVI backend with a sparse q(C): the update of
:mod:`spcopyro.guides.cavi`, at the cost of a Gibbs sweep.

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

**Active set** (``active_tolerance`` = tau). A cell's update reads the logits
:math:`a_l + \gamma n_l(i)` (a = E log pi, or E log pi plus the cell's expected log-likelihood
for an observed cell). If every logit moved by delta_l with :math:`|\delta_l - c| \le
\varepsilon` for a constant c since the cell's last update, its exact update moved by at most a
factor :math:`e^{\pm 2\varepsilon}` per concept (the normaliser moves by at most
:math:`e^{\pm\varepsilon}`). Each cell carries a bound on that epsilon, the sum of

* the globals' part: half the range over l of this iteration's change of E log pi (cells
  without observations) or of the observed cell's row (computed once per iteration, [M + 1]);
* the coupling's: :math:`|\Delta\gamma| D / 2` (n_l(i) lies in [0, D]);
* the neighbours': :math:`\gamma \sum_{r \sim i} \max_l |\Delta q_r(l)|`, each neighbour's
  change at its latest visit (0 when it was skipped). The pass visits every cell once, in the
  same order each time, so every neighbour is visited exactly once between two visits of the
  cell: its latest change is its change since the cell's last update.

The bound accumulates while the cell is skipped and restarts at 0 when it is updated; a cell is
skipped while it is <= tau (never with damping; every cell is updated on the first pass). Then:

* **the ELBO stays monotone**: a skipped cell keeps its q, the updated ones are exact
  coordinate steps (truncated as above), the globals' update is exact. Skipping only forgoes
  the gain of the skipped updates, :math:`\mathrm{KL}(q_i \| q_i^*) \le
  \log(1 + (e^{2\tau} - 1)^2) \approx 4\tau^2` per skipped cell (its log ratio to the exact
  update q_i^* lies in [-2 tau, 2 tau]): at most 0.11 nats an iteration on room2ldk4's 27,746
  cells with the default tau = 1e-3;
* every q_i is within a factor :math:`e^{\pm 2\tau}` of its exact update, concept by concept
  (tested against the dense reference block by block); the fixed point the run converges to
  satisfies the mean-field equations to that accuracy;
* tau = 0 skips a cell only when nothing it reads changed (the globals, the coupling and its
  neighbours' q all bit-for-bit the same): then the update is the same as the reference's.

**Running sums.** The globals' statistics (sum_i q_i), the entropy sum_i H[q_i] and the pairs'
term sum_{a~b} q_a . q_b are kept up to date cell by cell in the label pass: a cell's entropy
costs one log (:math:`H = \log\text{kept} - \sum_k v_k \log w_k`, the log weights being the
logits the update already has), the pairs' term changes by :math:`(q_i^{new} - q_i^{old}) \cdot
n(i)`, the field the update read. They are recomputed from scratch every ``RECOUNT_EVERY``
updates (and after every update with damping), which bounds their rounding drift (tested equal to
the recount and to the dense formulas). The ELBO then costs O(M L) plus the globals' KL.

**What truncation does to the fit.** A cell near disorder spreads its mass over all L concepts,
and a top-K cap renormalises it onto K of them, which behaves like a K-state Potts model: it
orders at a much lower gamma and changes the fit. The default is therefore no cap
(``support=0``) and a threshold of 1e-4: a disordered cell keeps all its concepts (1/L > 1e-4 for
L < 10^4), an ordered one its few non-negligible ones (at gamma = 4 a cell with 3 agreeing
neighbours still gives the others e^-12 = 6e-6, which a threshold of 1e-6 would keep). The ELBO
lost is at most the reported bound (``benchmarks/variational.py`` counts the decreases). The
measurements behind these defaults are in ``docs/variational.md`` ("Defaults and what they
give").

The first call compiles the kernels (seconds; ``cache=True`` keeps them for later processes).
Importing this module raises :class:`ImportError` when numba is missing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import torch

from spcopyro._util.number_checks import is_finite_number, is_int, is_number
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.numba_plan import flat_plan
from spcopyro.gibbs.state import SweepPlan
from spcopyro.guides.cavi import CAVIInfo
from spcopyro.guides.factors import (
    GlobalFactors,
    expected_log_emissions,
    expected_log_pi,
    kl_to_prior,
    prior_factors,
    update_factors,
)
from spcopyro.guides.numba_cavi_kernels import (
    _entropies,
    _from_dense,
    _observed,
    _recount,
    _to_dense,
    _update_cells,
)
from spcopyro.likelihood import (
    ConceptStatistics,
    multinomial_coefficients,
    observation_log_likelihood,
)
from spcopyro.model import DTYPE, ModelData

if TYPE_CHECKING:
    from spcopyro.guides.options import VariationalOptions

__all__ = ["SparseCAVIState", "SparseMeanField", "init", "sparse_from_dense", "step"]

RECOUNT_EVERY = 50
"""Updates between recomputations of the running sums from scratch (bounds their rounding)."""


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


class PriorKL:
    r""":func:`~spcopyro.guides.factors.kl_to_prior` of factors whose E log phi = psi(a) -
    psi(a_0) is already at hand: per modality, with the prior's b (constant, computed once),
    :math:`\sum_l [\log\Gamma(a_{l0}) - \log\Gamma(b_0)] + \sum_{lk} [\log\Gamma(b_k)
    - \log\Gamma(a_{lk}) + (a_{lk} - b_k) E\log\phi_{lk}]` (one lgamma per entry, no
    digamma). Shared by the compiled CAVI and LBP backends."""

    def __init__(self, data: ModelData, config: SpCoConfig, pi_family: str) -> None:
        self.data, self.config = data, config
        self.prior = prior_factors(data, config, pi_family)
        self.constants = [float(torch.lgamma(b).sum() - torch.lgamma(b.sum(-1)).sum())
                          if b.shape[-1] else 0.0  # no items (V = 0): lgamma(0) is inf
                          for b in self.prior.emissions]  # fmt: skip

    def __call__(self, factors: GlobalFactors, log_phi: tuple[torch.Tensor, ...]) -> float:
        pi_only = GlobalFactors(factors.pi, (), factors.pi_family)
        total = float(kl_to_prior(pi_only, self.data._replace(modalities=()), self.config))
        for a, b, e, constant in zip(factors.emissions, self.prior.emissions, log_phi,
                                     self.constants, strict=True):  # fmt: skip
            if not a.shape[-1]:  # over no items: q and the prior are one point, KL 0
                continue
            rows = float(torch.lgamma(a.sum(-1)).sum())
            entries = float(((a - b) * e).sum() - torch.lgamma(a).sum())
            total += rows + entries + constant
        return total


class SparseMeanField:
    """The numba backend's label field: a sparse q(C) (module docstring) and its updates.

    What :func:`step` calls: :meth:`update` (one colour-block pass at a coupling),
    :meth:`statistics` (for the globals), :meth:`elbo`, :meth:`num_used`; :meth:`labels` for
    thinning, and :meth:`dense` at the end.
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
        active_tolerance: float = 0.0,
        plan: SweepPlan | None = None,
    ) -> None:
        N, L = data.num_free, config.num_concepts
        if tuple(q.shape) != (N, L):
            raise ValueError(f"q must be [{N}, {L}], got {tuple(q.shape)}")
        if not is_int(support) or support < 0:
            raise ValueError(
                f"support must be an integer >= 0 (0: all L concepts), got {support!r}"
            )
        if not (is_number(threshold) and 0.0 <= threshold < 1.0):
            raise ValueError(f"threshold must be a number in [0, 1), got {threshold!r}")
        if not (is_finite_number(active_tolerance) and active_tolerance >= 0):
            raise ValueError(
                f"active_tolerance must be a finite number >= 0, got {active_tolerance!r}"
            )
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
        self.weight = np.zeros(L)
        self.row = np.zeros(L)
        rows = self.index.shape[0]
        self.entropy = np.zeros(rows)  # [N + D] H[q_i]
        _entropies(self.value, self.count, self.entropy)
        self.moved = np.zeros(rows)  # [N + D] max_l |change of q_i(l)| at its last visit
        self.drift = np.full(rows, np.inf)  # [N + D] logits' drift since the last update
        self.active_tolerance = float(active_tolerance)
        self._previous: tuple[np.ndarray, np.ndarray, float] | None = None
        self.updated_cells = 0
        """How many cells the last update recomputed (the others the active set skipped)."""
        order = np.argsort(self.pairs[:, 0], kind="stable") if len(self.pairs) else np.zeros(0, int)
        self.pair_partners = np.ascontiguousarray(self.pairs[order, 1], dtype=np.int64)  # [P]
        self.pair_starts = np.zeros(N + 1, dtype=np.int64)  # [N + 1]
        np.cumsum(np.bincount(self.pairs[:, 0], minlength=N), out=self.pair_starts[1:])
        self.sizes = np.zeros(L)  # [L] sum_i q_i, kept up to date by the updates
        self._argmax_cells = np.zeros(L, dtype=np.int64)  # [L]
        self.totals = np.zeros(2)  # [2] H[q(C)], sum over pairs of q_a . q_b
        self._since_recount = 0
        self._recount()
        self.truncation_bound = 0.0
        """sum_i -log(kept fraction) of the last update: the most it can have lowered the ELBO
        (0 without a threshold)."""
        self._constant = float(multinomial_coefficients(data, config))
        self._summary: tuple[ConceptStatistics, np.ndarray, float, float] | None = None
        self._loglik: tuple | None = None  # (factors, E log pi, loglik, E log phi)
        self._prior: PriorKL | None = None

    def _recount(self) -> None:
        """The running sums (sizes, argmax counts, entropy, pairs' term) from scratch."""
        _recount(
            self.index, self.value, self.count, self.data.num_free, self.entropy,
            self.pair_starts, self.pair_partners, self.sizes, self._argmax_cells, self.totals,
            self.row,
        )  # fmt: skip
        self._since_recount = 0

    # -- expectations of the globals, once per factors object
    def _expectations(self, factors: GlobalFactors) -> tuple[torch.Tensor, torch.Tensor]:
        """(E log pi [L], loglik [M, L]) of ``factors`` (cached for the last factors)."""
        if self._loglik is None or self._loglik[0] is not factors:
            log_pi = expected_log_pi(factors)  # [L]
            log_phi = expected_log_emissions(factors)
            loglik = observation_log_likelihood(log_phi, self.data, self.config)  # [M, L]
            self._loglik = (factors, log_pi, loglik, log_phi)
        return self._loglik[1], self._loglik[2]

    def _kl_to_prior(self, factors: GlobalFactors) -> float:
        """:func:`~spcopyro.guides.factors.kl_to_prior` from the cached E log phi
        (:class:`PriorKL`)."""
        self._expectations(factors)
        if self._prior is None:
            self._prior = PriorKL(self.data, self.config, factors.pi_family)
        return self._prior(factors, self._loglik[3])

    def update(self, factors: GlobalFactors, gamma: float) -> None:
        """One pass over every cell, colour block by colour block, at coupling ``gamma``."""
        log_pi_t, loglik = self._expectations(factors)
        log_pi = log_pi_t.numpy()
        log_pi = log_pi - log_pi.max()  # [L]
        order = np.argsort(-log_pi, kind="stable")  # [L]
        background = np.exp(log_pi)  # [L]
        raw = (loglik + log_pi_t).numpy()  # [M, L]
        observed = raw - raw.max(axis=1, keepdims=True) if raw.size else raw
        M = observed.shape[0]
        row_drift = np.full(M + 1, np.inf)  # [M + 1]
        if self._previous is not None:
            # a constant shift of a row's logits changes nothing: half the range of the change
            before_pi, before_rows, before_gamma = self._previous
            change = np.concatenate([raw - before_rows, (log_pi_t.numpy() - before_pi)[None]])
            row_drift = 0.5 * (change.max(1) - change.min(1)) if change.shape[1] else 0 * row_drift
            row_drift += 0.5 * abs(gamma - before_gamma) * self.flat.neighbours.shape[1]
        self._previous = (log_pi_t.numpy().copy(), raw.copy(), float(gamma))
        self.truncation_bound, self.updated_cells = _update_cells(
            self.index, self.value, self.count, self.flat.cells, self.flat.neighbours,
            self.flat.background_rows, log_pi, order, background, float(background.sum()),
            np.ascontiguousarray(observed), float(gamma), self.threshold, self.damping,
            self.mark, self.field, self.touched, self.weight, self.entropy, self.moved,
            self.drift, np.ascontiguousarray(row_drift), self.active_tolerance, self.sizes,
            self._argmax_cells, self.totals,
        )  # fmt: skip
        self._since_recount += 1
        if self.damping > 0.0 or self._since_recount >= RECOUNT_EVERY:
            self._recount()  # damping: no running pairs' term; else bound the rounding drift
        self._summary = None

    def _summaries(self) -> tuple[ConceptStatistics, np.ndarray, float, float]:
        """(statistics, observed q [M, L], entropy, expected agreements) of the current q."""
        if self._summary is None:
            L = self.config.num_concepts
            observed_q = np.zeros((self.obs_cells.shape[0], L))
            _observed(self.index, self.value, self.count, self.obs_cells, observed_q)
            entropy, agreements = float(self.totals[0]), float(self.totals[1])
            observed_t = torch.from_numpy(observed_q)  # [M, L]
            counts = []
            for modality in self.data.modalities:
                per_concept = torch.zeros(L, modality.counts.shape[-1], dtype=DTYPE)
                if self.config.uses(modality.name):
                    per_concept = observed_t.T @ modality.counts.to(DTYPE)  # [L, K_m]
                counts.append(per_concept)
            statistics = ConceptStatistics(torch.from_numpy(self.sizes.copy()), tuple(counts))
            self._summary = (statistics, observed_q, entropy, agreements)
        return self._summary

    def statistics(self) -> ConceptStatistics:
        """Expected concept sizes and per-concept counts under the sparse q."""
        return self._summaries()[0]

    def elbo(self, factors: GlobalFactors, gamma: float | None = None) -> float:
        """The ELBO of :mod:`spcopyro.guides.elbo`, from the sparse state."""
        gamma = self.config.gamma if gamma is None else gamma
        statistics, observed_q, entropy, agreements = self._summaries()
        log_pi, loglik = self._expectations(factors)
        expected = float((statistics.cells * log_pi).sum()) + gamma * agreements
        expected += float((loglik.numpy() * observed_q).sum()) + self._constant
        return expected - self._kl_to_prior(factors) + entropy

    def labels(self) -> torch.Tensor:
        """[N] int64 every cell's most probable concept (its first sparse entry)."""
        return torch.from_numpy(self.index[: self.data.num_free, 0].copy())

    def num_used(self) -> int:
        """How many concepts are some cell's most probable one."""
        self._summaries()
        return int((self._argmax_cells > 0).sum())

    def dense(self, out: torch.Tensor | None = None) -> torch.Tensor:
        """q as a dense ``[N, L]`` float64 tensor (written into ``out`` when given)."""
        N, L = self.data.num_free, self.config.num_concepts
        q = np.zeros((N, L))
        _to_dense(self.index, self.value, self.count, q)
        if out is None:
            return torch.from_numpy(q)
        return out.copy_(torch.from_numpy(q))


class SparseCAVIState(NamedTuple):
    """The compiled backend's CAVI state: the sparse q and the global factors optimal given it.

    Unlike the torch reference's :class:`~spcopyro.guides.cavi.CAVIState`, :func:`step` updates
    ``field`` in place (a copy per iteration would cost as much as the update)."""

    field: SparseMeanField
    factors: GlobalFactors


def init(
    q: torch.Tensor, data: ModelData, config: SpCoConfig, options: VariationalOptions
) -> SparseCAVIState:
    """The state at the dense start q ``[N, L]`` (truncated per ``options.support`` and
    ``options.threshold``), with the globals from it."""
    field = SparseMeanField(
        q, data, config, support=options.support, threshold=options.threshold,
        damping=options.damping, active_tolerance=options.active_tolerance,
    )  # fmt: skip
    return SparseCAVIState(field, update_factors(field.statistics(), data, config,
                                                 options.pi_family))  # fmt: skip


def step(
    state: SparseCAVIState,
    data: ModelData,
    config: SpCoConfig,
    gamma: float,
    options: VariationalOptions,
) -> tuple[SparseCAVIState, CAVIInfo]:
    """One iteration, as :func:`spcopyro.guides.cavi.step`: the sparse label pass at ``gamma``
    (in place), the globals from the new q, the ELBO at the model's gamma."""
    field = state.field
    field.update(state.factors, gamma)
    factors = update_factors(field.statistics(), data, config, options.pi_family)
    info = CAVIInfo(field.elbo(factors), field.num_used(), float(gamma))
    return SparseCAVIState(field, factors), info
