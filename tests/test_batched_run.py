"""K chains run in lock step and recorded as run_gibbs records one (spcopyro.gibbs.batched_run):
each chain's record is its own (log joint, concepts, best state, kept maps), from the start
start_chain gives its seed. The sweep's distribution is tests/test_batched_sweep.py's."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

from spcopyro.gibbs.batched_run import run_batched_chains, start_states
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import start_chain
from spcopyro.gibbs.sweep import log_joint
from spcopyro.model import DTYPE

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors

SEEDS = [3, 7, 11]


@pytest.fixture(scope="module")
def problem():
    _, data = random_problem(seed=2, num_observed=8)
    return data, config(num_concepts=4, gamma=0.7)


@pytest.mark.parametrize("dtype,rel", [(DTYPE, 1e-12), (torch.float32, 1e-5)])
def test_each_record_is_its_own_chains(problem, dtype, rel):
    data, cfg = problem
    runs = run_batched_chains(data, cfg, SEEDS, 12, thin=4, dtype=dtype)
    assert len(runs) == len(SEEDS)
    for run in runs:
        assert run.log_joint.shape == run.num_concepts.shape == run.seconds.shape == (12,)
        assert (np.diff(run.seconds) >= 0).all() and run.backend == "batched"
        final = float(log_joint(run.final_state, data, cfg))
        assert run.log_joint[-1] == pytest.approx(final, rel=rel)
        assert run.num_concepts[-1] == torch.unique(run.final_state.labels).numel()
        # The best state is the chain's own best visited state.
        assert run.log_joint[run.best_sweep] == run.log_joint.max()
        best = float(log_joint(run.best_state, data, cfg))
        assert best == pytest.approx(run.log_joint.max(), rel=rel)
        assert run.sample_sweeps.tolist() == [3, 7, 11]
        assert run.label_samples.shape == (3, data.num_free)
        assert np.array_equal(run.label_samples[-1], run.final_state.labels.numpy())
    # The chains are different chains.
    assert len({tuple(run.log_joint.tolist()) for run in runs}) == len(SEEDS)


def test_chain_k_starts_where_start_chain_of_seed_k_starts(problem):
    data, cfg = problem
    for seed, state in zip(SEEDS, start_states(data, cfg, SEEDS), strict=True):
        alone = start_chain(data, cfg, seed=seed).state
        assert torch.equal(state.labels, alone.labels)
        assert torch.equal(state.log_pi, alone.log_pi)


def test_moves_it_cannot_compose_are_named(problem):
    data, cfg = problem
    options = GibbsOptions(merge_moves=0.3, cluster_moves=0.1)
    with pytest.raises(ValueError, match="cluster_moves, merge_moves"):
        run_batched_chains(data, cfg, SEEDS, 2, options=options)
    # region_moves (added after the batched chains) was dropped without a word.
    with pytest.raises(ValueError, match="switch off region_moves"):
        run_batched_chains(data, cfg, SEEDS, 2, options=GibbsOptions(region_moves=0.5))
    with pytest.raises(ValueError, match="num_sweeps"):
        run_batched_chains(data, cfg, SEEDS, 0)


def test_float32_chains_record_their_log_joint_to_the_float64_digits(problem):
    # with original-code's pi concentration (1e6) the log joint's constant and state-dependent
    # part are about +-2e7 each; run_batched_chains summed them in float32, so a float32 run
    # recorded its log joint in steps of 2 nats (2510.0, 2290.0 on a synthetic house) and kept
    # as "best" the first of the states tied by that rounding
    data, _ = problem
    cfg = config(num_concepts=4, gamma=0.7, alpha=4e6)  # Dir(1e6, ..., 1e6)
    for run in run_batched_chains(data, cfg, SEEDS, 6, dtype=torch.float32):
        final = float(log_joint(run.final_state, data, cfg))  # at the float32 state, in float64
        assert abs(run.log_joint[-1] - final) < 1e-3, (run.log_joint[-1], final)
