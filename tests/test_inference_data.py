"""Gibbs runs in ArviZ (spcopyro.gibbs.inference_data, issue 24 item 5): an MCMC run of the
kernel and per-sweep chains load as InferenceData whose numbers are the run's own, and ArviZ's
split R-hat agrees with the project's (Pyro's) on the same draws."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem
from pyro.infer import MCMC

from spcopyro.gibbs.convergence import split_rhat
from spcopyro.gibbs.kernel import DEFAULT_SAVE_PARAMS, SpCoGibbs
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import run_gibbs

az = pytest.importorskip("arviz", reason="ArviZ is the arviz extra (pip install -e '.[dev]')")
pytestmark = pytest.mark.filterwarnings(
    "ignore:num_chains=2 is more than available_cpu", "ignore::FutureWarning"
)

from spcopyro.gibbs.inference_data import to_inference_data  # noqa: E402

TORCH = GibbsOptions(backend="torch")


@pytest.fixture(scope="module")
def problem():
    _, data = random_problem(seed=3)
    return data, config()


@pytest.fixture(scope="module")
def mcmc(problem):
    data, cfg = problem
    run = MCMC(SpCoGibbs(options=TORCH), num_samples=40, warmup_steps=5, num_chains=2,
               disable_progbar=True)  # fmt: skip
    run.run(data, cfg)
    return run


def test_an_mcmc_run_loads_with_the_models_sites_and_the_observations(mcmc, problem):
    data, cfg = problem
    idata = to_inference_data(mcmc)
    samples = mcmc.get_samples(group_by_chain=True)
    posterior = idata.posterior
    assert set(idata.groups()) >= {"posterior", "sample_stats", "observed_data"}
    assert posterior.sizes["chain"] == 2 and posterior.sizes["draw"] == 40
    for name in ("pi", "log_joint", *(m.parameter for m in data.modalities)):
        np.testing.assert_array_equal(posterior[name].values, samples[name].numpy())
    assert posterior["pi"].dims == ("chain", "draw", "concept")
    assert posterior["pi"].sizes["concept"] == cfg.num_concepts
    assert "labels" not in posterior  # large, and meaningless across chains: only on request
    assert posterior["num_concepts"].dtype == np.int64
    ranked = posterior["pi_sorted"].values  # [C, D, L]
    assert (np.diff(ranked, axis=-1) <= 0).all()
    np.testing.assert_allclose(np.sort(ranked, -1), np.sort(samples["pi"].numpy(), -1))
    np.testing.assert_array_equal(idata.sample_stats["lp"].values, samples["log_joint"].numpy())
    for m in data.modalities:
        np.testing.assert_array_equal(idata.observed_data[m.name].values, m.counts.numpy())
        assert idata.observed_data[m.name].dims == ("observation", f"{m.name}_item")
    with_labels = to_inference_data(mcmc, include_labels=True)
    np.testing.assert_array_equal(with_labels.posterior["labels"].values, samples["labels"])
    with pytest.raises(ValueError, match="warmup applies to per-sweep traces only"):
        to_inference_data(mcmc, warmup=2)  # was ignored silently


def test_arviz_diagnostics_agree_with_the_projects(mcmc):
    """ArviZ's classic split R-hat of the log joint is Pyro's split_gelman_rubin (the statistic
    of --sweeps auto) on the same draws; the summary has a row per label-invariant number."""
    idata = to_inference_data(mcmc)
    traces = mcmc.get_samples(group_by_chain=True)["log_joint"].numpy()  # [2, 40]
    ours = split_rhat(traces)
    theirs = float(az.rhat(idata, var_names=["log_joint"], method="split")["log_joint"])
    assert theirs == pytest.approx(ours, rel=1e-6)
    summary = az.summary(idata, var_names=["log_joint", "num_concepts", "pi_sorted"])
    assert {"log_joint", "num_concepts", "pi_sorted[1]"} <= set(summary.index)
    assert np.isfinite(summary.loc["log_joint", ["ess_bulk", "r_hat"]].astype(float)).all()


def test_per_sweep_chains_split_warmup_like_the_stopping_rule(problem):
    data, cfg = problem
    runs = [run_gibbs(data, cfg, 30, seed=s, options=TORCH, progress=False) for s in (0, 1)]
    idata = to_inference_data(runs)
    assert idata.posterior.sizes == {"chain": 2, "draw": 15}
    np.testing.assert_array_equal(idata.posterior["log_joint"].values[1], runs[1].log_joint[15:])
    np.testing.assert_array_equal(
        idata.warmup_posterior["num_concepts"].values[0], runs[0].num_concepts[:15]
    )
    window = np.stack([r.log_joint[15:] for r in runs])
    rhat = float(az.rhat(idata, var_names=["log_joint"], method="split")["log_joint"])
    assert rhat == pytest.approx(split_rhat(window), rel=1e-6)
    assert to_inference_data(runs[0], warmup=0).posterior.sizes == {"chain": 1, "draw": 30}
    with pytest.raises(ValueError, match="different numbers of sweeps"):
        to_inference_data([runs[0], run_gibbs(data, cfg, 10, seed=2, options=TORCH,
                                               progress=False)])  # fmt: skip
    with pytest.raises(ValueError, match=r"warmup must lie in \[0, 30\)"):
        to_inference_data(runs, warmup=30)
    with pytest.raises(TypeError, match="takes a pyro.infer.MCMC run"):
        to_inference_data([torch.zeros(3)])


def test_gibbs_results_convert_and_an_optimisers_trace_is_refused():
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=1, spec=HouseSpec(height=24, width=30, num_rooms=2, num_trials=2,
                                              min_room_size=8))  # fmt: skip
    settings = preset("original-code", gamma=3.0, num_concepts=5)
    results = fit_house_chains(house, settings, seeds=[0, 1], sweeps=8, progress=False)
    idata = to_inference_data(results, warmup=2)
    np.testing.assert_array_equal(idata.posterior["log_joint"].values[0],
                                  results[0].trace.objective[2:])  # fmt: skip
    cavi = fit_house_chains(house, settings, seeds=[0], sweeps=3, method="cavi", progress=False)
    with pytest.raises(ValueError, match="^a 'cavi' result's trace is an optimiser's objective"):
        to_inference_data(cavi)
    # vi-gibbs' trace is the sampler's log joint per sweep: a Markov chain (it was refused)
    warm = fit_house_chains(house, settings, seeds=[0, 1], sweeps=6, method="vi-gibbs",
                            progress=False)  # fmt: skip
    np.testing.assert_array_equal(to_inference_data(warm).posterior["log_joint"].values[1],
                                  warm[1].trace.objective[3:])  # fmt: skip


def test_arvizs_own_pyro_converter_takes_a_run_without_labels(problem):
    """``az.from_pyro`` asks the kernel for divergences (none) and Pyro for diagnostics, which
    crash on integer labels: without them it converts the run itself."""
    data, cfg = problem
    run = MCMC(SpCoGibbs(save_params=DEFAULT_SAVE_PARAMS, options=TORCH), num_samples=6,
               warmup_steps=2, disable_progbar=True)  # fmt: skip
    run.run(data, cfg)
    idata = az.from_pyro(run, log_likelihood=False)
    assert not idata.sample_stats["diverging"].values.any()
    np.testing.assert_array_equal(idata.posterior["pi"].values[0], run.get_samples()["pi"])


def test_without_arviz_the_error_says_how_to_install_it(mcmc, monkeypatch):
    monkeypatch.setitem(sys.modules, "arviz", None)
    with pytest.raises(ImportError, match=r"pip install 'spcopyro\[arviz\]'"):
        to_inference_data(mcmc)
