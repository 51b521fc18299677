"""The library API used as a researcher uses it (issues found by reading docs/library.md and
the docstrings): bad model data refused with a message by every inference entry point, seeds
checked, the Pyro kernel's ``save_params`` and the SVI guide's param-store round trip."""

from __future__ import annotations

import numpy as np
import pyro
import pytest
import torch
from pyro.infer import MCMC, SVI

from spcopyro.config import preset
from spcopyro.fit.house import fit_house, fit_house_chains
from spcopyro.fit.registry import get_method
from spcopyro.gibbs import SpCoGibbs, init, start_chain
from spcopyro.guides import MeanFieldELBO, MeanFieldGuide
from spcopyro.model import spcomapping_model
from spcopyro.synthetic import HouseSpec, make_house
from tests.gibbs_problems import config, random_problem

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _bad_counts(data):
    """(what, data) with the words' counts broken in each way an inference method mis-read."""
    words = data.word_counts
    nan = words.clone()
    nan[1, 2] = float("nan")
    inf, one_negative = words.clone(), words.clone()
    inf[3, 1] = float("inf")
    one_negative[2, 0] = -0.5  # the others >= 0: caught by the min, not a sum gone negative
    return [
        ("must be finite and >= 0; row 1 .* column 2 is nan", data.with_counts("words", nan)),
        ("must be finite and >= 0; row 3 .* column 1 is inf", data.with_counts("words", inf)),
        (
            "must be finite and >= 0; row 2 .* column 0 is -0.5",
            data.with_counts("words", one_negative),
        ),
        ("must be finite and >= 0; row 0", data.with_counts("words", -1.0 - words)),
        (r"have shape \(4, 4\), expected \(5, K\)", data.with_counts("words", words[:-1])),
        (  # and says the conversion (it named the dtype alone)
            r"must be torch.float64, got torch.float32: convert them with counts\.double\(\)",
            data.with_counts("words", words.float()),
        ),
    ]


@pytest.mark.parametrize("method", ["gibbs", "cavi", "lbp", "svi", "stochastic-vi"])
def test_every_method_refuses_counts_that_are_not_finite_non_negative_rows(method):
    # CAVI, LBP and memoized VI returned an ELBO of NaN for NaN or negative counts; Gibbs said
    # "gamma concentration must be finite and positive", a wrong row count "index_add_()".
    cfg = config()
    _, data = random_problem(seed=3)
    inference = get_method(method)
    for message, bad in _bad_counts(data):
        with pytest.raises(ValueError, match=f"counts of modality 'words' {message}"):
            inference.run(bad, cfg, iterations=1, generator=torch.Generator().manual_seed(0),
                          progress=False)  # fmt: skip


@pytest.mark.parametrize("method", ["gibbs", "cavi", "lbp", "svi", "stochastic-vi"])
def test_every_method_names_iterations_and_generator(method):
    # iterations=0 said "the checkpoint's run has done 0 iterations" (no checkpoint given); a
    # seed passed as the generator failed in torch.randint's argument list
    cfg = config()
    _, data = random_problem(seed=3)
    inference = get_method(method)
    generator = torch.Generator().manual_seed(0)
    for iterations in (0, True, 2.0):
        with pytest.raises(
            ValueError, match=f"iterations must be an integer >= 1, got {iterations}"
        ):
            inference.run(data, cfg, iterations=iterations, generator=generator, progress=False)
    with pytest.raises(TypeError, match="generator must be a torch.Generator .*got int"):
        inference.run(data, cfg, iterations=1, generator=0, progress=False)
    with pytest.raises(TypeError, match="generator must be a torch.Generator .*got int"):
        init(data, cfg, 0)


def test_gibbs_init_the_kernel_and_the_guide_refuse_bad_counts():
    cfg = config()
    _, data = random_problem(seed=3)
    for message, bad in _bad_counts(data):
        with pytest.raises(ValueError, match=message):
            init(bad, cfg, torch.Generator().manual_seed(0))
        with pytest.raises(ValueError, match=message):
            MCMC(SpCoGibbs(), num_samples=1, disable_progbar=True).run(bad, cfg)
        with pytest.raises(ValueError, match=message):
            MeanFieldGuide(bad, cfg)


def test_the_model_itself_refuses_bad_counts_and_a_config_of_another_type():
    """The model, traced or run by Predictive directly, checks its data as the kernel and the
    guide do: a 1-D count gave a log density, negative counts NaN, a missing row a broadcast
    error deep in torch, and SpCoSettings "has no attribute 'num_concepts'"."""
    cfg = config()
    _, data = random_problem(seed=3)
    trace = lambda d, c: pyro.poutine.trace(spcomapping_model).get_trace(d, c)  # noqa: E731
    for message, bad in _bad_counts(data):
        with pytest.raises(ValueError, match=message):
            trace(bad, cfg)
    settings = preset("original-code", num_concepts=3)
    for call in (
        lambda: trace(data, settings),
        lambda: MCMC(SpCoGibbs(), num_samples=1, disable_progbar=True).run(data, settings),
        lambda: MeanFieldGuide(data, settings),
        lambda: init(data, settings, torch.Generator().manual_seed(0)),
    ):
        with pytest.raises(
            TypeError, match=r"SpCoConfig \(pass settings.model\), got SpCoSettings"
        ):
            call()
    with pytest.raises(TypeError, match="data must be a ModelData"):
        trace(settings, cfg)


def test_data_made_for_one_connectivity_are_refused_under_another():
    """Data whose neighbour table has 4 neighbours a cell, fitted under connectivity 8, ran
    silently as the 4-neighbour model (the same log joint)."""
    _, data = random_problem(seed=3, connectivity=4)
    eight = config(connectivity=8)
    match = "4 neighbours a cell but config.connectivity is 8"
    with pytest.raises(ValueError, match=match):
        start_chain(data, eight, seed=0)
    with pytest.raises(ValueError, match=match):
        pyro.poutine.trace(spcomapping_model).get_trace(data, eight)
    with pytest.raises(ValueError, match=match):
        get_method("cavi").run(
            data, eight, iterations=2, generator=torch.Generator().manual_seed(0)
        )


def test_predictive_refuses_samples_drawn_for_other_data_or_another_l():
    """Posterior samples of w over 4 words, replayed on data with 5 words (or on another
    num_concepts), were used silently or failed in a reshape deep inside Pyro."""
    cfg = config()
    _, data = random_problem(seed=3, V=4)
    mcmc = MCMC(SpCoGibbs(save_params=("pi", "theta", "w", "labels")), num_samples=2,
                warmup_steps=1, disable_progbar=True)  # fmt: skip
    mcmc.run(data, cfg)
    samples = mcmc.get_samples()
    _, wider = random_problem(seed=3, V=5)
    predictive = pyro.infer.Predictive(spcomapping_model, posterior_samples=samples,
                                       return_sites=("words",))  # fmt: skip
    with pytest.raises(ValueError, match=r"site 'w' has shape \(3, 4\).*\(3, 5\)"):
        predictive(wider, cfg)
    with pytest.raises(ValueError, match=r"site 'pi' has shape \(3,\).*\(4,\)"):
        predictive(data, config(num_concepts=4))
    assert predictive(data, cfg)["words"].shape[0] == 2


def test_the_kernel_names_options_of_the_wrong_type():
    with pytest.raises(TypeError, match="options must be a GibbsOptions .*got dict"):
        SpCoGibbs(options={"cluster_moves": 0.1})
    with pytest.raises(TypeError, match="anneal must be True or False, got 'yes'"):
        SpCoGibbs(anneal="yes")


def test_the_guide_reads_a_loaded_param_store_without_a_call_first(tmp_path):
    # marginals() and concentration() read the module's own copy: after
    # pyro.get_param_store().load(...) they returned the start values until the guide ran.
    cfg = config()
    _, data = random_problem(seed=3)
    pyro.clear_param_store()
    guide = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
    svi = SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.5}), MeanFieldELBO())
    for _ in range(3):
        svi.step(data, cfg)
    fitted, pi = guide.marginals(), guide.concentration("pi").detach()
    pyro.get_param_store().save(tmp_path / "params.pt")
    pyro.clear_param_store()
    pyro.get_param_store().load(tmp_path / "params.pt")
    again = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
    assert torch.equal(again.marginals(), fitted)
    assert torch.equal(again.concentration("pi").detach(), pi)
    assert torch.equal(again.factors().pi, pi)
    pyro.clear_param_store()


def test_the_guide_names_a_modality_of_another_width():
    cfg = config()
    _, data = random_problem(seed=3)
    guide = MeanFieldGuide(data, cfg, name="qa_width")
    narrower = data.with_counts("words", data.word_counts[:, :-1].contiguous())
    with pytest.raises(ValueError, match=r"of \(3, 4\) items, called with \(3, 3\)"):
        guide(narrower, cfg)


def test_save_params_given_as_one_name():
    # a string was read as its letters: "unknown save_params ['i', 'p']"
    cfg = config()
    _, data = random_problem(seed=3)
    mcmc = MCMC(SpCoGibbs(save_params="pi"), num_samples=2, warmup_steps=1, disable_progbar=True)
    mcmc.run(data, cfg)
    assert set(mcmc.get_samples()) == {"pi"}


def test_mcmc_save_params_reach_the_kernel():
    # Pyro's MCMC(kernel, save_params=[...]) sets kernel.save_params; SpCoGibbs.setup replaced
    # it with every site, so all six were kept (labels too: N values a sample)
    cfg = config()
    _, data = random_problem(seed=3)
    mcmc = MCMC(SpCoGibbs(), num_samples=2, warmup_steps=1, save_params=["pi", "log_joint"],
                disable_progbar=True)  # fmt: skip
    mcmc.run(data, cfg)
    assert set(mcmc.get_samples()) == {"pi", "log_joint"}
    with pytest.raises(ValueError, match=r"unknown save_params \['beta'\]"):
        MCMC(SpCoGibbs(), num_samples=2, save_params=["beta"], disable_progbar=True).run(data, cfg)


@pytest.mark.parametrize("seed", [1.5, -1, True, "3", 2**63])
def test_start_chain_refuses_a_seed_that_is_not_one(seed):
    # 1.5 seeded as 1, "3" as 3, True as 1, -1 as 2**64 - 1 (the CLI refuses all of them)
    cfg = config()
    _, data = random_problem(seed=3)
    with pytest.raises(ValueError, match=r"seed must be an integer in 0..2\*\*63 - 1"):
        start_chain(data, cfg, seed=seed)


def test_start_chain_says_a_generator_is_no_seed():
    cfg = config()
    _, data = random_problem(seed=3)
    with pytest.raises(ValueError, match="pass a generator as the generator"):
        start_chain(data, cfg, seed=torch.Generator().manual_seed(0))
    assert start_chain(data, cfg, seed=np.int64(4)).sweeps_done == 0


@pytest.fixture(scope="module")
def small_house():
    return make_house(seed=0, spec=HouseSpec(height=30, width=40, num_rooms=2))


@pytest.mark.parametrize("seed", [1.5, None, -1, torch.Generator()])
def test_fit_house_refuses_a_seed_that_is_not_one(small_house, seed):
    # 1.5 fitted with seed 1, None and a generator raised "unsupported operand type(s) for +"
    settings = preset("original-code", num_concepts=4)
    with pytest.raises(ValueError, match="seed must be an integer"):
        fit_house(small_house, settings, sweeps=1, seed=seed, progress=False)
    with pytest.raises(ValueError, match="each of seeds must be an integer"):
        fit_house_chains(small_house, settings, sweeps=1, seeds=[0, seed], progress=False)
    with pytest.raises(ValueError, match="seeds must name at least one chain, got '01'"):
        fit_house_chains(small_house, settings, sweeps=1, seeds="01", progress=False)


def test_fit_house_names_settings_of_the_wrong_type(small_house):
    # an SpCoConfig (settings.model) raised "'SpCoConfig' object has no attribute 'data'"
    settings = preset("original-code", num_concepts=4)
    with pytest.raises(TypeError, match="settings must be an SpCoSettings.*got SpCoConfig"):
        fit_house(small_house, settings.model, sweeps=1, progress=False)
    with pytest.raises(ValueError, match="chains must be a positive integer, got True"):
        fit_house(small_house, settings, sweeps=1, chains=True, progress=False)
