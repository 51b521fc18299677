"""The region relabel move (spcopyro.gibbs.region_move): exact, and what it is for.

* Detailed balance, exactly: on a 2 x 2 map with three concepts the move's transition
  probabilities are enumerated here -- every bond configuration with its probability
  1 - e^-gamma per bonded agreeing pair, every seed cell, every label of the proposal's groups --
  with the module's acceptance ratio, and p(C) K(C, C') must equal p(C') K(C', C) for every pair
  of the 81 labelings, p being the enumerated posterior (the enumerator's log evidence of
  spcopyro.guides.testing, Potts term included, checked against the Pyro model in
  test_exact_tiny_maps), with the images and words and with a third modality. Power: the ratio
  without the label proposal's asymmetry breaks it (``test_a_broken_acceptance_ratio_is_detected``),
  and so does one blind to the third modality.
* The sampler draws what was enumerated: moves from one labeling land on each labeling as often
  as the enumerated row says (chi-square).
* What it is for: a room carried by two concepts whose halves' data agree is merged in a few
  moves, where the split-merge move's merge is rarely accepted.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import torch
from gibbs_problems import (
    all_labelings,
    config,
    model_data,
    replicate_grid,
    state_index,
    with_connectivity,
    without_words,
)
from scipy import stats
from statistical_checks import pooled_chisquare_p
from test_modalities import OBJECTS, with_objects

import spcopyro.gibbs.merge as merge
import spcopyro.gibbs.region_move as region_move
from spcopyro.gibbs.merge import collapsed_log_posterior
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.region_move import (
    BOND_SHARE,
    GROUP_WEIGHTS,
    maybe_region_move,
    region_relabel_labels,
    relabel_log_ratio,
)
from spcopyro.gibbs.sampler import init, step
from spcopyro.gibbs.sweep import gibbs_sweep
from spcopyro.guides.testing import labelling_log_evidence
from spcopyro.model import DTYPE

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors


def _square_problem():
    cfg = config(gamma=0.8, num_concepts=3, alpha=3.0, beta=0.5, chi=0.5)
    grid, n = replicate_grid(["..", ".."], 1)
    images = np.array([[3.0, 0.5], [0.5, 2.0]])
    words = np.array([[2.0, 0.0, 1.0], [0.0, 2.0, 0.5]])
    return cfg, n, model_data(grid, np.array([0, 3]), images, words)


def _objects_problem():
    """:func:`_square_problem` with a third modality: tests/test_modalities.py's object counts
    (Poisson(3) at the 2 observed cells, concentration 0.7), which move the enumerated p(C | x)
    by 0.22 in total variation."""
    cfg, n, data = _square_problem()
    grid, _ = replicate_grid(["..", ".."], 1)
    return cfg.replace(concentrations={OBJECTS: 0.7}), n, with_objects(grid, data, scale=3.0)


def _components(num_cells: int, bonds: list[tuple[int, int]]) -> list[frozenset[int]]:
    """The component of every cell under ``bonds`` (union-find, written out for the test)."""
    parent = list(range(num_cells))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i, j in bonds:
        parent[root(i)] = root(j)
    return [frozenset(k for k in range(num_cells) if root(k) == root(i)) for i in range(num_cells)]


def _proposal(labels: list[int], region: frozenset[int], pairs, num_concepts: int) -> dict:
    """g(a | region, C) of the module's docstring, computed here from its statement."""
    current = labels[next(iter(region))]
    touching = {labels[j] for i, j in pairs if i in region and j not in region}
    touching |= {labels[i] for i, j in pairs if j in region and i not in region}
    used = set(labels)
    groups = [
        sorted(touching - {current}),
        sorted(set(range(num_concepts)) - used),
        sorted(used - touching - {current}),
    ]
    total = sum(w for w, g in zip(GROUP_WEIGHTS, groups, strict=True) if g)
    return {a: w / total / len(g) for w, g in zip(GROUP_WEIGHTS, groups, strict=True) for a in g}


def _exact_kernel(
    cfg, n, data, bond_share: float = BOND_SHARE, ratio_share: float | None = None
) -> np.ndarray:
    """[S, S] the move's transition probabilities between all labelings (bonds with
    ``bond_share`` of the coupling; the module's ratio told ``ratio_share``, by default the
    same)."""
    ratio_share = bond_share if ratio_share is None else ratio_share
    L = cfg.num_concepts
    labelings = all_labelings(n, L)
    pairs = [tuple(int(v) for v in p) for p in data.pairs]
    bond = -math.expm1(-bond_share * cfg.gamma)
    kernel = np.zeros((len(labelings), len(labelings)))
    ratios: dict = {}
    for s, row in enumerate(labelings):
        labels = row.tolist()
        agreeing = [p for p in pairs if labels[p[0]] == labels[p[1]]]
        for bits in itertools.product([False, True], repeat=len(agreeing)):
            p_bonds = math.prod(bond if bit else 1 - bond for bit in bits)
            components = _components(n, [p for p, bit in zip(agreeing, bits, strict=True) if bit])
            for seed in range(n):
                region = components[seed]
                weight = p_bonds / n
                for a, g in _proposal(labels, region, pairs, L).items():
                    moved = [a if k in region else labels[k] for k in range(n)]
                    key = (s, region, a)
                    if key not in ratios:
                        mask = torch.tensor([k in region for k in range(n)])
                        border = region_move.border_labels(mask, row, data.pairs)
                        ratios[key] = relabel_log_ratio(
                            row, mask, a, border, data, cfg, ratio_share
                        )
                    accept = min(1.0, math.exp(min(ratios[key], 0.0)))
                    target = int(state_index(torch.tensor(moved), L))
                    kernel[s, target] += weight * g * accept
                    kernel[s, s] += weight * g * (1 - accept)
    return kernel


def _posterior(cfg, n, data) -> np.ndarray:
    """[S] the enumerated p(C | x) from the enumerator's log evidence (spcopyro.guides.testing,
    checked against the Pyro model in test_exact_tiny_maps, a third modality included): not
    from the move's own terms, whose modalities are the move's."""
    log_p = labelling_log_evidence(all_labelings(n, cfg.num_concepts), data, cfg).numpy()
    return np.exp(log_p - log_p.max()) / np.exp(log_p - log_p.max()).sum()


def _detailed_balance_gap(cfg, n, data, bond_share: float = BOND_SHARE) -> float:
    kernel = _exact_kernel(cfg, n, data, bond_share)
    assert np.allclose(kernel.sum(1), 1.0, atol=1e-12)
    flow = _posterior(cfg, n, data)[:, None] * kernel  # [S, S] p(C) K(C, C')
    return float(np.abs(flow - flow.T).max() / flow.max())


@pytest.mark.parametrize("bond_share", [BOND_SHARE, 1.0, 0.0])
def test_the_move_satisfies_detailed_balance_exactly(bond_share):
    """The default share of the coupling in the bonds, the pure Swendsen-Wang cut (1) and
    single cells (0)."""
    cfg, n, data = _square_problem()
    assert _detailed_balance_gap(cfg, n, data, bond_share) < 1e-10


@pytest.mark.parametrize(
    "variant", ["two-concepts", "8-neighbours", "zero-word-vocabulary", "three-modalities"]
)
def test_detailed_balance_holds_beyond_the_default_problem(variant):
    """L = 2 (no new concept to propose once both are used), the 8-neighbourhood (the diagonal
    pairs in the bonds and the border), words of V = 0 items (a house of images only), and a
    third modality (object counts; power: test_a_ratio_blind_to_the_third_modality_...)."""
    cfg, n, data = _square_problem()
    if variant == "three-modalities":
        cfg, n, data = _objects_problem()
    elif variant == "two-concepts":
        cfg = cfg.replace(num_concepts=2)
    elif variant == "8-neighbours":
        cfg = cfg.replace(connectivity=8)
        data = with_connectivity(replicate_grid(["..", ".."], 1)[0], data, 8)
        assert data.pairs.shape[0] == 6
    else:
        data = without_words(data)
    assert _detailed_balance_gap(cfg, n, data) < 1e-10


def test_a_broken_acceptance_ratio_is_detected(monkeypatch):
    # The ratio without the label proposal's asymmetry (as if g were symmetric).
    monkeypatch.setattr(region_move, "_log_acceptance_ratio", lambda delta, fwd, rev: delta)
    cfg, n, data = _square_problem()
    assert _detailed_balance_gap(cfg, n, data) > 1e-2


def test_a_ratio_blind_to_the_third_modality_is_detected(monkeypatch):
    # The two concepts' terms of the ratio without the objects' counts (a move that lists the
    # images and words only): gap 0.21, as against 2e-16 with them.
    two_concepts = merge.two_concepts

    def images_and_words(*args):
        sizes, counts = two_concepts(*args)
        return sizes, counts[:2]

    monkeypatch.setattr(region_move, "two_concepts", images_and_words)
    monkeypatch.setattr(region_move, "used_modalities", lambda *a: merge.used_modalities(*a)[:2])
    cfg, n, data = _objects_problem()
    assert _detailed_balance_gap(cfg, n, data) > 1e-2


def test_a_potts_share_left_out_is_detected():
    # The ratio as if the bonds carried all the coupling while they carry BOND_SHARE of it.
    cfg, n, data = _square_problem()
    broken = _exact_kernel(cfg, n, data, BOND_SHARE, ratio_share=1.0)
    flow = _posterior(cfg, n, data)[:, None] * broken
    assert np.abs(flow - flow.T).max() / flow.max() > 1e-2


@pytest.mark.parametrize("problem", [_square_problem, _objects_problem], ids=["two", "objects"])
@pytest.mark.parametrize("compiled", [False, True])
def test_the_sampler_draws_the_enumerated_transitions(compiled, problem):
    cfg, n, data = problem()
    kernel = _exact_kernel(cfg, n, data)
    start = torch.tensor([0, 0, 1, 1])
    row = kernel[int(state_index(start, cfg.num_concepts))]
    generator = torch.Generator().manual_seed(0)
    draws = 3000
    landed = [
        int(
            state_index(
                region_relabel_labels(start, data, cfg, generator, compiled=compiled)[0],
                cfg.num_concepts,
            )
        )
        for _ in range(draws)
    ]
    observed = np.bincount(landed, minlength=row.shape[0]).astype(float)  # [S]
    rare = row * draws < 5  # pooled by the chi-square: not landed on much more than expected
    assert observed[rare].sum() <= max(15.0, 3 * (row * draws)[rare].sum())
    assert pooled_chisquare_p(observed, row) > 1e-3


def _enumerated_regions(labels: list[int], pairs, bond: float) -> dict[frozenset[int], float]:
    """P(region) of steps 1-2: every bond configuration of the agreeing pairs, a uniform seed."""
    n = len(labels)
    agreeing = [p for p in pairs if labels[p[0]] == labels[p[1]]]
    out: dict[frozenset[int], float] = {}
    for bits in itertools.product([False, True], repeat=len(agreeing)):
        p_bonds = math.prod(bond if bit else 1 - bond for bit in bits)
        components = _components(n, [p for p, bit in zip(agreeing, bits, strict=True) if bit])
        for seed in range(n):
            out[components[seed]] = out.get(components[seed], 0.0) + p_bonds / n
    return out


def test_a_region_grown_from_its_seed_has_the_components_distribution():
    """grow_region (bonds drawn as the growth reaches them) against the seed's component under
    bonds on every agreeing pair, enumerated on a 2 x 3 map with two concepts (chi-square), and
    its border labels against border_labels."""
    from spcopyro.gibbs.numba_random import rng_state
    from spcopyro.gibbs.region_numba import grow_region

    grid, n = replicate_grid(["...", "..."], 1)
    data = model_data(grid, np.array([0]), np.array([[1.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    pairs = [tuple(int(v) for v in p) for p in data.pairs]
    labels = torch.tensor([0, 0, 1, 0, 0, 1])
    bond = 0.6
    expected = _enumerated_regions(labels.tolist(), pairs, bond)
    neighbours = np.ascontiguousarray(data.neighbours.numpy())
    state = rng_state(3)
    draws = 6000
    seen: dict[frozenset[int], int] = {}
    for _ in range(draws):
        inside, border = grow_region(labels.numpy(), neighbours, bond, state)
        region = frozenset(np.flatnonzero(inside).tolist())
        seen[region] = seen.get(region, 0) + 1
        by_pairs = region_move.border_labels(torch.from_numpy(inside), labels, data.pairs)
        assert sorted(border.tolist()) == sorted(by_pairs.tolist())
    assert set(seen) <= set(expected)
    keys = sorted(expected, key=sorted)
    observed = np.array([seen.get(k, 0) for k in keys], dtype=float)
    probabilities = np.array([expected[k] for k in keys])
    assert stats.chisquare(observed, probabilities * draws).pvalue > 1e-3
    # Power: bonds drawn with another probability are told apart.
    wrong = _enumerated_regions(labels.tolist(), pairs, 0.4)
    assert stats.chisquare(observed, np.array([wrong[k] for k in keys]) * draws).pvalue < 1e-6


def _split_room_problem():
    """A 6 x 12 room whose words and images are the same everywhere, labelled as two concepts
    (left half 0, right half 1)."""
    grid, n = replicate_grid(["." * 12] * 6, 1)
    cells = np.arange(0, n, 7)
    images = np.tile([[2.0, 1.0]], (cells.shape[0], 1))
    words = np.tile([[3.0, 0.0, 0.0]], (cells.shape[0], 1))
    data = model_data(grid, cells, images, words)
    labels = torch.tensor([0 if (k % 12) < 6 else 1 for k in range(n)])
    return data, labels


@pytest.mark.parametrize("compiled", [False, True])
def test_a_room_split_between_two_concepts_is_merged(compiled):
    data, labels = _split_room_problem()
    cfg = config(gamma=2.0, num_concepts=6, alpha=1.0, beta=0.1, chi=1.0)
    gain = collapsed_log_posterior(torch.zeros_like(labels), data, cfg) - collapsed_log_posterior(
        labels, data, cfg
    )
    assert gain > 0  # the model prefers one concept here
    generator = torch.Generator().manual_seed(1)
    used = []
    for _ in range(300):  # median over 150 seeds: 33.5 moves (torch), 32 (compiled)
        labels, _ = region_relabel_labels(labels, data, cfg, generator, compiled=compiled)
        used.append(int((torch.bincount(labels) > 0).sum()))
        if used[-1] == 1:
            break
    assert used[-1] == 1, used


def test_option_and_step_composition():
    cfg, _, data = _square_problem()
    generator = torch.Generator().manual_seed(1)
    state = init(data, cfg, generator)
    before = generator.get_state()
    assert maybe_region_move(state, data, cfg, generator, 0.0) is state  # no draw at 0
    assert torch.equal(generator.get_state(), before)
    accepted = None
    for seed in range(30):  # an accepted move redraws the globals; a rejected one keeps them
        moved, info = region_move.region_move(state, data, cfg, torch.Generator().manual_seed(seed))
        assert info.kind == "relabel"
        if info.accepted:
            accepted = moved
            assert moved.log_pi is not state.log_pi
        else:
            assert moved is state
    assert accepted is not None
    options = GibbsOptions(backend="torch", region_moves=1.0)
    stepped, _ = step(state, data, cfg, torch.Generator().manual_seed(2), options=options)
    by_hand_generator = torch.Generator().manual_seed(2)
    by_hand = maybe_region_move(state, data, cfg, by_hand_generator, 1.0)
    by_hand = gibbs_sweep(by_hand, data, cfg, by_hand_generator)
    assert torch.equal(stepped.labels, by_hand.labels)
    assert torch.equal(stepped.log_w, by_hand.log_w)
    assert stepped.log_pi.dtype == DTYPE
    with pytest.raises(ValueError, match="region_moves"):
        GibbsOptions(region_moves=-0.1)
