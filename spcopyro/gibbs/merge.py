r"""A split-merge move for the labels: two touching concepts become one, or one becomes two.

Single-site Gibbs (eq. 13) and the Swendsen-Wang move (:mod:`spcopyro.gibbs.cluster`) both work
*given* pi, theta and w; a room carried by two concepts stays so as long as each concept's
parameters fit its own half. This move compares "one concept" with "two concepts" with the
parameters integrated out, so two concepts whose emissions are indistinguishable merge, and it
is exact: a Metropolis-Hastings step on the labels that leaves p(C | data) invariant, after
which (if accepted) pi and the emission distributions are redrawn from their conditionals
(eqs. 14-17). Propose-then-redraw leaves the joint p(C, pi, theta, w | data) invariant; when the
move is rejected, keeping the parameters is also exact, since the acceptance does not look at
them.

**Target.** With the Dirichlet priors integrated out (the Dirichlet-multinomial marginals, valid
for real-valued counts too: the multinomial coefficients do not depend on C),

.. math::

    \log p(C \mid x) = \gamma E(C) + \sum_l \Big[\log\Gamma(a_\pi + m_l)
        + \sum_{\text{modality } u} \log B(a_u \mathbf{1} + n^u_l) - \log B(a_u \mathbf{1})\Big]
        + \text{const},

with :math:`m_l` the cells of concept l, :math:`n^u_l` its summed counts of modality u,
:math:`a_\pi` = alpha/L (weak-limit DP, eq. 7) or alpha, :math:`a_u` = chi, beta, ... and
:math:`B(v) = \prod_k \Gamma(v_k) / \Gamma(\sum_k v_k)`. A merge or split changes only the two
concepts' terms and :math:`E(C)` by the number of neighbouring pairs across them.

**Proposal** (Jain & Neal 2004, "A split-merge Markov chain Monte Carlo procedure for the
Dirichlet process mixture model", restricted Gibbs version, adapted to the grid):

1. a fair coin chooses *merge* or *split*;
2. merge: a directed neighbouring pair (i, j) with :math:`C_i \ne C_j`, uniformly among the
   :math:`2 D(C)` such pairs (:math:`D(C)` = disagreeing neighbour pairs), so touching concepts
   are proposed in proportion to their common border; every cell of :math:`b = C_j` takes
   :math:`a = C_i`. Split: a directed pair (i, j) with :math:`C_i = C_j = a`, uniformly among the
   :math:`2 A(C)` agreeing ones, and a label b uniformly among the :math:`Z(C)` empty labels (no
   move if there is none); the cells of a are split into "i's side" (keeps a) and "j's side"
   (takes b) by step 3;
3. the split itself: over T, the cells of a and b, a *launch state* -- each cell on the side of
   i or j whichever is nearer along the grid inside T (breadth-first distances; ties and cells
   that reach neither by a fair coin) -- refined by ``scans`` restricted scans, then a final
   restricted scan. A restricted scan redraws, colour block by colour block (vectorised: cells of
   one colour do not touch), each cell of T but i and j between the two sides with
   probabilities

   .. math::

       q_k(s) \propto e^{\gamma n_s(k)} \, (a_\pi + m^{-k}_s)
           \prod_u \frac{B(a_u + n^{u,-k}_s + x^u_k)}{B(a_u + n^{u,-k}_s)},

   with :math:`n_s(k)` the neighbours of k on side s and the side totals taken at the block's
   start without k (any well-defined proposal will do; this one resembles the collapsed
   conditional). The launch depends on T, i and j only, the same set in both directions, so (Jain
   & Neal's argument) the reverse of a split is a merge, and the reverse of a merge is the split
   whose final scan lands exactly on the current labels: its probability
   :math:`q_\text{final}(C \mid \text{launch})` is the product of the final scan's
   :math:`q_k` evaluated at the current sides.

**Acceptance.** For a merge :math:`C \to C'`,

.. math::

    \log r = \log\frac{p(C' \mid x)}{p(C \mid x)} + \log\frac{2 D(C)}{2 A(C')}
        - \log Z(C') + \log q_\text{final}(C \mid \text{launch}),

and a split :math:`C \to C'` has the reciprocal terms
:math:`\log\frac{2 A(C)}{2 D(C')} + \log Z(C) - \log q_\text{final}(C' \mid \text{launch})`.
The move is accepted with probability :math:`\min(1, r)`. The tests compare it with the
enumerated posterior on a tiny map, and show that dropping the proposal terms is detected.

Cost: O(N + P) per move (the masks and the breadth-first search over T) plus
``2 (scans + 1)`` vectorised colour-block passes over T -- about a single-site sweep's cost for
a large concept (measured in docs/defaults.md, "Split-merge moves").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import torch

from spcopyro._util.random_draws import coin_flip, metropolis_accept
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.backends import globals_sampler
from spcopyro.gibbs.state import GibbsState
from spcopyro.likelihood import dirichlet_multinomial_log_marginals
from spcopyro.model import DTYPE, ModelData

MERGE_SCANS = 3
"""Restricted scans between the launch state and the final scan (Jain & Neal's t)."""


class MoveInfo(NamedTuple):
    """What one split-merge proposal did."""

    kind: str
    """``"merge"`` or ``"split"`` (the coin's choice)."""
    accepted: bool
    log_ratio: float
    """log r of the Metropolis-Hastings ratio; -inf when there was nothing to propose (no pair
    of that kind, or no empty label for a split)."""


def used_modalities(data: ModelData, config: SpCoConfig) -> list[tuple[torch.Tensor, float]]:
    """(counts [M, K_u], concentration a_u) of every modality the model uses. One of K_u = 0
    (the words of a house where none was heard) adds 0 to every concept's term
    (:func:`~spcopyro.likelihood.dirichlet_multinomial_log_marginals`)."""
    return [
        (m.counts, config.concentration(m.name)) for m in data.modalities if config.uses(m.name)
    ]


Counts = list[tuple[float, torch.Tensor]]
"""Per modality in use: (its concentration a_u, [G, K_u] summed counts of G concepts)."""


def concept_log_marginals(sizes: torch.Tensor, counts: Counts, config: SpCoConfig) -> torch.Tensor:
    """[G] each concept's term of the collapsed log posterior (module doc): log Gamma(a_pi + m)
    for sizes [G] plus the Dirichlet-multinomial marginals of its counts."""
    a_pi = torch.tensor(config.pi_concentration, dtype=DTYPE)
    total = torch.lgamma(a_pi + sizes.to(DTYPE))  # [G]
    for concentration, per_concept in counts:
        total = total + dirichlet_multinomial_log_marginals(concentration, per_concept)
    return total


def collapsed_log_posterior(labels: torch.Tensor, data: ModelData, config: SpCoConfig) -> float:
    """log p(C | x) up to a constant (the module doc's target), pi, theta and w integrated out."""
    L = config.num_concepts
    sizes = torch.bincount(labels, minlength=L)  # [L]
    counts = []
    for modality_counts, concentration in used_modalities(data, config):
        per_concept = torch.zeros(L, modality_counts.shape[-1], dtype=DTYPE)  # [L, K_u]
        per_concept.index_add_(0, labels[data.obs_cells], modality_counts)
        counts.append((concentration, per_concept))
    agreements = (labels[data.pairs[:, 0]] == labels[data.pairs[:, 1]]).sum().to(DTYPE)
    return float(config.gamma * agreements + concept_log_marginals(sizes, counts, config).sum())


class _Restricted(NamedTuple):
    """The cells T of the two concepts, in local indices 0..n_T-1."""

    cells: torch.Tensor  # [n_T] free indices
    neighbours: torch.Tensor  # [n_T, D] local indices of neighbours in T, -1 otherwise
    blocks: tuple[torch.Tensor, ...]  # local indices per colour, i and j left out
    observed: torch.Tensor  # [M_T] local indices of T's observed cells
    counts: Counts  # per modality in use: (a_u, [M_T, K_u]) of T's observed cells
    first: int  # local index of i
    second: int  # local index of j


def _restricted(
    mask: torch.Tensor, i: int, j: int, data: ModelData, config: SpCoConfig
) -> _Restricted:
    cells = mask.nonzero(as_tuple=True)[0]  # [n_T]
    local = torch.full((data.num_free,), -1, dtype=torch.long)
    local[cells] = torch.arange(cells.shape[0])
    nb = data.neighbours[cells]  # [n_T, D]
    neighbours = torch.where(nb >= 0, local[nb.clamp_min(0)], -1)  # [n_T, D]
    fixed = torch.zeros(data.num_free, dtype=torch.bool)
    fixed[[i, j]] = True
    blocks = tuple(local[c[mask[c] & ~fixed[c]]] for c in data.colours)
    obs_in = mask[data.obs_cells]  # [M]
    counts = [(a, c[obs_in]) for c, a in used_modalities(data, config)]
    return _Restricted(
        cells, neighbours, blocks, local[data.obs_cells[obs_in]], counts, int(local[i]),
        int(local[j]),
    )  # fmt: skip


def _launch(
    region: _Restricted, pairs: torch.Tensor, local_of: torch.Tensor, generator: torch.Generator
) -> torch.Tensor:
    """[n_T] launch sides: nearer to i (0) or j (1) along the grid inside T; ties by a coin."""
    import scipy.sparse  # here, not at import: a fit without merge moves skips scipy.sparse
    from scipy.sparse.csgraph import dijkstra

    n = region.cells.shape[0]
    inside = (local_of[pairs[:, 0]] >= 0) & (local_of[pairs[:, 1]] >= 0)  # [P]
    rows = local_of[pairs[inside, 0]].numpy()
    cols = local_of[pairs[inside, 1]].numpy()
    graph = scipy.sparse.coo_matrix((np.ones(rows.shape[0]), (rows, cols)), shape=(n, n)).tocsr()
    distance = dijkstra(graph, directed=False, indices=[region.first, region.second],
                        unweighted=True)  # fmt: skip  # [2, n_T]
    near_i = torch.from_numpy(distance[0] < distance[1])
    near_j = torch.from_numpy(distance[1] < distance[0])
    coin = torch.rand(n, dtype=DTYPE, generator=generator) < 0.5  # [n_T]
    side = torch.where(near_i, False, torch.where(near_j, True, coin)).long()
    side[region.first], side[region.second] = 0, 1
    return side


def _restricted_scan(
    side: torch.Tensor,
    region: _Restricted,
    config: SpCoConfig,
    generator: torch.Generator,
    forced: torch.Tensor | None = None,
) -> tuple[torch.Tensor, float]:
    """One restricted scan (module doc, step 3): (new sides [n_T], log q of the scan's outcome).

    ``forced``: the sides to land on (for the reverse of a merge): nothing is drawn, and the
    log probability of reaching ``forced`` is returned.
    """
    side = side.clone()
    a_pi = config.pi_concentration
    observed_row = torch.full((side.shape[0],), -1, dtype=torch.long)
    observed_row[region.observed] = torch.arange(region.observed.shape[0])
    log_q = 0.0
    for block in region.blocks:
        if block.numel() == 0:
            continue
        onehot = torch.nn.functional.one_hot(side, 2).to(DTYPE)  # [n_T, 2]
        sizes = onehot.sum(0)  # [2]
        own = onehot[block]  # [nb, 2]
        nb = region.neighbours[block]  # [nb, D]
        padded = torch.cat([onehot, torch.zeros(1, 2, dtype=DTYPE)])  # [n_T + 1, 2]
        field = padded[torch.where(nb >= 0, nb, side.shape[0])].sum(1)  # [nb, 2]
        logits = config.gamma * field + torch.log(a_pi + sizes - own)  # [nb, 2]
        rows = observed_row[block]  # [nb]
        hit = rows >= 0
        if hit.any():
            obs_onehot = onehot[region.observed]  # [M_T, 2]
            for concentration, counts in region.counts:
                totals = obs_onehot.T @ counts  # [2, K_u]
                x = counts[rows[hit]]  # [h, K_u]
                without = totals[None] - own[hit][:, :, None] * x[:, None, :]  # [h, 2, K_u]
                predictive = dirichlet_multinomial_log_marginals(
                    concentration, without + x[:, None, :]
                ) - dirichlet_multinomial_log_marginals(concentration, without)  # [h, 2]
                logits[hit] += predictive
        log_p = torch.log_softmax(logits, -1)  # [nb, 2]
        if forced is None:
            u = torch.rand(block.shape[0], dtype=DTYPE, generator=generator)
            new = (u >= log_p[:, 0].exp()).long()  # [nb]
        else:
            new = forced[block]
        log_q += float(log_p.gather(1, new[:, None]).sum())
        side[block] = new
    return side, log_q


Scans = Callable[..., object]
"""A move's launch and restricted scans over its region, as one function: ``scan(None)`` is the
launch sides [n_T]; ``scan(side)`` a restricted scan from ``side``, and ``scan(side, forced)``
its probability of landing on ``forced``: (new sides [n_T], log q)."""


def _torch_scans(
    region: _Restricted, data: ModelData, config: SpCoConfig, generator: torch.Generator
) -> Scans:
    """:data:`Scans` by the torch functions :func:`_launch` and :func:`_restricted_scan`."""

    def scan(side: torch.Tensor | None, forced: torch.Tensor | None = None) -> object:
        if side is None:
            local_of = torch.full((data.num_free,), -1, dtype=torch.long)
            local_of[region.cells] = torch.arange(region.cells.shape[0])
            return _launch(region, data.pairs, local_of, generator)
        return _restricted_scan(side, region, config, generator, forced=forced)

    return scan


def _compiled_scans(
    region: _Restricted, data: ModelData, config: SpCoConfig, generator: torch.Generator
) -> Scans:
    """:data:`Scans` by :mod:`spcopyro.gibbs.merge_numba`, from the compiled sampler's own
    stream: one seed is drawn from ``generator`` for the whole move."""
    from spcopyro.gibbs.merge_numba import launch_sides, restricted_scan
    from spcopyro.gibbs.numba_random import draw_seed, rng_state

    rng = rng_state(draw_seed(generator))
    neighbours = np.ascontiguousarray(region.neighbours.numpy())  # [n_T, D]
    blocks = [b.numpy() for b in region.blocks]
    block_cells = np.concatenate(blocks) if blocks else np.zeros(0, dtype=np.int64)
    block_starts = np.cumsum([0] + [len(b) for b in blocks]).astype(np.int64)  # [B + 1]
    observed = np.ascontiguousarray(region.observed.numpy())  # [M_T]
    counts = tuple(np.ascontiguousarray(c.numpy()) for _, c in region.counts)
    concentrations = np.array([a for a, _ in region.counts] or [1.0], dtype=np.float64)
    placeholder = counts or (np.zeros((observed.shape[0], 1)),)
    no_forcing = np.zeros(0, dtype=np.int64)

    def scan(side: torch.Tensor | None, forced: torch.Tensor | None = None) -> object:
        if side is None:
            return torch.from_numpy(launch_sides(neighbours, region.first, region.second, rng))
        out = side.numpy().copy()
        log_q = restricted_scan(
            out, neighbours, block_cells, block_starts, observed, placeholder, concentrations,
            len(counts), float(config.gamma), float(config.pi_concentration),
            no_forcing if forced is None else forced.numpy(), forced is not None, rng,
        )  # fmt: skip
        return torch.from_numpy(out), float(log_q)

    return scan


def _log_acceptance_ratio(delta_log_target: float, log_forward: float, log_reverse: float) -> float:
    """log r = log p(C')/p(C) + log q(C | C') - log q(C' | C)."""
    return delta_log_target + log_reverse - log_forward


def two_concepts(
    labels: torch.Tensor, data: ModelData, config: SpCoConfig, a: int, b: int
) -> tuple[torch.Tensor, Counts]:
    """Sizes [2] and per-modality counts [2, K_u] of concepts a and b (in that order)."""
    sizes = torch.stack([(labels == a).sum(), (labels == b).sum()])  # [2]
    observed = labels[data.obs_cells]  # [M]
    counts = []
    for modality_counts, concentration in used_modalities(data, config):
        per = torch.stack(
            [modality_counts[observed == a].sum(0), modality_counts[observed == b].sum(0)]
        )  # [2, K_u]
        counts.append((concentration, per))
    return sizes, counts


def _pair_terms(
    labels: torch.Tensor, data: ModelData, config: SpCoConfig, a: int, b: int
) -> tuple[torch.Tensor, Counts, int]:
    """:func:`two_concepts` of a and b, and their common border."""
    sizes, counts = two_concepts(labels, data, config, a, b)
    first, second = labels[data.pairs[:, 0]], labels[data.pairs[:, 1]]
    border = int((((first == a) & (second == b)) | ((first == b) & (second == a))).sum())
    return sizes, counts, border


def _merge_delta(sizes: torch.Tensor, counts: Counts, border: int, config: SpCoConfig) -> float:
    """log p(merged) - log p(split) of the module doc, given the split pair's statistics."""
    split = concept_log_marginals(sizes, counts, config).sum()
    merged_sizes = torch.stack([sizes.sum(), torch.zeros((), dtype=sizes.dtype)])
    merged_counts = [(a, torch.stack([c.sum(0), torch.zeros_like(c[0])])) for a, c in counts]
    merged = concept_log_marginals(merged_sizes, merged_counts, config).sum()
    return float(merged - split + config.gamma * border)


def split_merge_labels(
    labels: torch.Tensor,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    scans: int = MERGE_SCANS,
    compiled: bool = False,
) -> tuple[torch.Tensor, MoveInfo]:
    """One split-merge Metropolis-Hastings step on ``labels`` [N] targeting p(C | x) (module
    doc). Returns the new labels (``labels`` itself when nothing changes) and what happened.

    ``compiled``: the launch and the restricted scans by :mod:`spcopyro.gibbs.merge_numba` (the
    same proposal, from the compiled sampler's own random stream; the numba backend's chains use
    it), else by the torch functions here.
    """
    L = config.num_concepts
    first, second = labels[data.pairs[:, 0]], labels[data.pairs[:, 1]]  # [P]
    agree = first == second  # [P]
    num_agree = int(agree.sum())
    num_disagree = agree.shape[0] - num_agree
    used = torch.bincount(labels, minlength=L) > 0  # [L]
    num_empty = L - int(used.sum())
    merge = float(torch.rand((), dtype=DTYPE, generator=generator)) < 0.5
    candidates = (~agree if merge else agree).nonzero(as_tuple=True)[0]
    if candidates.numel() == 0 or (not merge and num_empty == 0):
        return labels, MoveInfo("merge" if merge else "split", False, -math.inf)
    pick = int(torch.randint(candidates.numel(), (), generator=generator))
    i, j = (int(v) for v in data.pairs[candidates[pick]])
    if float(torch.rand((), dtype=DTYPE, generator=generator)) < 0.5:
        i, j = j, i
    a = int(labels[i])
    if merge:
        b = int(labels[j])
        mask = (labels == a) | (labels == b)
    else:
        empty = (~used).nonzero(as_tuple=True)[0]
        b = int(empty[int(torch.randint(empty.numel(), (), generator=generator))])
        mask = labels == a
    region = _restricted(mask, i, j, data, config)
    scan = (_compiled_scans if compiled else _torch_scans)(region, data, config, generator)
    side = scan(None)
    for _ in range(scans):
        side, _ = scan(side)
    if merge:
        current = (labels[region.cells] == b).long()  # [n_T] the split we are in
        _, log_final = scan(side, current)
        sizes, counts, border = _pair_terms(labels, data, config, a, b)
        delta = _merge_delta(sizes, counts, border, config)
        log_forward = -math.log(2 * num_disagree)
        log_reverse = -math.log(2 * (num_agree + border)) - math.log(num_empty + 1) + log_final
        proposed = torch.where(mask, a, labels)
    else:
        side, log_final = scan(side)
        proposed = labels.clone()
        proposed[region.cells[side == 1]] = b
        sizes, counts, border = _pair_terms(proposed, data, config, a, b)
        delta = -_merge_delta(sizes, counts, border, config)
        log_forward = -math.log(2 * num_agree) - math.log(num_empty) + log_final
        log_reverse = -math.log(2 * (num_disagree + border))
    log_ratio = _log_acceptance_ratio(delta, log_forward, log_reverse)
    accept = metropolis_accept(log_ratio, generator)
    kind = "merge" if merge else "split"
    return (proposed if accept else labels), MoveInfo(kind, bool(accept), log_ratio)


def merge_move(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    scans: int = MERGE_SCANS,
    compiled: bool = False,
) -> tuple[GibbsState, MoveInfo]:
    """:func:`split_merge_labels`, then (if accepted) pi, theta and w redrawn given the labels
    (by the compiled sampler's draws when ``compiled``)."""
    labels, info = split_merge_labels(state.labels, data, config, generator, scans, compiled)
    return with_globals_redrawn(state, labels, info, data, config, generator, compiled), info


def with_globals_redrawn(
    state: GibbsState,
    labels: torch.Tensor,
    info: MoveInfo,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    compiled: bool,
) -> GibbsState:
    """After a move on the labels with pi, theta and w integrated out: ``state`` when it was
    rejected (keeping them is exact: the acceptance does not look at them), else ``labels``
    with pi, theta and w drawn from their conditionals (eqs. 14-17; by the compiled sampler's
    draws when ``compiled``)."""
    if not info.accepted:
        return state
    sample_globals = globals_sampler("numba" if compiled else "torch")
    return GibbsState(labels, *sample_globals(labels, data, config, generator))


def maybe_merge_move(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    probability: float,
    compiled: bool = False,
) -> GibbsState:
    """:func:`merge_move` with probability ``probability`` (``GibbsOptions.merge_moves``), else
    ``state`` (draws nothing from ``generator`` when the probability is 0). ``compiled``: as for
    :func:`split_merge_labels`."""
    if not coin_flip(probability, generator):
        return state
    return merge_move(state, data, config, generator, compiled=compiled)[0]
