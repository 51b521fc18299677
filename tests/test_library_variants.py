"""Model variants written as docs/library.md suggests (a further modality in
``ModelData.modalities``, switches and sizes of ``SpCoConfig``), run through Pyro's MCMC and
Predictive: the issues found doing so (a sampled hyperparameter saved under an observation
site's name, modality names that clash with the model's sites, settings ignored silently)."""

from __future__ import annotations

import numpy as np
import pyro
import pytest
import torch
from pyro import poutine
from pyro.infer import MCMC, SVI, Predictive

from spcopyro.config import SpCoConfig, preset
from spcopyro.data import ModalityObservations
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs import GibbsOptions, SpCoGibbs
from spcopyro.gibbs.hyper_options import HyperparameterOptions
from spcopyro.guides import MeanFieldELBO, MeanFieldGuide
from spcopyro.model import Modality, parameter_site, spcomapping_model
from spcopyro.model_checks import refuse_observed_latents
from spcopyro.synthetic import HouseSpec, make_house
from tests.gibbs_problems import config, random_problem

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _with_modality(data, name: str, parameter: str | None = None, seed: int = 1):
    """``data`` with a further modality of whole counts [M, 4] (3 draws a cell)."""
    M = data.obs_cells.shape[0]
    generator = torch.Generator().manual_seed(seed)
    items = torch.randint(0, 4, (M, 3), generator=generator)  # [M, 3]
    counts = torch.zeros(M, 4, dtype=torch.float64).scatter_add_(
        1, items, torch.ones(M, 3, dtype=torch.float64)
    )
    modality = Modality(name, parameter or parameter_site(name), counts)
    return data._replace(modalities=(*data.modalities, modality))


def test_a_sampled_further_concentration_is_no_observation_site():
    # with hyper.concentrations the kernel saved the modality "objects"' concentration as the
    # site "objects", the name of its observation site: Predictive then conditioned the observed
    # counts on that scalar ("needs non-negative whole total_count, got 6.11...: real-valued
    # counts ... can be scored but not drawn", of whole counts)
    _, data = random_problem(seed=0)
    whole = data.with_counts("images", data.image_counts.round() + 1)
    whole = _with_modality(whole.with_counts("words", whole.word_counts.round()), "objects")
    cfg = config().replace(concentrations={"objects": 1.0})
    options = GibbsOptions(hyper=HyperparameterOptions(concentrations=True))
    mcmc = MCMC(SpCoGibbs(options=options), num_samples=3, warmup_steps=1, disable_progbar=True)
    mcmc.run(whole, cfg)
    samples = mcmc.get_samples()
    assert "objects" not in samples
    assert {"chi", "beta", "objects_concentration", "objects_probs"} <= set(samples)
    assert samples["objects_concentration"].shape == (3,)
    draws = Predictive(
        poutine.uncondition(spcomapping_model), posterior_samples=samples,
        return_sites=("objects",),
    )(whole, cfg)  # fmt: skip
    totals = whole.modality("objects").counts.sum(-1)  # [M]
    assert torch.equal(draws["objects"].sum(-1), totals.expand(3, -1))


@pytest.mark.parametrize(
    ("name", "parameter", "message"),
    [
        ("labels", None, "its name 'labels' is already a site of the model"),
        ("theta", None, "its name 'theta' is already a site of modality 'images'"),
        ("cells", None, "its name 'cells' is already a plate of the model"),
        ("objects", "objects", r"make it Modality\(name, parameter_site\(name\), counts\)"),
        ("words", None, "its name 'words' is already a site of modality 'words'"),
    ],
)
def test_a_modality_named_as_a_site_of_the_model_is_refused(name, parameter, message):
    # each failed in Pyro with "Multiple sample sites named ...", naming no modality
    _, data = random_problem(seed=0)
    clashing = _with_modality(data, name, parameter)
    cfg = config().replace(concentrations={} if name == "words" else {name: 1.0})
    with pytest.raises(ValueError, match=message):
        poutine.trace(spcomapping_model).get_trace(clashing, cfg)
    with pytest.raises(ValueError, match=message):
        MCMC(SpCoGibbs(), num_samples=1, disable_progbar=True).run(clashing, cfg)


def test_a_modality_named_as_a_site_the_kernel_saves_is_refused():
    # "log_joint" is no site of the model but one of mcmc.get_samples(): the modality's
    # observation site and the kernel's diagnostic shared one name
    _, data = random_problem(seed=0)
    clashing = _with_modality(data, "log_joint")
    cfg = config().replace(concentrations={"log_joint": 1.0})
    with pytest.raises(ValueError, match="modality 'log_joint' has the name of a site SpCoGibbs"):
        MCMC(SpCoGibbs(), num_samples=1, disable_progbar=True).run(clashing, cfg)


def test_a_modality_of_no_items_is_refused_naming_it():
    # it failed in Pyro: "Expected parameter probs (Tensor of shape (5, 0)) ... Simplex()"
    _, data = random_problem(seed=0)
    M = data.obs_cells.shape[0]
    empty = Modality("objects", parameter_site("objects"), torch.zeros(M, 0, dtype=torch.float64))
    cfg = config().replace(concentrations={"objects": 1.0})
    with pytest.raises(
        ValueError, match=rf"modality 'objects' has no items \(its counts are \[{M}, 0\]\)"
    ):
        poutine.trace(spcomapping_model).get_trace(
            data._replace(modalities=(*data.modalities, empty)), cfg
        )


@pytest.mark.parametrize(
    "name", ["cells", "concepts", "observed_cells", "alpha", "x_concentration"]
)
def test_a_dataset_modality_may_not_take_a_plate_or_a_saved_site_s_name(name):
    # modality_cells.csv was accepted and every Pyro tool then failed on the model's plate
    with pytest.raises(ValueError, match="must not be one of"):
        ModalityObservations(name, ("a",), positions=[[0, 0]], trials=[0], counts=[[1]])


@pytest.mark.parametrize(
    ("field", "value"),
    [("num_concepts", True), ("connectivity", 4.0), ("use_images", "no"), ("use_words", 0)],
)
def test_the_config_refuses_switches_and_sizes_of_another_type(field, value):
    # use_images="no" switched the images on (a truthy string), num_concepts=True made L = 1,
    # connectivity 4.0 was stored as a float
    with pytest.raises(ValueError, match=f"SpCoConfig.{field}="):
        SpCoConfig(**{field: value})


def test_a_concentration_for_a_modality_the_house_lacks_is_refused():
    # a misspelt or absent modality's concentration was ignored: the fit ran without it
    house = make_house(seed=1, spec=HouseSpec(height=30, width=40, num_rooms=2))
    settings = preset("original-code", num_concepts=4, concentrations={"objects": 0.5})
    # the model's test (spcopyro.model.check_concentration_names), in the house's words
    message = (
        f"SpCoConfig.concentrations names ['objects'], but house {house.name!r} has no such "
        "modality (further modalities: none): modality_<name>.csv adds one, or correct the name"
    )
    with pytest.raises(ValueError) as refused:
        prepare_model_data(house, settings)
    assert str(refused.value) == message
    counts, data = prepare_model_data(house, settings.replace(concentrations={}))
    assert np.isfinite(counts.image_counts).all() and len(data.modalities) == 2


@pytest.mark.parametrize("site", ["pi", "labels"])
def test_a_model_that_holds_a_latent_site_fixed_is_refused(site):
    # poutine.condition(model, {"pi": ...}) -- a variant with pi known -- was sampled and
    # fitted as if pi were free: SpCoGibbs drew pi anyway (its density check conditions on
    # its own values), MeanFieldELBO scored the guide's draws at the fixed value
    _, data = random_problem(seed=0)
    cfg = config()
    value = {
        "pi": torch.tensor([0.5, 0.3, 0.2], dtype=torch.float64),
        "labels": torch.zeros(data.num_free, dtype=torch.long),
    }[site]
    fixed = poutine.condition(spcomapping_model, {site: value})
    message = f"site '{site}' is observed .* cannot hold '{site}' fixed"
    with pytest.raises(ValueError, match=message) as kernel:
        MCMC(SpCoGibbs(fixed), num_samples=1, disable_progbar=True).run(data, cfg)
    with pyro.get_param_store().scope():
        guide = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
        svi = SVI(fixed, guide, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
        with pytest.raises(ValueError, match=message) as loss:
            svi.step(data, cfg)
    # one check, one message (spcopyro.model_checks.refuse_observed_latents): the two had their own
    assert str(loss.value) == str(kernel.value).replace("SpCoGibbs", "MeanFieldELBO")
    assert "pass the model without conditioning" in str(kernel.value)
    # and for pi the variant that holds it near uniform (it said only what cannot be done)
    hint = "held near uniform, the variant is SpCoConfig(prior='dirichlet', alpha=1e4)"
    assert (hint in str(kernel.value)) == (site == "pi")


def test_variational_md_does_not_offer_svi_for_a_changed_model():
    # its method table said to pick svi "to change the model and refit without deriving
    # updates", but MeanFieldELBO takes spcomapping_model's label terms in closed form and
    # refuses any model whose density differs (a doubled coupling: tested in
    # tests/test_library_pyro_use.py, test_the_svi_loss_refuses_a_model_whose_label_terms_...)
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "variational.md").read_text()
    (row,) = [line for line in text.splitlines() if line.startswith("| `svi` |")]
    assert "change the model and refit" not in row
    assert "refuses a model whose density differs" in row


def test_the_guide_names_a_seed_a_numpy_start_and_a_site_it_has_not():
    # generator=0 (a seed) fell back to torch's global generator silently (0 is falsy), a
    # NumPy q failed with "'numpy.ndarray' object has no attribute 'to'", concentration("labels")
    # returned the labels' logits and concentration("phi") "has no attribute 'phi_concentration'"
    _, data = random_problem(seed=0)
    cfg = config()
    with pyro.get_param_store().scope():
        for seed in (0, 5):
            with pytest.raises(TypeError, match="generator must be a torch.Generator .*got int"):
                MeanFieldGuide(data, cfg, generator=seed)
        q = np.full((data.num_free, cfg.num_concepts), 1 / cfg.num_concepts)
        guide = MeanFieldGuide(data, cfg, q=q, name="numpy_start")
        assert torch.allclose(guide.marginals(), torch.as_tensor(q))
        for site in ("labels", "phi"):
            with pytest.raises(ValueError, match=r"Dirichlet sites are \('pi', 'theta', 'w'\)"):
                guide.concentration(site)
        assert guide.concentration("w").shape == (cfg.num_concepts, data.vocabulary_size)


def test_library_md_says_how_preset_takes_none_and_it_holds():
    # preset("coarse", cell_size=None) kept the preset's 0.25 m cells, silently: the guide
    # said only that overrides are routed to their layer
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "library.md").read_text()
    assert "override of `None` is ignored" in text and '`cell_size="map"`' in text
    assert preset("coarse", cell_size=None).data.cell_size == 0.25
    assert preset("coarse", cell_size="map").data.cell_size is None
    assert preset("coarse").replace(cell_size=None).data.cell_size is None


def test_preset_points_an_inference_option_to_fit_house():
    # preset("coarse", anneal_sweeps=200) listed the two layers' fields only
    with pytest.raises(ValueError, match=r"unknown settings \['anneal_sweeps'\].*fit_house\("):
        preset("coarse", anneal_sweeps=200)


def test_the_config_takes_numpy_scalars_as_the_numbers_they_are():
    # num_concepts=np.int64(5) (a count from NumPy) was refused as "must be a positive
    # integer", alpha=np.float32(2) as "must be a finite positive number"
    cfg = SpCoConfig(num_concepts=np.int64(5), connectivity=np.int32(8), alpha=np.float32(2))
    assert (cfg.num_concepts, cfg.connectivity, cfg.alpha) == (5, 8, 2.0)
    assert type(cfg.num_concepts) is int and type(cfg.alpha) is float
    with pytest.raises(ValueError, match="num_concepts=np.True_: must be a positive integer"):
        SpCoConfig(num_concepts=np.bool_(True))


def test_a_fixed_table_is_refused_with_the_variant_of_its_modality():
    # the hint named a further modality by cutting '_probs' off its parameter site's name:
    # one whose site is named otherwise (Modality(name, "object_table", counts)) had none, and
    # theta and w were keyed by site; now the callers pass each site's modality name
    _, data = random_problem(seed=0)
    data = _with_modality(data, "objects", parameter="object_table")
    cfg = config(concentrations={"objects": 1.0})
    drawn = poutine.trace(spcomapping_model).get_trace(data, cfg)
    for site, variant in (("object_table", "concentrations={'objects': 1e4}"),
                          ("theta", "chi=1e4"), ("w", "beta=1e4")):  # fmt: skip
        fixed = poutine.condition(spcomapping_model, {site: drawn.nodes[site]["value"]})
        hint = f"(held near uniform, the variant is SpCoConfig({variant}): its Dirichlet"
        with pytest.raises(ValueError, match=f"cannot hold '{site}' fixed") as kernel:
            MCMC(SpCoGibbs(fixed), num_samples=1, disable_progbar=True).run(data, cfg)
        assert hint in str(kernel.value)
        with pyro.get_param_store().scope():
            guide = MeanFieldGuide(data, cfg, generator=torch.Generator().manual_seed(0))
            svi = SVI(fixed, guide, pyro.optim.Adam({"lr": 0.1}), MeanFieldELBO())
            with pytest.raises(ValueError, match=f"cannot hold '{site}' fixed") as loss:
                svi.step(data, cfg)
        assert hint in str(loss.value)


def test_the_refusal_takes_the_data_s_modalities_and_reads_them_only_to_say_it():
    # its callers built {m.parameter: m.name for m in data.modalities} for it on every call
    # (MeanFieldELBO's on every particle step), read only when it raised: it takes
    # data.modalities now and looks the site's modality up only in its message
    _, data = random_problem(seed=0)
    data = _with_modality(data, "objects", parameter="object_table")
    cfg = config(concentrations={"objects": 1.0})
    drawn = poutine.trace(spcomapping_model).get_trace(data, cfg)
    refuse_observed_latents(drawn, ("pi", "object_table"), "SpCoGibbs", data.modalities)
    fixed = poutine.condition(
        spcomapping_model, {"object_table": drawn.nodes["object_table"]["value"]}
    )
    trace = poutine.trace(fixed).get_trace(data, cfg)
    with pytest.raises(ValueError, match=r"SpCoConfig\(concentrations=\{'objects': 1e4\}\)"):
        refuse_observed_latents(trace, ("object_table",), "SpCoGibbs", data.modalities)
