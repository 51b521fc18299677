"""Running SpCoMapping forward: draw a world (concepts, labels, observations) from the model.

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

from spcopyro._util.random_draws import sample_log_dirichlet
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import sample_labels
from spcopyro.model import DTYPE, SITE_LABELS, SITE_PI, ModelData, spcomapping_model


def check_whole_totals(data: ModelData, config: SpCoConfig) -> None:
    """ValueError naming the modality and cell when an observed cell of a modality the model
    uses holds counts whose total is not a whole number: a multinomial draws whole counts.

    Image probabilities (``feature_scaling="probability"``, the default presets' and
    ``paper-dp``'s) and words spread over a footprint are fractions; the model scores them, but
    cannot draw them (this was Pyro's "MultinomialCounts.sample needs non-negative integer
    total_count" after a dump of the model's trace)."""
    for modality in data.modalities:
        if not config.uses(modality.name) or modality.counts.numel() == 0:
            continue
        totals = modality.counts.sum(-1)  # [M]
        whole = totals == totals.round()  # [M] (as MultinomialCounts.sample checks them)
        if not bool(whole.all()):
            m = int(torch.nonzero(~whole)[0])
            raise ValueError(
                f"observed cell {m} (free cell {int(data.obs_cells[m])}) holds "
                f"{float(totals[m]):.6g} {modality.name} counts in all, not a whole number: "
                f"draws from the model need whole counts per cell; prepare the data with whole "
                f"counts (e.g. preset('original-code'): images as floor(100 f), each word "
                f"counted once at its cell)"
            )


def sample_observations(state: GibbsState, data: ModelData, config: SpCoConfig) -> ModelData:
    """New counts for the observed cells of ``data``, drawn from the model given the state.

    Each observed cell keeps its total counts (which must be whole numbers:
    :func:`check_whole_totals`); the model under
    :func:`pyro.poutine.uncondition` draws each modality's counts from its concept's
    distribution, e.g. f ~ Mult(theta_C), S ~ Mult(w_C) (eqs. 5, 6). A switched-off modality
    keeps its counts. Uses torch's global RNG (seed it with ``pyro.set_rng_seed``).
    """
    check_whole_totals(data, config)
    values = {SITE_PI: state.log_pi.exp(), SITE_LABELS: state.labels}
    for modality, log_phi in zip(data.modalities, state.log_emissions, strict=True):
        values[modality.parameter] = log_phi.exp()
    # uncondition innermost: it frees the observed sites, then condition fixes the latent ones
    # (the other way round, uncondition would free the conditioned latents too).
    forward = poutine.condition(poutine.uncondition(spcomapping_model), data=values)
    trace = poutine.trace(forward).get_trace(data, config)
    for modality in data.modalities:
        if config.uses(modality.name):
            data = data.with_counts(modality.name, trace.nodes[modality.name]["value"].to(DTYPE))
    return data


def sample_prior_world(
    data: ModelData, config: SpCoConfig, generator: torch.Generator, sweeps: int = 200
) -> tuple[GibbsState, ModelData]:
    """A world drawn from the model: (globals and labels, data with freshly drawn counts).

    ``data`` gives the map and which cells hold how many observations (their totals).
    ``generator`` decides the whole draw: the counts, drawn by the Pyro model with torch's
    global RNG (:func:`sample_observations`), are drawn under a seed taken from it, and the
    global RNG is left as it was (it used to draw them from the global RNG's state, so two calls
    with equally seeded generators gave the same labels and other counts). Counts whose total
    per cell is not whole are refused before any sweep (:func:`check_whole_totals`).
    """
    if not isinstance(sweeps, int) or isinstance(sweeps, bool) or sweeps < 0:
        raise ValueError(f"sweeps must be an integer >= 0, got {sweeps!r}")
    check_whole_totals(data, config)  # before the sweeps, not after them
    L = config.num_concepts
    log_pi = sample_log_dirichlet(torch.full((L,), config.pi_concentration, dtype=DTYPE), generator)
    log_emissions = tuple(
        sample_log_dirichlet(
            torch.full((L, m.counts.shape[-1]), config.concentration(m.name), dtype=DTYPE),
            generator,
        )
        for m in data.modalities
    )
    u = torch.rand(data.num_free, dtype=DTYPE, generator=generator)
    labels = torch.searchsorted(log_pi.exp().cumsum(0), u, right=True).clamp_max(L - 1)
    state = GibbsState(labels, log_pi, log_emissions)
    # Label-only sweeps: the emissions' likelihood switched off (images and words by the config's
    # switches, any further modality by leaving it out of the sweep's data).
    prior_only = config.replace(use_images=False, use_words=False)
    label_data = data._replace(modalities=data.modalities[:2])
    plan = make_sweep_plan(data)
    for _ in range(sweeps):
        label_state = state._replace(log_emissions=state.log_emissions[:2])
        labels = sample_labels(label_state, label_data, prior_only, generator, plan)
        state = state._replace(labels=labels)
    seed = int(torch.randint(2**62, (), generator=generator))
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return state, sample_observations(state, data, config)
