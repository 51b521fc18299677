"""The split-merge move (spcopyro.gibbs.merge): its target, its exactness, and its composition.

* The collapsed target p(C | x) it uses equals the model's: log p(C, pi, theta, w, x) minus the
  log densities of the conjugate conditionals p(pi, theta, w | C, x) is log p(C | x) plus one
  constant for every C (the "candidate's formula"), checked against the Pyro-tested log joint.
* Exactness by enumeration: labelings drawn from the enumerated p(C | x) of a 6-cell map stay so
  distributed after split-merge moves (invariance needs no irreducibility, so the move runs on
  its own). Chi-square on the states, p > 1e-3. Power: the same test with the proposal terms
  left out of the acceptance ratio (as if the proposal were symmetric) fails it, shown by
  ``test_a_broken_acceptance_ratio_is_detected`` (800 copies, 2 moves each: the broken ratio's
  p-value underflows to 0.0; the exact move's was 0.39 with these seeds).
* The same with a third modality (object counts), both backends, p(C | x) from the enumerator's
  log evidence (spcopyro.guides.testing) rather than the move's own target.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from gibbs_problems import (
    all_labelings,
    config,
    model_data,
    random_problem,
    replicate_grid,
    state_index,
    without_words,
)
from statistical_checks import pooled_chisquare_p
from test_modalities import OBJECTS, with_objects

import spcopyro.gibbs.merge as merge
from spcopyro.gibbs.merge import (
    collapsed_log_posterior,
    maybe_merge_move,
    merge_move,
    split_merge_labels,
)
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.sampler import init, step
from spcopyro.gibbs.sweep import gibbs_sweep, log_joint
from spcopyro.guides.testing import labelling_log_evidence
from spcopyro.likelihood import concept_statistics
from spcopyro.model import DTYPE

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors


def _tiny_problem():
    cfg = config(gamma=0.8, num_concepts=3, alpha=3.0, beta=0.5, chi=0.5)
    grid, n = replicate_grid(["...", "..."], 1)
    images = np.array([[3.0, 0.5], [0.0, 3.0], [2.0, 1.0]])
    words = np.array([[2.0, 0, 0], [0, 0, 2.0], [1.0, 1.0, 0]])
    return cfg, n, model_data(grid, np.array([0, 2, 4]), images, words)


def _four_concept_problem():
    """A 2 x 2 map, L = 4 (4^4 = 256 labelings): a split can choose among up to Z = 3 empty
    labels, which L = 3 never offers (one concept leaves 2), and a merge of a state with every
    label in use has Z(C') = 1."""
    cfg = config(gamma=1.5, num_concepts=4, alpha=2.0, beta=0.5, chi=0.5)
    grid, n = replicate_grid(["..", ".."], 1)
    images = np.array([[3.0, 0.5], [0.0, 3.0], [2.0, 1.0]])
    words = np.array([[2.0, 0, 0], [0, 0, 2.0], [1.0, 1.0, 0]])
    return cfg, n, model_data(grid, np.array([0, 1, 3]), images, words)


def _objects_problem():
    """:func:`_tiny_problem` with a third modality: tests/test_modalities.py's object counts
    (Poisson(3) at the 3 observed cells, concentration 0.7), which move the enumerated
    p(C | x) by 0.64 in total variation."""
    cfg, n, data = _tiny_problem()
    grid, _ = replicate_grid(["...", "..."], 1)
    return cfg.replace(concentrations={OBJECTS: 0.7}), n, with_objects(grid, data, scale=3.0)


def _log_dirichlet(log_p: torch.Tensor, concentration: torch.Tensor) -> torch.Tensor:
    """sum over rows of log Dir(p; concentration) at p = exp(log_p) (rows of [..., K])."""
    normaliser = torch.lgamma(concentration.sum(-1)) - torch.lgamma(concentration).sum(-1)
    return (normaliser + ((concentration - 1) * log_p).sum(-1)).sum()


@pytest.mark.parametrize("problem", [_tiny_problem, _objects_problem], ids=["two", "objects"])
def test_collapsed_target_is_the_models_marginal(problem):
    cfg, n, data = problem()
    generator = torch.Generator().manual_seed(3)
    state = init(data, cfg, generator)
    differences = []
    for labels in all_labelings(n, 3)[::37]:
        stats_ = concept_statistics(labels, data, cfg)
        conditional = _log_dirichlet(state.log_pi, cfg.pi_concentration + stats_.cells)
        for m, log_phi, counts in zip(
            data.modalities, state.log_emissions, stats_.counts, strict=True
        ):
            conditional = conditional + _log_dirichlet(log_phi, cfg.concentration(m.name) + counts)
        joint = log_joint(state._replace(labels=labels), data, cfg)
        differences.append(float(joint - conditional) - collapsed_log_posterior(labels, data, cfg))
    assert np.ptp(differences) < 1e-9, differences


def _invariance_p_value(
    generator_seed: int,
    copies: int,
    moves: int,
    compiled: bool = False,
    no_words: bool = False,
    problem=_tiny_problem,
    evidence: bool = False,
) -> float:
    """p-value of the chi-square of ``copies`` labelings drawn from the enumerated p(C | x), each
    moved ``moves`` times. ``evidence``: p(C | x) from the enumerator's log evidence
    (spcopyro.guides.testing, checked against the Pyro model in test_exact_tiny_maps), not from
    the move's own collapsed_log_posterior, whose modalities are the move's."""
    cfg, n, data = problem()
    data = without_words(data) if no_words else data
    labelings = all_labelings(n, cfg.num_concepts)
    if evidence:
        log_p = labelling_log_evidence(labelings, data, cfg)  # [L^n]
    else:
        log_p = torch.tensor(
            [collapsed_log_posterior(lab, data, cfg) for lab in labelings], dtype=DTYPE
        )
    exact = torch.softmax(log_p, 0)
    generator = torch.Generator().manual_seed(generator_seed)
    start = torch.multinomial(exact, copies, replacement=True, generator=generator)
    final = []
    for index in start:
        labels = labelings[index].clone()
        for _ in range(moves):
            labels, _ = split_merge_labels(labels, data, cfg, generator, 1, compiled)
        final.append(labels)
    observed = torch.bincount(state_index(torch.stack(final), cfg.num_concepts),
                              minlength=len(labelings)).double()  # fmt: skip
    return pooled_chisquare_p(observed, exact)


@pytest.mark.slow
@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_split_merge_leaves_the_enumerated_posterior_invariant(compiled):
    """Both implementations of the launch and scans (the numba backend's chains use the
    compiled one)."""
    if compiled:
        pytest.importorskip("numba")
    p_value = _invariance_p_value(5, copies=800, moves=2, compiled=compiled)
    assert p_value > 1e-3, p_value


@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_a_house_of_images_only_keeps_its_target_and_its_moves(compiled):
    """Words with V = 0 items: the collapsed target is the enumerator's log evidence (an
    independent reference) up to one constant, and split-merge and region moves are accepted on
    both backends. Was: the target was nan (lgamma(0) - lgamma(0)), so no move was accepted."""
    from spcopyro.gibbs.region_move import region_move
    from spcopyro.guides.testing import labelling_log_evidence

    if compiled:
        pytest.importorskip("numba")
    cfg, n, data = _tiny_problem()
    data = without_words(data)
    labelings = all_labelings(n, cfg.num_concepts)[::7]
    evidence = labelling_log_evidence(labelings, data, cfg)
    ours = torch.tensor([collapsed_log_posterior(lab, data, cfg) for lab in labelings], dtype=DTYPE)
    assert torch.isfinite(ours).all()
    assert float(torch.max(ours - evidence) - torch.min(ours - evidence)) < 1e-9
    state = init(data, cfg, torch.Generator().manual_seed(3))
    accepted = {"merge": 0, "region": 0}
    for seed in range(40):
        generator = torch.Generator().manual_seed(seed)
        accepted["merge"] += merge_move(state, data, cfg, generator, compiled=compiled)[1].accepted
        accepted["region"] += region_move(state, data, cfg, generator, compiled=compiled)[
            1
        ].accepted
    assert min(accepted.values()) > 0, accepted


@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_split_merge_leaves_the_posterior_of_images_only_invariant(compiled):
    if compiled:
        pytest.importorskip("numba")
    p_value = _invariance_p_value(5, copies=800, moves=2, compiled=compiled, no_words=True)
    assert p_value > 1e-3, p_value


@pytest.mark.slow
@pytest.mark.parametrize("no_words", [False, True], ids=["words", "no-words"])
@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_split_merge_keeps_the_enumerated_posterior_with_four_concepts(compiled, no_words):
    """L = 4 on a 2 x 2 map (the test above is L = 3 only): the empty-label term log Z of the
    ratio at Z = 3, and a house of images only (words of V = 0 items) on both backends. Power:
    with the proposal terms left out of the ratio all four fail (p < 1e-45); with log Z capped at
    log 2 (a bug L = 3 cannot show) torch-words, numba-words and numba-no-words fail (p 3e-6,
    3e-4, 9e-4), torch-no-words does not (0.04)."""
    if compiled:
        pytest.importorskip("numba")
    p_value = _invariance_p_value(
        7, copies=2000, moves=2, compiled=compiled, no_words=no_words,
        problem=_four_concept_problem,
    )  # fmt: skip
    assert p_value > 1e-3, p_value


@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_split_merge_keeps_the_enumerated_posterior_with_three_modalities(compiled):
    """A third modality (object counts) in the target and in the restricted scans, on both
    backends (800 copies, 2 moves: p 0.53 torch, 0.13 numba; seeds 1-4 0.06-0.89); the reference
    is the enumerator's, not the move's own target. Power: with the objects' counts left out of
    the acceptance ratio (two_concepts without them) p = 1e-210 torch, 8e-180 numba; with the
    whole move blind to them (used_modalities without them: ratio and scans) 3e-62, 4e-63."""
    if compiled:
        pytest.importorskip("numba")
    p_value = _invariance_p_value(
        5, copies=800, moves=2, compiled=compiled, problem=_objects_problem, evidence=True
    )
    assert p_value > 1e-3, p_value


@pytest.mark.slow
def test_a_broken_acceptance_ratio_is_detected(monkeypatch):
    # The commonest bug: the Metropolis ratio without the proposal's asymmetry (pair choice,
    # empty label, the final restricted scan's probability).
    monkeypatch.setattr(merge, "_log_acceptance_ratio", lambda delta, forward, reverse: delta)
    p_value = _invariance_p_value(5, copies=800, moves=2)
    assert p_value < 1e-6, p_value


def test_moves_happen_and_are_reversible_in_kind():
    cfg, n, data = _tiny_problem()
    generator = torch.Generator().manual_seed(0)
    labels = torch.tensor([0, 0, 0, 1, 1, 1])
    kinds = {"merge": 0, "split": 0}
    for _ in range(200):
        new, info = split_merge_labels(labels, data, cfg, generator)
        assert math.isfinite(info.log_ratio) or not info.accepted
        if info.accepted:
            kinds[info.kind] += 1
            before = int((torch.bincount(labels) > 0).sum())
            after = int((torch.bincount(new) > 0).sum())
            assert after == before + (1 if info.kind == "split" else -1)
        labels = new
    assert kinds["merge"] > 0 and kinds["split"] > 0, kinds


def test_no_split_without_an_empty_label_and_no_merge_of_one_concept():
    cfg, _, data = _tiny_problem()
    generator = torch.Generator().manual_seed(0)
    full = torch.tensor([0, 1, 2, 0, 1, 2])  # every label in use: a split has no label to take
    single = torch.zeros(6, dtype=torch.long)  # one concept: nothing to merge
    for _ in range(20):
        new, info = split_merge_labels(full, data, cfg, generator)
        assert info.kind == "merge" or (new is full and not info.accepted)
        new, info = split_merge_labels(single, data, cfg, generator)
        assert info.kind == "split" or (new is single and not info.accepted)


def test_merge_move_option_and_step_composition():
    cfg = config(gamma=0.9)
    _, data = random_problem(seed=14)
    generator = torch.Generator().manual_seed(1)
    state = init(data, cfg, generator)
    before = generator.get_state()
    assert maybe_merge_move(state, data, cfg, generator, 0.0) is state  # no draw at 0
    assert torch.equal(generator.get_state(), before)
    accepted = None
    for seed in range(30):  # an accepted move redraws the globals; a rejected one keeps them
        moved, info = merge_move(state, data, cfg, torch.Generator().manual_seed(seed))
        if info.accepted:
            accepted = moved
            assert moved.log_pi is not state.log_pi
        else:
            assert moved is state
    assert accepted is not None
    options = GibbsOptions(backend="torch", merge_moves=1.0)
    stepped, _ = step(state, data, cfg, torch.Generator().manual_seed(2), options=options)
    by_hand_generator = torch.Generator().manual_seed(2)
    by_hand = maybe_merge_move(state, data, cfg, by_hand_generator, 1.0)
    by_hand = gibbs_sweep(by_hand, data, cfg, by_hand_generator)
    assert torch.equal(stepped.labels, by_hand.labels)
    assert torch.equal(stepped.log_w, by_hand.log_w)
    with pytest.raises(ValueError, match="merge_moves"):
        GibbsOptions(merge_moves=1.5)
    assert stepped.log_pi.dtype == DTYPE


@pytest.mark.parametrize("objects", [False, True], ids=["two", "objects"])
def test_compiled_scans_give_the_torch_scans_probabilities(objects):
    """Landing on a given outcome from a given start has one probability, computed by either
    implementation (the numba backend's chains use the compiled one), with the images and words
    or a third modality too; and the launch puts every cell nearer to i than to j on i's side,
    as the torch launch does."""
    pytest.importorskip("numba")
    cfg = config(gamma=0.7, num_concepts=4)
    grid, data = random_problem(seed=15, copies=3)
    if objects:
        cfg = cfg.replace(concentrations={OBJECTS: 0.7})
        data = with_objects(grid, data, scale=3.0, copies=3)
    generator = torch.Generator().manual_seed(4)
    mask = torch.ones(data.num_free, dtype=torch.bool)
    i, j = (int(v) for v in data.pairs[3])
    region = merge._restricted(mask, i, j, data, cfg)
    scan = merge._compiled_scans(region, data, cfg, generator)
    for seed in range(4):
        start = torch.randint(0, 2, (region.cells.shape[0],), generator=generator)
        start[region.first], start[region.second] = 0, 1
        target = torch.randint(0, 2, start.shape, generator=generator)
        target[region.first], target[region.second] = 0, 1
        _, expected = merge._restricted_scan(start, region, cfg, generator, forced=target)
        landed, log_q = scan(start, target)
        assert torch.equal(landed, target)
        assert log_q == pytest.approx(expected, rel=1e-9, abs=1e-9), seed
    from spcopyro.gibbs.merge_numba import _distances

    neighbours = region.neighbours.numpy()
    to_i, to_j = _distances(neighbours, region.first), _distances(neighbours, region.second)
    sides = scan(None).numpy()
    assert (sides[to_i < to_j] == 0).all() and (sides[to_j < to_i] == 1).all()
    assert (to_i < to_j).any() and (to_j < to_i).any() and (to_i == to_j).any()  # coins too
    # the distances are the grid's: each cell one step further than its nearest neighbour's
    for k in np.flatnonzero((to_i > 0) & (to_i < np.iinfo(np.int64).max)):
        reached = [to_i[m] for m in neighbours[k] if m >= 0]
        assert min(reached) == to_i[k] - 1
