"""The batched sweep of B chains (spcopyro.gibbs.batched, issue 25 item 5), on the CPU here and
on a GPU where one is lent:

* each chain's per-cell conditionals, as the batched sweep draws them, equal
  :func:`~spcopyro.gibbs.sweep.label_log_conditionals` of that chain's own state (B different
  states: nothing mixes across chains), exactly;
* first-block draws of every chain follow that chain's conditional (chi-square over 1000
  wall-separated copies of a small map);
* whole sweeps (labels and globals) of many chains reach the exact posterior of a tiny map with
  pi and the emission distributions integrated out (enumerated), in float64 and float32;
* the batched log-gamma draws against scipy's gamma distribution (shapes far below 1 included).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import (
    config,
    random_problem,
    tiny_grid,
    with_connectivity,
    without_words,
)
from scipy import stats
from statistical_checks import pooled_chisquare_p

from spcopyro.gibbs.batched import (
    BatchedState,
    block_log_conditionals,
    gibbs_sweep_batched,
    init_batched,
    make_batched_plan,
    sample_labels_batched,
    sample_log_gamma_batched,
    stack_states,
    trace_batched,
)
from spcopyro.gibbs.sampler import init
from spcopyro.gibbs.sweep import label_log_conditionals
from spcopyro.guides.testing import all_labellings, labelling_log_evidence
from spcopyro.guides.tiny_maps import tiny_map
from spcopyro.likelihood import log_joint_variable
from spcopyro.model import DTYPE, Modality

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors

CUDA = pytest.mark.skipif(
    not torch.cuda.is_available(), reason="no CUDA device here: the batched sweep is tested on CPU"
)


def distinct_states(data, cfg, num_chains: int, seed: int = 0) -> list:
    """``num_chains`` states from different random labels and globals, each with a chain-specific
    bias (chain b favours concept b mod L) so that their conditionals differ clearly."""
    generator = torch.Generator().manual_seed(seed)
    states = []
    for b in range(num_chains):
        labels = torch.randint(cfg.num_concepts, (data.num_free,), generator=generator)
        labels[torch.rand(data.num_free, generator=generator) < 0.4] = b % cfg.num_concepts
        states.append(init(data, cfg, generator, labels))
    return states


def with_objects(data, cfg_overrides: dict):
    """The data with a third modality (Poisson counts, concentration 0.7) and its config."""
    counts = torch.as_tensor(
        np.random.default_rng(3).poisson(2.0, (data.obs_cells.shape[0], 3)), dtype=DTYPE
    )
    objects = Modality("objects", "objects_probs", counts)
    data = data._replace(modalities=(*data.modalities, objects))
    return data, config(concentrations={"objects": 0.7}, **cfg_overrides)


CONDITIONAL_VARIANTS = [
    pytest.param(dict(), id="default"),
    pytest.param(dict(connectivity=8, gamma=1.3), id="8-neighbours"),
    pytest.param(dict(use_words=False, num_concepts=5), id="no-words"),
    pytest.param(dict(prior="dirichlet", alpha=0.3, gamma=2.5), id="dirichlet"),
    pytest.param(dict(objects=True), id="third-modality"),
]


def problem_for(overrides: dict):
    overrides = dict(overrides)
    objects = overrides.pop("objects", False)
    connectivity = overrides.get("connectivity", 4)
    _, data = random_problem(seed=2, connectivity=connectivity, num_observed=8)
    if objects:
        return with_objects(data, overrides)
    return data, config(**overrides)


def check_conditionals(states, data, cfg, device: str, dtype: torch.dtype, atol: float) -> None:
    """The batched conditionals of every block and chain against the single-chain reference."""
    batch = stack_states(states, device, dtype)
    plan = make_batched_plan(data, cfg, device, dtype)
    for index, block in enumerate(plan.blocks):
        batched = block_log_conditionals(batch, plan, cfg, index).cpu()  # [B, Nc, L]
        assert batched.dtype == dtype
        cells = block.cells.cpu()
        for b, state in enumerate(states):
            reference = label_log_conditionals(state, data, cfg, cells)  # [Nc, L]
            torch.testing.assert_close(batched[b].to(DTYPE), reference, rtol=0, atol=atol)


@pytest.mark.parametrize("overrides", CONDITIONAL_VARIANTS)
def test_each_chains_conditionals_equal_the_reference(overrides):
    """Every cell of every block, every chain: the distribution the batched sweep draws from (the
    mixture for cells without observations, the enumeration for observed ones) equals eq. (13)
    enumerated on that chain's own state."""
    data, cfg = problem_for(overrides)
    states = distinct_states(data, cfg, num_chains=4)
    # The chains' conditionals differ, so a batched sweep mixing chains up would be caught.
    cells = torch.arange(data.num_free)
    first, second = (label_log_conditionals(s, data, cfg, cells) for s in states[:2])
    assert (first - second).abs().max() > 0.5
    check_conditionals(states, data, cfg, "cpu", DTYPE, atol=1e-12)


def test_float32_conditionals_are_the_reference_up_to_rounding():
    data, cfg = problem_for({})
    check_conditionals(distinct_states(data, cfg, 3), data, cfg, "cpu", torch.float32, atol=2e-5)


def test_first_block_draws_follow_each_chains_own_conditional():
    """1000 wall-separated copies of a small map share a state within a chain, and 3 chains hold
    3 different states: every first-block cell's draws, per chain, against that chain's
    enumerated conditional (chi-square, Bonferroni over cells and chains)."""
    copies, repeats, num_chains = 1000, 12, 3
    cfg = config(num_concepts=4, gamma=1.2)
    _, one = random_problem(seed=5, num_observed=6)
    _, data = random_problem(seed=5, num_observed=6, copies=copies)
    n = one.num_free
    small = distinct_states(one, cfg, num_chains, seed=4)
    states = [s._replace(labels=s.labels.repeat(copies)) for s in small]
    batch = stack_states(states)
    plan = make_batched_plan(data, cfg)
    first = plan.blocks[0].cells
    first = first[first < n]  # first-block cells of copy 0
    assert (one.observation_rows()[first] >= 0).any()  # the observed path is exercised
    generator = torch.Generator().manual_seed(8)
    counts = torch.zeros(num_chains, first.numel(), cfg.num_concepts)  # [B, n1, L]
    for _ in range(repeats):
        labels = sample_labels_batched(batch, plan, cfg, generator)  # [B, N]
        drawn = labels.view(num_chains, copies, n)[:, :, first]  # [B, copies, n1]
        counts += torch.nn.functional.one_hot(drawn, cfg.num_concepts).sum(1)
    p_values = []
    for b, state in enumerate(small):
        expected = label_log_conditionals(state, one, cfg, first).exp() * copies * repeats
        p_values += [
            stats.chisquare(counts[b, i].numpy(), expected[i].numpy()).pvalue
            for i in range(first.numel())
        ]
    assert min(p_values) * len(p_values) > 1e-3, min(p_values)
    # Power: chain 1's draws are not chain 0's distribution.
    wrong = label_log_conditionals(small[0], one, cfg, first).exp() * copies * repeats
    p_wrong = [stats.chisquare(counts[1, i].numpy(), wrong[i].numpy()).pvalue
               for i in range(first.numel())]  # fmt: skip
    assert min(p_wrong) < 1e-6


def canonical_partitions(labellings: torch.Tensor) -> torch.Tensor:
    """[S, N] labellings -> [S] an integer id of each one's partition of the cells (labels renamed
    in order of first appearance), which every relabelling of the concepts leaves unchanged."""
    S, N = labellings.shape
    first_cell = torch.full((S, int(labellings.max()) + 1), N, dtype=torch.long)
    first_cell.scatter_reduce_(1, labellings, torch.arange(N).expand(S, N), reduce="amin")
    rank = first_cell.argsort(1).argsort(1)  # [S, L] order of each label's first appearance
    renamed = rank.gather(1, labellings)  # [S, N]
    return (renamed * N ** torch.arange(N - 1, -1, -1)).sum(-1)


POSTERIOR_VARIANTS = [
    pytest.param(dict(), 1.0, DTYPE, id="default"),
    pytest.param(dict(prior="dirichlet", alpha=1.5, gamma=0.5), 1.0, DTYPE, id="dirichlet"),
    pytest.param(dict(num_concepts=4), 0.3, DTYPE, id="refresh-0.3"),
    pytest.param(dict(), 1.0, torch.float32, id="float32"),
    pytest.param(dict(connectivity=8, gamma=0.7), 1.0, DTYPE, id="8-neighbours"),
    pytest.param(dict(use_words=False), 1.0, DTYPE, id="no-words"),
    pytest.param(dict(vocabulary=0), 1.0, DTYPE, id="zero-word-vocabulary"),
    pytest.param(dict(objects=True), 1.0, DTYPE, id="third-modality"),
]
"""(config overrides, unobserved_refresh, dtype); ``vocabulary=0``: the words modality with
V = 0 items (a house of images only), ``objects``: a third modality (see
:func:`posterior_problem`)."""


def posterior_problem(overrides: dict):
    """The 2 x 3 map with three observed cells of the whole-sweep test, and its config."""
    overrides = dict(overrides)
    objects = overrides.pop("objects", False)
    vocabulary = overrides.pop("vocabulary", None)
    rows = ("...", "...")
    data = tiny_map(4, rows=rows, num_observed=3)
    connectivity = overrides.get("connectivity", 4)
    if connectivity != 4:  # the same observations, the other neighbourhood
        data = with_connectivity(tiny_grid(list(rows)), data, connectivity)
    if vocabulary == 0:
        data = without_words(data)
    if objects:
        return with_objects(data, overrides)
    return data, config(**overrides)


@pytest.mark.parametrize("overrides,refresh,dtype", POSTERIOR_VARIANTS)
def test_whole_sweeps_reach_the_exact_posterior(overrides, refresh, dtype):
    """20000 chains of full batched sweeps (labels, then pi, theta, w) on a 2 x 3 map with three
    observed cells: after 30 sweeps, each chain's labelling is one draw; the frequencies of the
    partitions (label-invariant) against the exact posterior with the globals integrated out
    (:func:`~spcopyro.guides.testing.labelling_log_evidence`, enumerated), chi-square."""
    data, cfg = posterior_problem(overrides)
    labellings = all_labellings(data.num_free, cfg.num_concepts)
    exact = torch.softmax(labelling_log_evidence(labellings, data, cfg), 0)  # [S]
    ids, partition = torch.unique(canonical_partitions(labellings), return_inverse=True)
    exact_by_partition = torch.zeros(ids.numel(), dtype=DTYPE).index_add_(0, partition, exact)

    num_chains = 20000
    plan = make_batched_plan(data, cfg, "cpu", dtype)
    generator = torch.Generator().manual_seed(31)
    batch = init_batched(data, cfg, plan, generator, num_chains)
    for _ in range(30):
        batch = gibbs_sweep_batched(batch, plan, cfg, generator, refresh)
    assert batch.log_pi.dtype == dtype
    drawn = torch.searchsorted(ids, canonical_partitions(batch.labels))
    observed = torch.bincount(drawn, minlength=ids.numel()).to(DTYPE)  # [S] partitions
    assert pooled_chisquare_p(observed, exact_by_partition) > 1e-3


@pytest.mark.parametrize("overrides", CONDITIONAL_VARIANTS)
def test_trace_is_each_chains_log_joint(overrides):
    """The batched trace: log_joint_variable and the concepts in use of every chain's own state
    (one of them using only a few concepts, so the count is not L everywhere)."""
    data, cfg = problem_for(overrides)
    states = distinct_states(data, cfg, num_chains=3)
    states[2] = states[2]._replace(labels=states[2].labels % 2)
    values, concepts = trace_batched(stack_states(states), make_batched_plan(data, cfg), cfg)
    for b, state in enumerate(states):
        expected = log_joint_variable(state.labels, state.log_pi, state.log_emissions, data, cfg)
        assert float(values[b]) == pytest.approx(float(expected), rel=1e-12, abs=1e-9)
        assert int(concepts[b]) == int(torch.unique(state.labels).numel())
    assert int(concepts[2]) == 2


@pytest.mark.parametrize("shape", [0.01, 0.3, 1.0, 4.5])
def test_batched_log_gamma_draws_follow_the_gamma_distribution(shape):
    generator = torch.Generator().manual_seed(2)
    concentration = torch.full((3, 4000), shape, dtype=DTYPE)
    log_g = sample_log_gamma_batched(concentration, generator)
    assert torch.isfinite(log_g).all()
    # log G's CDF at x is the gamma CDF at e^x (computed in log space for small shapes).
    p_value = stats.kstest(log_g.flatten().numpy(),
                           lambda x: stats.gamma.cdf(np.exp(x), shape)).pvalue  # fmt: skip
    assert p_value > 1e-3


def test_stacked_states_come_back_as_they_went_in():
    data, cfg = problem_for({})
    states = distinct_states(data, cfg, 3)
    batch = stack_states(states)
    assert isinstance(batch, BatchedState) and batch.num_chains == 3
    for original, back in zip(states, batch.chains(), strict=True):
        assert torch.equal(original.labels, back.labels)
        assert torch.equal(original.log_pi, back.log_pi)
        for a, b in zip(original.log_emissions, back.log_emissions, strict=True):
            assert torch.equal(a, b)


@CUDA
@pytest.mark.parametrize("dtype,atol", [(DTYPE, 1e-10), (torch.float32, 1e-4)])
def test_runs_on_cuda(dtype, atol):
    """On the GPU: the conditionals of B different states equal the CPU reference, and sweeps
    run with a device generator without a single host sync, keep every tensor on the device
    and valid labels."""
    data, cfg = problem_for(dict(connectivity=8, gamma=1.3))
    states = distinct_states(data, cfg, 4)
    check_conditionals(states, data, cfg, "cuda", dtype, atol=atol)
    plan = make_batched_plan(data, cfg, "cuda", dtype)
    generator = torch.Generator(device="cuda").manual_seed(0)
    batch = stack_states(states, "cuda", dtype)
    torch.cuda.synchronize()
    torch.cuda.set_sync_debug_mode("error")  # a host sync inside a sweep raises
    try:
        for _ in range(5):
            batch = gibbs_sweep_batched(batch, plan, cfg, generator, 0.5)
    finally:
        torch.cuda.set_sync_debug_mode("default")
    assert batch.labels.is_cuda and batch.log_pi.is_cuda
    assert all(t.is_cuda and t.dtype == dtype for t in batch.log_emissions)
    labels = batch.labels.cpu()
    assert int(labels.min()) >= 0 and int(labels.max()) < cfg.num_concepts
    assert torch.isfinite(batch.log_pi).all()
