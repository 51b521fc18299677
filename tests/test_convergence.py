"""The ``--sweeps auto`` stopping rule: split R-hat of label-invariant statistics across chains,
checked after every block of sweeps; each block continues its chains exactly."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from gibbs_problems import config as small_config
from gibbs_problems import random_problem

from spcopyro.cli.main import main
from spcopyro.config import SpCoConfig, SpCoSettings
from spcopyro.data import cell_counts
from spcopyro.fit.house import fit_house_converged
from spcopyro.gibbs.convergence import check_convergence, run_until_converged, split_rhat
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import run_gibbs
from spcopyro.model import make_model_data
from spcopyro.synthetic import make_house


@pytest.fixture(scope="module")
def house():
    return make_house(seed=0)


@pytest.fixture(scope="module")
def data(house):
    return make_model_data(house.grid, cell_counts(house.grid, house.observations), 4)


def test_split_rhat_by_hand():
    # halves [0,1] [0,1] [2,3] [2,3]: n = 2, W = 0.5, B = n var(0.5, 0.5, 2.5, 2.5) = 8/3,
    # R = sqrt(((n-1)/n W + B/n) / W) = sqrt((0.25 + 4/3) / 0.5)
    traces = np.array([[0.0, 1.0, 0.0, 1.0], [2.0, 3.0, 2.0, 3.0]])
    assert split_rhat(traces) == pytest.approx(math.sqrt((0.25 + 4 / 3) / 0.5), rel=1e-9)


def test_split_rhat_degenerate_cases():
    assert split_rhat(np.full((3, 10), 7.0)) == 1.0  # all equal: the chains agree
    stuck = np.repeat([[5.0], [6.0]], 10, axis=1)  # each chain constant, different values
    assert split_rhat(stuck) == math.inf
    with pytest.raises(ValueError, match="K >= 2"):
        split_rhat(np.zeros((1, 10)))
    with pytest.raises(ValueError, match="NaN"):
        split_rhat(np.array([[0.0, 1, 2, np.nan], [0, 1, 2, 3]]))


def test_check_convergence_rejects_disagreeing_chains():
    rng = np.random.default_rng(0)
    noise = rng.normal(size=(4, 200))
    same_concepts = np.full((4, 200), 6)
    ok, check = check_convergence(noise, same_concepts)
    assert ok and check.rhat_num_concepts == 1.0 and check.rhat_log_joint < 1.05
    # one chain stuck at another level of the log joint: R-hat of the log joint fails
    shifted = noise + np.array([0.0, 0.0, 0.0, 5.0])[:, None]
    ok, check = check_convergence(shifted, same_concepts)
    assert not ok and check.rhat_log_joint > 1.5
    # chains that keep different numbers of concepts: R-hat of the concepts fails
    concepts = same_concepts + (rng.random((4, 200)) < 0.5) + np.array([0, 0, 3, 3])[:, None]
    ok, check = check_convergence(noise, concepts)
    assert not ok and check.rhat_num_concepts > 1.5
    # too few draws in the window (second half of 10 sweeps = 5 < MIN_DRAWS): never passes
    ok, check = check_convergence(noise[:, :10], same_concepts[:, :10])
    assert not ok and check.rhat_log_joint == math.inf


def test_stops_early_on_an_easy_problem(data):
    # No MRF coupling and 3 concepts: labels mix in one sweep, the number of concepts stays 3.
    config = SpCoConfig(num_concepts=3, prior="dirichlet", alpha=1e3, gamma=0.0)
    run, diag = run_until_converged(data, config, chains=3, block=20, max_sweeps=400, seed=1,
                                    progress=False)  # fmt: skip
    assert diag.converged
    assert diag.sweeps == 20 and len(diag.checks) == 1
    assert diag.log_joint.shape == (3, 20) and diag.num_concepts.shape == (3, 20)
    assert np.all(diag.num_concepts == 3)
    assert diag.seeds == (1, 2, 3)
    # the answer is the chain whose best visited log joint is the highest
    assert diag.best_chain == int(np.argmax(diag.log_joint.max(axis=1)))
    assert run.log_joint[run.best_sweep] == diag.log_joint.max()


def test_hard_problem_runs_to_the_cap_and_blocks_continue(data):
    # paper-dp coupling from random labels: regions coarsen for thousands of sweeps, so chains
    # disagree on the number of concepts and the log joint keeps rising.
    config = SpCoConfig()
    run, diag = run_until_converged(data, config, chains=2, block=30, max_sweeps=70, seed=0,
                                    progress=False)  # fmt: skip
    assert not diag.converged
    assert diag.sweeps == 70
    assert [c.sweeps for c in diag.checks] == [30, 60, 70]
    assert len(run.log_joint) == 70 and len(run.seconds) == 70
    assert np.all(np.diff(run.seconds) > 0)  # block times are offset, not restarted
    # continuing across blocks keeps coarsening: fewer concepts at the end than after block 1
    assert diag.num_concepts[:, -1].max() < diag.num_concepts[:, 29].min()


def test_blocks_continue_each_chain_exactly(backend):
    """K chains of S sweeps run in blocks are the K single runs of S sweeps (seeds seed + k):
    the same trace sweep for sweep, and the returned chain's states are the single run's. The
    options' moves and annealing are on, so their draws are continued too."""
    cfg = small_config(gamma=1.2)
    _, data = random_problem(seed=9, copies=3)
    options = GibbsOptions(backend=backend.name, cluster_moves=0.3, unobserved_refresh=0.5,
                           anneal_sweeps=3)  # fmt: skip
    # A threshold no R-hat of real chains passes: the blocks run to max_sweeps (7 + 7 + 6).
    run, diag = run_until_converged(data, cfg, options=options, chains=3, block=7, max_sweeps=20,
                                    threshold=1 + 1e-12, seed=4, progress=False)  # fmt: skip
    assert not diag.converged and diag.sweeps == 20
    assert [c.sweeps for c in diag.checks] == [7, 14, 20]
    assert diag.log_joint.shape == (3, 3 + 20)  # annealing sweeps first
    singles = [
        run_gibbs(data, cfg, 3 + 20, options=options, seed=4 + k, progress=False) for k in range(3)
    ]
    for k, single in enumerate(singles):
        np.testing.assert_array_equal(diag.log_joint[k], single.log_joint)
        np.testing.assert_array_equal(diag.num_concepts[k], single.num_concepts)
    kept = singles[diag.best_chain]
    np.testing.assert_array_equal(run.log_joint, kept.log_joint)
    assert run.best_sweep == kept.best_sweep
    assert torch.equal(run.final_state.labels, kept.final_state.labels)
    assert torch.equal(run.best_state.labels, kept.best_state.labels)
    assert torch.equal(run.final_state.log_w, kept.final_state.log_w)


def test_fit_house_converged_and_cli(house, tmp_path):
    config = SpCoConfig(num_concepts=3, prior="dirichlet", alpha=1e3, gamma=0.0)
    result, diag = fit_house_converged(house, SpCoSettings(model=config), chains=2, block=20,
                                       max_sweeps=40, progress=False)  # fmt: skip
    assert diag.converged and len(result.trace.objective) == diag.sweeps == 20
    out = tmp_path / "fit"
    code = main(["fit", "--out", str(out), "--sweeps", "auto", "--chains", "2",
                 "--max-sweeps", "20", "--concepts", "8"])  # fmt: skip
    assert code == 0
    report = json.loads((out / "convergence.json").read_text())
    assert report["sweeps_per_chain"] == 20 and report["seeds"] == [0, 1]
    assert len(report["checks"]) == 1
    with pytest.raises(SystemExit):
        main(["fit", "--out", str(out), "--sweeps", "many"])
