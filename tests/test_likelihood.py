"""The inference-neutral per-cell math (spcopyro.likelihood): labels and soft assignments agree.

A label vector is the one-hot special case of soft assignments q [N, L], so every function must
give the same value for both; for genuinely soft q, the value must be the expectation under the
mean-field distribution prod_i q_i(C_i), checked by enumerating every labelling of a tiny map.
"""

from __future__ import annotations

import pytest
import torch
from gibbs_problems import all_labelings, config, model_data, random_problem, tiny_grid

from spcopyro.gibbs.sampler import init
from spcopyro.likelihood import (
    concept_statistics,
    expected_agreements,
    log_joint_constant,
    log_joint_variable,
    neighbour_field,
    observation_log_likelihood,
)
from spcopyro.model import DTYPE, potts_agreements

VARIANTS = [dict(), dict(use_images=False), dict(use_words=False), dict(connectivity=8)]


def _one_hot(labels: torch.Tensor, num_concepts: int) -> torch.Tensor:
    return torch.nn.functional.one_hot(labels, num_concepts).to(DTYPE)  # [N, L]


def _soft(num_cells: int, num_concepts: int, seed: int) -> torch.Tensor:
    """[N, L] random soft assignments (rows on the simplex)."""
    logits = torch.randn(num_cells, num_concepts, generator=torch.Generator().manual_seed(seed))
    return torch.softmax(logits.to(DTYPE), -1)


@pytest.mark.parametrize("variant", VARIANTS, ids=str)
def test_one_hot_assignments_equal_labels(variant):
    cfg = config(**variant)
    _, data = random_problem(seed=2, connectivity=cfg.connectivity)
    state = init(data, cfg, torch.Generator().manual_seed(0))
    q = _one_hot(state.labels, cfg.num_concepts)  # [N, L]

    torch.testing.assert_close(
        neighbour_field(q, data.neighbours, cfg.num_concepts),
        neighbour_field(state.labels, data.neighbours, cfg.num_concepts),
    )
    assert float(expected_agreements(q, data.pairs)) == float(
        potts_agreements(state.labels, data.pairs)
    )
    hard, soft = concept_statistics(state.labels, data, cfg), concept_statistics(q, data, cfg)
    torch.testing.assert_close(soft.cells, hard.cells)
    for soft_counts, hard_counts in zip(soft.counts, hard.counts, strict=True):
        torch.testing.assert_close(soft_counts, hard_counts)
    args = (state.log_pi, state.log_emissions, data, cfg)
    torch.testing.assert_close(
        log_joint_variable(q, *args), log_joint_variable(state.labels, *args), rtol=1e-12, atol=1e-9
    )


def test_neighbour_field_by_hand():
    """Cell 4 is the centre of a 3 x 3 free map: its field is the sum of its 4 neighbours' q."""
    grid = tiny_grid(["...", "...", "..."])
    data = model_data(grid, [0], [[1.0]], [[1.0]])
    q = _soft(9, 3, seed=1)  # [9, 3]
    field = neighbour_field(q, data.neighbours, 3)  # [9, 3]
    torch.testing.assert_close(field[4], q[1] + q[3] + q[5] + q[7])
    torch.testing.assert_close(field[0], q[1] + q[3])  # a corner has two neighbours


@pytest.mark.parametrize("variant", VARIANTS[:3], ids=str)
def test_soft_values_are_mean_field_expectations(variant):
    """E over C ~ prod_i q_i of the labels' log joint (and statistics) == the soft value."""
    cfg = config(num_concepts=2, **variant)
    grid = tiny_grid(["...", "..#", "..."])  # 8 free cells: 2^8 labellings
    data = model_data(grid, [0, 4, 7], [[1.0, 2.0], [0.5, 0.0], [3.0, 1.0]], [[1.0, 0.0, 2.0]] * 3)
    state = init(data, cfg, torch.Generator().manual_seed(3))
    q = _soft(data.num_free, 2, seed=4)  # [N, 2]
    labelings = all_labelings(data.num_free, 2)  # [2^N, N]
    weights = q[torch.arange(data.num_free), labelings].prod(-1)  # [2^N] prod_i q_i(C_i)
    assert float(weights.sum()) == pytest.approx(1.0)

    args = (state.log_pi, state.log_emissions, data, cfg)
    values = torch.stack([log_joint_variable(c, *args) for c in labelings])  # [2^N]
    torch.testing.assert_close(
        log_joint_variable(q, *args), (weights * values).sum(), rtol=1e-12, atol=1e-9
    )
    agreements = torch.stack([potts_agreements(c, data.pairs) for c in labelings])
    torch.testing.assert_close(expected_agreements(q, data.pairs), (weights * agreements).sum())
    soft = concept_statistics(q, data, cfg)
    for modality, expected_counts in enumerate(soft.counts):
        per_labelling = torch.stack(
            [concept_statistics(c, data, cfg).counts[modality] for c in labelings]
        )  # [2^N, L, K_m]
        torch.testing.assert_close(expected_counts, (weights[:, None, None] * per_labelling).sum(0))


def test_observation_log_likelihood_by_hand_and_switches():
    cfg = config()
    _, data = random_problem(seed=5)
    state = init(data, cfg, torch.Generator().manual_seed(1))
    loglik = observation_log_likelihood(state.log_emissions, data, cfg)  # [M, L]
    expected = data.image_counts @ state.log_theta.T + data.word_counts @ state.log_w.T
    torch.testing.assert_close(loglik, expected)
    images_only = observation_log_likelihood(
        state.log_emissions, data, cfg.replace(use_words=False)
    )
    torch.testing.assert_close(images_only, data.image_counts @ state.log_theta.T)
    with pytest.raises(ValueError, match="2 modalities"):
        observation_log_likelihood(state.log_emissions[:1], data, cfg)


def test_shapes_are_checked():
    cfg = config()
    _, data = random_problem(seed=5)
    with pytest.raises(ValueError, match=r"\[N, L\]"):
        neighbour_field(torch.zeros(3, dtype=DTYPE), data.neighbours, 3)
    with pytest.raises(ValueError, match=r"\[N\]"):
        concept_statistics(torch.zeros(3, 2, dtype=torch.long), data, cfg)


def test_log_joint_constant_needs_no_state():
    """The constant depends on the data and hyperparameters only (Dirichlet normalisers and
    multinomial coefficients); switching a modality off drops its coefficients, not its prior."""
    cfg = config()
    _, data = random_problem(seed=6)
    full = log_joint_constant(data, cfg)
    no_words = log_joint_constant(data, cfg.replace(use_words=False))
    assert torch.isfinite(full) and float(full) != float(no_words)


def _graph_ops(tensor: torch.Tensor) -> set[str]:
    """The names of the autograd nodes behind ``tensor``."""
    seen, stack = set(), [tensor.grad_fn]
    while stack:
        node = stack.pop()
        if node is None or node in seen:
            continue
        seen.add(node)
        stack.extend(next_node for next_node, _ in node.next_functions)
    return {type(node).__name__ for node in seen}


@pytest.mark.parametrize("connectivity", [4, 8])
def test_expected_agreements_gradient_is_an_index_add_with_the_same_bits(connectivity):
    """SVI differentiates E_q[E(C)] through q [N, L] every step: its backward scatters [P, L]
    rows into [N, L]. Gathered by index_select that is an index_add_ (IndexSelectBackward0),
    not advanced indexing's slower index_put_ with accumulate (IndexBackward0: about 25 ms a
    step of SVI on room1dk5, 2026-12-06); rows are added in the same order, so value and
    gradient keep every bit of the advanced-indexing form (seeded SVI fits unchanged)."""
    _, data = random_problem(seed=4, connectivity=connectivity)
    q = _soft(data.num_free, 7, seed=5)  # [N, L]
    mine, theirs = q.clone().requires_grad_(), q.clone().requires_grad_()
    value = expected_agreements(mine, data.pairs)
    indexed = (theirs[data.pairs[:, 0]] * theirs[data.pairs[:, 1]]).sum().to(DTYPE)
    (3.7 * value).backward()
    (3.7 * indexed).backward()
    assert torch.equal(value, indexed) and torch.equal(mine.grad, theirs.grad)
    assert "IndexSelectBackward0" in _graph_ops(value)
    assert "IndexBackward0" not in _graph_ops(value)
