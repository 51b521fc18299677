"""The sampler's conditionals against the Pyro model's own log density, and every backend's draws
against them.

The reference (:func:`label_log_conditionals`, :func:`log_joint`) is checked against
``log_prob_sum`` of Pyro traces of the model. Each backend (the ``backend`` fixture: torch, then
numba where installed) is then checked distributionally -- the two draw different random streams
from one seed: per-cell chi-square tests of the label draws against the enumerated conditionals,
a sweep worked out by hand, conjugate means of the globals, KS tests of the log-gamma draws --
and for the sweep's contract (reproducible with a seed, input left alone, the reference's types).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import config, model_data, random_problem, replicate_grid
from scipy import stats
from statistical_checks import (
    BLOCK_VARIANTS,
    assert_conditionals_match_model,
    backend_samplers,
    min_block_p_value,
    model_log_density,
)

from spcopyro.gibbs.sampler import init
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import gibbs_sweep, log_joint
from spcopyro.model import DTYPE

VARIANTS = [
    dict(prior="dp"),
    dict(prior="dirichlet", alpha=2.0),
    dict(connectivity=8),
    dict(use_images=False),
    dict(use_words=False),
    dict(use_images=False, use_words=False, gamma=1.7),
    dict(num_concepts=5, gamma=0.0),
]


# -- the reference against the model ---------------------------------------------------------------


@pytest.mark.parametrize(
    "variant", VARIANTS, ids=lambda v: ",".join(f"{k}={x}" for k, x in v.items())
)
def test_enumerated_conditionals_equal_model_density_differences(variant):
    cfg = config(**variant)
    grid, data = random_problem(seed=3, connectivity=cfg.connectivity)
    generator = torch.Generator().manual_seed(1)
    state = init(data, cfg, generator)
    # Every cell with observations, plus a few without.
    cells = torch.cat([data.obs_cells, torch.tensor([0, 7, data.num_free - 1])]).unique()
    assert_conditionals_match_model(state, data, cfg, cells)


@pytest.mark.parametrize("variant", VARIANTS[:4], ids=str)
def test_log_joint_equals_pyro_trace(variant):
    cfg = config(**variant)
    _, data = random_problem(seed=4, connectivity=cfg.connectivity)
    state = init(data, cfg, torch.Generator().manual_seed(2))
    torch.testing.assert_close(
        log_joint(state, data, cfg), model_log_density(state, data, cfg), atol=1e-6, rtol=1e-9
    )


# -- each backend's label draws ------------------------------------------------------------------


@pytest.mark.parametrize("variant", BLOCK_VARIANTS, ids=str)
def test_block_draws_follow_enumerated_conditionals(backend, variant):
    """The first colour block is drawn from the exact conditional given the current state."""
    # A correct sampler fails this with probability < 1e-3.
    sample_labels = backend_samplers(backend.name).labels
    assert min_block_p_value(sample_labels, config(**variant)) > 1e-3


def test_one_sweep_by_hand(backend):
    """Three cells in a row, all labelled 0; L = 2, pi = (1/2, 1/2), e^gamma = 3, no observations.

    The ends (first colour block) are drawn first, given the middle's 0: p(0) = 3 / (3 + 1) = 3/4
    each. The middle is then drawn given the new ends: p(0) = 9/10 if both are 0, 1/2 if one
    is, 1/10 if none is; in all p(0) = (9/16)(9/10) + (6/16)(1/2) + (1/16)(1/10) = 7/10.
    """
    copies = 4000
    grid, n = replicate_grid(["..."], copies)
    data = model_data(grid, np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros((0, 2)))
    cfg = config(num_concepts=2, gamma=float(np.log(3.0)), use_images=False, use_words=False)
    half = torch.full((2,), -np.log(2.0), dtype=DTYPE)  # [L] log 1/2
    state = GibbsState(
        torch.zeros(data.num_free, dtype=torch.long), half, (half.expand(2, 2), half.expand(2, 2))
    )
    plan = make_sweep_plan(data)
    ends, middle = torch.tensor([0, 2]), torch.tensor([1])
    assert set(plan.blocks[0].cells[:2].tolist()) == set(ends.tolist())  # ends first
    generator = torch.Generator().manual_seed(7)
    sample_labels = backend_samplers(backend.name).labels
    labels = torch.stack(
        [sample_labels(state, data, cfg, generator, plan).view(copies, n) for _ in range(5)]
    )  # [5, copies, 3]
    for cells, p in ((ends, 0.75), (middle, 0.7)):
        zeros = labels[:, :, cells] == 0
        z = (zeros.double().mean() - p) / np.sqrt(p * (1 - p) / zeros.numel())
        assert abs(z) < 4.0, (cells, zeros.double().mean(), z)


def test_background_draws_follow_pi_for_many_concepts(backend):
    """gamma = 0 and no modalities: every label is an independent draw from pi (here L = 37, so
    the binary search in pi's CDF takes several uneven steps)."""
    L = 37
    cfg = config(num_concepts=L, gamma=0.0, use_images=False, use_words=False)
    _, data = random_problem(seed=21, copies=200)
    pi = torch.arange(1, L + 1, dtype=DTYPE) / (L * (L + 1) / 2)  # [L] proportional to 1..L
    generator = torch.Generator().manual_seed(22)
    state = init(data, cfg, generator)._replace(log_pi=pi.log())
    plan = make_sweep_plan(data)
    sample_labels = backend_samplers(backend.name).labels
    labels = torch.cat([sample_labels(state, data, cfg, generator, plan) for _ in range(5)])
    observed = torch.bincount(labels, minlength=L).numpy()
    assert stats.chisquare(observed, pi.numpy() * labels.numel()).pvalue > 1e-3


@pytest.mark.parametrize("connectivity", [4, 8])
def test_cells_inside_a_region_follow_their_conditional(backend, connectivity):
    """A cell whose D neighbours all hold label a (the compiled sweep's short path) is drawn
    from p(l) proportional to pi_l e^{D gamma [l = a]}; L = 5, no observations, every cell 1.
    D = 8: the middle of a 5 x 5 map (that of a 3 x 3 one is not in the first colour block)."""
    L, gamma, copies = 5, 0.6, 3000
    side = 3 if connectivity == 4 else 5
    grid, n = replicate_grid(["." * side] * side, copies)
    data = model_data(grid, np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros((0, 2)),
                      connectivity)  # fmt: skip
    cfg = config(num_concepts=L, gamma=gamma, use_images=False, use_words=False,
                 connectivity=connectivity)  # fmt: skip
    pi = torch.tensor([0.1, 0.02, 0.3, 0.38, 0.2], dtype=DTYPE)  # [L]
    half = torch.full((L, 2), -np.log(2.0), dtype=DTYPE)
    state = GibbsState(torch.ones(data.num_free, dtype=torch.long), pi.log(), (half, half))
    plan = make_sweep_plan(data)
    centres = torch.arange(copies) * n + n // 2  # the middle of each copy
    assert bool(torch.isin(centres, plan.blocks[0].cells).all())  # drawn first, given the 1s
    generator = torch.Generator().manual_seed(23)
    sample_labels = backend_samplers(backend.name).labels
    drawn = torch.cat([sample_labels(state, data, cfg, generator, plan)[centres] for _ in range(3)])
    weights = pi * torch.exp(gamma * connectivity * (torch.arange(L) == 1))  # [L]
    expected = (weights / weights.sum()).numpy() * drawn.numel()
    observed = torch.bincount(drawn, minlength=L).numpy()
    assert stats.chisquare(observed, expected).pvalue > 1e-3


# -- each backend's global draws ------------------------------------------------------------------


def test_globals_follow_conjugate_posterior(backend):
    """pi | C ~ Dir(alpha/L + m), theta_l | . ~ Dir(chi + image counts of the cells labelled l),
    w_l | . ~ Dir(beta + their word counts): sample means against the closed forms."""
    cfg = config(num_concepts=4, alpha=2.0, chi=0.7, beta=1.3)
    _, data = random_problem(seed=6)
    labels = torch.tensor([0] * 10 + [1] * 5 + [3] * (data.num_free - 15))
    generator = torch.Generator().manual_seed(4)
    sample_globals = backend_samplers(backend.name).globals
    draws = []
    for _ in range(3000):
        log_pi, (log_theta, log_w) = sample_globals(labels, data, cfg, generator)
        draws.append((log_pi, log_theta, log_w))
    observed = labels[data.obs_cells].numpy()  # [M] the concepts holding the observations
    images, words = data.image_counts.numpy(), data.word_counts.numpy()
    checks = []
    for index, (base, totals) in enumerate(
        [
            (cfg.pi_concentration, np.bincount(labels.numpy(), minlength=4)[None]),
            (cfg.chi, np.stack([images[observed == l].sum(0) for l in range(4)])),
            (cfg.beta, np.stack([words[observed == l].sum(0) for l in range(4)])),
        ]
    ):
        a = base + totals  # [R, C] Dirichlet concentrations, row by row
        mean = a / a.sum(-1, keepdims=True)
        var = mean * (1 - mean) / (a.sum(-1, keepdims=True) + 1)
        sample = torch.stack([d[index].exp() for d in draws]).numpy().reshape(-1, *a.shape)
        checks.append((sample.mean(0) - mean) / np.sqrt(var / len(draws)))
    z = np.concatenate([c.ravel() for c in checks])
    # 4 + 4 K + 4 V = 32 statistics; a correct sampler stays within 4.5 sigma (p ~ 2e-4).
    assert np.abs(z).max() < 4.5, z.round(2)


def test_globals_with_switched_off_modalities_draw_from_the_prior(backend):
    cfg = config(num_concepts=3, chi=2.0, beta=0.5, use_images=False, use_words=False)
    _, data = random_problem(seed=8)
    labels = torch.zeros(data.num_free, dtype=torch.long)
    generator = torch.Generator().manual_seed(9)
    sample_globals = backend_samplers(backend.name).globals
    theta = torch.stack(
        [sample_globals(labels, data, cfg, generator)[1][0].exp() for _ in range(2000)]
    )  # [2000, L, K]
    # Dir(2, 2, 2): every component has mean 1/3 and variance (1/3)(2/3)/7, whatever the counts.
    z = (theta.mean(0) - 1 / 3) / np.sqrt((1 / 3) * (2 / 3) / 7 / theta.shape[0])
    assert z.abs().max() < 4.5, z


def test_tiny_concentrations_stay_finite_in_log_space(backend):
    """alpha / L = 1e-3: pi underflows to exact zeros in linear space but not in log space."""
    cfg = config(num_concepts=120, alpha=0.12, beta=1e-3, chi=1e-3)
    _, data = random_problem(seed=10)
    labels = torch.zeros(data.num_free, dtype=torch.long)
    generator = torch.Generator().manual_seed(11)
    sample_globals = backend_samplers(backend.name).globals
    for _ in range(20):
        log_pi, log_emissions = sample_globals(labels, data, cfg, generator)
        for log_p in (log_pi, *log_emissions):  # [L], [L, K], [L, V]
            assert torch.isfinite(log_p).all()
            torch.testing.assert_close(
                torch.logsumexp(log_p, -1), torch.zeros(log_p.shape[:-1], dtype=DTYPE)
            )
            assert log_p.min() < -700  # far below float64's exp underflow: log space matters


@pytest.mark.parametrize("shape", [0.01, 0.3, 1.0, 7.5, 1e4])
def test_log_gamma_matches_scipy(backend, shape):
    log_g = backend_samplers(backend.name).log_gamma(np.full(20000, shape), 12)  # [20000]
    assert np.isfinite(log_g).all()
    # Kolmogorov-Smirnov on log G (finite even where G underflows).
    assert stats.kstest(log_g, stats.loggamma(shape).cdf).pvalue > 1e-3


# -- the sweep as a function -----------------------------------------------------------------------


def test_sweep_is_reproducible_and_matches_the_reference_types(backend):
    cfg = config(num_concepts=5)
    _, data = random_problem(seed=13, K=6, V=7)
    start = init(data, cfg, torch.Generator().manual_seed(14))
    before = (start.labels.clone(), start.log_pi.clone(), *(t.clone() for t in start.log_emissions))
    plan = make_sweep_plan(data)

    def flat(state: GibbsState) -> tuple[torch.Tensor, ...]:
        return (state.labels, state.log_pi, *state.log_emissions)

    def run(seed: int) -> list[GibbsState]:
        generator, state, states = torch.Generator().manual_seed(seed), start, []
        for _ in range(5):
            state = backend.sweep(state, data, cfg, generator, plan, 1.0)
            states.append(state)
        return states

    first, again, other = run(15), run(15), run(16)
    for a, b in zip(first, again, strict=True):
        for x, y in zip(flat(a), flat(b), strict=True):
            assert torch.equal(x, y)
    assert not all(torch.equal(a.labels, b.labels) for a, b in zip(first, other, strict=True))
    for x, y in zip(flat(start), before, strict=True):
        assert torch.equal(x, y)  # the input state is left alone

    reference = gibbs_sweep(start, data, cfg, torch.Generator().manual_seed(17), plan)
    for state in first:
        assert len(state.log_emissions) == len(data.modalities)
        for mine, theirs in zip(flat(state), flat(reference), strict=True):
            assert mine.dtype == theirs.dtype and mine.shape == theirs.shape
        assert 0 <= int(state.labels.min()) and int(state.labels.max()) < cfg.num_concepts
    # Without a plan the sweep makes one; the same seed then gives the same draws.
    no_plan = backend.sweep(start, data, cfg, torch.Generator().manual_seed(15), None, 1.0)
    assert torch.equal(no_plan.labels, first[0].labels)
