"""The lean compiled label loop's own bookkeeping (spcopyro.gibbs.numba_labels): its layout, the
alias table it draws pi from, the compact label types, and the E(C) and concept sizes a sweep
hands to the run loop's log joint. Its *distribution* is judged with the torch reference's by the
``backend`` tests (test_gibbs_conditionals.py, test_gibbs_joint.py, test_backends_agree.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

pytest.importorskip("numba")

from gibbs_problems import config, random_problem  # noqa: E402
from scipy import stats  # noqa: E402

from spcopyro.gibbs.numba_labels import (  # noqa: E402
    alias_table,
    compact_label_dtype,
    label_plan,
)
from spcopyro.gibbs.numba_sweep import (  # noqa: E402
    gibbs_sweep_numba,
    label_counts_numba,
    potts_agreements_numba,
    sample_labels_numba,
)
from spcopyro.gibbs.sampler import init  # noqa: E402
from spcopyro.gibbs.state import make_sweep_plan  # noqa: E402
from spcopyro.model import potts_agreements  # noqa: E402


def _alias_probabilities(keep: np.ndarray, alias: np.ndarray) -> np.ndarray:
    """What an alias table draws: (keep[i] + sum_{j: alias[j] = i} (1 - keep[j])) / L."""
    L = keep.shape[0]
    p = keep.copy()
    np.add.at(p, alias, 1.0 - keep)
    return p / L


@pytest.mark.parametrize("seed", range(5))
def test_alias_table_draws_the_weights(seed):
    rng = np.random.default_rng(seed)
    L = int(rng.integers(1, 300))
    weights = rng.gamma(0.3, size=L) * (rng.random(L) < 0.7)  # some exact zeros
    weights[rng.integers(L)] += 1.0  # not all zero
    keep, alias = np.empty(L), np.empty(L, dtype=np.int64)
    alias_table(weights, keep, alias)
    assert ((keep >= 0) & (keep <= 1)).all() and ((alias >= 0) & (alias < L)).all()
    np.testing.assert_allclose(
        _alias_probabilities(keep, alias), weights / weights.sum(), atol=1e-12
    )
    assert (_alias_probabilities(keep, alias)[weights == 0] < 1e-12).all()


@pytest.mark.parametrize("connectivity", [4, 8])
def test_label_plan_visits_every_cell_once_block_by_block(connectivity):
    _, data = random_problem(seed=5, connectivity=connectivity, copies=3)
    plan = make_sweep_plan(data)
    layout = label_plan(plan, data)
    N, M = data.num_free, data.obs_cells.shape[0]
    assert sorted(layout.order.tolist()) == list(range(N))
    assert layout.segments[0] == 0 and layout.segments[-1] == N
    assert len(layout.segments) == 2 * len(plan.blocks) + 1
    for b, block in enumerate(plan.blocks):
        unobserved = slice(layout.segments[2 * b], layout.segments[2 * b + 1])
        observed = slice(layout.segments[2 * b + 1], layout.segments[2 * b + 2])
        cells = np.concatenate([layout.order[unobserved], layout.order[observed]])
        assert set(cells.tolist()) == set(block.cells.tolist())
        assert (layout.rows[unobserved] == M).all()
        rows = data.observation_rows().numpy()
        np.testing.assert_array_equal(layout.rows[observed], rows[layout.order[observed]])
    neighbours = data.neighbours.numpy()[layout.order]  # [N, D], -1 where missing
    expected = np.where(neighbours >= 0, neighbours, N + np.arange(neighbours.shape[1]))
    np.testing.assert_array_equal(layout.neighbours, expected)
    assert label_plan(plan, data) is layout  # cached per plan


@pytest.mark.parametrize(
    ("connectivity", "num_concepts", "dtype"),
    [(4, 3, np.uint8), (8, 6, np.uint8), (4, 300, np.uint16), (8, 300, np.uint16)],
)
def test_the_sweep_counts_agreements_and_concept_sizes_of_what_it_leaves(
    connectivity, num_concepts, dtype
):
    """E(C) from the sweep equals the reference's count on the new labels (every pair counted once,
    at its later cell, whatever the colouring), for compact labels of either width."""
    assert compact_label_dtype(num_concepts, connectivity) is dtype
    cfg = config(connectivity=connectivity, num_concepts=num_concepts, gamma=1.0)
    _, data = random_problem(seed=6, connectivity=connectivity, copies=4)
    generator = torch.Generator().manual_seed(3)
    state = init(data, cfg, generator)
    plan = make_sweep_plan(data)
    for _ in range(4):
        state = gibbs_sweep_numba(state, data, cfg, generator, plan)
        expected = potts_agreements(state.labels, data.pairs)
        assert float(potts_agreements_numba(state.labels, data.pairs)) == float(expected)
        torch.testing.assert_close(
            label_counts_numba(state.labels, num_concepts),
            torch.bincount(state.labels, minlength=num_concepts),
        )


def test_remembered_facts_are_dropped_when_the_labels_change_in_place():
    cfg = config(num_concepts=4, gamma=2.0)
    _, data = random_problem(seed=7, copies=2)
    generator = torch.Generator().manual_seed(4)
    state = gibbs_sweep_numba(init(data, cfg, generator), data, cfg, generator)
    labels = state.labels
    labels[: data.num_free // 2] = (labels[: data.num_free // 2] + 1) % 4  # in place
    assert float(potts_agreements_numba(labels, data.pairs)) == float(
        potts_agreements(labels, data.pairs)
    )
    torch.testing.assert_close(label_counts_numba(labels, 4), torch.bincount(labels, minlength=4))
    other_pairs = data.pairs[:3].clone()
    fresh = gibbs_sweep_numba(state._replace(labels=labels.clone()), data, cfg, generator)
    assert float(potts_agreements_numba(fresh.labels, other_pairs)) == float(
        potts_agreements(fresh.labels, other_pairs)
    )


def test_wide_labels_draw_pi_through_the_alias_table():
    """L = 300 (uint16 labels), gamma = 0, no modalities: every label is a draw from pi."""
    L = 300
    cfg = config(num_concepts=L, gamma=0.0, use_images=False, use_words=False)
    _, data = random_problem(seed=8, copies=150)
    pi = torch.arange(1, L + 1, dtype=torch.float64) ** 2
    pi = pi / pi.sum()
    generator = torch.Generator().manual_seed(9)
    state = init(data, cfg, generator)._replace(log_pi=pi.log())
    plan = make_sweep_plan(data)
    labels = torch.cat([sample_labels_numba(state, data, cfg, generator, plan) for _ in range(6)])
    observed = torch.bincount(labels, minlength=L).numpy()
    assert stats.chisquare(observed, pi.numpy() * labels.numel()).pvalue > 1e-3


@pytest.mark.parametrize(
    "variant",
    [dict(prior="dp"), dict(prior="dirichlet", alpha=2.0), dict(use_words=False), dict(gamma=0.0)],
    ids=str,
)
def test_compiled_trace_equals_the_reference(variant):
    """The run loop's per-sweep record on the numba backend (from what the sweep counted, and
    recounted after a change in place) against the torch backend's (likelihood.log_joint_variable
    and a bincount)."""
    from spcopyro.gibbs.backends import get_backend

    cfg = config(**variant)
    _, data = random_problem(seed=10, copies=3)
    generator = torch.Generator().manual_seed(5)
    state = gibbs_sweep_numba(init(data, cfg, generator), data, cfg, generator)
    torch_backend, numba_backend = get_backend("torch"), get_backend("numba")

    def agree(config_) -> None:
        expected, concepts = torch_backend.trace(state, data, config_)
        value, counted = numba_backend.trace(state, data, config_)
        assert value == pytest.approx(expected, rel=1e-12, abs=1e-9) and counted == concepts

    agree(cfg)  # what the sweep recorded
    agree(dataclasses.replace(cfg, gamma=cfg.gamma + 0.5))  # the chain's gamma after annealing
    agree(dataclasses.replace(cfg, chi=cfg.chi + 1.0))  # other hyperparameters: recomputed
    state.log_pi.add_(0.01)  # in place: recomputed
    agree(cfg)
    state.labels[:5] = (state.labels[:5] + 1) % cfg.num_concepts  # in place: recounted
    agree(cfg)
