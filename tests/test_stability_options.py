"""The stability options of issue 4 (:class:`~spcopyro.gibbs.options.GibbsOptions`): gamma
annealing (burn-in), Swendsen-Wang cluster moves, and best-of-K chains. (The cluster move's
distribution is tested in test_gibbs_joint.py: against the enumerated posterior, and in Geweke's
test on both backends.)"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem
from pyro.infer import MCMC

from spcopyro.cli.main import main
from spcopyro.config import preset
from spcopyro.fit.house import best_chain, fit_house, fit_house_chains, fit_house_converged
from spcopyro.gibbs.anneal import annealed_config, annealed_gamma, check_anneal_sweeps
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.cluster import bond_clusters, maybe_cluster_move
from spcopyro.gibbs.kernel import SpCoGibbs
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import run_gibbs
from spcopyro.gibbs.sampler import init, step
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.gibbs.sweep import gibbs_sweep
from spcopyro.synthetic import HouseSpec, make_house, write_synthetic

TORCH = GibbsOptions(backend="torch")


def test_schedule_by_hand():
    assert [annealed_gamma(4.0, s, 4) for s in range(6)] == [1.0, 2.0, 3.0, 4.0, 4.0, 4.0]
    assert annealed_gamma(4.0, 0, 0) == 4.0
    cfg = config(gamma=2.0)
    assert annealed_config(cfg, 0, 2).gamma == 1.0
    assert annealed_config(cfg, 1, 2) is cfg  # the target from sweep A - 1 on
    assert check_anneal_sweeps(3) == 3
    for bad in (-1, 1.5, True, float("inf"), float("nan"), None, "3"):  # inf: OverflowError
        with pytest.raises(ValueError, match="non-negative integer"):
            check_anneal_sweeps(bad)


def test_run_gibbs_anneals_the_label_sweeps_and_keeps_the_best_after_them():
    """The annealed run is the manual loop with gamma_s, draw for draw; its trace is the target's
    log joint; its best state is never an annealing sweep's."""
    cfg = config(gamma=1.5)
    _, data = random_problem(seed=11)
    anneal, sweeps = 6, 10
    options = GibbsOptions(backend="torch", anneal_sweeps=anneal)
    run = run_gibbs(data, cfg, sweeps, seed=3, options=options, progress=False)

    generator = torch.Generator().manual_seed(3)
    plan = make_sweep_plan(data)
    state = init(data, cfg, generator, None)
    for s in range(sweeps):
        state = gibbs_sweep(state, data, annealed_config(cfg, s, anneal), generator, plan)
    assert torch.equal(run.final_state.labels, state.labels)
    torch.testing.assert_close(run.final_state.log_w, state.log_w)

    plain = run_gibbs(data, cfg, sweeps, seed=3, options=GibbsOptions(backend="torch"),
                      progress=False)  # fmt: skip
    assert not torch.equal(plain.final_state.labels, run.final_state.labels)
    assert run.best_sweep >= anneal - 1
    assert run.log_joint[run.best_sweep] == run.log_joint[anneal - 1 :].max()
    with pytest.raises(ValueError, match="must not exceed num_sweeps"):
        run_gibbs(data, cfg, 5, seed=3, options=GibbsOptions(anneal_sweeps=6), progress=False)


def test_step_reports_the_annealed_coupling():
    cfg = config(gamma=3.0)
    _, data = random_problem(seed=11)
    generator = torch.Generator().manual_seed(0)
    state = init(data, cfg, generator)
    options = GibbsOptions(backend="torch", anneal_sweeps=3)
    infos = []
    for s in range(5):
        state, info = step(state, data, cfg, generator, sweep=s, options=options)
        infos.append((info.gamma, info.annealing))
    assert infos == [(1.0, True), (2.0, True), (3.0, False), (3.0, False), (3.0, False)]


def test_annealing_reaches_the_backends(backend):
    """Both backends read gamma per sweep: a run annealed over all its sweeps differs from a
    plain one with the same seed, and annealing over 0 or 1 sweep changes nothing."""
    cfg = config(gamma=0.8)
    _, data = random_problem(seed=12, copies=3)

    def trace(anneal: int) -> np.ndarray:
        options = GibbsOptions(backend=backend.name, anneal_sweeps=anneal)
        return run_gibbs(data, cfg, 8, seed=5, options=options, progress=False).log_joint

    np.testing.assert_array_equal(trace(0), trace(1))
    assert not np.array_equal(trace(0), trace(8))


def test_kernel_anneals_over_warmup_only():
    cfg = config(gamma=3.0)
    _, data = random_problem(seed=13)
    kernel = SpCoGibbs(options=GibbsOptions(backend="torch"), anneal=True)
    gammas: list[float] = []
    torch_backend = get_backend("torch")

    class Spy:
        """The torch backend, recording the coupling each sweep is drawn under."""

        name = "spy"

        def sweep(self, state, data, config, generator, plan, unobserved_refresh):
            gammas.append(config.gamma)
            return torch_backend.sweep(state, data, config, generator, plan, unobserved_refresh)

        def __getattr__(self, name):  # the rest of the backend, as it is
            return getattr(torch_backend, name)

    kernel._backend = Spy()
    MCMC(kernel, num_samples=2, warmup_steps=3, disable_progbar=True).run(data, cfg)
    assert gammas == pytest.approx([1.0, 2.0, 3.0, 3.0, 3.0])
    gammas.clear()
    kernel.anneal = False
    MCMC(kernel, num_samples=2, warmup_steps=3, disable_progbar=True).run(data, cfg)
    assert gammas == [3.0] * 5


def test_kernel_refuses_annealing_without_warmup():
    """anneal=True with warmup_steps=0 annealed over nothing: it ran at the full gamma silently."""
    cfg = config(gamma=3.0)
    _, data = random_problem(seed=13)
    kernel = SpCoGibbs(options=GibbsOptions(backend="torch"), anneal=True)
    with pytest.raises(ValueError, match="warmup_steps=0"):
        MCMC(kernel, num_samples=2, warmup_steps=0, disable_progbar=True).run(data, cfg)


def test_options_are_validated():
    assert GibbsOptions() == GibbsOptions("auto", 1.0, 0.0, 0)
    for bad, field in (
        (dict(cluster_moves=1.5), "cluster_moves"),
        (dict(cluster_moves=-0.1), "cluster_moves"),
        (dict(unobserved_refresh=0.0), "unobserved_refresh"),
        (dict(unobserved_refresh=1.5), "unobserved_refresh"),
        (dict(backend="jax"), "backend"),
    ):
        with pytest.raises(ValueError, match=f"GibbsOptions.{field}="):
            GibbsOptions(**bad)
    with pytest.raises(ValueError, match="non-negative integer"):
        GibbsOptions(anneal_sweeps=-1)
    assert GibbsOptions().replace(cluster_moves=0.5).cluster_moves == 0.5


def test_cluster_move_option():
    cfg = config(gamma=0.9)
    _, data = random_problem(seed=14)
    generator = torch.Generator().manual_seed(1)
    state = init(data, cfg, generator)
    before = generator.get_state()
    assert maybe_cluster_move(state, data, cfg, generator, 0.0) is state  # probability 0: no draw
    assert torch.equal(generator.get_state(), before)
    moved = maybe_cluster_move(state, data, cfg, generator, 1.0)
    assert moved is not state and moved.log_emissions is state.log_emissions  # labels only
    # step() composes the move before the backend's sweep: with cluster_moves = 1 the step is the
    # cluster move then gibbs_sweep, draw for draw.
    options = GibbsOptions(backend="torch", cluster_moves=1.0)
    stepped, _ = step(state, data, cfg, torch.Generator().manual_seed(2), options=options)
    by_hand_generator = torch.Generator().manual_seed(2)
    by_hand = maybe_cluster_move(state, data, cfg, by_hand_generator, 1.0)
    by_hand = gibbs_sweep(by_hand, data, cfg, by_hand_generator)
    assert torch.equal(stepped.labels, by_hand.labels)
    assert torch.equal(stepped.log_w, by_hand.log_w)
    plain, _ = step(state, data, cfg, torch.Generator().manual_seed(2), options=TORCH)
    assert not torch.equal(plain.labels, stepped.labels)
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
    options = GibbsOptions(anneal_sweeps=15)
    result, diag = fit_house_converged(house, cfg, options=options, chains=2, block=10,
                                       max_sweeps=20, progress=False)  # fmt: skip
    assert diag.sweeps in (10, 20)
    assert len(result.trace.objective) == diag.log_joint.shape[1] == 15 + diag.sweeps
    assert result.best_iteration >= 14


def test_best_of_chains_keeps_the_highest_log_joint(house):
    cfg = preset("original-code", gamma=3.0, num_concepts=8)
    results = fit_house_chains(house, cfg, sweeps=15, seeds=[5, 6, 7], progress=False)
    values = [r.best_objective for r in results]
    assert values == [float(r.trace.objective[r.best_iteration]) for r in results]
    assert len(set(values)) == 3  # the chains are seeded differently
    kept = fit_house(house, cfg, sweeps=15, seed=5, chains=3, progress=False)
    np.testing.assert_array_equal(kept.labels, results[best_chain(results)].labels)
    assert kept.best_objective == max(values)
    one = fit_house(house, cfg, sweeps=15, seed=5, progress=False)
    np.testing.assert_array_equal(one.labels, results[0].labels)
    assert [r.inference["seed"] for r in results] == [5, 6, 7]
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
