"""Joint-distribution tests of the sampler on enumerable problems.

* Geweke's "getting it right": marginal-conditional draws (labels from their exact marginal by
  enumeration, then pi, theta, w and the data) against successive-conditional draws (alternating
  kernel sweeps and data draws from the model). Label-invariant statistics must agree within
  Monte Carlo error (with the successive chain's effective sample size).
* The colour-block sweep against Algorithm 1's sequential raster-order sweep, and the
  Swendsen-Wang cluster move on its own: all must reach the exact posterior of the labels (given
  the globals), enumerated.
"""

from __future__ import annotations

import numpy as np
import pyro
import pytest
import torch
from gibbs_problems import all_labelings, config, model_data, replicate_grid, state_index
from pyro.ops.stats import effective_sample_size
from scipy import stats

from spcopyro.gibbs.cluster import swendsen_wang_labels
from spcopyro.gibbs.init import initial_state
from spcopyro.gibbs.prior import sample_observations
from spcopyro.gibbs.random import sample_log_dirichlet
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import gibbs_sweep, label_log_conditionals, log_joint, sample_labels
from spcopyro.model import DTYPE, potts_agreements

Z_LIMIT = 4.0  # per statistic; with 12 statistics a correct sampler fails with p < 1e-3


def label_invariant_statistics(
    labels, log_pi, log_theta, log_w, image_counts, word_counts, pairs, obs_cells, L: int
) -> torch.Tensor:
    """[B, S] statistics unchanged by relabelling the concepts, for a batch of B states."""
    pi = log_pi.exp()  # [B, L]
    first, last = labels[:, obs_cells[0]], labels[:, obs_cells[-1]]  # [B]
    rows = torch.arange(labels.shape[0])
    return torch.stack(
        [
            potts_agreements(labels, pairs),
            torch.nn.functional.one_hot(labels, L).amax(1).sum(-1).to(DTYPE),
            (labels[:, 0] == labels[:, -1]).to(DTYPE),
            (labels[:, 0] == labels[:, 1]).to(DTYPE),
            pi.amax(-1),
            pi[rows, labels[:, 0]],
            log_theta.exp()[rows, first, 0],
            log_w.exp()[rows, last, 1],
            image_counts[:, 0, 0],
            word_counts[:, -1, 1],
            # fit of data and parameters: sum over observed cells of counts . log theta_C
            (image_counts * log_theta[rows[:, None], labels[:, obs_cells]]).sum((-1, -2)),
            (word_counts * log_w[rows[:, None], labels[:, obs_cells]]).sum((-1, -2)),
        ],
        dim=-1,
    )


def draw_counts(log_probs: torch.Tensor, totals: torch.Tensor, generator) -> torch.Tensor:
    """[B, M, K] multinomial counts given [B, M, K] log probs and [M] integer totals.

    Written independently of the model's forward mode, which the other half of the test uses.
    """
    B, M, K = log_probs.shape
    counts = torch.zeros_like(log_probs)
    for row, total in enumerate(totals.long().tolist()):
        picks = torch.multinomial(log_probs[:, row].exp(), total, replacement=True,
                                  generator=generator)  # fmt: skip
        counts[:, row] = torch.nn.functional.one_hot(picks, K).sum(1).to(counts.dtype)
    return counts


def exact_label_marginal(grid_pairs, num_cells: int, cfg) -> tuple[torch.Tensor, torch.Tensor]:
    """All labelings and their probabilities under p(C) = int Dir(pi) prod pi_C e^{gamma E} dpi.

    Integrating pi out gives the Dirichlet-multinomial: p(C) propto e^{gamma E(C)} B(a + m(C)),
    m(C) the label counts (the data are integrated out too: they sum to one given the globals).
    """
    L = cfg.num_concepts
    labelings = all_labelings(num_cells, L)  # [L^n, n]
    m = torch.nn.functional.one_hot(labelings, L).sum(1).to(DTYPE)  # [L^n, L]
    a = cfg.pi_concentration + m
    log_beta = torch.lgamma(a).sum(-1) - torch.lgamma(a.sum(-1))
    log_p = cfg.gamma * potts_agreements(labelings, grid_pairs) + log_beta
    return labelings, torch.softmax(log_p, 0)


GEWEKE_VARIANTS = [
    dict(),
    dict(prior="dirichlet", alpha=1.5, gamma=0.5),
    # 4 concepts, 3 observed cells: some concept always lacks observations, so the partial
    # refresh of theta and w (SpCoConfig.unobserved_refresh) is exercised.
    dict(num_concepts=4, unobserved_refresh=0.3),
    # Half the sweeps start with a Swendsen-Wang cluster move (spcopyro.gibbs.cluster). This checks
    # the composition with the sweep; a wrong cluster weight is caught by the enumerated-posterior
    # test below (the sweep that follows the move hides it from Geweke's statistics).
    dict(gamma=1.5, cluster_moves=0.5),
]


def model_redraw(state: GibbsState, world, cfg, generator):
    """New data given the state, drawn by the model itself (its forward mode)."""
    return sample_observations(state, world, cfg)


def geweke_z_scores(cfg, sweep, redraw=model_redraw, steps: int = 8000) -> torch.Tensor:
    """[S] z-scores of label-invariant statistics, marginal-conditional vs successive-conditional.

    Marginal-conditional draws: C from its exact marginal (enumerated), pi | C, theta and w from
    their priors, the data given all of them (``draw_counts``). Successive-conditional draws:
    ``sweep(state, data, cfg, generator, plan)`` alternated with ``redraw(state, data, cfg,
    generator)``. The standard error uses the successive chain's effective sample size.
    """
    pyro.set_rng_seed(11)
    grid, n = replicate_grid(["...", "...", "..."], 1)  # 9 cells, 3^9 labelings
    # Integer totals: 3 image counts over K=2 classes, 2 words over V=3 in each observed cell.
    data = model_data(
        grid, np.array([0, 4, 8]), [[3, 0], [2, 1], [0, 3]], [[2, 0, 0], [0, 1, 1], [0, 0, 2]],
        cfg.connectivity,
    )  # fmt: skip
    L = cfg.num_concepts
    generator = torch.Generator().manual_seed(12)
    labelings, probs = exact_label_marginal(data.pairs, n, cfg)

    draws = 20000  # marginal-conditional, vectorised over draws
    labels = labelings[torch.multinomial(probs, draws, replacement=True, generator=generator)]
    m = torch.nn.functional.one_hot(labels, L).sum(1).to(DTYPE)  # [draws, L]
    log_pi = sample_log_dirichlet(cfg.pi_concentration + m, generator)
    log_theta = sample_log_dirichlet(torch.full((draws, L, 2), cfg.chi, dtype=DTYPE), generator)
    log_w = sample_log_dirichlet(torch.full((draws, L, 3), cfg.beta, dtype=DTYPE), generator)
    rows, c = torch.arange(draws)[:, None], labels[:, data.obs_cells]  # c: [draws, M]
    images = draw_counts(log_theta[rows, c], data.image_counts.sum(-1), generator)
    words = draw_counts(log_w[rows, c], data.word_counts.sum(-1), generator)
    forward = label_invariant_statistics(
        labels, log_pi, log_theta, log_w, images, words, data.pairs, data.obs_cells, L
    )  # [draws, S]

    state, world = initial_state(data, cfg, generator), data
    plan = make_sweep_plan(data)
    chain = []
    for _ in range(steps):
        state = sweep(state, world, cfg, generator, plan)
        # Recorded between the kernel step and the data draw: a kernel that ignored the data
        # would be caught here (recorded after the data draw, (params, data) would still be
        # jointly right for a kernel that draws w from its prior).
        chain.append((*state, world.image_counts, world.word_counts))
        world = redraw(state, world, cfg, generator)
    chain = label_invariant_statistics(
        *(torch.stack(x) for x in zip(*chain, strict=True)), data.pairs, data.obs_cells, L
    )  # [steps, S]

    ess = effective_sample_size(chain[None], chain_dim=0, sample_dim=1).clamp(min=10.0)
    se = (forward.var(0) / draws + chain.var(0) / ess).sqrt()
    return (forward.mean(0) - chain.mean(0)) / se


@pytest.mark.slow
@pytest.mark.parametrize("variant", GEWEKE_VARIANTS, ids=str)
def test_geweke_getting_it_right(variant):
    z = geweke_z_scores(config(**variant), gibbs_sweep)
    assert z.abs().max() < Z_LIMIT, f"z-scores {z.numpy().round(2)}"


def _sequential_raster_sweep(state, data, cfg, generator, cells_per_copy: int, copies: int):
    """Algorithm 1's label loop: cells one at a time in raster order (all copies at once)."""
    labels = state.labels.clone()
    for position in range(cells_per_copy):
        cells = position + cells_per_copy * torch.arange(copies)
        log_p = label_log_conditionals(state._replace(labels=labels), data, cfg, cells)
        labels[cells] = torch.multinomial(log_p.exp(), 1, generator=generator)[:, 0]
    return labels


@pytest.mark.parametrize("connectivity", [4, 8])
def test_block_raster_and_cluster_moves_reach_the_exact_posterior(connectivity):
    cfg = config(gamma=0.8, connectivity=connectivity)
    rows = ["...", ".#.", "..."]  # a ring of 8 cells round a wall: 3^8 labelings
    copies = 6000
    grid, n = replicate_grid(rows, copies)
    obs = np.array([0, 5])
    images, words = np.array([[2.0, 0.5], [0.0, 3.0]]), np.array([[1.0, 0, 0], [0, 0, 2.0]])
    data = model_data(
        grid,
        (np.arange(copies)[:, None] * n + obs).ravel(),
        np.tile(images, (copies, 1)),
        np.tile(words, (copies, 1)),
        connectivity,
    )
    generator = torch.Generator().manual_seed(21)
    # Globals fixed by hand, distinct per concept, so that pi and both emissions matter.
    fixed = initial_state(data, cfg, generator)._replace(
        log_pi=torch.tensor([0.5, 0.3, 0.2], dtype=DTYPE).log(),
        log_theta=torch.tensor([[0.8, 0.2], [0.3, 0.7], [0.5, 0.5]], dtype=DTYPE).log(),
        log_w=torch.tensor([[0.6, 0.3, 0.1], [0.1, 0.2, 0.7], [0.3, 0.4, 0.3]], dtype=DTYPE).log(),
    )

    # Exact posterior of one copy's labels given the globals, by enumeration.
    one_grid, _ = replicate_grid(rows, 1)
    one = model_data(one_grid, obs, images, words, connectivity)
    labelings = all_labelings(n, cfg.num_concepts)
    log_p = torch.stack([log_joint(fixed._replace(labels=lab), one, cfg) for lab in labelings])
    exact = torch.softmax(log_p, 0)

    plan = make_sweep_plan(data)
    start = torch.randint(cfg.num_concepts, (data.num_free,), generator=generator)
    block, raster = fixed._replace(labels=start), fixed._replace(labels=start.clone())
    cluster = fixed._replace(labels=start.clone())
    for _ in range(25):
        block = block._replace(labels=sample_labels(block, data, cfg, generator, plan))
        raster = raster._replace(
            labels=_sequential_raster_sweep(raster, data, cfg, generator, n, copies)
        )
        cluster = cluster._replace(labels=swendsen_wang_labels(cluster, data, cfg, generator))
    for name, chain in (("block", block), ("raster", raster), ("cluster", cluster)):
        states = state_index(chain.labels.view(copies, n), cfg.num_concepts)
        observed = torch.bincount(states, minlength=len(labelings)).double()
        expected = exact * copies
        # Chi-square on the states, pooling those with small expected counts into one bin.
        big = expected >= 5
        obs_bins = torch.cat([observed[big], observed[~big].sum()[None]])
        exp_bins = torch.cat([expected[big], expected[~big].sum()[None]])
        p_value = stats.chisquare(obs_bins.numpy(), exp_bins.numpy()).pvalue
        assert p_value > 1e-3, (name, p_value)
