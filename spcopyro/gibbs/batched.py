r"""B Gibbs chains in lock step, as one batch of tensors: a sweep that runs on a GPU when one is
lent (issue 25 item 5), and on the CPU everywhere else (where it is tested).

The chains share the data and the sweep plan (:class:`BatchedPlan`, built once on the device)
and keep their states side by side with a leading chain axis (:class:`BatchedState`: labels
``[B, N]``, log pi ``[B, L]``, one ``[B, L, K_m]`` log table per modality). Every tensor lives
on the state's device, in its floating dtype (float64, or float32 on a GPU that is slow in
float64); nothing in a sweep reads a value back to the host, and no Python loop runs over cells
or chains, only over the 2 (or 4) colour blocks and the modalities.

**Labels (eq. 13).** A colour block of all B chains is drawn at once, exactly as
:func:`spcopyro.gibbs.sweep.sample_labels` draws one chain's: a cell without observations from
the background + neighbour mixture

.. math::

    p(C_i = l) \propto \pi_l + \sum_{k \in \text{distinct nbr labels}}
        \delta_{lk} \, \pi_k \, \mathrm{expm1}(\gamma n_k(i)),

(one binary search in pi's CDF per cell, O(D^2) work), a cell with observations by Gumbel-max
over its L enumerated logits log pi_l + gamma n_l(i) + sum_m x_i . log phi_{m,l}.
:func:`block_log_conditionals` writes both out densely over L: the distribution the sweep
draws from, which the tests compare with :func:`~spcopyro.gibbs.sweep.label_log_conditionals`
chain by chain.

**Globals (eqs. 14-17).** pi | C ~ Dir(a_pi + m_l) and each modality's rows
phi_l | . ~ Dir(a_m + counts of the cells labelled l), for every chain at once, from log-gamma
variates: log G(a) = log G(a + 1) + log(U) / a for a < 1 (the boost of
:mod:`spcopyro._util.random_draws`, so the DP prior's alpha / L never underflows), where G(a + 1)
is torch's own gamma sampler (``torch._standard_gamma``, which takes a generator on every
device and has no host-side rejection loop). With probability 1 - ``unobserved_refresh`` a chain
keeps the rows of concepts holding no observed cell (as
:func:`~spcopyro.gibbs.sweep.concepts_to_refresh`), the choice made per chain.

**Memory** on the device, beyond the state (B N int64 labels and the B L (1 + sum_m K_m)
tables, old and new during a sweep): per block of N_c cells, a handful of ``[B, N_c, D]``
tensors (neighbour labels, their agreement counts, slot weights, the uniforms; D = 4 or 8) and
one ``[B, N_c, D, D]`` comparison, ``[B, M_c, L]`` logits of the block's observed cells,
``[B, M, L]`` observation log-likelihoods, and the globals' ``[B, L, K_m]`` gamma variates and
their temporaries. Measured on the CPU as the peak RSS a sweep adds (float64, room2ldk4:
N = 27 746, M = 86, L = 120, K + V = 220): about 5 MiB a chain, 311 MiB at B = 64, so B = 256
needs about 1.2 GiB; float32 halves the float part.

Not composed here: annealing, cluster, merge and region moves, sampled hyperparameters (what
:func:`spcopyro.gibbs.sampler.step` adds around a sweep; the batched chains refuse them:
:func:`spcopyro.gibbs.batched_run.check_batched_options`). The random stream is the device's
generator, so a batched chain is not the single chain of the same seed (it samples the same
distribution: tested).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.model import DTYPE, ModelData, potts_agreements


class BatchedState(NamedTuple):
    """B chains' states, stacked along a leading chain axis (one device, one float dtype)."""

    labels: torch.Tensor
    """[B, N] int64 the concept of every free cell, per chain."""
    log_pi: torch.Tensor
    """[B, L] log concept weights."""
    log_emissions: tuple[torch.Tensor, ...]
    """Per modality of ``data.modalities``, [B, L, K_m] log distributions (theta, w, ...)."""

    @property
    def num_chains(self) -> int:
        return self.labels.shape[0]

    def chain(self, index: int) -> GibbsState:
        """Chain ``index`` as a :class:`GibbsState` on the CPU in the sampler's dtype."""
        return GibbsState(
            self.labels[index].cpu(),
            self.log_pi[index].to("cpu", DTYPE),
            tuple(table[index].to("cpu", DTYPE) for table in self.log_emissions),
        )

    def chains(self) -> list[GibbsState]:
        """Every chain as a :class:`GibbsState` (CPU, float64)."""
        return [self.chain(b) for b in range(self.num_chains)]


def stack_states(
    states: Sequence[GibbsState],
    device: torch.device | str = "cpu",
    dtype: torch.dtype = DTYPE,
) -> BatchedState:
    """B single-chain states as one :class:`BatchedState` on ``device`` in ``dtype``."""
    if not states:
        raise ValueError("stack_states needs at least one state")
    return BatchedState(
        torch.stack([s.labels for s in states]).to(device),
        torch.stack([s.log_pi for s in states]).to(device, dtype),
        tuple(
            torch.stack(tables).to(device, dtype)
            for tables in zip(*(s.log_emissions for s in states), strict=True)
        ),
    )


class BlockPlan(NamedTuple):
    """One colour block on the device (:class:`~spcopyro.gibbs.state.ColourBlock`, with the
    sentinels of missing neighbours at N + s, s = 0..D-1)."""

    cells: torch.Tensor  # [Nc] int64 free indices
    neighbours: torch.Tensor  # [Nc, D] int64 free indices, N + s where slot s has none
    observed_positions: torch.Tensor  # [Mc] positions within ``cells`` of observed cells
    observed_rows: torch.Tensor  # [Mc] their rows of the count tensors


class BatchedPlan(NamedTuple):
    """What every chain shares, on the device: the blocks, the observed cells and the counts of
    the modalities in use."""

    num_free: int
    blocks: tuple[BlockPlan, ...]
    obs_cells: torch.Tensor
    """[M] int64 free index of each observed cell."""
    counts: tuple[torch.Tensor, ...]
    """Per modality, [M, K_m] counts in the state's dtype; zeros for a modality not in use."""
    concentrations: tuple[float, ...]
    """Per modality, its Dirichlet concentration a_m."""
    pairs: torch.Tensor
    """[P, 2] int64 every pair of neighbouring free cells once (for E(C))."""


def make_batched_plan(
    data: ModelData,
    config: SpCoConfig,
    device: torch.device | str = "cpu",
    dtype: torch.dtype = DTYPE,
) -> BatchedPlan:
    """The sweep plan of ``data`` moved to ``device`` once (counts in ``dtype``)."""
    blocks = tuple(
        BlockPlan(*(t.to(device) for t in block)) for block in make_sweep_plan(data).blocks
    )
    counts = tuple(
        (m.counts if config.uses(m.name) else torch.zeros_like(m.counts)).to(device, dtype)
        for m in data.modalities
    )
    concentrations = tuple(config.concentration(m.name) for m in data.modalities)
    return BatchedPlan(data.num_free, blocks, data.obs_cells.to(device), counts, concentrations,
                       data.pairs.to(device))  # fmt: skip


# -- labels ---------------------------------------------------------------------------------------


class LabelTables(NamedTuple):
    """Per-sweep tables of the label draws, every chain at once (:func:`label_tables`)."""

    log_pi: torch.Tensor  # [B, L]
    pi_ext: torch.Tensor  # [B, L + D] pi then D zeros: a sentinel label L + s reads a zero
    pi_cdf: torch.Tensor  # [B, L] cumulative sum of pi
    tilt: torch.Tensor  # [D + 1] expm1(gamma k) / k, 0 at k = 0
    loglik: torch.Tensor  # [B, M, L] sum_m x_i . log phi_{m,l} of every observed cell


def observation_log_likelihoods(
    log_emissions: Sequence[torch.Tensor], plan: BatchedPlan
) -> torch.Tensor:
    """[B, M, L] each chain's observed cells' log-likelihood under each concept (eqs. 5, 6):
    sum over the modalities of counts [M, K_m] @ log phi [B, L, K_m]^T (unused ones are zero)."""
    return sum(
        counts @ log_phi.transpose(-1, -2)  # [M, K] @ [B, K, L] -> [B, M, L]
        for counts, log_phi in zip(plan.counts, log_emissions, strict=True)
    )


def label_tables(state: BatchedState, plan: BatchedPlan, gamma: float) -> LabelTables:
    """What the label draws of one sweep read, computed once per sweep."""
    B = state.num_chains
    D = plan.blocks[0].neighbours.shape[1]
    pi = state.log_pi.exp()  # [B, L]
    pi_ext = torch.cat([pi, pi.new_zeros(B, D)], dim=1)  # [B, L + D]
    k = torch.arange(D + 1, dtype=pi.dtype, device=pi.device)
    tilt = torch.where(k > 0, torch.expm1(gamma * k) / k.clamp_min(1), 0.0)  # [D + 1]
    loglik = observation_log_likelihoods(state.log_emissions, plan)  # [B, M, L]
    return LabelTables(state.log_pi, pi_ext, pi.cumsum(-1), tilt, loglik)


def _slot_weights(neighbour_labels: torch.Tensor, tables: LabelTables) -> torch.Tensor:
    """[B, n, D] slot s of a cell weighs pi_{a_s} expm1(gamma n_{a_s}) / n_{a_s}, so the slots
    sharing a label add up to that label's neighbour part (sentinels weigh 0)."""
    B, n, D = neighbour_labels.shape
    agree = (neighbour_labels[..., :, None] == neighbour_labels[..., None, :]).sum(-1)  # [B,n,D]
    pi_nb = tables.pi_ext.gather(1, neighbour_labels.reshape(B, n * D)).view(B, n, D)
    return pi_nb * tables.tilt[agree]


def _agreement_counts(
    neighbour_labels: torch.Tensor, num_concepts: int, dtype: torch.dtype
) -> torch.Tensor:
    """[B, n, L] n_l(i): neighbours labelled l (sentinels L + s are counted past L and cut)."""
    B, n, D = neighbour_labels.shape
    counts = neighbour_labels.new_zeros(B, n, num_concepts + D, dtype=dtype)
    counts.scatter_add_(2, neighbour_labels, torch.ones_like(counts[..., :D]))
    return counts[..., :num_concepts]


def _observed_logits(
    neighbour_labels: torch.Tensor, block: BlockPlan, tables: LabelTables, gamma: float
) -> torch.Tensor:
    """[B, Mc, L] log pi_l + gamma n_l(i) + loglik_il of the block's observed cells."""
    L = tables.log_pi.shape[-1]
    observed_nb = neighbour_labels[:, block.observed_positions]  # [B, Mc, D]
    agreements = _agreement_counts(observed_nb, L, tables.log_pi.dtype)  # [B, Mc, L]
    return (
        tables.log_pi[:, None, :]
        + gamma * agreements
        + tables.loglik[:, block.observed_rows]  # [B, Mc, L]
    )


def _neighbour_labels(labels_ext: torch.Tensor, block: BlockPlan) -> torch.Tensor:
    """[B, Nc, D] the labels of the block's neighbours (sentinel L + s where slot s has none)."""
    B = labels_ext.shape[0]
    Nc, D = block.neighbours.shape
    return labels_ext.gather(1, block.neighbours.reshape(1, Nc * D).expand(B, -1)).view(B, Nc, D)


def _extended_labels(labels: torch.Tensor, num_concepts: int, D: int) -> torch.Tensor:
    """[B, N + D] labels followed by the sentinels L, ..., L + D - 1 (never a label)."""
    B = labels.shape[0]
    sentinels = num_concepts + torch.arange(D, device=labels.device)  # [D]
    return torch.cat([labels, sentinels.expand(B, D)], dim=1)


def block_log_conditionals(
    state: BatchedState, plan: BatchedPlan, config: SpCoConfig, block_index: int
) -> torch.Tensor:
    """[B, Nc, L] normalised log p(C_i = l | rest) of every cell of block ``block_index``, as the
    sweep draws them (the mixture for cells without observations, the enumeration for the
    others), written out densely: what the tests compare with
    :func:`~spcopyro.gibbs.sweep.label_log_conditionals`."""
    L = config.num_concepts
    block = plan.blocks[block_index]
    D = block.neighbours.shape[1]
    tables = label_tables(state, plan, config.gamma)
    neighbour_labels = _neighbour_labels(_extended_labels(state.labels, L, D), block)
    weights = _slot_weights(neighbour_labels, tables)  # [B, Nc, D]
    B, Nc = neighbour_labels.shape[:2]
    mixture = tables.pi_ext[:, None, :].expand(B, Nc, L + D).clone()  # [B, Nc, L + D]
    mixture.scatter_add_(2, neighbour_labels, weights)
    log_p = torch.log(mixture[..., :L]) - torch.log(mixture.sum(-1, keepdim=True))
    if block.observed_positions.numel():
        logits = _observed_logits(neighbour_labels, block, tables, config.gamma)
        log_p[:, block.observed_positions] = torch.log_softmax(logits, dim=-1)
    return log_p


def _sample_block(
    labels_ext: torch.Tensor,
    block: BlockPlan,
    tables: LabelTables,
    gamma: float,
    generator: torch.Generator,
) -> None:
    """Redraw one colour block of every chain in place (``labels_ext``: [B, N + D])."""
    neighbour_labels = _neighbour_labels(labels_ext, block)  # [B, Nc, D]
    B, Nc, D = neighbour_labels.shape
    weights = _slot_weights(neighbour_labels, tables)  # [B, Nc, D]
    cumulative = weights.cumsum(-1)  # [B, Nc, D]
    neighbour_mass = cumulative[..., -1]  # [B, Nc]
    pi_mass = tables.pi_cdf[:, -1:]  # [B, 1] (1 up to rounding)
    u = torch.rand(B, Nc, dtype=weights.dtype, device=weights.device, generator=generator)
    u = u * (pi_mass + neighbour_mass)  # [B, Nc]
    slot = (u[..., None] >= cumulative).sum(-1)  # [B, Nc], D means "background"
    chosen = neighbour_labels.gather(2, slot.clamp_max(D - 1)[..., None])[..., 0]  # [B, Nc]
    # Given the background part, u - neighbour_mass is uniform on [0, pi_mass): reuse it.
    background = torch.searchsorted(tables.pi_cdf, u - neighbour_mass, right=True)  # [B, Nc]
    new = torch.where(slot < D, chosen, background.clamp_max(tables.pi_cdf.shape[-1] - 1))
    if block.observed_positions.numel():
        logits = _observed_logits(neighbour_labels, block, tables, gamma)  # [B, Mc, L]
        gumbel_u = torch.rand(logits.shape, dtype=logits.dtype, device=logits.device,
                              generator=generator)  # fmt: skip
        gumbel_u = gumbel_u.clamp_min(torch.finfo(logits.dtype).tiny)
        gumbel = -torch.log(-torch.log(gumbel_u))  # [B, Mc, L]
        new[:, block.observed_positions] = torch.argmax(logits + gumbel, dim=-1)
    labels_ext[:, block.cells] = new


def sample_labels_batched(
    state: BatchedState, plan: BatchedPlan, config: SpCoConfig, generator: torch.Generator
) -> torch.Tensor:
    """[B, N] new labels of every chain: each colour block of all chains drawn at once (eq. 13)."""
    D = plan.blocks[0].neighbours.shape[1]
    labels_ext = _extended_labels(state.labels, config.num_concepts, D)  # [B, N + D]
    tables = label_tables(state, plan, config.gamma)
    for block in plan.blocks:
        _sample_block(labels_ext, block, tables, config.gamma, generator)
    return labels_ext[:, : plan.num_free]


# -- globals --------------------------------------------------------------------------------------


def sample_log_gamma_batched(
    concentration: torch.Tensor, generator: torch.Generator
) -> torch.Tensor:
    """log G, G ~ Gamma(concentration, 1) elementwise, any positive concentration, no host sync:
    log G(a) = log G(a + 1) + log(U) / a below 1, torch's gamma sampler above."""
    boosted = concentration < 1
    shape = torch.where(boosted, concentration + 1, concentration)
    log_g = torch.log(torch._standard_gamma(shape, generator=generator))
    u = torch.rand(concentration.shape, dtype=concentration.dtype, device=concentration.device,
                   generator=generator)  # fmt: skip
    log_u = torch.log(u.clamp_min(torch.finfo(u.dtype).tiny))
    return torch.where(boosted, log_g + log_u / concentration, log_g)


def sample_log_dirichlet_batched(
    concentration: torch.Tensor, generator: torch.Generator
) -> torch.Tensor:
    """log p, p ~ Dir(concentration) over the last dim, finite where p underflows."""
    log_g = sample_log_gamma_batched(concentration, generator)
    return log_g - torch.logsumexp(log_g, dim=-1, keepdim=True)


def concept_counts(labels: torch.Tensor, plan: BatchedPlan, num_concepts: int):
    """([B, L] cells per concept, per modality [B, L, K_m] counts of the cells labelled l)."""
    B = labels.shape[0]
    dtype = plan.counts[0].dtype
    cells = labels.new_zeros(B, num_concepts, dtype=dtype)
    cells.scatter_add_(1, labels, torch.ones_like(labels, dtype=dtype))  # [B, L]
    observed = labels[:, plan.obs_cells]  # [B, M]
    M = observed.shape[1]
    rows = (observed + num_concepts * torch.arange(B, device=labels.device)[:, None]).view(-1)
    per_modality = tuple(
        counts.new_zeros(B * num_concepts, counts.shape[-1])
        .index_add_(0, rows, counts.expand(B, M, -1).reshape(B * M, -1))  # row b L + C_i += x_i
        .view(B, num_concepts, -1)  # [B, L, K_m]
        for counts in plan.counts
    )
    return cells, per_modality


def sample_globals_batched(
    labels: torch.Tensor,
    plan: BatchedPlan,
    config: SpCoConfig,
    generator: torch.Generator,
    previous: Sequence[torch.Tensor] | None = None,
    unobserved_refresh: float = 1.0,
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi [B, L], per modality [B, L, K_m]) from their conjugate conditionals (eqs. 14-17)
    given each chain's labels; with ``previous`` and ``unobserved_refresh`` < 1, each chain
    keeps (with probability 1 - ``unobserved_refresh``) the rows of the concepts holding no
    observed cell (:func:`~spcopyro.gibbs.sweep.concepts_to_refresh`)."""
    L = config.num_concepts
    cells, per_modality = concept_counts(labels, plan, L)
    log_pi = sample_log_dirichlet_batched(config.pi_concentration + cells, generator)  # [B, L]
    drawn = tuple(
        sample_log_dirichlet_batched(a + counts, generator)  # [B, L, K_m]
        for a, counts in zip(plan.concentrations, per_modality, strict=True)
    )
    if previous is None or unobserved_refresh >= 1.0:
        return log_pi, drawn
    B = labels.shape[0]
    coin = torch.rand(B, dtype=log_pi.dtype, device=log_pi.device, generator=generator)
    holding = labels.new_zeros(B, L, dtype=torch.bool)
    holding.scatter_(1, labels[:, plan.obs_cells], True)  # [B, L]
    redraw = (coin < unobserved_refresh)[:, None] | holding  # [B, L]
    kept = tuple(
        torch.where(redraw[..., None], new, old) for new, old in zip(drawn, previous, strict=True)
    )
    return log_pi, kept


def gibbs_sweep_batched(
    state: BatchedState,
    plan: BatchedPlan,
    config: SpCoConfig,
    generator: torch.Generator,
    unobserved_refresh: float = 1.0,
) -> BatchedState:
    """One iteration of Algorithm 1 for B chains at once: every label (eq. 13), then pi and the
    emission distributions (eqs. 14-17). ``generator`` must be on the state's device."""
    labels = sample_labels_batched(state, plan, config, generator)
    log_pi, log_emissions = sample_globals_batched(
        labels, plan, config, generator, state.log_emissions, unobserved_refresh
    )
    return BatchedState(labels, log_pi, log_emissions)


def init_batched(
    data: ModelData,
    config: SpCoConfig,
    plan: BatchedPlan,
    generator: torch.Generator,
    num_chains: int,
) -> BatchedState:
    """B chains from uniformly random labels, with the globals drawn given them (eqs. 14-17),
    on ``generator``'s device in the plan's dtype."""
    device = generator.device
    labels = torch.randint(config.num_concepts, (num_chains, data.num_free), device=device,
                           generator=generator)  # fmt: skip
    return BatchedState(labels, *sample_globals_batched(labels, plan, config, generator))


# -- the trace ------------------------------------------------------------------------------------


def trace_batched(
    state: BatchedState, plan: BatchedPlan, config: SpCoConfig
) -> tuple[torch.Tensor, torch.Tensor]:
    """([B] the log joint's state-dependent part, [B] int64 concepts in use) of every chain, on
    the device: :func:`spcopyro.likelihood.log_joint_variable` at each chain's state,

    sum_l (a_pi - 1) log pi_l + sum_m sum_lk (a_m - 1) log phi_mlk + sum_i log pi_{C_i}
    + gamma E(C) + sum_m sum_i x_i . log phi_{m, C_i},

    with E(C) the number of agreeing neighbour pairs. What a run loop of batched chains records
    each sweep (one transfer of 2B numbers to the host, not one per chain). Summed in float64
    whatever the state's dtype (O(B (L sum_m K_m + N)), small beside a sweep): with
    original-code's pi concentration (1e6) the terms reach about -2e7, where float32 steps by 2
    nats, and so did the log joint a float32 run recorded."""
    f64 = torch.float64
    cells, per_modality = concept_counts(state.labels, plan, config.num_concepts)  # [B, L], ...
    agreements = potts_agreements(state.labels, plan.pairs)  # [B] float64
    log_pi = state.log_pi.to(f64)  # [B, L]
    total = (config.pi_concentration - 1) * log_pi.sum(-1)  # [B] float64
    for a, counts, log_phi in zip(plan.concentrations, per_modality, state.log_emissions,
                                  strict=True):  # fmt: skip
        log_phi = log_phi.to(f64)  # [B, L, K_m]
        total = total + (a - 1) * log_phi.sum((-1, -2)) + (counts.to(f64) * log_phi).sum((-1, -2))
    total = total + (cells.to(f64) * log_pi).sum(-1) + config.gamma * agreements
    return total, (cells > 0).sum(-1)
