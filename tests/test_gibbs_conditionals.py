"""The sampler's conditionals against the Pyro model's own log density, and its fast path."""

from __future__ import annotations

import numpy as np
import pyro.poutine as poutine
import pytest
import torch
from gibbs_problems import config, random_problem
from scipy import stats

from spcopyro.gibbs.init import initial_state
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import (
    label_log_conditionals,
    log_joint,
    sample_globals,
    sample_labels,
)
from spcopyro.model import spcomapping_model

VARIANTS = [
    dict(prior="dp"),
    dict(prior="dirichlet", alpha=2.0),
    dict(connectivity=8),
    dict(use_images=False),
    dict(use_words=False),
    dict(use_images=False, use_words=False, gamma=1.7),
    dict(num_concepts=5, gamma=0.0),
]


def model_log_density(state: GibbsState, data, cfg) -> torch.Tensor:
    """log_prob_sum of a trace of the Pyro model conditioned on the state."""
    values = {
        "pi": state.log_pi.exp(),
        "theta": state.log_theta.exp(),
        "w": state.log_w.exp(),
        "labels": state.labels,
    }
    conditioned = poutine.condition(spcomapping_model, data=values)
    return poutine.trace(conditioned).get_trace(data, cfg).log_prob_sum()


@pytest.mark.parametrize(
    "variant", VARIANTS, ids=lambda v: ",".join(f"{k}={x}" for k, x in v.items())
)
def test_enumerated_conditionals_equal_model_density_differences(variant):
    cfg = config(**variant)
    grid, data = random_problem(seed=3, connectivity=cfg.connectivity)
    generator = torch.Generator().manual_seed(1)
    state = initial_state(data, cfg, generator)
    # Every cell with observations, plus a few without.
    cells = torch.cat([data.obs_cells, torch.tensor([0, 7, data.num_free - 1])]).unique()
    conditionals = label_log_conditionals(state, data, cfg, cells)  # [n, L]
    for row, cell in enumerate(cells.tolist()):
        densities = []
        for label in range(cfg.num_concepts):
            labels = state.labels.clone()
            labels[cell] = label
            densities.append(model_log_density(state._replace(labels=labels), data, cfg))
        expected = torch.log_softmax(torch.stack(densities), 0)
        torch.testing.assert_close(conditionals[row], expected, atol=1e-5, rtol=0)


@pytest.mark.parametrize("variant", VARIANTS[:4], ids=str)
def test_log_joint_equals_pyro_trace(variant):
    cfg = config(**variant)
    _, data = random_problem(seed=4, connectivity=cfg.connectivity)
    state = initial_state(data, cfg, torch.Generator().manual_seed(2))
    torch.testing.assert_close(
        log_joint(state, data, cfg), model_log_density(state, data, cfg), atol=1e-6, rtol=1e-9
    )


BLOCK_VARIANTS = [
    dict(gamma=1.5),
    dict(connectivity=8),
    dict(gamma=2.5, num_concepts=4),
    dict(gamma=0.0),
]


def min_block_p_value(sample_labels_fn, cfg) -> float:
    """Smallest per-cell chi-square p-value of first-block draws against the exact conditional.

    The problem is repeated in 1000 wall-separated copies sharing one state, so every call of
    ``sample_labels_fn(state, data, cfg, generator, plan)`` gives 1000 independent draws of each
    first-block cell (the fast background path and the observed cells' enumeration alike);
    frequencies are compared with :func:`label_log_conditionals` cell by cell of one copy.
    """
    copies, repeats = 1000, 20
    _, data = random_problem(seed=5, connectivity=cfg.connectivity, copies=copies)
    n = data.num_free // copies
    generator = torch.Generator().manual_seed(3)
    one = initial_state(data, cfg, generator)
    state = one._replace(labels=one.labels[:n].repeat(copies))  # same state in every copy
    plan = make_sweep_plan(data)
    first = plan.blocks[0].cells
    first = first[first < n]  # first-block cells of copy 0
    assert (data.observation_rows()[first] >= 0).any()  # the observed path is exercised
    counts = torch.zeros(first.numel(), cfg.num_concepts)
    for _ in range(repeats):
        labels = sample_labels_fn(state, data, cfg, generator, plan).view(copies, n)[:, first]
        counts += torch.nn.functional.one_hot(labels, cfg.num_concepts).sum(0)
    expected = label_log_conditionals(state, data, cfg, first).exp() * copies * repeats
    p_values = [
        stats.chisquare(counts[i].numpy(), expected[i].numpy()).pvalue for i in range(len(first))
    ]
    return min(p_values) * len(p_values)  # Bonferroni over cells


@pytest.mark.parametrize("variant", BLOCK_VARIANTS, ids=str)
def test_block_draws_follow_enumerated_conditionals(variant):
    """The first colour block is drawn from the exact conditional given the current state."""
    # A correct sampler fails this with probability < 1e-3.
    assert min_block_p_value(sample_labels, config(**variant)) > 1e-3


def test_globals_follow_conjugate_posterior():
    """pi | C ~ Dir(alpha/L + m): compare the sample mean with the closed form."""
    cfg = config(num_concepts=4, alpha=2.0)
    _, data = random_problem(seed=6)
    labels = torch.tensor([0] * 10 + [1] * 5 + [3] * (data.num_free - 15))
    generator = torch.Generator().manual_seed(4)
    draws = torch.stack(
        [sample_globals(labels, data, cfg, generator)[0].exp() for _ in range(3000)]
    )
    m = torch.bincount(labels, minlength=4).double()
    a = cfg.pi_concentration + m
    mean, var = a / a.sum(), a * (a.sum() - a) / (a.sum() ** 2 * (a.sum() + 1))
    z = (draws.mean(0) - mean) / (var / draws.shape[0]).sqrt()
    assert z.abs().max() < 4.0, z


def test_log_gamma_matches_scipy_for_small_and_large_shapes():
    from spcopyro.gibbs.random import sample_log_gamma

    generator = torch.Generator().manual_seed(5)
    for shape in (0.01, 0.3, 1.0, 7.5, 1e4):
        log_g = sample_log_gamma(torch.full((20000,), shape, dtype=torch.float64), generator)
        assert torch.isfinite(log_g).all()
        # Kolmogorov-Smirnov on log G (finite even where G underflows).
        samples = log_g.numpy()
        cdf = lambda x, a=shape: stats.gamma.cdf(np.exp(x), a)  # noqa: E731
        assert stats.kstest(samples, cdf).pvalue > 1e-3, shape
