"""Running SpCoMapping forward: draw a synthetic world (concepts, labels, observations) from it.

The Pyro model can draw pi, theta, w and the emissions, but not the cell labels: their prior
includes the Potts factor exp(gamma E(C)), which a ``pyro.factor`` only scores. The labels are
therefore drawn by the kernel itself: starting from labels drawn i.i.d. from pi, ``sweeps``
label-only Gibbs sweeps (no observations, globals fixed) sample the Potts-times-pi conditional
p(C | pi) proportional to prod pi_{C_ij} exp(gamma E(C)). This is the paper's generative story
(pi first, then the labels), which treats the Potts normaliser as a constant; a few hundred sweeps
suffice for maps below the critical coupling, while above it the draw is a coarsening snapshot.
The emissions are then drawn by the model itself, conditioned on the globals and labels.
"""

from __future__ import annotations

import pyro.poutine as poutine
import torch

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.random import sample_log_dirichlet
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import sample_labels
from spcopyro.model import (
    DTYPE,
    SITE_IMAGES,
    SITE_LABELS,
    SITE_PI,
    SITE_THETA,
    SITE_W,
    SITE_WORDS,
    ModelData,
    spcomapping_model,
)


def sample_observations(state: GibbsState, data: ModelData, config: SpCoConfig) -> ModelData:
    """New counts for the observed cells of ``data``, drawn from the model given the state.

    Each observed cell keeps its total counts (which must be integers); the model under
    :func:`pyro.poutine.uncondition` draws f ~ Mult(theta_C), S ~ Mult(w_C) (eqs. 5, 7). Uses
    torch's global RNG (seed it with ``pyro.set_rng_seed``).
    """
    values = {
        SITE_PI: state.log_pi.exp(),
        SITE_THETA: state.log_theta.exp(),
        SITE_W: state.log_w.exp(),
        SITE_LABELS: state.labels,
    }
    # uncondition innermost: it frees the observed sites, then condition fixes the latent ones
    # (the other way round, uncondition would free the conditioned latents too).
    forward = poutine.condition(poutine.uncondition(spcomapping_model), data=values)
    trace = poutine.trace(forward).get_trace(data, config)
    images = trace.nodes[SITE_IMAGES]["value"] if config.use_images else data.image_counts
    words = trace.nodes[SITE_WORDS]["value"] if config.use_words else data.word_counts
    return data._replace(image_counts=images.to(DTYPE), word_counts=words.to(DTYPE))


def sample_prior_world(
    data: ModelData, config: SpCoConfig, generator: torch.Generator, sweeps: int = 200
) -> tuple[GibbsState, ModelData]:
    """A world drawn from the model: (globals and labels, data with freshly drawn counts).

    ``data`` gives the map and which cells hold how many observations (their totals).
    """
    L = config.num_concepts
    K, V = data.num_feature_classes, data.vocabulary_size
    log_pi = sample_log_dirichlet(torch.full((L,), config.pi_concentration, dtype=DTYPE), generator)
    log_theta = sample_log_dirichlet(torch.full((L, K), config.chi, dtype=DTYPE), generator)
    log_w = sample_log_dirichlet(torch.full((L, V), config.beta, dtype=DTYPE), generator)
    u = torch.rand(data.num_free, dtype=DTYPE, generator=generator)
    labels = torch.searchsorted(log_pi.exp().cumsum(0), u, right=True).clamp_max(L - 1)
    state = GibbsState(labels, log_pi, log_theta, log_w)
    prior_only = config.replace(use_images=False, use_words=False)
    plan = make_sweep_plan(data)
    for _ in range(sweeps):
        state = state._replace(labels=sample_labels(state, data, prior_only, generator, plan))
    return state, sample_observations(state, data, config)
