"""Statistical checks of the sampler shared by several test modules (no tests in here).

* :func:`model_log_density`, :func:`assert_conditionals_match_model`: the enumerated conditionals
  (eq. 13) against differences of the Pyro model's own log density.
* :func:`backend_samplers`: a backend's label-only and globals-only draws, by backend name (the
  ``backend`` fixture of ``conftest.py`` gives the backend object; its ``.name`` picks these).
* :func:`min_block_p_value`: chi-square of first-colour-block label draws against the enumerated
  conditional (eq. 13), over :data:`BLOCK_VARIANTS`.
* Geweke's "getting it right" (:func:`geweke_z_scores`, :data:`GEWEKE_VARIANTS`): marginal-
  conditional against successive-conditional draws of label-invariant statistics.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import pyro
import pyro.poutine as poutine
import pytest
import torch
from gibbs_problems import all_labelings, model_data, random_problem, replicate_grid
from pyro.ops.stats import effective_sample_size
from scipy import stats

from spcopyro._util.random_draws import sample_log_dirichlet
from spcopyro.config import DEFAULT_PRESET, preset_inference
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.sampler import init, step
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import label_log_conditionals
from spcopyro.model import DTYPE, ModelData, potts_agreements, spcomapping_model
from spcopyro.simulate import sample_observations

# -- the reference against the model --------------------------------------------------------------


def model_log_density(state: GibbsState, data, cfg) -> torch.Tensor:
    """log_prob_sum of a trace of the Pyro model conditioned on the state (every modality)."""
    values = {"pi": state.log_pi.exp(), "labels": state.labels}
    for modality, log_table in zip(data.modalities, state.log_emissions, strict=True):
        values[modality.parameter] = log_table.exp()  # theta [L, K], w [L, V], ... [L, K_m]
    conditioned = poutine.condition(spcomapping_model, data=values)
    return poutine.trace(conditioned).get_trace(data, cfg).log_prob_sum()


def assert_conditionals_match_model(state: GibbsState, data, cfg, cells: torch.Tensor) -> None:
    """:func:`label_log_conditionals` of ``cells`` equal the normalised differences of the Pyro
    model's log density over each cell's L labels (all else fixed)."""
    conditionals = label_log_conditionals(state, data, cfg, cells)  # [n, L]
    for row, cell in enumerate(cells.tolist()):
        densities = []
        for label in range(cfg.num_concepts):
            labels = state.labels.clone()
            labels[cell] = label
            densities.append(model_log_density(state._replace(labels=labels), data, cfg))
        expected = torch.log_softmax(torch.stack(densities), 0)
        torch.testing.assert_close(conditionals[row], expected, atol=1e-5, rtol=0)


# -- per-backend draws ---------------------------------------------------------------------------


class Samplers(NamedTuple):
    """The parts of one backend's sweep, callable on their own."""

    labels: Callable[..., torch.Tensor]
    """``(state, data, config, generator, plan) -> [N]``: every label from eq. (13)."""
    globals: Callable[..., tuple[torch.Tensor, tuple[torch.Tensor, ...]]]
    """``(labels, data, config, generator) -> (log pi [L], per modality [L, K_m])``:
    eqs. (14)-(17)."""
    log_gamma: Callable[[np.ndarray, int], np.ndarray]
    """``(shapes [n], seed) -> [n]`` log of Gamma(shape, 1) draws."""


def backend_samplers(name: str) -> Samplers:
    """The label, globals and log-gamma samplers of the backend called ``name``."""
    if name == "torch":
        from spcopyro._util.random_draws import sample_log_gamma
        from spcopyro.gibbs.sweep import sample_globals, sample_labels

        def log_gamma(shapes: np.ndarray, seed: int) -> np.ndarray:
            generator = torch.Generator().manual_seed(seed)
            return sample_log_gamma(torch.as_tensor(shapes, dtype=DTYPE), generator).numpy()

        return Samplers(sample_labels, sample_globals, log_gamma)
    if name == "numba":
        from spcopyro.gibbs.numba_sweep import (
            sample_globals_numba,
            sample_labels_numba,
            sample_log_gamma_numba,
        )

        return Samplers(sample_labels_numba, sample_globals_numba, sample_log_gamma_numba)
    raise ValueError(f"no samplers for backend {name!r}")


# -- first colour block against the enumerated conditional --------------------------------------

BLOCK_VARIANTS = [
    dict(gamma=1.5),
    dict(connectivity=8),
    dict(gamma=2.5, num_concepts=4),
    dict(gamma=0.0),
]
"""Config overrides (of ``gibbs_problems.config``) for :func:`min_block_p_value`."""


def min_block_p_value(sample_labels_fn, cfg) -> float:
    """Smallest per-cell chi-square p-value of first-block draws against the exact conditional.

    The problem is repeated in 1000 wall-separated copies sharing one state, so every call of
    ``sample_labels_fn(state, data, cfg, generator, plan)`` gives 1000 independent draws of each
    first-block cell (the fast background path and the observed cells' enumeration alike);
    frequencies are compared with :func:`label_log_conditionals` cell by cell of one copy.
    Returns the Bonferroni-corrected smallest p-value (a correct sampler: uniform-ish, rarely
    below 1e-3).
    """
    copies, repeats = 1000, 20
    _, data = random_problem(seed=5, connectivity=cfg.connectivity, copies=copies)
    n = data.num_free // copies
    generator = torch.Generator().manual_seed(3)
    one = init(data, cfg, generator)
    state = one._replace(labels=one.labels[:n].repeat(copies))  # same state in every copy
    plan = make_sweep_plan(data)
    first = plan.blocks[0].cells
    first = first[first < n]  # first-block cells of copy 0
    assert (data.observation_rows()[first] >= 0).any()  # the observed path is exercised
    counts = torch.zeros(first.numel(), cfg.num_concepts)  # [n1, L]
    for _ in range(repeats):
        labels = sample_labels_fn(state, data, cfg, generator, plan).view(copies, n)[:, first]
        counts += torch.nn.functional.one_hot(labels, cfg.num_concepts).sum(0)
    expected = label_log_conditionals(state, data, cfg, first).exp() * copies * repeats
    p_values = [
        stats.chisquare(counts[i].numpy(), expected[i].numpy()).pvalue for i in range(len(first))
    ]
    return min(p_values) * len(p_values)  # Bonferroni over cells


def pooled_chisquare_p(counts, probs) -> float:
    """Chi-square p-value of ``counts`` [S] (draws of S states) against the probabilities
    ``probs`` [S] (enumerated): expected counts ``probs * counts.sum()``, the states expected
    fewer than 5 times pooled into one bin (where there are any), the expected rescaled to the
    counts' total (``probs`` summing to 1 up to rounding). Tensors or arrays."""
    observed = np.asarray(counts, dtype=np.float64)  # [S]
    expected = np.asarray(probs, dtype=np.float64) * observed.sum()  # [S]
    big = expected >= 5
    obs, exp = observed[big], expected[big]
    if expected[~big].sum() > 0:
        obs, exp = np.append(obs, observed[~big].sum()), np.append(exp, expected[~big].sum())
    return float(stats.chisquare(obs, exp * obs.sum() / exp.sum()).pvalue)


# -- Geweke's joint test ---------------------------------------------------------------------------

Z_LIMIT = 4.0
"""Per statistic: a correct sampler fails with p < 8e-4 over label_invariant_statistics' 12
statistics, ~1.1e-3 over test_hyperparameters' _statistics' 17 (two-sided, a union bound)."""

PRESET_MOVES = {
    name: value
    for name, value in preset_inference(DEFAULT_PRESET).items()
    if name in ("cluster_moves", "merge_moves", "region_moves", "unobserved_refresh")
}
"""The moves the default preset turns on (``coarse``: merge and region moves, 0.2 each)."""

GEWEKE_VARIANTS = [
    pytest.param(dict(), GibbsOptions(), id="default"),
    pytest.param(dict(prior="dirichlet", alpha=1.5, gamma=0.5), GibbsOptions(), id="dirichlet"),
    # 4 concepts, 3 observed cells: some concept always lacks observations, so the partial
    # refresh of theta and w (GibbsOptions.unobserved_refresh) is exercised.
    pytest.param(dict(num_concepts=4), GibbsOptions(unobserved_refresh=0.3), id="refresh-0.3"),
    # Half the sweeps start with a Swendsen-Wang cluster move (spcopyro.gibbs.cluster). This checks
    # the composition with the sweep; a wrong cluster weight is caught by the enumerated-posterior
    # test of test_gibbs_joint.py (the sweep that follows the move hides it from Geweke's
    # statistics).
    pytest.param(dict(gamma=1.5), GibbsOptions(cluster_moves=0.5), id="cluster-0.5"),
    # A third of the sweeps start with a split-merge move (spcopyro.gibbs.merge): the globals
    # redrawn after an accepted move and kept after a rejected one. Its exactness on the labels
    # is test_merge_move.py's enumerated-posterior test.
    pytest.param(dict(gamma=1.5), GibbsOptions(merge_moves=0.3), id="merge-0.3"),
    # A third start with a region relabel move (spcopyro.gibbs.region_move), likewise: its
    # exactness on the labels is test_region_move.py's detailed balance, enumerated.
    pytest.param(dict(gamma=1.5), GibbsOptions(region_moves=0.3), id="region-0.3"),
    pytest.param(dict(connectivity=8, gamma=0.7), GibbsOptions(), id="8-neighbours"),
    # Every move on at once: the default preset's moves (merge and region, at its own
    # probabilities), Swendsen-Wang too, and the partial refresh with 4 concepts (as above).
    pytest.param(
        dict(num_concepts=4, gamma=1.5),
        GibbsOptions(**(dict(cluster_moves=0.2, unobserved_refresh=0.3) | PRESET_MOVES)),
        id="moves-together",
    ),
]
"""(config overrides, sampler options) of Geweke's test; the options' backend is replaced by
the backend under test."""


def label_invariant_statistics(
    labels, log_pi, log_theta, log_w, image_counts, word_counts, pairs, obs_cells, L: int
) -> torch.Tensor:
    """[B, S] statistics unchanged by relabelling the concepts, for a batch of B states.

    labels [B, N], log_pi [B, L], log_theta [B, L, K], log_w [B, L, V], image_counts [B, M, K],
    word_counts [B, M, V].
    """
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

    Written independently of the model's forward mode, which :func:`model_redraw` uses.
    """
    B, M, K = log_probs.shape
    counts = torch.zeros_like(log_probs)
    for row, total in enumerate(totals.long().tolist()):
        picks = torch.multinomial(log_probs[:, row].exp(), total, replacement=True,
                                  generator=generator)  # fmt: skip
        counts[:, row] = torch.nn.functional.one_hot(picks, K).sum(1).to(counts.dtype)
    return counts


def exact_label_marginal(grid_pairs, num_cells: int, cfg) -> tuple[torch.Tensor, torch.Tensor]:
    """All labelings [L^n, n] and their probabilities [L^n] under
    p(C) = int Dir(pi) prod pi_C e^{gamma E} dpi.

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


def model_redraw(state: GibbsState, world: ModelData, cfg, generator) -> ModelData:
    """New data given the state, drawn by the model itself (its forward mode)."""
    return sample_observations(state, world, cfg)


def counts_redraw(state: GibbsState, world: ModelData, cfg, generator) -> ModelData:
    """New data given the state, drawn by :func:`draw_counts` (independent of the model)."""
    c = state.labels[world.obs_cells][None]  # [1, M]
    images = draw_counts(state.log_theta[c], world.image_counts.sum(-1), generator)[0]
    words = draw_counts(state.log_w[c], world.word_counts.sum(-1), generator)[0]
    return world.with_counts("images", images).with_counts("words", words)


def geweke_z_scores(
    cfg, options: GibbsOptions, redraw=model_redraw, steps: int = 8000
) -> torch.Tensor:
    """[S] z-scores of label-invariant statistics, marginal-conditional vs successive-conditional.

    Marginal-conditional draws: C from its exact marginal (enumerated), pi | C, theta and w from
    their priors, the data given all of them (``draw_counts``). Successive-conditional draws:
    :func:`spcopyro.gibbs.sampler.step` with ``options`` (its backend, cluster moves, refresh)
    alternated with ``redraw(state, data, cfg, generator)``. The standard error uses the
    successive chain's effective sample size.
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
    log_pi = sample_log_dirichlet(cfg.pi_concentration + m, generator)  # [draws, L]
    log_theta = sample_log_dirichlet(torch.full((draws, L, 2), cfg.chi, dtype=DTYPE), generator)
    log_w = sample_log_dirichlet(torch.full((draws, L, 3), cfg.beta, dtype=DTYPE), generator)
    rows, c = torch.arange(draws)[:, None], labels[:, data.obs_cells]  # c: [draws, M]
    images = draw_counts(log_theta[rows, c], data.image_counts.sum(-1), generator)
    words = draw_counts(log_w[rows, c], data.word_counts.sum(-1), generator)
    forward = label_invariant_statistics(
        labels, log_pi, log_theta, log_w, images, words, data.pairs, data.obs_cells, L
    )  # [draws, S]

    backend = get_backend(options.backend)
    state, world = init(data, cfg, generator), data
    plan = make_sweep_plan(data)
    chain = []
    for sweep in range(steps):
        state, _ = step(state, world, cfg, generator, sweep=sweep, options=options,
                        backend=backend, plan=plan)  # fmt: skip
        # Recorded between the kernel step and the data draw: a kernel that ignored the data
        # would be caught here (recorded after the data draw, (params, data) would still be
        # jointly right for a kernel that draws w from its prior).
        chain.append(
            (state.labels, state.log_pi, state.log_theta, state.log_w,
             world.image_counts, world.word_counts)
        )  # fmt: skip
        world = redraw(state, world, cfg, generator)
    chain = label_invariant_statistics(
        *(torch.stack(x) for x in zip(*chain, strict=True)), data.pairs, data.obs_cells, L
    )  # [steps, S]

    ess = effective_sample_size(chain[None], chain_dim=0, sample_dim=1).clamp(min=10.0)
    se = (forward.var(0) / draws + chain.var(0) / ess).sqrt()
    return (forward.mean(0) - chain.mean(0)) / se
