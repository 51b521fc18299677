"""A new inference method needs only the shared math, the result type and one registry entry.

The method here is a toy -- iterated conditional modes in expectation: soft assignments q [N, L]
updated from ``spcopyro.likelihood`` by colour blocks, globals at their Dirichlet posterior means
-- written in this file against the public interface only. Registered under a name, it is
fitted by ``fit_house``, ``spcopyro fit --method``, and its result answers "where is X?", gives
top words, is scored by the metrics, saved, loaded and drawn, like a Gibbs result.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from spcopyro.cli.main import main
from spcopyro.config import SpCoConfig, preset
from spcopyro.figures.plotting import plot_trace
from spcopyro.fit import registry
from spcopyro.fit.house import fit_house
from spcopyro.inference.protocol import InferenceOutput, Trace
from spcopyro.likelihood import (
    concept_statistics,
    log_joint_constant,
    log_joint_variable,
    neighbour_field,
    observation_log_likelihood,
)
from spcopyro.metrics import adjusted_rand_index, heldout_word_prediction
from spcopyro.model import DTYPE, ModelData
from spcopyro.results.result import SpCoResult
from spcopyro.results.semantic_map import SpCoSemanticMap
from spcopyro.synthetic import HouseSpec, make_house


class SoftModes:
    """Toy method: q(C_i) proportional to exp(log pi + gamma n(i) + loglik), block by block."""

    name = "soft-modes"
    objective_name = "expected log joint"

    def default_options(self) -> None:
        return None

    def run(self, data: ModelData, config: SpCoConfig, *, iterations, generator,
            init_labels=None, options=None, progress=None, thin=0) -> InferenceOutput:  # fmt: skip
        L = config.num_concepts
        logits = torch.randn(data.num_free, L, generator=generator, dtype=DTYPE)
        q = torch.softmax(logits, -1)  # [N, L]
        constant = float(log_joint_constant(data, config))
        objective, concepts = [], []
        for _ in range(iterations):
            stats = concept_statistics(q, data, config)
            log_pi = torch.log(config.pi_concentration + stats.cells)
            log_pi = log_pi - torch.logsumexp(log_pi, 0)  # [L]
            log_phi = []
            for modality, counts in zip(data.modalities, stats.counts, strict=True):
                a = config.concentration(modality.name) + counts  # [L, K_m]
                log_phi.append(torch.log(a / a.sum(-1, keepdim=True)))
            loglik = observation_log_likelihood(log_phi, data, config)  # [M, L]
            rows = data.observation_rows()
            for cells in data.colours:  # exact block updates: no cell neighbours its block
                field = neighbour_field(q, data.neighbours[cells], L)  # [n, L]
                block = log_pi + config.gamma * field
                observed = rows[cells] >= 0
                block[observed] += loglik[rows[cells][observed]]
                q[cells] = torch.softmax(block, -1)
            value = log_joint_variable(q, log_pi, log_phi, data, config)
            objective.append(constant + float(value))
            concepts.append(int((torch.bincount(q.argmax(-1), minlength=L) > 0).sum()))
        return InferenceOutput(
            labels=q.argmax(-1).numpy(),
            pi=log_pi.exp().numpy(),
            emissions=tuple(t.exp().numpy() for t in log_phi),
            trace=Trace(
                np.array(objective), np.array(concepts), np.zeros(iterations), self.objective_name
            ),  # fmt: skip
            best_iteration=iterations - 1,
            marginals=q.numpy(),
            options={"iterations": iterations},
        )


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(registry.INFERENCE_METHODS, SoftModes.name, SoftModes())
    return SoftModes.name


@pytest.fixture(scope="module")
def house():
    return make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=3))


def test_a_registered_method_fits_and_its_result_works_everywhere(registered, house, tmp_path):
    settings = preset("original-code", gamma=3.0, num_concepts=8)
    result = fit_house(house, settings, method=registered, sweeps=15, progress=False)
    assert result.method == registered and result.marginals.shape == (house.grid.num_free, 8)
    assert result.trace.objective_name == "expected log joint"
    assert np.isfinite(result.trace.objective).all() and len(result.trace.objective) == 15
    assert adjusted_rand_index(result.label_image(), house.truth) > 0.3

    word = result.vocabulary[0]
    answer = result.where(word)
    assert answer.region.sum() > 0 and result.top_words(answer.concept)
    model = SpCoSemanticMap(result)
    cells = np.arange(5)
    expected = result.marginals[cells] @ result.w  # p(word | cell) from the marginals
    np.testing.assert_allclose(model.word_distribution(cells), expected)
    test_trial = house.observations.select_trials([2])
    assert heldout_word_prediction(model, test_trial).num_scored > 0

    loaded = SpCoResult.load(result.save(tmp_path / "fit"))
    np.testing.assert_array_equal(loaded.marginals, result.marginals)
    assert loaded.method == registered and loaded.labels_final is None
    with pytest.raises(ValueError, match="no final state"):
        loaded.label_image("final")
    assert plot_trace(loaded, tmp_path / "trace.png").is_file()


def test_the_cli_offers_a_registered_method(registered, tmp_path, capsys):
    out = tmp_path / "fit"
    args = ["fit", "--out", str(out), "--method", registered, "--sweeps", "5",
            "--preset", "original-code", "--gamma", "3", "--concepts", "8"]  # fmt: skip
    assert main(args) == 0
    settings = json.loads((out / "config.json").read_text())
    assert settings["method"] == registered and settings["inference"]["iterations"] == 5
    assert main([*args[:-6], "--sweeps", "auto"]) == 2
    err = capsys.readouterr().err  # it read "not 'name''s"
    assert f"Gibbs' convergence rule, not one of --method {registered}: give a number" in err


def test_an_unknown_method_on_the_command_line_is_a_clear_error(tmp_path, capsys):
    """``--method`` lists the known methods without importing torch, so it has no argparse
    choices (a program may register one at run time): the fit checks the name first."""
    assert main(["fit", "--out", str(tmp_path / "fit"), "--method", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown inference method 'nope'" in err and "gibbs" in err and "cavi" in err
    assert not (tmp_path / "fit").exists()


def test_unknown_method_is_a_clear_error(house):
    with pytest.raises(ValueError, match="unknown inference method 'nope'.*gibbs"):
        fit_house(house, method="nope", sweeps=1, progress=False)
