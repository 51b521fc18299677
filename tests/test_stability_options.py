"""The stability options of issue 4: gamma annealing (burn-in), Swendsen-Wang cluster moves and
best-of-K chains. (The cluster move's distribution is tested in test_gibbs_joint.py: against the
enumerated posterior, and in Geweke's test on both backends.)"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem
from pyro.infer import MCMC

from spcopyro.cli import main
from spcopyro.config import SpCoConfig, preset
from spcopyro.fit import best_chain, fit_house, fit_house_chains, fit_house_converged
from spcopyro.gibbs.anneal import annealed_config, annealed_gamma, check_anneal_sweeps
from spcopyro.gibbs.api import run_gibbs
from spcopyro.gibbs.cluster import bond_clusters, maybe_cluster_move
from spcopyro.gibbs.init import initial_state
from spcopyro.gibbs.kernel import SpCoGibbs
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.gibbs.sweep import gibbs_sweep
from spcopyro.synthetic import HouseSpec, make_house, write_synthetic


def test_schedule_by_hand():
    assert [annealed_gamma(4.0, s, 4) for s in range(6)] == [1.0, 2.0, 3.0, 4.0, 4.0, 4.0]
    assert annealed_gamma(4.0, 0, 0) == 4.0
    cfg = config(gamma=2.0)
    assert annealed_config(cfg, 0, 2).gamma == 1.0
    assert annealed_config(cfg, 1, 2) is cfg  # the target from sweep A - 1 on
    assert check_anneal_sweeps(3) == 3
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="non-negative integer"):
            check_anneal_sweeps(bad)


def test_run_gibbs_anneals_the_label_sweeps_and_keeps_the_best_after_them():
    """The annealed run is the manual loop with gamma_s, draw for draw; its trace is the target's
    log joint; its best state is never an annealing sweep's."""
    cfg = config(gamma=1.5)
    _, data = random_problem(seed=11)
    anneal, sweeps = 6, 10
    run = run_gibbs(data, cfg, sweeps, seed=3, backend="torch", progress=False,
                    anneal_sweeps=anneal)  # fmt: skip

    generator = torch.Generator().manual_seed(3)
    plan = make_sweep_plan(data)
    state = initial_state(data, cfg, generator, None)
    for s in range(sweeps):
        state = gibbs_sweep(state, data, annealed_config(cfg, s, anneal), generator, plan)
    assert torch.equal(run.final_state.labels, state.labels)
    torch.testing.assert_close(run.final_state.log_w, state.log_w)

    plain = run_gibbs(data, cfg, sweeps, seed=3, backend="torch", progress=False)
    assert not torch.equal(plain.final_state.labels, run.final_state.labels)
    assert run.best_sweep >= anneal - 1
    assert run.log_joint[run.best_sweep] == run.log_joint[anneal - 1 :].max()
    with pytest.raises(ValueError, match="must not exceed num_sweeps"):
        run_gibbs(data, cfg, 5, seed=3, anneal_sweeps=6, progress=False)


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_annealing_reaches_the_backends(backend):
    """Both backends read gamma per sweep: a run annealed over all its sweeps differs from a
    plain one with the same seed, and annealing over 0 or 1 sweep changes nothing."""
    cfg = config(gamma=0.8)
    _, data = random_problem(seed=12, copies=3)

    def trace(anneal: int) -> np.ndarray:
        run = run_gibbs(data, cfg, 8, seed=5, backend=backend, progress=False,
                        anneal_sweeps=anneal)  # fmt: skip
        return run.log_joint

    np.testing.assert_array_equal(trace(0), trace(1))
    assert not np.array_equal(trace(0), trace(8))


def test_kernel_anneals_over_warmup_only():
    cfg = config(gamma=3.0)
    _, data = random_problem(seed=13)
    kernel = SpCoGibbs(backend="torch", anneal=True)
    gammas: list[float] = []
    sweep = kernel._sweep

    def spy(state, data, config, generator, plan):
        gammas.append(config.gamma)
        return sweep(state, data, config, generator, plan)

    kernel._sweep = spy
    MCMC(kernel, num_samples=2, warmup_steps=3, disable_progbar=True).run(data, cfg)
    assert gammas == pytest.approx([1.0, 2.0, 3.0, 3.0, 3.0])
    gammas.clear()
    kernel.anneal = False
    MCMC(kernel, num_samples=2, warmup_steps=3, disable_progbar=True).run(data, cfg)
    assert gammas == [3.0] * 5


def test_cluster_move_option():
    with pytest.raises(ValueError, match="cluster_moves"):
        SpCoConfig(cluster_moves=1.5)
    cfg = config(gamma=0.9)
    _, data = random_problem(seed=14)
    generator = torch.Generator().manual_seed(1)
    state = initial_state(data, cfg, generator)
    before = generator.get_state()
    assert maybe_cluster_move(state, data, cfg, generator) is state  # probability 0: no draw
    assert torch.equal(generator.get_state(), before)
    moved = maybe_cluster_move(state, data, cfg.replace(cluster_moves=1.0), generator)
    assert moved is not state and moved.log_w is state.log_w  # labels only
    # Bonds join agreeing neighbours only: with gamma huge, the clusters are the label regions.
    labels = torch.zeros(data.num_free, dtype=torch.long)
    labels[: data.num_free // 2] = 1
    count, cluster = bond_clusters(labels, data.pairs, 50.0, generator)
    same = labels[data.pairs[:, 0]] == labels[data.pairs[:, 1]]
    joined = cluster[data.pairs[:, 0]] == cluster[data.pairs[:, 1]]
    assert torch.equal(same, joined) and count == 2
    assert bond_clusters(labels, data.pairs, 0.0, generator)[0] == data.num_free


@pytest.fixture(scope="module")
def house():
    return make_house(seed=4, spec=HouseSpec(height=36, width=44, num_rooms=3))


def test_converged_run_leaves_the_annealing_out_of_rhat_and_the_sweep_count(house):
    cfg = preset("original-code", gamma=3.0, num_concepts=6)
    result, diag = fit_house_converged(house, cfg, chains=2, block=10, max_sweeps=20,
                                       progress=False, anneal_sweeps=15)  # fmt: skip
    assert diag.sweeps in (10, 20)
    assert len(result.log_joint) == diag.log_joint.shape[1] == 15 + diag.sweeps
    assert result.best_sweep >= 14


def test_best_of_chains_keeps_the_highest_log_joint(house):
    cfg = preset("original-code", gamma=3.0, num_concepts=8)
    results = fit_house_chains(house, cfg, sweeps=15, seeds=[5, 6, 7], progress=False)
    values = [r.best_log_joint for r in results]
    assert values == [float(r.log_joint[r.best_sweep]) for r in results]
    assert len(set(values)) == 3  # the chains are seeded differently
    kept = fit_house(house, cfg, sweeps=15, seed=5, chains=3, progress=False)
    np.testing.assert_array_equal(kept.labels_best, results[best_chain(results)].labels_best)
    assert kept.best_log_joint == max(values)
    one = fit_house(house, cfg, sweeps=15, seed=5, progress=False)
    np.testing.assert_array_equal(one.labels_best, results[0].labels_best)
    with pytest.raises(ValueError, match="chains must be a positive integer"):
        fit_house(house, cfg, sweeps=15, chains=0)
    with pytest.raises(ValueError, match="positive integer or 'auto'"):
        fit_house(house, cfg, sweeps="many")


def test_cli_fit_with_chains_and_annealing(tmp_path, capsys):
    data = write_synthetic(tmp_path / "d", seed=2, spec=HouseSpec(height=36, width=44, num_rooms=3))
    out = tmp_path / "fit"
    argv = ["fit", str(data), "--out", str(out), "--sweeps", "12", "--chains", "2",
            "--anneal-sweeps", "4", "--preset", "original-code", "--gamma", "3",
            "--concepts", "8", "--cluster-moves", "0.5"]  # fmt: skip
    assert main(argv) == 0
    assert "best of 2 chains: kept chain" in capsys.readouterr().out
    report = json.loads((out / "chains.json").read_text())
    assert report["seeds"] == [0, 1] and len(report["best_log_joint"]) == 2
    assert report["best_chain"] == int(np.argmax(report["best_log_joint"]))
    assert main([*argv[:5], "3", *argv[6:]]) == 2  # 3 sweeps cannot hold 4 annealing sweeps
    assert "anneal_sweeps (4) must not exceed num_sweeps (3)" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*argv[:7], "0", *argv[8:]])  # --chains 0
