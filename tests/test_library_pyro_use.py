"""The model, the Gibbs kernel and the SVI guide used with Pyro's own tools as a Pyro user
would (issues found by running them so: Pyro's model inspection, ...)."""

from __future__ import annotations

import pytest
from pyro.infer.inspect import get_model_relations

from spcopyro.model import spcomapping_model
from tests.gibbs_problems import config, random_problem

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_pyro_inspects_the_model():
    # pyro.render_model (through get_model_relations, which traces the model with tensors whose
    # shape slices are tuples) failed in the model with "'tuple' object has no attribute 'numel'"
    _, data = random_problem(seed=0)
    relations = get_model_relations(spcomapping_model, model_args=(data, config()))
    assert relations["sample_sample"]["labels"] == ["pi"]
    assert sorted(relations["sample_sample"]["words"]) == ["labels", "w"]
    assert relations["plate_sample"]["cells"] == ["labels"]
