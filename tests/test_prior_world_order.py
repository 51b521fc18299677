"""spcomapping_model's docstring says what sample_prior_world does, in order: pi, then theta and
w from their Dirichlets before (and independently of) the labels, then the labels, then only the
emissions from the model conditioned on all of them."""

from __future__ import annotations

import torch
from gibbs_problems import config, random_problem

from spcopyro.model import spcomapping_model
from spcopyro.simulate import sample_prior_world


def test_theta_and_w_are_drawn_before_the_labels_and_kept_for_the_emissions():
    cfg = config(gamma=1.0, num_concepts=3)
    _, data = random_problem(seed=3)
    data = data.with_counts("images", data.image_counts.round()).with_counts(
        "words", data.word_counts.round()
    )
    none, _ = sample_prior_world(data, cfg, torch.Generator().manual_seed(0), sweeps=0)
    some, _ = sample_prior_world(data, cfg, torch.Generator().manual_seed(0), sweeps=5)
    # The label sweeps use the generator after pi, theta and w are drawn: those are the same.
    assert torch.equal(none.log_pi, some.log_pi)
    for a, b in zip(none.log_emissions, some.log_emissions, strict=True):
        assert torch.equal(a, b)
    assert not torch.equal(none.labels, some.labels)


def test_the_docstring_says_theta_and_w_are_not_drawn_after_the_labels():
    doc = " ".join((spcomapping_model.__doc__ or "").split())
    assert "conditioned on those labels draws theta" not in doc
    assert "conditioned on pi, theta, w and those labels, draws only the emissions" in doc
    assert "before and independently of the labels" in doc
