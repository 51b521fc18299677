r"""One Gibbs sweep of SpCoMapping (the paper's Algorithm 1), vectorised over cells and concepts.

A sweep draws every free cell's label from its full conditional (eq. 13), colour block by colour
block, then pi, theta and w from their conjugate Dirichlet conditionals (eqs. 14-17).

**Cell labels (eq. 13).** For a free cell i with neighbour labels n_l(i) = #{j ~ i : C_j = l},

.. math::

    p(C_i = l \mid \text{rest}) \propto \pi_l \, e^{\gamma n_l(i)}
        \prod_{t \in i} \theta_{l, f_t} \, w_{l, S_t}.

Cells of one colour of the neighbour graph (checkerboard for the 4-neighbourhood, 2x2 pattern for
8) are conditionally independent, so each colour is drawn at once; the result is a valid Gibbs
scan (a systematic scan in colour order instead of raster order; both leave the posterior
invariant, and the tests check they agree in distribution).

**Cells without observations** are almost all of them, and their conditional is a pi-weighted
background tilted towards at most D neighbour labels. Writing e^{gamma n} = 1 + expm1(gamma n),

.. math::

    p(C_i = l) \propto \pi_l + \sum_{k \in \text{distinct nbr labels}}
        \delta_{lk} \, \pi_k \, \mathrm{expm1}(\gamma n_k(i)),

a two-part mixture of total mass 1 + sum_k pi_k expm1(gamma n_k): with the first part's share draw
l from pi (one binary search in pi's CDF), otherwise one of the <= D neighbour labels. That costs
O(D^2 + log L) per cell instead of O(L). Cells with observations (a few hundred) get the full
O(L) enumeration. The reference for both is :func:`label_log_conditionals`.
"""

from __future__ import annotations

import torch

from spcopyro._util.random_draws import sample_categorical_logits, sample_log_dirichlet
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.state import ColourBlock, GibbsState, SweepPlan, make_sweep_plan
from spcopyro.likelihood import (
    concept_statistics,
    log_joint_constant,
    log_joint_variable,
    neighbour_agreements,
    observation_log_likelihood,
)
from spcopyro.model import DTYPE, ModelData


def _gather_neighbour_labels(labels: torch.Tensor, neighbours: torch.Tensor) -> torch.Tensor:
    """[n, D] labels of the neighbours, -1 where there is none."""
    return torch.where(neighbours >= 0, labels[neighbours.clamp_min(0)], -1)


def label_log_conditionals(
    state: GibbsState, data: ModelData, config: SpCoConfig, cells: torch.Tensor
) -> torch.Tensor:
    """[n, L] normalised log p(C_i = l | everything else) for the given cells: eq. (13), enumerated.

    The readable reference that the sweep's fast path is tested against.
    """
    neighbour_labels = _gather_neighbour_labels(state.labels, data.neighbours[cells])  # [n, D]
    logits = state.log_pi + config.gamma * neighbour_agreements(
        neighbour_labels, config.num_concepts
    )  # [n, L]
    obs_row = data.observation_rows()[cells]  # [n]
    observed = obs_row >= 0
    if observed.any():
        loglik = observation_log_likelihood(state.log_emissions, data, config)  # [M, L]
        logits[observed] += loglik[obs_row[observed]]
    return torch.log_softmax(logits, dim=-1)


def _sample_block_unobserved(
    neighbour_labels: torch.Tensor,
    pi_ext: torch.Tensor,
    tilt: torch.Tensor,
    pi_cdf: torch.Tensor,
    generator: torch.Generator,
) -> torch.Tensor:
    """[n] draws from pi_l e^{gamma n_l} via the background + neighbour mixture (module doc).

    Slot s of a cell carries weight pi_{a_s} expm1(gamma n_{a_s}) / n_{a_s}, so the slots sharing
    a label add up to that label's neighbour part without any de-duplication.

    Args:
        neighbour_labels: [n, D] int64, a distinct negative sentinel where no neighbour.
        pi_ext: [L + D] float64 pi followed by D zeros (indexed by label, sentinels wrap to zeros).
        tilt: [D + 1] float64 expm1(gamma k) / k for k = 0..D (0 at k = 0).
        pi_cdf: [L] float64 cumulative sum of pi.
    """
    D = neighbour_labels.shape[1]
    agree = (neighbour_labels[:, :, None] == neighbour_labels[:, None, :]).sum(-1)  # [n, D]
    weight = pi_ext[neighbour_labels] * tilt[agree]  # [n, D]
    cumulative = weight.cumsum(-1)  # [n, D]
    neighbour_mass = cumulative[:, -1]  # [n]
    u = torch.rand(neighbour_mass.shape, dtype=DTYPE, generator=generator)
    u = u * (1.0 + neighbour_mass)  # [n]
    slot = (u[:, None] >= cumulative).sum(-1)  # [n], D means "background"
    chosen = neighbour_labels.gather(1, slot.clamp_max(D - 1)[:, None])[:, 0]  # [n]
    # Given the background part, (u - neighbour_mass) is uniform on [0, 1): reuse it.
    background = torch.searchsorted(pi_cdf, u - neighbour_mass, right=True)
    background = background.clamp_max(pi_cdf.shape[0] - 1)  # [n]
    return torch.where(slot < D, chosen, background)


def _sample_block(
    labels_ext: torch.Tensor,
    block: ColourBlock,
    log_pi: torch.Tensor,
    pi_ext: torch.Tensor,
    tilt: torch.Tensor,
    pi_cdf: torch.Tensor,
    loglik: torch.Tensor,
    config: SpCoConfig,
    generator: torch.Generator,
) -> None:
    """Redraw the labels of one colour block in place (``labels_ext``: [N + D] with sentinels)."""
    neighbour_labels = labels_ext[block.neighbours]  # [Nc, D]
    new = _sample_block_unobserved(neighbour_labels, pi_ext, tilt, pi_cdf, generator)
    if block.observed_positions.numel():
        observed_nb = neighbour_labels[block.observed_positions]  # [Mc, D]
        logits = (
            log_pi
            + config.gamma * neighbour_agreements(observed_nb, config.num_concepts)
            + loglik[block.observed_rows]
        )  # [Mc, L]
        new[block.observed_positions] = sample_categorical_logits(logits, generator)
    labels_ext[block.cells] = new


def sample_labels(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    plan: SweepPlan | None = None,
) -> torch.Tensor:
    """[N] new labels: every free cell drawn from eq. (13), one colour block at a time."""
    plan = make_sweep_plan(data) if plan is None else plan
    D = data.neighbours.shape[1]
    sentinels = -1 - torch.arange(D)  # [D] distinct, never equal to a label
    labels_ext = torch.cat([state.labels, sentinels])  # [N + D]
    pi = torch.exp(state.log_pi)  # [L]
    pi_ext = torch.cat([pi, torch.zeros(D, dtype=DTYPE)])  # [L + D]; index -1-s hits a zero
    k = torch.arange(D + 1, dtype=DTYPE)
    tilt = torch.where(k > 0, torch.expm1(config.gamma * k) / k.clamp_min(1), 0.0)  # [D + 1]
    pi_cdf = pi.cumsum(0)  # [L]
    loglik = observation_log_likelihood(state.log_emissions, data, config)  # [M, L]
    for block in plan.blocks:
        _sample_block(
            labels_ext, block, state.log_pi, pi_ext, tilt, pi_cdf, loglik, config, generator
        )
    return labels_ext[: data.num_free]


def concepts_holding_observations(labels: torch.Tensor, data: ModelData) -> torch.Tensor:
    """[G] the concepts labelling at least one observed cell (ascending): the rows of the
    emission distributions whose conditional is not their prior."""
    return torch.unique(labels[data.obs_cells])


def concepts_to_refresh(
    labels: torch.Tensor,
    data: ModelData,
    unobserved_refresh: float,
    generator: torch.Generator,
    previous: tuple[torch.Tensor, ...] | None,
) -> torch.Tensor | None:
    """The concepts whose emission distributions this sweep redraws: None for all of them, else
    (with probability 1 - ``unobserved_refresh``) only those holding an observed cell.

    The choice is made before looking at the state, and the set depends only on the labels,
    which the global draws do not change; so each choice is a Gibbs update of conditionally
    independent blocks, and the posterior stays invariant (``GibbsOptions.unobserved_refresh``).
    """
    if previous is None or unobserved_refresh >= 1.0:
        return None
    if float(torch.rand((), dtype=DTYPE, generator=generator)) < unobserved_refresh:
        return None
    return concepts_holding_observations(labels, data)  # [G]


def sample_globals(
    labels: torch.Tensor,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    previous: tuple[torch.Tensor, ...] | None = None,
    unobserved_refresh: float = 1.0,
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi, per-modality log distributions) from their conjugate conditionals given labels.

    pi | C ~ Dir(alpha/L + m_l) (DP, eq. 14) or Dir(alpha + m_l) (eq. 15), m_l = #cells labelled l;
    theta_l | . ~ Dir(chi + sum of image counts in cells labelled l) (eq. 16);
    w_l | . ~ Dir(beta + sum of word counts in cells labelled l) (eq. 17); a further modality
    likewise with its own concentration. ``previous`` (the state's log distributions) lets
    :func:`concepts_to_refresh` keep the rows of concepts without observed cells.
    """
    statistics = concept_statistics(labels, data, config)
    log_pi = sample_log_dirichlet(config.pi_concentration + statistics.cells, generator)
    rows = concepts_to_refresh(labels, data, unobserved_refresh, generator, previous)
    concentrations = [config.concentration(m.name) for m in data.modalities]
    if rows is None:
        return log_pi, tuple(
            sample_log_dirichlet(a + counts, generator)
            for a, counts in zip(concentrations, statistics.counts, strict=True)
        )
    log_emissions = []
    for a, counts, kept in zip(concentrations, statistics.counts, previous, strict=True):
        redrawn = kept.clone()
        redrawn[rows] = sample_log_dirichlet(a + counts[rows], generator)
        log_emissions.append(redrawn)
    return log_pi, tuple(log_emissions)


def gibbs_sweep(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    plan: SweepPlan | None = None,
    unobserved_refresh: float = 1.0,
) -> GibbsState:
    """One iteration of Algorithm 1 in torch: all cell labels (eq. 13), then pi and the emission
    distributions (eqs. 14-17). The moves composed around it (cluster moves, annealing) are
    :func:`spcopyro.gibbs.sampler.step`'s."""
    labels = sample_labels(state, data, config, generator, plan)
    previous = state.log_emissions
    return GibbsState(
        labels, *sample_globals(labels, data, config, generator, previous, unobserved_refresh)
    )


def log_joint(state: GibbsState, data: ModelData, config: SpCoConfig) -> torch.Tensor:
    """The model's unnormalised log joint (see :func:`~spcopyro.model.spcomapping_model`).

    Equal to the ``log_prob_sum`` of a Pyro trace of the model at this state (tested).
    """
    return log_joint_constant(data, config) + log_joint_variable(
        state.labels, state.log_pi, state.log_emissions, data, config
    )
