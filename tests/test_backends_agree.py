"""The two sweep backends against each other: one full step from the same state, many times.

Each backend is tested against exact conditionals elsewhere; this two-sample test compares them
directly on the whole step (cluster move, labels, partial refresh of the globals), where the two
are written differently (the torch reference's mixture sampler and block loop, the compiled
kernel's background table and its own random numbers). From one fixed state, R independent steps
per backend; per cell, the label counts form a 2 x L contingency table (chi-square test of
homogeneity); per global summary, a two-sample Kolmogorov-Smirnov test; Bonferroni over all.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem
from scipy import stats

from spcopyro.gibbs import GibbsOptions
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.sampler import init, step
from spcopyro.gibbs.state import make_sweep_plan

pytest.importorskip("numba")

STEPS = 300
OPTIONS = [
    GibbsOptions(),
    GibbsOptions(cluster_moves=1.0),
    GibbsOptions(unobserved_refresh=0.3),
]


def _steps(name: str, state, data, cfg, options: GibbsOptions, seed: int):
    """R one-step draws from ``state``: labels [R, N] and global summaries [R, 4]."""
    backend = get_backend(name)
    plan = make_sweep_plan(data)
    generator = torch.Generator().manual_seed(seed)
    labels, summaries = [], []
    for _ in range(STEPS):
        new, _ = step(
            state, data, cfg, generator, options=options, backend=backend, plan=plan
        )  # fmt: skip
        labels.append(new.labels)
        summaries.append(
            torch.stack(
                [new.log_pi[0], new.log_theta[1, 0], new.log_w[0, 2], new.log_w[2].exp().max()]
            )
        )
    return torch.stack(labels).numpy(), torch.stack(summaries).numpy()


def _min_p_value(first, second, num_concepts: int) -> float:
    (labels_a, globals_a), (labels_b, globals_b) = first, second
    p_values = []
    for cell in range(labels_a.shape[1]):
        table = np.stack(
            [np.bincount(labels_a[:, cell], minlength=num_concepts),
             np.bincount(labels_b[:, cell], minlength=num_concepts)]
        )  # fmt: skip  # [2, L]
        table = table[:, table.sum(0) > 0]
        if table.shape[1] > 1:
            p_values.append(stats.chi2_contingency(table).pvalue)
    for k in range(globals_a.shape[1]):
        p_values.append(stats.ks_2samp(globals_a[:, k], globals_b[:, k]).pvalue)
    return min(p_values) * len(p_values)


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: f"moves={o.cluster_moves},"
                         f"refresh={o.unobserved_refresh}")  # fmt: skip
def test_one_step_from_one_state_has_one_distribution(options):
    cfg = config(gamma=1.3)
    _, data = random_problem(seed=8)
    state = init(data, cfg, torch.Generator().manual_seed(4))
    torch_draws = _steps("torch", state, data, cfg, options, seed=1)
    numba_draws = _steps("numba", state, data, cfg, options, seed=2)
    # A correct pair of backends fails with probability < 1e-3.
    assert _min_p_value(torch_draws, numba_draws, cfg.num_concepts) > 1e-3


def test_the_two_sample_test_sees_a_different_coupling():
    """Its power: the same backend under gamma 1.3 and gamma 0.3 is told apart."""
    _, data = random_problem(seed=8)
    cfg = config(gamma=1.3)
    state = init(data, cfg, torch.Generator().manual_seed(4))
    strong = _steps("numba", state, data, cfg, GibbsOptions(), seed=1)
    weak = _steps("numba", state, data, cfg.replace(gamma=0.3), GibbsOptions(), seed=2)
    assert _min_p_value(strong, weak, cfg.num_concepts) < 1e-3
