"""Trying a model variant through the Python API as docs/library.md shows it (issues found by a
Bayesian-ML user: the summary table, the neighbourhood's error, the saved log joint)."""

from __future__ import annotations

from pathlib import Path

import pyro
import pytest
import torch
from pyro import poutine
from pyro.infer import MCMC

from spcopyro.gibbs import SpCoGibbs, mcmc_summary
from spcopyro.model import check_model_data, spcomapping_model
from tests.gibbs_problems import config, random_problem

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def mcmc_run():
    _, data = random_problem(seed=2)
    cfg = config()
    pyro.set_rng_seed(0)
    mcmc = MCMC(SpCoGibbs(), num_samples=6, warmup_steps=2, disable_progbar=True)
    mcmc.run(data, cfg)
    return mcmc, data, cfg


def test_mcmc_summary_takes_the_sites_to_summarise(mcmc_run, capsys):
    # mcmc_summary printed one row per entry of every saved site: with the default save_params
    # pi, theta [L, K] and w [L, V], 26,760 rows on the README's house, and had no way to ask
    # for the label-invariant sites the docs say to judge R-hat by
    mcmc, data, _ = mcmc_run
    everything = mcmc_summary(mcmc, show=False)
    capsys.readouterr()
    chosen = mcmc_summary(mcmc, sites=("log_joint", "num_concepts", "labels"))
    assert set(chosen) == {"log_joint", "num_concepts", "labels"}
    for site in ("log_joint", "num_concepts"):
        for name, value in everything[site].items():
            torch.testing.assert_close(chosen[site][name], value, equal_nan=True)
    torch.testing.assert_close(chosen["labels"]["entropy"], everything["labels"]["entropy"])
    printed = capsys.readouterr().out
    assert "log_joint" in printed and f"labels: {data.num_free} cells" in printed
    assert "theta[" not in printed and "pi[" not in printed
    assert set(mcmc_summary(mcmc, show=False, sites="pi")) == {"pi"}  # one name, not letters
    with pytest.raises(ValueError, match=r"no saved site 'gamma'; the run saved \['labels', "):
        mcmc_summary(mcmc, sites=("log_joint", "gamma"))


def test_the_saved_log_joint_is_the_models_log_density_at_the_sample(mcmc_run):
    # docs/library.md: "The log_joint that SpCoGibbs saves per sample is this sum [the trace's
    # log_prob_sum] at the sample's pi, theta, w and labels"
    mcmc, data, cfg = mcmc_run
    samples = mcmc.get_samples()
    for i in range(samples["pi"].shape[0]):
        values = {site: samples[site][i] for site in ("pi", "theta", "w", "labels")}
        model = poutine.condition(spcomapping_model, data=values)
        density = float(poutine.trace(model).get_trace(data, cfg).log_prob_sum())
        assert density == pytest.approx(float(samples["log_joint"][i]), rel=1e-9, abs=1e-9)


def test_with_sampled_hyperparameters_the_saved_log_joint_adds_their_hyperpriors():
    # docs/library.md: with hyperparameters sampled the saved log_joint is the trace's sum under
    # the sample's alpha and gamma plus their log hyperpriors (the trace at the starting config
    # differed by 5-900 nats on the library's house, with no word of why)
    from spcopyro.gibbs import GibbsOptions
    from spcopyro.gibbs.hyper_options import HyperparameterOptions
    from spcopyro.gibbs.hyperparameters import log_hyperprior

    _, data = random_problem(seed=2)
    hyper = HyperparameterOptions(alpha=True, gamma="exchange")
    pyro.set_rng_seed(0)
    mcmc = MCMC(SpCoGibbs(options=GibbsOptions(hyper=hyper)), num_samples=3, warmup_steps=2,
                disable_progbar=True)  # fmt: skip
    mcmc.run(data, config())
    samples = mcmc.get_samples()
    for i in range(3):
        values = {site: samples[site][i] for site in ("pi", "theta", "w", "labels")}
        cfg = config(alpha=float(samples["alpha"][i]), gamma=float(samples["gamma"][i]))
        model = poutine.condition(spcomapping_model, data=values)
        density = float(poutine.trace(model).get_trace(data, cfg).log_prob_sum())
        density += log_hyperprior(data, cfg, hyper)
        assert density == pytest.approx(float(samples["log_joint"][i]), rel=1e-9, abs=1e-9)


def test_a_neighbourhood_mismatch_says_how_prepare_model_data_remakes_the_data():
    # config.replace(connectivity=8) with data made for 4 neighbours: the error pointed to
    # make_model_data(grid, counts, ...) alone, which a user of prepare_model_data(house,
    # settings) has neither argument of
    _, data = random_problem(seed=0)
    with pytest.raises(ValueError, match=r"4 neighbours a cell but config.connectivity is 8") as e:
        check_model_data(data, config(connectivity=8))
    assert "prepare_model_data(house, settings.replace(connectivity=8))" in str(e.value)
    assert "make_model_data(grid, counts, connectivity=8)" in str(e.value)


@pytest.mark.parametrize("extra", ["prior", "factor"])
def test_the_kernel_names_a_site_spcomapping_model_has_not(extra):
    # a custom model with a further latent site (a prior on a parameter) or a pyro.factor was
    # refused only by the density check, "the model's log density ... is 71476.54 where
    # spcomapping_model's ... is 71475.54", naming no site
    _, data = random_problem(seed=0)
    cfg = config()

    def custom(data, config):
        spcomapping_model(data, config)
        if extra == "prior":
            pyro.sample("tau", pyro.distributions.Gamma(2.0, 1.0))
        else:
            pyro.factor("bonus", torch.tensor(1.0, dtype=torch.float64))

    name, what = (
        ("tau", "latent site") if extra == "prior" else ("bonus", "observed site or factor")
    )
    mcmc = MCMC(SpCoGibbs(custom), num_samples=2, disable_progbar=True)
    with pytest.raises(
        ValueError, match=rf"the model has a {what} '{name}' that spcomapping_model"
    ):
        mcmc.run(data, cfg)


def test_the_kernel_still_takes_deterministic_sites():
    # pyro.deterministic adds no density: a model recording one is spcomapping_model's
    _, data = random_problem(seed=0)

    def recording(data, config):
        spcomapping_model(data, config)
        pyro.deterministic("twice_gamma", torch.tensor(2.0 * config.gamma))

    mcmc = MCMC(SpCoGibbs(recording), num_samples=2, disable_progbar=True)
    mcmc.run(data, config())
    assert mcmc.get_samples()["pi"].shape == (2, 3)


def test_the_trace_sites_come_in_the_order_the_library_page_gives():
    # docs/library.md said a further modality's sites come after the paper's seven; its table
    # comes after w (in the concepts plate), its observations after words. use_images=False
    # drops the observed site images, not theta
    from pyro.poutine.util import site_is_subsample

    from spcopyro.model import Modality, parameter_site

    _, data = random_problem(seed=0)
    objects = torch.ones(data.obs_cells.shape[0], 2, dtype=torch.float64)
    data = data._replace(
        modalities=(*data.modalities, Modality("objects", parameter_site("objects"), objects))
    )
    cfg = config(use_images=False, concentrations={"objects": 1.0})
    trace = poutine.trace(spcomapping_model).get_trace(data, cfg)
    names = [
        n for n, s in trace.nodes.items() if s["type"] == "sample" and not site_is_subsample(s)
    ]
    assert names == ["pi", "theta", "w", "objects_probs", "labels", "potts", "words", "objects"]
    page = (Path(__file__).resolve().parents[1] / "docs" / "library.md").read_text("utf-8")
    assert "`<name>_probs` `[L, K_m]` after `w` and\n`<name>` `[M, K_m]` after `words`" in page


def test_a_second_guide_needs_a_fresh_param_store_as_the_library_page_says():
    # The SVI recipe of docs/library.md made a MeanFieldGuide with no word on Pyro's global
    # param store: fitting a second variant in the same session (another L) failed with
    # "Shape mismatch inside plate('concepts') at site theta dim -1, 5 vs 3", and one of the same
    # L silently continued from the first guide's trained values
    from pyro.infer import SVI

    from spcopyro.guides import MeanFieldELBO, MeanFieldGuide

    _, data = random_problem(seed=0)

    def fit(L: int, **guide_options) -> MeanFieldGuide:
        cfg = config(num_concepts=L)
        guide = MeanFieldGuide(data, cfg, **guide_options)
        svi = SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
        svi.step(data, cfg)
        assert guide.marginals().shape == (data.num_free, L)
        return guide

    pyro.clear_param_store()
    fit(3)
    with pytest.raises(ValueError, match=r"Shape mismatch inside plate\('concepts'\)"):
        fit(5)  # what the page warns of
    fit(5, name="five_concepts")  # a name of its own
    pyro.clear_param_store()  # or a fresh store
    fit(5)
    page = (Path(__file__).resolve().parents[1] / "docs" / "library.md").read_text("utf-8")
    svi_block = page.split("With Pyro's SVI:", 1)[1].split("```", 2)[1]
    assert svi_block.index("pyro.clear_param_store()") < svi_block.index("MeanFieldGuide(data")
    assert "Call `pyro.clear_param_store()` before making each new\nguide" in page


@pytest.mark.parametrize("save_params", [("num_concepts",), ("log_joint", "num_concepts")])
def test_num_concepts_is_float64_whatever_else_is_saved(save_params):
    # num_concepts was made in torch's default dtype (float32) and MCMC packs the saved sites
    # into one tensor: saved beside log_joint or pi it came back float64, alone float32
    _, data = random_problem(seed=2)
    pyro.set_rng_seed(0)
    mcmc = MCMC(
        SpCoGibbs(save_params=save_params), num_samples=3, warmup_steps=1, disable_progbar=True
    )
    mcmc.run(data, config())
    samples = mcmc.get_samples()
    assert {name: value.dtype for name, value in samples.items()} == dict.fromkeys(
        save_params, torch.float64
    )
