"""The model, the Gibbs kernel and the SVI guide used with Pyro's own tools as a Pyro user
would (issues found by running them so: Pyro's model inspection, ...)."""

from __future__ import annotations

import math

import numpy as np
import pyro
import pytest
import torch
from pyro import poutine
from pyro.infer import MCMC, NUTS, SVI, Predictive
from pyro.infer.inspect import get_model_relations

from spcopyro.config import preset
from spcopyro.fit.house import fit_house
from spcopyro.gibbs import DEFAULT_SAVE_PARAMS, SpCoGibbs, run_gibbs
from spcopyro.gibbs.inference_data import to_inference_data
from spcopyro.guides import MeanFieldELBO, MeanFieldGuide
from spcopyro.model import spcomapping_model
from spcopyro.synthetic import HouseSpec, make_house
from tests.gibbs_problems import PROBLEM_ROWS, config, model_data, random_problem, tiny_grid

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_pyro_inspects_the_model():
    # pyro.render_model (through get_model_relations, which traces the model with tensors whose
    # shape slices are tuples) failed in the model with "'tuple' object has no attribute 'numel'"
    _, data = random_problem(seed=0)
    relations = get_model_relations(spcomapping_model, model_args=(data, config()))
    assert relations["sample_sample"]["labels"] == ["pi"]
    assert sorted(relations["sample_sample"]["words"]) == ["labels", "w"]
    assert relations["plate_sample"]["cells"] == ["labels"]


def test_predictive_draws_the_observations_under_uncondition_and_says_which_it_cannot():
    # docs/library.md called Predictive(spcomapping_model, ...)'s images "posterior predictive"
    # draws: Pyro keeps observed sites at the data, so they were the data's counts in every
    # sample. Under poutine.uncondition they are drawn; real-valued counts cannot be, and the
    # error said only "needs non-negative integer total_count"
    _, data = random_problem(seed=0)
    cfg = config()
    whole = data.with_counts("images", data.image_counts.round() + 1)
    mcmc = MCMC(SpCoGibbs(), num_samples=4, warmup_steps=2, disable_progbar=True)
    mcmc.run(whole, cfg)
    samples = mcmc.get_samples()
    sites = ("labels", "images", "words")
    kept = Predictive(spcomapping_model, posterior_samples=samples, return_sites=sites)
    assert (kept(whole, cfg)["images"] == whole.image_counts).all()
    drawn = Predictive(
        poutine.uncondition(spcomapping_model), posterior_samples=samples, return_sites=sites
    )
    with pytest.raises(ValueError, match=r"whole total_count, got \d+\.\d+ at batch index \(0,\)"):
        drawn(whole, cfg)  # the words' counts are real-valued
    whole = whole.with_counts("words", whole.word_counts.round())
    mcmc.run(whole, cfg)
    samples = mcmc.get_samples()
    draws = Predictive(
        poutine.uncondition(spcomapping_model), posterior_samples=samples, return_sites=sites
    )(whole, cfg)
    assert torch.equal(draws["labels"], samples["labels"])
    assert not (draws["images"] == whole.image_counts).all()
    assert torch.equal(draws["images"].sum(-1), whole.image_counts.sum(-1).expand(4, -1))


def test_mcmc_summary_gives_pyros_table_of_the_float_sites_and_the_labels_entropy(capsys):
    # Pyro's mcmc.summary() and mcmc.diagnostics() fail on the integer labels site (Pyro 1.9):
    # summary() with "mean(): could not infer output dtype ... Got: Long"; diagnostics() warns
    # with that traceback, then ends with "value cannot be converted to type int64_t without
    # overflow" (docs/library.md). The documented way out was to save no labels, losing them
    # for Predictive. mcmc_summary gives both parts.
    from pyro.infer.mcmc.util import summary

    from spcopyro.gibbs import mcmc_summary

    _, data = random_problem(seed=3)
    cfg = config()
    mcmc = MCMC(SpCoGibbs(), num_samples=8, warmup_steps=3, disable_progbar=True)
    mcmc.run(data, cfg)
    with pytest.raises(RuntimeError, match="Long"):  # what the helper is for
        mcmc.summary()
    with (
        pytest.warns(UserWarning, match="Got: Long"),
        pytest.raises(RuntimeError, match="int64_t without overflow"),
    ):
        mcmc.diagnostics()
    result = mcmc_summary(mcmc)
    samples = mcmc.get_samples(group_by_chain=True)
    floats = {k: v for k, v in samples.items() if k != "labels"}
    expected = summary(floats, prob=0.9)
    assert set(result) == {*floats, "labels"}
    for site, stats in expected.items():
        for name, value in stats.items():
            torch.testing.assert_close(result[site][name], value, equal_nan=True)
    labels = samples["labels"][0]  # [8, N], one chain
    for cell in range(data.num_free):
        shares = torch.bincount(labels[:, cell]).double() / 8
        shares = shares[shares > 0]
        entropy = float(-(shares * shares.log()).sum())
        assert float(result["labels"]["entropy"][0, cell]) == pytest.approx(entropy, abs=1e-12)
        assert float(result["labels"]["mode_share"][0, cell]) == float(shares.max())
    printed = capsys.readouterr().out
    assert "r_hat" in printed and "log_joint" in printed
    assert f"labels: {data.num_free} cells; each cell's label entropy" in printed
    small = MCMC(SpCoGibbs(save_params=DEFAULT_SAVE_PARAMS), num_samples=4, disable_progbar=True)
    small.run(data, cfg)
    assert "labels" not in mcmc_summary(small, show=False)
    assert capsys.readouterr().out == ""


@pytest.mark.parametrize("counts", ["real", "whole"])
def test_kernel_and_loss_say_what_an_unconditioned_model_does(counts):
    # SpCoGibbs(poutine.uncondition(model)) on real-valued counts (tf-idf words, image
    # probabilities) failed while the kernel traced the model, with MultinomialCounts.sample's
    # "needs non-negative whole total_count ... can be scored but not drawn": the model drew
    # its observation sites, the data were never looked at. On whole counts the density check
    # said only that the model's density differs (it scored its own draws). MeanFieldELBO the same.
    _, data = random_problem(seed=0)
    cfg = config()
    if counts == "whole":
        for name in ("images", "words"):
            data = data.with_counts(name, data.modality(name).counts.round())
        why = "it would score its own draws, not the data"
    else:
        why = r"these counts are real-valued .*row 0 \(free cell \d+\), column 0 is \d"
    unconditioned = poutine.uncondition(spcomapping_model)
    message = f"draws its observation site 'images' instead of observing .*{why}"
    with pytest.raises(ValueError, match=f"{message}.*SpCoGibbs fits the posterior"):
        MCMC(SpCoGibbs(unconditioned), num_samples=1, disable_progbar=True).run(data, cfg)
    with pyro.get_param_store().scope():
        guide = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
        svi = SVI(unconditioned, guide, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
        with pytest.raises(ValueError, match=f"{message}.*MeanFieldELBO fits the posterior"):
            svi.step(data, cfg)
        svi = SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
        assert math.isfinite(svi.step(data, cfg))  # the model itself is taken


def test_the_kernel_refuses_a_model_whose_density_it_does_not_sample():
    # SpCoGibbs(model) checked the model's site names and shapes only: a variant with the same
    # sites (here twice the coupling) was sampled as spcomapping_model, silently
    _, data = random_problem(seed=0)
    cfg = config()

    def stronger_coupling(data, config):
        spcomapping_model(data, config.replace(gamma=2 * config.gamma))

    def wrapped(data, config):
        spcomapping_model(data, config)

    mcmc = MCMC(SpCoGibbs(wrapped), num_samples=2, warmup_steps=1, disable_progbar=True)
    mcmc.run(data, cfg)  # the same density: accepted
    mcmc = MCMC(SpCoGibbs(stronger_coupling), num_samples=2, disable_progbar=True)
    with pytest.raises(ValueError, match="cannot sample another model"):
        mcmc.run(data, cfg)
    tiny = config(alpha=1e-3, beta=1e-3, chi=1e-3, num_concepts=10)  # draws underflow to 0
    for seed in range(5):
        pyro.set_rng_seed(seed)
        MCMC(SpCoGibbs(), num_samples=1, warmup_steps=0, disable_progbar=True).run(data, tiny)


def test_the_svi_loss_refuses_a_model_whose_label_terms_it_does_not_take():
    # MeanFieldELBO reads the globals' densities from the model's trace but takes the labels,
    # Potts and observation terms from spcopyro.likelihood: a variant with other such terms
    # (here twice the coupling) was fitted as spcomapping_model, silently
    _, data = random_problem(seed=0)
    cfg = config()

    def stronger_coupling(data, config):
        spcomapping_model(data, config.replace(gamma=2 * config.gamma))

    with pyro.get_param_store().scope():
        guide = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
        adam = pyro.optim.Adam({"lr": 0.05})
        loss = SVI(spcomapping_model, guide, adam, MeanFieldELBO()).step(data, cfg)
        assert math.isfinite(loss)
        svi = SVI(stronger_coupling, guide, adam, MeanFieldELBO())
        with pytest.raises(ValueError, match="cannot fit another model"):
            svi.step(data, cfg)


def test_fit_house_names_a_start_it_does_not_take():
    # labels of one's own (e.g. an MCMC sample) as a NumPy array failed with NumPy's "The truth
    # value of an array with more than one element is ambiguous"
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3))
    labels = np.zeros(house.grid.num_free, dtype=np.int64)
    for init in (labels, torch.as_tensor(labels), "bogus"):
        with pytest.raises(ValueError, match=r"init must be one of .* SpCoResult .* got "):
            fit_house(house, preset("original-code"), sweeps=2, init=init, progress=False)


def test_nuts_on_the_model_says_its_labels_cannot_be_enumerated():
    # NUTS enumerates the discrete labels ([L, 1]); the model then failed inside its Potts
    # factor with "IndexError: index 1 is out of bounds for dimension 0 with size 1"
    _, data = random_problem(seed=0)
    mcmc = MCMC(NUTS(spcomapping_model), num_samples=1, warmup_steps=1, disable_progbar=True)
    with pytest.raises(ValueError, match=r"labels have shape \(3, 1\).* cannot be enumerated"):
        mcmc.run(data, config())


def test_to_inference_data_says_when_it_has_no_labels_to_include():
    # include_labels=True was ignored silently where the run saved no labels, and for
    # per-sweep traces, which hold none
    pytest.importorskip("arviz")
    _, data = random_problem(seed=0)
    mcmc = MCMC(SpCoGibbs(save_params=DEFAULT_SAVE_PARAMS), num_samples=4, disable_progbar=True)
    mcmc.run(data, config())
    with pytest.raises(ValueError, match="saved no labels"):
        to_inference_data(mcmc, include_labels=True)
    assert "labels" not in to_inference_data(mcmc).posterior
    run = run_gibbs(data, config(), 6, seed=0, progress=False)
    with pytest.raises(ValueError, match="include_labels applies to an MCMC run"):
        to_inference_data([run], include_labels=True)
    mcmc = MCMC(SpCoGibbs(), num_samples=4, disable_progbar=True)
    mcmc.run(data, config())
    assert to_inference_data(mcmc, include_labels=True).posterior["labels"].shape == (1, 4, 27)


def test_the_model_names_labels_given_as_floats():
    # poutine.condition(model, {"labels": float labels}) failed in the observation sites with
    # "IndexError: tensors used as indices must be long, int, byte or bool tensors"
    _, data = random_problem(seed=0)
    labels = (torch.arange(data.num_free) % 3).double()
    conditioned = poutine.condition(spcomapping_model, {"labels": labels})
    with pytest.raises(ValueError, match=r"integer concept ids \(torch.long\), got torch.float64"):
        poutine.trace(conditioned).get_trace(data, config())
    conditioned = poutine.condition(spcomapping_model, {"labels": labels.long()})
    assert torch.isfinite(poutine.trace(conditioned).get_trace(data, config()).log_prob_sum())


def test_the_pyro_model_kernel_and_guide_take_a_map_with_no_observations():
    # Gibbs, CAVI, LBP and memoized VI fitted such a map (the prior alone); the Pyro model
    # failed in Pyro's plate with "ZeroDivisionError: size cannot be zero", and with it MCMC
    # with SpCoGibbs and SVI with the mean-field guide
    grid = tiny_grid(PROBLEM_ROWS)
    data = model_data(grid, np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 4)))
    cfg = config()
    mcmc = MCMC(SpCoGibbs(), num_samples=2, warmup_steps=1, disable_progbar=True)
    mcmc.run(data, cfg)
    assert mcmc.get_samples()["labels"].shape == (2, data.num_free)
    with pyro.get_param_store().scope():
        guide = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
        svi = SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
        assert math.isfinite(svi.step(data, cfg))


@pytest.mark.parametrize("given", [3, -1])
def test_the_model_names_labels_outside_its_concepts(given):
    # labels of a fit with a larger L, given to a variant of L = 3 (poutine.condition, or
    # Predictive's posterior samples), failed with "IndexError: index 3 is out of bounds for
    # dimension 0 with size 3"; a -1 gave Predictive the last concept's draws, silently
    _, data = random_problem(seed=0)
    labels = torch.arange(data.num_free) % 3  # [N]
    labels[data.obs_cells[0]] = given
    message = rf"concept ids in \[0, 3\) .* free cell {int(data.obs_cells[0])}'s is {given} "
    conditioned = poutine.condition(spcomapping_model, {"labels": labels})
    with pytest.raises(ValueError, match=message):
        poutine.trace(conditioned).get_trace(data, config())
    predictive = Predictive(spcomapping_model, posterior_samples={"labels": labels[None]})
    with pytest.raises(ValueError, match=message):
        predictive(data, config())


def test_a_guide_says_when_the_param_store_holds_its_parameters(caplog):
    # a second MeanFieldGuide of the same name took the first one's trained values, not its own
    # start (its q too), with no word; one of another L failed only at its first SVI step
    _, data = random_problem(seed=0)
    pyro.clear_param_store()
    first = MeanFieldGuide(data, config())
    svi = SVI(spcomapping_model, first, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
    svi.step(data, config())
    assert not caplog.records
    q = torch.full((data.num_free, 3), 1 / 3, dtype=torch.float64)
    second = MeanFieldGuide(data, config(), q=q)
    torch.testing.assert_close(second.marginals(), first.marginals())  # the store's, not q
    (record,) = caplog.records
    assert "already holds 'spcomapping_guide.labels_logits'" in record.getMessage()
    assert "will use those values, not its own start" in record.getMessage()
    MeanFieldGuide(data, config(num_concepts=5))
    assert "are (27, 3) where this guide's are (27, 5)" in caplog.records[-1].getMessage()
    caplog.clear()
    MeanFieldGuide(data, config(), name="another")  # a name of its own: no word
    pyro.clear_param_store()
    MeanFieldGuide(data, config())  # a fresh store: no word
    assert not caplog.records
    pyro.clear_param_store()


def test_an_elbo_of_a_guide_without_labels_says_it_fits_nothing_of_the_map():
    # an autoguide of the globals (the labels hidden, as Pyro's own error for the full model
    # suggests) under Trace_ELBO took steps: the model drew the labels from Categorical(pi)
    # without the Potts factor, with no more than Pyro's 'Found vars in model but not guide'
    from pyro.infer import Trace_ELBO
    from pyro.infer.autoguide import AutoNormal

    _, data = random_problem(seed=0)
    pyro.clear_param_store()
    guide = AutoNormal(poutine.block(spcomapping_model, hide=["labels"]))
    svi = SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.1}), Trace_ELBO())
    with pytest.raises(ValueError, match=r"Trace_ELBO runs a guide with no 'labels' site"):
        svi.step(data, config())
    # given labels, the same guide fits the globals: p(pi, theta, w | labels, data)
    labels = torch.arange(data.num_free) % 3
    given = poutine.condition(spcomapping_model, {"labels": labels})
    pyro.clear_param_store()
    guide = AutoNormal(poutine.block(given, hide=["labels"]))
    svi = SVI(given, guide, pyro.optim.Adam({"lr": 0.1}), Trace_ELBO())
    assert math.isfinite(svi.step(data, config()))
    pyro.clear_param_store()


def test_a_concentration_for_a_modality_the_data_have_not_is_named():
    # docs/library.md's third-modality variant with the modality's name misspelt in the config,
    # or the config passed with data made before the modality was added: the model, SpCoGibbs
    # and the guide fitted the data without it, silently (prepare_model_data refuses it for a
    # house, the Pyro path did not)
    from spcopyro.model import Modality, parameter_site

    _, data = random_problem(seed=0)
    cfg = config(concentrations={"objects": 1.0})
    message = r"concentrations names \['objects'\], but the data have no such modality"
    with pytest.raises(ValueError, match=message + r" \(further modalities: none\)"):
        poutine.trace(spcomapping_model).get_trace(data, cfg)
    with pytest.raises(ValueError, match=message):
        MCMC(SpCoGibbs(), num_samples=1, warmup_steps=1, disable_progbar=True).run(data, cfg)
    with pytest.raises(ValueError, match=message):
        MeanFieldGuide(data, cfg)
    objects = torch.ones(data.obs_cells.shape[0], 2, dtype=torch.float64)  # [M, 2]
    data3 = data._replace(
        modalities=(*data.modalities, Modality("object", parameter_site("object"), objects))
    )
    with pytest.raises(ValueError, match=r"\(further modalities: \['object'\]\)"):
        poutine.trace(spcomapping_model).get_trace(data3, cfg)
    cfg3 = config(concentrations={"object": 1.0})
    assert "object_probs" in poutine.trace(spcomapping_model).get_trace(data3, cfg3).nodes
