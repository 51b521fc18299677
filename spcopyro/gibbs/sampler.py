"""The Gibbs sampler as two pure functions, :func:`init` and :func:`step` (BlackJAX's shape).

::

    state = init(data, config, generator)                 # labels, then globals given them
    for sweep in range(num_sweeps):
        state, info = step(state, data, config, generator, sweep=sweep, options=options)

:func:`step` is one iteration of Algorithm 1 with everything the options add composed around it,
in this order, for every backend and every driver (the run loop, the Pyro kernel, ``--sweeps
auto``):

1. annealing: the labels' coupling of this sweep, gamma_s (:mod:`spcopyro.gibbs.anneal`);
2. with probability ``options.cluster_moves``, a Swendsen-Wang move of the labels
   (:mod:`spcopyro.gibbs.cluster`) under gamma_s;
3. with probability ``options.merge_moves``, a split-merge move of the labels with the
   parameters integrated out, then pi, theta, w redrawn if it was accepted
   (:mod:`spcopyro.gibbs.merge`), under gamma_s;
4. with probability ``options.region_moves``, a region relabel move (one Swendsen-Wang cluster
   takes another concept, parameters integrated out; :mod:`spcopyro.gibbs.region_move`), then
   pi, theta, w redrawn if it was accepted, under gamma_s;
5. the backend's sweep: every label from eq. (13) under gamma_s, then pi and the emission
   distributions (eqs. 14-17), partially refreshed per ``options.unobserved_refresh``;
6. when ``options.hyper`` samples hyperparameters (and the sweep is not an annealing one), their
   updates given the new labels, each a blocked update that redraws the globals it changes
   (:mod:`spcopyro.gibbs.hyperparameters`); the chain's config then changes: :class:`StepInfo`
   carries the new one, which the caller passes to the next step.

:func:`trace_point` is the per-sweep log joint and number of concepts, always of the target
model (gamma, not gamma_s).
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from spcopyro._util.random_draws import check_generator
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.anneal import annealed_config
from spcopyro.gibbs.backends import SweepBackend, get_backend
from spcopyro.gibbs.cluster import maybe_cluster_move
from spcopyro.gibbs.hyperparameters import (
    AuxiliaryDraw,
    check_gamma_start,
    log_hyperprior,
    update_hyperparameters,
)
from spcopyro.gibbs.merge import maybe_merge_move
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.region_move import maybe_region_move
from spcopyro.gibbs.state import GibbsState, SweepPlan
from spcopyro.gibbs.sweep import sample_globals
from spcopyro.inference.initialisation import check_labels, random_labels
from spcopyro.model import ModelData, check_model_data


class StepInfo(NamedTuple):
    """What one :func:`step` did."""

    gamma: float
    """The coupling the labels were drawn under (below the model's gamma while annealing)."""
    annealing: bool
    """Whether this was an annealing (burn-in) sweep, i.e. not a draw of the target chain."""
    config: SpCoConfig | None = None
    """The chain's model config after this step when ``options.hyper`` samples hyperparameters
    (the next step's ``config``), else None (unchanged)."""


def init(
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    labels: torch.Tensor | None = None,
) -> GibbsState:
    """A state from initial labels (uniformly random if None), with pi and the emission
    distributions drawn from their conditionals given those labels (eqs. 14-17). ValueError
    for counts that are not finite and >= 0 (:func:`~spcopyro.model.check_model_data`)."""
    check_model_data(data, config)
    check_generator(generator)
    if labels is None:
        labels = random_labels(data.num_free, config, generator)
    labels = check_labels(labels, data.num_free, config).clone()
    return GibbsState(labels, *sample_globals(labels, data, config, generator))


def step(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    *,
    sweep: int = 0,
    options: GibbsOptions = GibbsOptions(),
    backend: SweepBackend | None = None,
    plan: SweepPlan | None = None,
    aux_draw: AuxiliaryDraw | None = None,
) -> tuple[GibbsState, StepInfo]:
    """One sweep of the chain (the module docstring's steps 1-6).

    Args:
        sweep: the 0-based index of this sweep in the chain (annealing reads it).
        options: the sampler's options (backend, cluster moves, refresh, annealing).
        backend: the backend to use (default: ``options.backend``'s); pass one to reuse it.
        plan: the map's :class:`~spcopyro.gibbs.state.SweepPlan` (made once per map if given).
        aux_draw: the hyperparameters' auxiliary label draw (default: the approximate one of
            :func:`~spcopyro.gibbs.hyperparameters.auxiliary_labels`; the tests pass an exact one).
    """
    check_gamma_start(config, options.hyper)  # every driver's first step, before any move
    backend = get_backend(options.backend) if backend is None else backend
    sweep_config = annealed_config(config, sweep, options.anneal_sweeps)
    state = maybe_cluster_move(state, data, sweep_config, generator, options.cluster_moves)
    state = maybe_merge_move(state, data, sweep_config, generator, options.merge_moves,
                             compiled=backend.name == "numba")  # fmt: skip
    state = maybe_region_move(state, data, sweep_config, generator, options.region_moves,
                              compiled=backend.name == "numba")  # fmt: skip
    state = backend.sweep(state, data, sweep_config, generator, plan, options.unobserved_refresh)
    annealing = sweep + 1 < options.anneal_sweeps
    if not options.hyper.active:
        return state, StepInfo(gamma=sweep_config.gamma, annealing=annealing)
    if not annealing:
        state, config, _ = update_hyperparameters(
            state, data, config, generator, options.hyper, backend_name=backend.name,
            agreements=lambda labels: float(backend.potts_agreements(labels, data.pairs)),
            aux_draw=aux_draw,
        )  # fmt: skip
    return state, StepInfo(gamma=sweep_config.gamma, annealing=annealing, config=config)


def trace_point(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    constant: float,
    backend: SweepBackend,
    options: GibbsOptions | None = None,
) -> tuple[float, int]:
    """(log joint of the target model, number of concepts in use) at ``state``.

    ``constant`` is :func:`spcopyro.likelihood.log_joint_constant` (computed once per chain, and
    again whenever sampled hyperparameters change it). When ``options.hyper`` samples
    hyperparameters, ``config`` is the chain's current one and the log joint includes the log
    hyperpriors of the sampled log hyperparameters (not the intractable Potts normaliser
    Z(gamma, alpha): see :mod:`spcopyro.gibbs.hyper_targets`).
    """
    variable, concepts = backend.trace(state, data, config)
    value = constant + variable
    if options is not None and options.hyper.active:
        value += log_hyperprior(data, config, options.hyper)
    return value, concepts
