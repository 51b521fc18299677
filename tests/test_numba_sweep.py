"""The compiled (numba) sweep samples the same conditionals as the torch reference.

Its random numbers differ from the reference's, so everything here is distributional: per-cell
chi-square tests of the label draws against the enumerated conditionals, conjugate means of the
globals, KS tests of the log-gamma draws, and Geweke's joint test with the numba sweep inside.
"""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest
import torch

pytest.importorskip("numba")

from gibbs_problems import config, model_data, random_problem, replicate_grid  # noqa: E402
from scipy import stats  # noqa: E402
from test_gibbs_conditionals import BLOCK_VARIANTS, min_block_p_value  # noqa: E402
from test_gibbs_joint import (  # noqa: E402
    GEWEKE_VARIANTS,
    Z_LIMIT,
    draw_counts,
    geweke_z_scores,
)

from spcopyro.gibbs.backends import sweep_function  # noqa: E402
from spcopyro.gibbs.init import initial_state  # noqa: E402
from spcopyro.gibbs.numba_sweep import (  # noqa: E402
    gibbs_sweep_numba,
    sample_globals_numba,
    sample_labels_numba,
    sample_log_gamma_numba,
    sample_standard_normal_numba,
)
from spcopyro.gibbs.state import GibbsState, make_sweep_plan  # noqa: E402
from spcopyro.gibbs.sweep import gibbs_sweep  # noqa: E402
from spcopyro.model import DTYPE  # noqa: E402


@pytest.mark.parametrize("variant", BLOCK_VARIANTS, ids=str)
def test_block_draws_follow_enumerated_conditionals(variant):
    """The reference's chi-square test of the first colour block, with the numba label step."""
    assert min_block_p_value(sample_labels_numba, config(**variant)) > 1e-3


def test_one_sweep_by_hand():
    """Three cells in a row, all labelled 0; L = 2, pi = (1/2, 1/2), e^gamma = 3, no observations.

    The ends (first colour block) are drawn first, given the middle's 0: p(0) = 3 / (3 + 1) = 3/4
    each. The middle is then drawn given the new ends: p(0) = 9/10 if both are 0, 1/2 if one
    is, 1/10 if none is; in all p(0) = (9/16)(9/10) + (6/16)(1/2) + (1/16)(1/10) = 7/10.
    """
    copies = 4000
    grid, n = replicate_grid(["..."], copies)
    data = model_data(grid, np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros((0, 2)))
    cfg = config(num_concepts=2, gamma=float(np.log(3.0)), use_images=False, use_words=False)
    half = torch.full((2,), -np.log(2.0), dtype=DTYPE)
    state = GibbsState(
        torch.zeros(data.num_free, dtype=torch.long), half, half.expand(2, 2), half.expand(2, 2)
    )
    plan = make_sweep_plan(data)
    ends, middle = torch.tensor([0, 2]), torch.tensor([1])
    assert set(plan.blocks[0].cells[:2].tolist()) == set(ends.tolist())  # ends first
    generator = torch.Generator().manual_seed(7)
    labels = torch.stack(
        [sample_labels_numba(state, data, cfg, generator, plan).view(copies, n) for _ in range(5)]
    )  # [5, copies, 3]
    for cells, p in ((ends, 0.75), (middle, 0.7)):
        zeros = labels[:, :, cells] == 0
        z = (zeros.double().mean() - p) / np.sqrt(p * (1 - p) / zeros.numel())
        assert abs(z) < 4.0, (cells, zeros.double().mean(), z)


def test_background_draws_follow_pi_for_many_concepts():
    """gamma = 0 and no modalities: every label is an independent draw from pi (here L = 37, so
    the binary search in pi's CDF takes several uneven steps)."""
    L = 37
    cfg = config(num_concepts=L, gamma=0.0, use_images=False, use_words=False)
    _, data = random_problem(seed=21, copies=200)
    pi = torch.arange(1, L + 1, dtype=DTYPE) / (L * (L + 1) / 2)  # [L] proportional to 1..L
    generator = torch.Generator().manual_seed(22)
    state = initial_state(data, cfg, generator)._replace(log_pi=pi.log())
    plan = make_sweep_plan(data)
    labels = torch.cat([sample_labels_numba(state, data, cfg, generator, plan) for _ in range(5)])
    observed = torch.bincount(labels, minlength=L).numpy()
    assert stats.chisquare(observed, pi.numpy() * labels.numel()).pvalue > 1e-3


def test_globals_follow_conjugate_posterior():
    """pi | C ~ Dir(alpha/L + m), theta_l | . ~ Dir(chi + image counts of the cells labelled l),
    w_l | . ~ Dir(beta + their word counts): sample means against the closed forms."""
    cfg = config(num_concepts=4, alpha=2.0, chi=0.7, beta=1.3)
    _, data = random_problem(seed=6)
    labels = torch.tensor([0] * 10 + [1] * 5 + [3] * (data.num_free - 15))
    generator = torch.Generator().manual_seed(4)
    draws = [sample_globals_numba(labels, data, cfg, generator) for _ in range(3000)]
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


def test_globals_with_switched_off_modalities_draw_from_the_prior():
    cfg = config(num_concepts=3, chi=2.0, beta=0.5, use_images=False, use_words=False)
    _, data = random_problem(seed=8)
    labels = torch.zeros(data.num_free, dtype=torch.long)
    generator = torch.Generator().manual_seed(9)
    theta = torch.stack([sample_globals_numba(labels, data, cfg, generator)[1].exp()])
    for _ in range(1999):
        theta = torch.cat(
            [theta, sample_globals_numba(labels, data, cfg, generator)[1].exp()[None]]
        )
    # Dir(2, 2, 2): every component has mean 1/3 and variance (1/3)(2/3)/7, whatever the counts.
    z = (theta.mean(0) - 1 / 3) / np.sqrt((1 / 3) * (2 / 3) / 7 / theta.shape[0])
    assert z.abs().max() < 4.5, z


def test_tiny_concentrations_stay_finite_in_log_space():
    """alpha / L = 1e-3: pi underflows to exact zeros in linear space but not in log space."""
    cfg = config(num_concepts=120, alpha=0.12, beta=1e-3, chi=1e-3)
    _, data = random_problem(seed=10)
    labels = torch.zeros(data.num_free, dtype=torch.long)
    generator = torch.Generator().manual_seed(11)
    for _ in range(20):
        for log_p in sample_globals_numba(labels, data, cfg, generator):
            assert torch.isfinite(log_p).all()
            torch.testing.assert_close(
                torch.logsumexp(log_p, -1), torch.zeros(log_p.shape[:-1], dtype=DTYPE)
            )
            assert log_p.min() < -700  # far below float64's exp underflow: log space matters


@pytest.mark.parametrize("shape", [0.01, 0.3, 1.0, 7.5, 1e4])
def test_log_gamma_matches_scipy(shape):
    log_g = sample_log_gamma_numba(np.full(20000, shape), seed=12)
    assert np.isfinite(log_g).all()
    # Kolmogorov-Smirnov on log G (finite even where G underflows).
    assert stats.kstest(log_g, stats.loggamma(shape).cdf).pvalue > 1e-3


def test_ziggurat_normals_match_the_normal_distribution_tails_included():
    z = sample_standard_normal_numba(2_000_000, seed=20)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    # The ziggurat's base strip and tail (|z| > 3.4426) are separate code paths: count them.
    for lo, hi in ((3.4426, np.inf), (-np.inf, -3.4426), (2.0, 3.4426), (-3.4426, -2.0)):
        p = stats.norm.cdf(hi) - stats.norm.cdf(lo)
        hits = ((z > lo) & (z < hi)).sum()
        assert abs(hits - p * z.size) < 4.5 * np.sqrt(p * z.size), (lo, hi, hits, p * z.size)


def test_sweep_is_reproducible_and_matches_the_reference_types():
    cfg = config(num_concepts=5)
    _, data = random_problem(seed=13, K=6, V=7)
    start = initial_state(data, cfg, torch.Generator().manual_seed(14))
    before = tuple(x.clone() for x in start)
    plan = make_sweep_plan(data)

    def run(seed: int) -> list[GibbsState]:
        generator, state, states = torch.Generator().manual_seed(seed), start, []
        for _ in range(5):
            state = gibbs_sweep_numba(state, data, cfg, generator, plan)
            states.append(state)
        return states

    first, again, other = run(15), run(15), run(16)
    for a, b in zip(first, again, strict=True):
        for x, y in zip(a, b, strict=True):
            assert torch.equal(x, y)
    assert not all(torch.equal(a.labels, b.labels) for a, b in zip(first, other, strict=True))
    for x, y in zip(start, before, strict=True):
        assert torch.equal(x, y)  # the input state is left alone

    reference = gibbs_sweep(start, data, cfg, torch.Generator().manual_seed(17), plan)
    for state in first:
        for mine, theirs in zip(state, reference, strict=True):
            assert mine.dtype == theirs.dtype and mine.shape == theirs.shape
        assert 0 <= int(state.labels.min()) and int(state.labels.max()) < cfg.num_concepts
    # Without a plan the sweep makes one; the same seed then gives the same draws.
    no_plan = gibbs_sweep_numba(start, data, cfg, torch.Generator().manual_seed(15))
    assert torch.equal(no_plan.labels, first[0].labels)


def test_invalid_input_raises_clear_errors():
    cfg = config()
    _, data = random_problem(seed=18)
    generator = torch.Generator().manual_seed(19)
    state = initial_state(data, cfg, generator)
    bad = state.labels.clone()
    bad[4] = cfg.num_concepts
    with pytest.raises(ValueError, match=r"labels\[4\] = 3 lies outside \[0, 3\)"):
        gibbs_sweep_numba(state._replace(labels=bad), data, cfg, generator)
    with pytest.raises(ValueError, match="log_theta has shape"):
        gibbs_sweep_numba(state._replace(log_theta=state.log_theta[:, :1]), data, cfg, generator)
    _, other = random_problem(seed=18, num_observed=4)
    with pytest.raises(ValueError, match="observed rows do not match"):
        gibbs_sweep_numba(state, data, cfg, generator, make_sweep_plan(other))
    with pytest.raises(ValueError, match=r"gamma \* connectivity must be <= 700"):
        cfg.replace(gamma=200.0)  # exp(gamma D) would overflow: the config refuses it
    nan_words = data._replace(word_counts=data.word_counts * float("nan"))
    with pytest.raises(ValueError, match="log-likelihood is not finite"):
        gibbs_sweep_numba(state, nan_words, cfg, generator)
    negative = data._replace(image_counts=-10.0 * data.image_counts)  # chi = 1: Dir(< 0)
    with pytest.raises(ValueError, match=r"concentration of theta\[\d+, \d+\] is -"):
        sample_globals_numba(state.labels, negative, cfg, generator)


def test_backend_choice_and_import_error_without_numba(monkeypatch):
    assert sweep_function("numba") is gibbs_sweep_numba
    assert sweep_function("auto") is gibbs_sweep_numba
    monkeypatch.setitem(sys.modules, "numba", None)  # as if numba were not installed
    monkeypatch.delitem(sys.modules, "spcopyro.gibbs.numba_sweep")
    with pytest.raises(ImportError):
        importlib.import_module("spcopyro.gibbs.numba_sweep")
    assert sweep_function("auto") is gibbs_sweep
    with pytest.raises(ImportError, match="needs the numba package"):
        sweep_function("numba")


@pytest.mark.slow
@pytest.mark.parametrize(
    "variant",
    [*GEWEKE_VARIANTS, dict(connectivity=8, gamma=0.7)],
    ids=str,
)
def test_geweke_getting_it_right(variant):
    """Geweke's test of tests/test_gibbs_joint.py with the numba sweep as the kernel; both halves
    draw their data with the independent ``draw_counts`` (not the model)."""

    def redraw(state, world, cfg, generator):
        c = state.labels[world.obs_cells][None]  # [1, M]
        return world._replace(
            image_counts=draw_counts(state.log_theta[c], world.image_counts.sum(-1), generator)[0],
            word_counts=draw_counts(state.log_w[c], world.word_counts.sum(-1), generator)[0],
        )

    z = geweke_z_scores(config(**variant), gibbs_sweep_numba, redraw)
    assert z.abs().max() < Z_LIMIT, f"z-scores {z.numpy().round(2)}"
