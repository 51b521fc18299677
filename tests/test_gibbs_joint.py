"""Joint-distribution tests of the sampler on enumerable problems.

* Geweke's "getting it right" on every backend (the ``backend`` fixture), with the options'
  moves composed by :func:`spcopyro.gibbs.sampler.step`: marginal-conditional draws (labels from
  their exact marginal by enumeration, then pi, theta, w and the data) against
  successive-conditional draws (alternating steps and data draws). Label-invariant statistics
  must agree within Monte Carlo error (with the successive chain's effective sample size). The
  torch reference redraws the data with the model's forward mode (so that is tested too), the
  compiled backend with independent multinomial draws. The helpers are in
  ``statistical_checks.py``.
* The colour-block sweep against Algorithm 1's sequential raster-order sweep, and the
  Swendsen-Wang cluster move on its own: all must reach the exact posterior of the labels (given
  the globals), enumerated.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import all_labelings, config, model_data, replicate_grid, state_index
from statistical_checks import (
    GEWEKE_VARIANTS,
    Z_LIMIT,
    counts_redraw,
    geweke_z_scores,
    model_redraw,
    pooled_chisquare_p,
)

from spcopyro.gibbs.cluster import swendsen_wang_labels
from spcopyro.gibbs.sampler import init
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.gibbs.sweep import label_log_conditionals, log_joint, sample_labels
from spcopyro.model import DTYPE

REDRAWS = {"torch": model_redraw, "numba": counts_redraw}
"""How Geweke's successive-conditional chain redraws the data, per backend."""


@pytest.mark.slow
@pytest.mark.parametrize("variant,options", GEWEKE_VARIANTS)
def test_geweke_getting_it_right(backend, variant, options):
    options = options.replace(backend=backend.name)
    z = geweke_z_scores(config(**variant), options, REDRAWS[backend.name])
    assert z.abs().max() < Z_LIMIT, f"z-scores {z.numpy().round(2)}"


def _sequential_raster_sweep(state, data, cfg, generator, cells_per_copy: int, copies: int):
    """Algorithm 1's label loop: cells one at a time in raster order (all copies at once)."""
    labels = state.labels.clone()
    for position in range(cells_per_copy):
        cells = position + cells_per_copy * torch.arange(copies)
        log_p = label_log_conditionals(state._replace(labels=labels), data, cfg, cells)
        labels[cells] = torch.multinomial(log_p.exp(), 1, generator=generator)[:, 0]
    return labels


@pytest.mark.slow
@pytest.mark.parametrize("connectivity", [4, 8])
def test_block_raster_and_cluster_moves_reach_the_exact_posterior(connectivity):
    cfg = config(gamma=0.8, connectivity=connectivity)
    rows = ["...", ".#.", "..."]  # a ring of 8 cells round a wall: 3^8 labelings
    copies = 6000
    grid, n = replicate_grid(rows, copies)
    obs = np.array([0, 5])
    images, words = np.array([[2.0, 0.5], [0.0, 3.0]]), np.array([[1.0, 0, 0], [0, 0, 2.0]])
    data = model_data(
        grid,
        (np.arange(copies)[:, None] * n + obs).ravel(),
        np.tile(images, (copies, 1)),
        np.tile(words, (copies, 1)),
        connectivity,
    )
    generator = torch.Generator().manual_seed(21)
    # Globals fixed by hand, distinct per concept, so that pi and both emissions matter.
    fixed = init(data, cfg, generator)._replace(
        log_pi=torch.tensor([0.5, 0.3, 0.2], dtype=DTYPE).log(),
        log_emissions=(
            torch.tensor([[0.8, 0.2], [0.3, 0.7], [0.5, 0.5]], dtype=DTYPE).log(),  # theta [L, K]
            torch.tensor([[0.6, 0.3, 0.1], [0.1, 0.2, 0.7], [0.3, 0.4, 0.3]], dtype=DTYPE).log(),
        ),  # w [L, V]
    )

    # Exact posterior of one copy's labels given the globals, by enumeration.
    one_grid, _ = replicate_grid(rows, 1)
    one = model_data(one_grid, obs, images, words, connectivity)
    labelings = all_labelings(n, cfg.num_concepts)
    log_p = torch.stack([log_joint(fixed._replace(labels=lab), one, cfg) for lab in labelings])
    exact = torch.softmax(log_p, 0)

    plan = make_sweep_plan(data)
    start = torch.randint(cfg.num_concepts, (data.num_free,), generator=generator)
    block, raster = fixed._replace(labels=start), fixed._replace(labels=start.clone())
    cluster = fixed._replace(labels=start.clone())
    for _ in range(25):
        block = block._replace(labels=sample_labels(block, data, cfg, generator, plan))
        raster = raster._replace(
            labels=_sequential_raster_sweep(raster, data, cfg, generator, n, copies)
        )
        cluster = cluster._replace(labels=swendsen_wang_labels(cluster, data, cfg, generator))
    for name, chain in (("block", block), ("raster", raster), ("cluster", cluster)):
        states = state_index(chain.labels.view(copies, n), cfg.num_concepts)
        observed = torch.bincount(states, minlength=len(labelings)).double()  # [S]
        p_value = pooled_chisquare_p(observed, exact)
        assert p_value > 1e-3, (name, p_value)
