"""A third emission modality (object-detection counts) end to end: the Pyro model, both Gibbs
backends' conditionals and draws, results (top items per concept), data loading and the CLI.

The paper says places should be learnt from any number of modalities; a modality is one entry of
``ModelData.modalities`` (name, counts) with a Dirichlet concentration from the config, so a
third one needs no code of its own anywhere. Its conditionals are checked against the Pyro
model's own log density like the paper's two.
"""

from __future__ import annotations

import dataclasses
import json
import re
import types

import numpy as np
import pyro.poutine as poutine
import pytest
import torch
from gibbs_problems import config, random_problem, replicate_grid
from pyro.infer import MCMC
from scipy import stats
from statistical_checks import (
    assert_conditionals_match_model,
    model_log_density,
    pooled_chisquare_p,
)

from spcopyro.cli.main import main
from spcopyro.config import preset
from spcopyro.data import ModalityObservations, save_house
from spcopyro.fit.house import fit_house
from spcopyro.gibbs import GibbsOptions, SpCoGibbs
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.sampler import init
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.gibbs.sweep import label_log_conditionals, log_joint, sample_globals, sample_labels
from spcopyro.model import make_model_data, spcomapping_model
from spcopyro.results.result import SpCoResult
from spcopyro.results.semantic_map import SpCoSemanticMap
from spcopyro.synthetic import HouseSpec, make_house

OBJECTS = "objects"
ITEMS = ("sofa", "bed", "sink")


def with_objects(grid, data, seed: int = 0, scale: float = 2.0, copies: int = 1):
    """``data`` with a third modality: Poisson object counts [M, 3] at its observed cells (the
    same in each of ``copies`` replicated maps, like the other counts of ``random_problem``)."""
    rng = np.random.default_rng(seed)
    M = data.obs_cells.shape[0]
    one = rng.poisson(scale, (M // copies, len(ITEMS))).astype(float)  # [M / copies, 3]
    counts = types.SimpleNamespace(
        num_free=grid.num_free,
        cells=data.obs_cells.numpy(),
        image_counts=data.image_counts.numpy(),
        word_counts=data.word_counts.numpy(),
        modalities=(
            types.SimpleNamespace(name=OBJECTS, items=ITEMS, counts=np.tile(one, (copies, 1))),
        ),
    )
    connectivity = data.neighbours.shape[1]
    return make_model_data(grid, counts, connectivity)


def objects_config(**changes):
    return config(concentrations={OBJECTS: 0.7}, **changes)


def test_the_model_has_a_site_per_modality():
    grid, data = random_problem(seed=1)
    data = with_objects(grid, data)
    assert [m.name for m in data.modalities] == ["images", "words", OBJECTS]
    trace = poutine.trace(spcomapping_model).get_trace(data, objects_config())
    assert trace.nodes["objects_probs"]["value"].shape == (3, len(ITEMS))  # [L, K_3]
    assert trace.nodes[OBJECTS]["is_observed"]
    given = "SpCoConfig(concentrations={'objects': VALUE}) (fit's --concentration objects=VALUE)"
    with pytest.raises(ValueError, match=re.escape(f"modality 'objects': set {given}")):
        poutine.trace(spcomapping_model).get_trace(data, config())


@pytest.mark.parametrize("variant", [dict(), dict(use_images=False, use_words=False)], ids=str)
def test_conditionals_and_log_joint_equal_the_model_density(variant):
    cfg = objects_config(**variant)
    grid, data = random_problem(seed=3)
    data = with_objects(grid, data)
    state = init(data, cfg, torch.Generator().manual_seed(1))
    assert len(state.log_emissions) == 3
    torch.testing.assert_close(
        log_joint(state, data, cfg), model_log_density(state, data, cfg), atol=1e-6, rtol=1e-9
    )
    cells = torch.cat([data.obs_cells, torch.tensor([0, data.num_free - 1])]).unique()
    assert_conditionals_match_model(state, data, cfg, cells)


def _label_sampler(name: str):
    if name == "torch":
        return sample_labels
    from spcopyro.gibbs.numba_sweep import sample_labels_numba

    return sample_labels_numba


@pytest.mark.parametrize("name", ["torch", "numba"])
def test_block_draws_follow_the_conditionals_with_three_modalities(name):
    """1000 wall-separated copies of the map share one state: one label sweep gives 1000
    independent draws of each first-block cell, compared with the enumerated conditional."""
    if name == "numba":
        pytest.importorskip("numba")
    cfg = objects_config(gamma=1.2)
    copies, repeats = 1000, 5
    grid, data = random_problem(seed=5, copies=copies)
    data = with_objects(grid, data, scale=3.0, copies=copies)
    n = data.num_free // copies
    generator = torch.Generator().manual_seed(3)
    one = init(data, cfg, generator)
    # Distinct object distributions per concept, so the third modality moves the conditionals
    # (drawn given random labels, they would be nearly equal and a sampler ignoring them pass).
    distinct = torch.full((3, len(ITEMS)), 0.1, dtype=torch.float64).fill_diagonal_(0.8).log()
    state = one._replace(
        labels=one.labels[:n].repeat(copies),
        log_emissions=(*one.log_emissions[:2], distinct),
    )
    plan = make_sweep_plan(data)
    first = plan.blocks[0].cells
    first = first[first < n]
    assert (data.observation_rows()[first] >= 0).any()
    counts = torch.zeros(first.numel(), cfg.num_concepts)
    for _ in range(repeats):
        labels = _label_sampler(name)(state, data, cfg, generator, plan).view(copies, n)[:, first]
        counts += torch.nn.functional.one_hot(labels, cfg.num_concepts).sum(0)
    expected = label_log_conditionals(state, data, cfg, first).exp() * copies * repeats
    p_values = [
        stats.chisquare(counts[i].numpy(), expected[i].numpy()).pvalue for i in range(len(first))
    ]
    assert min(p_values) * len(p_values) > 1e-3  # Bonferroni; a correct sampler fails < 1e-3


@pytest.mark.parametrize("name", ["torch", "numba"])
def test_the_third_modality_distributions_follow_their_dirichlet_conditional(name):
    """Mean of 400 draws of phi_objects given fixed labels vs the Dirichlet posterior mean."""
    if name == "numba":
        pytest.importorskip("numba")
        from spcopyro.gibbs.numba_sweep import sample_globals_numba as draw
    else:
        draw = sample_globals
    cfg = objects_config()
    grid, data = random_problem(seed=7)
    data = with_objects(grid, data, scale=4.0)
    labels = init(data, cfg, torch.Generator().manual_seed(2)).labels
    generator = torch.Generator().manual_seed(5)
    draws = torch.stack([draw(labels, data, cfg, generator)[1][2].exp() for _ in range(400)])
    counts = torch.zeros(cfg.num_concepts, len(ITEMS), dtype=draws.dtype)
    counts.index_add_(0, labels[data.obs_cells], data.modality(OBJECTS).counts)
    alpha = 0.7 + counts  # [L, K_3]
    mean = alpha / alpha.sum(-1, keepdim=True)
    sd = (mean * (1 - mean) / (alpha.sum(-1, keepdim=True) + 1)).sqrt()
    z = (draws.mean(0) - mean) / (sd / 20)  # 400 draws: standard error sd / 20
    assert z.abs().max() < 4.5


@pytest.fixture(scope="module")
def house_with_objects():
    """A small synthetic house whose images also report object counts (a third modality)."""
    house = make_house(seed=2, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))
    obs = house.observations
    truth = house.truth[tuple(house.grid.world_to_cell(obs.image_xy).T)]  # [T] category
    rng = np.random.default_rng(0)
    rates = rng.gamma(1.0, 1.0, (truth.max() + 1, len(ITEMS))) * 3  # [C, 3] per category
    objects = ModalityObservations(
        name=OBJECTS, items=ITEMS, positions=obs.image_xy, trials=obs.image_trial,
        counts=rng.poisson(rates[truth]).astype(float),
    )  # fmt: skip
    return dataclasses.replace(house, observations=dataclasses.replace(obs, modalities=(objects,)))


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_fit_reports_top_items_of_the_third_modality(house_with_objects, backend, tmp_path):
    if backend == "numba":
        pytest.importorskip("numba")
    settings = preset("original-code", gamma=3.0, num_concepts=10, concentrations={OBJECTS: 0.5})
    result = fit_house(
        house_with_objects, settings, options=GibbsOptions(backend=backend), sweeps=10,
        progress=False,
    )  # fmt: skip
    table = result.emission(OBJECTS)
    assert table.items == ITEMS and table.probabilities.shape == (10, len(ITEMS))
    concept = result.concepts()[0]
    assert [item for item, _ in concept[f"top_{OBJECTS}"]] != []
    assert {item for item, _ in result.top_items(OBJECTS, concept["concept"], 3)} == set(ITEMS)
    loaded = SpCoResult.load(result.save(tmp_path / "fit"))
    np.testing.assert_array_equal(loaded.emission(OBJECTS).probabilities, table.probabilities)
    assert loaded.config.concentration(OBJECTS) == 0.5
    assert SpCoSemanticMap(loaded).word_distribution(np.arange(3)).shape == (
        3,
        len(ITEMS) * 0 + len(result.vocabulary),
    )


def test_the_cli_loads_a_third_modality_and_needs_its_concentration(
    house_with_objects, tmp_path, capsys
):
    room = save_house(house_with_objects, tmp_path / "data")
    out = tmp_path / "fit"
    args = ["fit", str(room), "--out", str(out), "--sweeps", "5", "--preset", "original-code",
            "--gamma", "3", "--concepts", "8"]  # fmt: skip
    assert main(args) == 2
    assert "--concentration objects=VALUE" in capsys.readouterr().err
    assert main([*args, "--concentration", "objects=0.5"]) == 0
    concepts = json.loads((out / "concepts.json").read_text())
    assert all(f"top_{OBJECTS}" in c for c in concepts)
    settings = json.loads((out / "config.json").read_text())
    assert settings["model"]["concentrations"] == {OBJECTS: 0.5}
    assert f"; {OBJECTS}: " in capsys.readouterr().out
    assert main([*args, "--concentration", "objects"]) == 2
    assert "NAME=NUMBER" in capsys.readouterr().err
    # a concentration for a modality the house lacks (a typo) is refused, naming what it has
    assert main([*args, "--concentration", "objects=0.5", "--concentration", "object=1"]) == 2
    err = capsys.readouterr().err
    assert "no modality 'object'" in err and "further modalities: objects" in err


def test_mcmc_saves_the_third_modality_site():
    grid, data = random_problem(seed=9)
    data = with_objects(grid, data)
    kernel = SpCoGibbs(options=GibbsOptions(backend="torch"), save_params=("objects_probs", "pi"))
    mcmc = MCMC(kernel, num_samples=4, warmup_steps=1, disable_progbar=True)
    mcmc.run(data, objects_config())
    assert mcmc.get_samples()["objects_probs"].shape == (4, 3, len(ITEMS))


def test_replicated_grid_helper_keeps_copies_apart():
    """The copies trick above relies on walls between copies (no shared neighbours)."""
    grid, n = replicate_grid(["..", ".."], 3)
    assert grid.num_free == 3 * n
    _ = get_backend("torch")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["torch", "numba"])
def test_the_sweep_keeps_the_enumerated_posterior_with_three_modalities(name):
    """Stationarity of the whole sweep with a third modality: labels from the enumerated
    p(C | x) (spcopyro.guides.testing, checked against the Pyro model with objects in
    test_exact_tiny_maps), pi and every modality's distributions from their conjugate
    conditionals drawn here, then two sweeps (the second's labels read the first's globals):
    the labels must still follow p(C | x). 1500 copies of a 2 x 3 map (3^6 labelings),
    chi-square on the states (correct: passes on both backends, 4-7 s; sweeps given the objects'
    counts zeroed, as a sweep blind to the third modality: p = 0.0 on both)."""
    from gibbs_problems import all_labelings, model_data, state_index

    from spcopyro._util.random_draws import sample_log_dirichlet
    from spcopyro.gibbs.options import GibbsOptions
    from spcopyro.gibbs.sampler import step
    from spcopyro.gibbs.state import GibbsState
    from spcopyro.guides.testing import labelling_log_evidence

    if name == "numba":
        pytest.importorskip("numba")
    cfg = objects_config(gamma=0.6, alpha=3.0, chi=0.5, beta=0.5)
    grid, n = replicate_grid(["...", "..."], 1)
    images = np.array([[2.0, 1.0], [1.0, 2.0], [1.5, 1.5]])
    words = np.array([[1.0, 1.0, 0], [0, 1.0, 1.0], [1.0, 0, 1.0]])
    data = with_objects(grid, model_data(grid, np.array([0, 2, 5]), images, words), scale=3.0)
    L, copies = cfg.num_concepts, 1500
    labelings = all_labelings(n, L)
    exact = torch.softmax(labelling_log_evidence(labelings, data, cfg), 0)  # [L^n]
    generator = torch.Generator().manual_seed(8)
    options, backend = GibbsOptions(backend=name), get_backend(name)
    plan = make_sweep_plan(data)
    final = []
    for index in torch.multinomial(exact, copies, replacement=True, generator=generator):
        labels = labelings[index]
        observed = labels[data.obs_cells]
        sizes = torch.bincount(labels, minlength=L).to(torch.float64)
        log_pi = sample_log_dirichlet(cfg.pi_concentration + sizes, generator)
        tables = []
        for modality in data.modalities:
            a = torch.full((L, modality.counts.shape[-1]), cfg.concentration(modality.name),
                           dtype=torch.float64).index_add(0, observed, modality.counts)  # fmt: skip
            tables.append(sample_log_dirichlet(a, generator))
        state = GibbsState(labels.clone(), log_pi, tuple(tables))
        for sweep in range(2):
            state, _ = step(state, data, cfg, generator, sweep=sweep, options=options,
                            backend=backend, plan=plan)  # fmt: skip
        final.append(state.labels)
    counts = torch.bincount(state_index(torch.stack(final), L), minlength=len(labelings)).double()
    p_value = pooled_chisquare_p(counts, exact)
    assert p_value > 1e-3, p_value
