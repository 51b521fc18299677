r"""Hyperparameters inferred inside the Gibbs chain: alpha, every concentration, gamma.

:func:`update_hyperparameters` is one sweep's hyperparameter step, composed by
:func:`spcopyro.gibbs.sampler.step` *after* the backend's sweep (labels, then pi and the emission
distributions); it returns the state and the chain's new :class:`~spcopyro.config.SpCoConfig`.
The log targets and their derivation (how the Potts normaliser enters) are in
:mod:`spcopyro.gibbs.hyper_targets`; the hyperpriors and step sizes in
:class:`~spcopyro.gibbs.hyper_options.HyperparameterOptions`. Each update is exact for the
joint :math:`p(\text{hyper}) \times` the model's joint normalised over (pi, C), except where the
auxiliary draw below is approximate:

1. **Concentrations** (chi, beta, each further modality's :math:`a_m`): ``concentration_moves``
   random-walk Metropolis-Hastings steps on :math:`\log a_m` under the Dirichlet-multinomial
   marginal of the concepts' counts (:math:`\phi_m` integrated out).
2. **alpha**: an exchange update with pi integrated out, :math:`f(C; \alpha) = B(a_\pi + n(C)) /
   B(a_\pi)` times the Potts factor (which cancels). (A plain MH step on
   :math:`p(\alpha)\,\mathrm{Dir}(\pi; a_\pi)` would be exact only at gamma = 0: the model's
   normaliser Z(gamma, alpha) depends on alpha. The joint-distribution test tells the two apart:
   with that target, log alpha's z-score is 10.)

   Then, *if alpha or a concentration changed*, pi and every modality's distributions are
   redrawn from their conjugate conditionals given the labels and the new values (eqs. 14-17,
   by the backend's own globals draw). Updates 1-2 leave p(hyper | C) invariant with the globals
   integrated out, so with this redraw they are a blocked update of (hyper, globals) given C,
   exact. Skipping the redraw when every proposal was rejected is exact too: the rejections
   depend on the hyperparameters and the proposals' random numbers only, so the kept globals
   are still a draw from their conditional.
3. **gamma** (``hyper.gamma``):

   * ``"exchange"`` (use this one): propose :math:`\log\gamma' = \log\gamma + \epsilon`, draw
     auxiliary labels C' under gamma', accept with :math:`p(\gamma')/p(\gamma)\,
     e^{(\gamma' - \gamma)(E(C) - E(C'))}`. It targets the model's own conditional of gamma,
     so the chain is the model's posterior -- up to the auxiliary draw.
   * ``"pseudolikelihood"``: ``concentration_moves`` MH steps targeting Besag's
     pseudo-posterior :math:`p(\gamma)\, \mathrm{PL}(\gamma; C, \pi)`
     (:class:`~spcopyro.gibbs.hyper_targets.PseudoLikelihood`): O(N D) per step, no auxiliary
     draw, but *not* the model's posterior: it is consistent for the coupling as the map grows
     (its maximiser is Besag's estimator) yet its spread is wrong (too narrow for strong
     coupling) and it ignores how alpha and gamma trade off through Z.

**The auxiliary draw** (:func:`auxiliary_labels`). The exchange algorithm is exact when C' is an
exact draw from the prior over labels under the proposed value, :math:`p(C') \propto
e^{\gamma' E(C')} B(a_\pi + n(C')) / B(a_\pi)`. On tiny maps the tests draw it exactly
(enumeration: pass ``aux_draw``). On a real map it is approximated by ``aux_sweeps`` sweeps of
an observation-free chain started from the current labels: each draws pi' from Dir(a_pi +
n(C')), then (with ``aux_cluster_moves``) a Swendsen-Wang move (:mod:`spcopyro.gibbs.cluster`)
and a single-site sweep of the backend, both with no observations. What this costs in
accuracy: started from a posterior draw, whose regions the data shaped, a few sweeps relax the
local structure of C' (isolated flips, region borders: what E(C') mostly measures) to the prior
under the proposed value, but not its large-scale layout (coarsening takes thousands of sweeps).
Where C' has not moved far, E(C') stays near E(C), the ratio near the prior ratio, and the update
drifts towards the prior; so the sampled gamma is biased towards what the local structure alone
supports, and its spread is overstated (more ``aux_sweeps``: less bias). In time: each exchange
update costs ``aux_sweeps`` label-only sweeps (plus a Swendsen-Wang move each with
``aux_cluster_moves``), so alpha and gamma together add about 2 x 3 sweeps' worth at the
defaults (``exchange_probability`` spreads them out).

**References:** I. Murray, Z. Ghahramani, D. MacKay, "MCMC for doubly-intractable
distributions", UAI 2006. J. Besag, "Statistical analysis of non-lattice data", The
Statistician 24, 1975. M. D. Escobar, M. West, "Bayesian density estimation and inference using
mixtures", JASA 90, 1995 (alpha's role; its auxiliary-variable update assumes no Potts term).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import torch

from spcopyro._util.messages import setting
from spcopyro._util.random_draws import coin_flip, sample_log_dirichlet
from spcopyro.config import (
    CONCENTRATION_FIELDS,
    HYPERPARAMETER_FIELDS,
    SpCoConfig,
    concentration_name,
)
from spcopyro.gibbs.backends import globals_sampler, label_sampler
from spcopyro.gibbs.cluster import swendsen_wang_labels
from spcopyro.gibbs.hyper_options import HyperparameterOptions
from spcopyro.gibbs.hyper_targets import (
    PseudoLikelihood,
    dirichlet_multinomial_log_marginal,
    exchange_log_ratio,
    label_log_marginal,
    log_normal_prior,
)
from spcopyro.gibbs.state import GibbsState, SweepPlan, make_sweep_plan
from spcopyro.likelihood import concept_statistics
from spcopyro.model import DTYPE, ModelData, potts_agreements

AuxiliaryDraw = Callable[[torch.Tensor, SpCoConfig, torch.Generator], torch.Tensor]
"""``aux_draw(labels, config, generator) -> [N] labels``: a draw from the labels' prior under
``config`` (the exchange algorithm's auxiliary variable), started from ``labels`` if it likes."""


class HyperMoves(NamedTuple):
    """What one :func:`update_hyperparameters` call accepted (for acceptance rates)."""

    proposed: dict[str, int]
    accepted: dict[str, int]


def hyperparameter_names(data: ModelData) -> list[str]:
    """The hyperparameters in trace order: alpha, gamma, then each modality's concentration
    (``chi`` for images, ``beta`` for words, the modality's name for a further one)."""
    return ["alpha", "gamma", *(concentration_name(m.name) for m in data.modalities)]


def hyperparameter_values(data: ModelData, config: SpCoConfig) -> list[float]:
    """The values of :func:`hyperparameter_names` under ``config``."""
    return [float(config.alpha), float(config.gamma),
            *(config.concentration(m.name) for m in data.modalities)]  # fmt: skip


def with_concentration(config: SpCoConfig, modality: str, value: float) -> SpCoConfig:
    """``config`` with modality's Dirichlet concentration set to ``value``."""
    if modality in CONCENTRATION_FIELDS:  # chi, beta
        return config.replace(**{CONCENTRATION_FIELDS[modality]: value})
    further = dict(config.concentrations)
    further[modality] = value
    return config.replace(concentrations=further)


def log_hyperprior(data: ModelData, config: SpCoConfig, hyper: HyperparameterOptions) -> float:
    """The log density of the *sampled* log hyperparameters under their priors (0 when none is
    sampled): what the traced log joint adds when hyperparameters are inferred."""
    total = 0.0
    if hyper.alpha:
        total += log_normal_prior(math.log(config.alpha), hyper.log_alpha_mean, hyper.log_alpha_sd)
    if hyper.gamma != "fixed":
        total += log_normal_prior(math.log(config.gamma), hyper.log_gamma_mean, hyper.log_gamma_sd)
    if hyper.concentrations:
        for modality in data.modalities:
            total += log_normal_prior(
                math.log(config.concentration(modality.name)),
                hyper.log_concentration_mean,
                hyper.log_concentration_sd,
            )
    return total


def _normal(generator: torch.Generator) -> float:
    return float(torch.randn((), dtype=DTYPE, generator=generator))


def _accept(log_ratio: float, generator: torch.Generator) -> bool:
    """Metropolis-Hastings: accept with probability min(1, exp(log_ratio))."""
    u = float(torch.rand((), dtype=DTYPE, generator=generator))
    return math.log(u) < log_ratio if u > 0 else True


# -- 1. concentrations ---------------------------------------------------------------------------


def update_concentration(
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    hyper: HyperparameterOptions,
    index: int,
    counts: torch.Tensor,
) -> tuple[SpCoConfig, int]:
    """``concentration_moves`` MH steps on modality ``index``'s log concentration under its
    Dirichlet-multinomial marginal (module doc, 1; the distributions are redrawn by
    :func:`update_hyperparameters`). ``counts`` is [G, K_m]: the counts of the concepts holding
    any observed cell (the others add nothing). Returns (config, number of accepted steps)."""
    modality = data.modalities[index]
    rows = counts  # [G, K_m]
    old = config.concentration(modality.name)
    log_a = math.log(old)

    def log_target(log_value: float) -> float:
        prior = log_normal_prior(
            log_value, hyper.log_concentration_mean, hyper.log_concentration_sd
        )
        return prior + dirichlet_multinomial_log_marginal(rows, math.exp(log_value))

    current, accepted = log_target(log_a), 0
    for _ in range(hyper.concentration_moves):
        proposal = log_a + hyper.concentration_step * _normal(generator)
        if not math.isfinite(math.exp(proposal)) or math.exp(proposal) <= 0:
            continue
        candidate = log_target(proposal)
        if _accept(candidate - current, generator):
            log_a, current, accepted = proposal, candidate, accepted + 1
    if not accepted:
        return config, 0
    return with_concentration(config, modality.name, math.exp(log_a)), accepted


# -- the auxiliary draw ----------------------------------------------------------------------------


class _PriorMap(NamedTuple):
    data: ModelData
    prior_data: ModelData
    plan: SweepPlan


_PRIOR_MAP: list[_PriorMap] = []


def prior_map(data: ModelData) -> tuple[ModelData, SweepPlan]:
    """``data`` without observations (the same map, no observed cell) and its sweep plan
    (cached for the last map asked for)."""
    if _PRIOR_MAP and _PRIOR_MAP[0].data is data:
        return _PRIOR_MAP[0].prior_data, _PRIOR_MAP[0].plan
    prior_data = data._replace(
        obs_cells=data.obs_cells[:0],
        modalities=tuple(m._replace(counts=m.counts[:0], spread=None) for m in data.modalities),
    )
    plan = make_sweep_plan(prior_data)
    _PRIOR_MAP[:] = [_PriorMap(data, prior_data, plan)]
    return prior_data, plan


def auxiliary_labels(
    labels: torch.Tensor,
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    sweeps: int,
    backend_name: str = "torch",
    cluster_moves: bool = False,
) -> torch.Tensor:
    """[N] labels from ``sweeps`` sweeps of the observation-free chain under ``config``, from
    ``labels`` (the module doc's approximate auxiliary draw). ``state`` lends its emission
    tables' shapes only (no observation is scored)."""
    prior_data, plan = prior_map(data)
    sample = label_sampler(backend_name)
    L = config.num_concepts
    aux = state._replace(labels=labels)
    for _ in range(sweeps):
        cells = torch.bincount(aux.labels, minlength=L).to(DTYPE)  # [L]
        aux = aux._replace(log_pi=sample_log_dirichlet(config.pi_concentration + cells, generator))
        if cluster_moves:
            aux = aux._replace(labels=swendsen_wang_labels(aux, prior_data, config, generator))
        aux = aux._replace(labels=sample(aux, prior_data, config, generator, plan))
    return aux.labels


# -- 2. alpha ----------------------------------------------------------------------------------


def update_alpha(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    hyper: HyperparameterOptions,
    aux_draw: AuxiliaryDraw,
) -> tuple[SpCoConfig, bool]:
    """The exchange update of alpha with pi integrated out (module doc, 2; pi is redrawn by
    :func:`update_hyperparameters`). Returns (config, accepted)."""
    L = config.num_concepts
    log_alpha = math.log(config.alpha)
    proposal = log_alpha + hyper.alpha_step * _normal(generator)
    try:
        proposed = config.replace(alpha=math.exp(proposal))
    except ValueError:  # overflow or underflow of alpha: outside the model, rejected
        return config, False
    aux = aux_draw(state.labels, proposed, generator)  # [N] under alpha'
    counts = torch.bincount(state.labels, minlength=L)  # [L]
    aux_counts = torch.bincount(aux, minlength=L)  # [L]
    a_old, a_new = config.pi_concentration, proposed.pi_concentration
    log_ratio = exchange_log_ratio(
        log_normal_prior(proposal, hyper.log_alpha_mean, hyper.log_alpha_sd),
        log_normal_prior(log_alpha, hyper.log_alpha_mean, hyper.log_alpha_sd),
        label_log_marginal(counts, a_new),
        label_log_marginal(counts, a_old),
        label_log_marginal(aux_counts, a_new),
        label_log_marginal(aux_counts, a_old),
    )
    if not _accept(log_ratio, generator):
        return config, False
    return proposed, True


# -- 3. gamma ----------------------------------------------------------------------------------


def gamma_step_size(data: ModelData, hyper: HyperparameterOptions) -> float:
    """The proposal's standard deviation on log gamma: ``gamma_step / sqrt(P)``."""
    return hyper.gamma_step / math.sqrt(max(1, int(data.pairs.shape[0])))


def check_gamma_start(config: SpCoConfig, hyper: HyperparameterOptions) -> None:
    """ValueError naming both settings when ``hyper`` samples gamma from a start of 0 (its log
    is sampled). Checked at the top of :func:`spcopyro.gibbs.sampler.step`, which every driver
    runs (so a chain refuses at its first step, annealing or not, whatever the exchange coin
    says), and by :func:`update_hyperparameters` for a caller that samples hyperparameters
    without ``step``: gamma cannot reach 0 once sampled, so no gamma update checks it."""
    if hyper.gamma != "fixed" and config.gamma <= 0:
        sampled = setting(f"HyperparameterOptions.gamma={hyper.gamma!r}",
                          f"--method-option hyper.gamma={hyper.gamma}")  # fmt: skip
        raise ValueError(
            f"{sampled} samples log gamma, so it needs a positive start, but "
            f"{setting(f'SpCoConfig.gamma={config.gamma!r}', f'--gamma {config.gamma:g}')}: "
            "set gamma > 0 (e.g. 1.0), or keep gamma 0 with hyper.gamma='fixed'"
        )


def update_gamma_exchange(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    hyper: HyperparameterOptions,
    aux_draw: AuxiliaryDraw,
    agreements: Callable[[torch.Tensor], float],
) -> tuple[SpCoConfig, bool]:
    """The exchange update of gamma (module doc, 3). Returns (config, accepted)."""
    log_gamma = math.log(config.gamma)
    proposal = log_gamma + gamma_step_size(data, hyper) * _normal(generator)
    try:
        proposed = config.replace(gamma=math.exp(proposal))
    except ValueError:  # gamma * D > 700: outside the model, rejected
        return config, False
    aux = aux_draw(state.labels, proposed, generator)  # [N] under gamma'
    e_data, e_aux = agreements(state.labels), agreements(aux)
    log_ratio = exchange_log_ratio(
        log_normal_prior(proposal, hyper.log_gamma_mean, hyper.log_gamma_sd),
        log_normal_prior(log_gamma, hyper.log_gamma_mean, hyper.log_gamma_sd),
        proposed.gamma * e_data,
        config.gamma * e_data,
        proposed.gamma * e_aux,
        config.gamma * e_aux,
    )
    if not _accept(log_ratio, generator):
        return config, False
    return proposed, True


def update_gamma_pseudolikelihood(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    hyper: HyperparameterOptions,
) -> tuple[SpCoConfig, int]:
    """``concentration_moves`` MH steps on log gamma under the pseudo-posterior (module doc,
    3). Returns (config, number of accepted steps)."""
    pl = PseudoLikelihood(state.labels, state.log_pi, data.neighbours)
    limit = math.log(700.0 / config.connectivity)

    def log_target(log_value: float) -> float:
        prior = log_normal_prior(log_value, hyper.log_gamma_mean, hyper.log_gamma_sd)
        return prior + pl(math.exp(log_value))

    log_gamma, accepted = math.log(config.gamma), 0
    current = log_target(log_gamma)
    step = gamma_step_size(data, hyper)
    for _ in range(hyper.concentration_moves):
        proposal = log_gamma + step * _normal(generator)
        if proposal > limit:
            continue
        candidate = log_target(proposal)
        if _accept(candidate - current, generator):
            log_gamma, current, accepted = proposal, candidate, accepted + 1
    return (config.replace(gamma=math.exp(log_gamma)) if accepted else config), accepted


# -- the step ----------------------------------------------------------------------------------


def update_hyperparameters(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    hyper: HyperparameterOptions,
    *,
    backend_name: str = "torch",
    agreements: Callable[[torch.Tensor], float] | None = None,
    aux_draw: AuxiliaryDraw | None = None,
) -> tuple[GibbsState, SpCoConfig, HyperMoves]:
    """One sweep's hyperparameter updates given the labels: the concentrations, then alpha, then
    gamma (module doc). Returns the state (its globals redrawn where their hyperparameter
    changed), the chain's new config, and what was proposed and accepted.

    Args:
        hyper: which hyperparameters to sample, their priors and steps.
        backend_name: the backend whose label-only sweep the auxiliary chain uses.
        agreements: E(C) as a float (default :func:`spcopyro.model.potts_agreements`).
        aux_draw: the exchange algorithm's auxiliary draw (default :func:`auxiliary_labels`
            with ``hyper.aux_sweeps`` sweeps; the tests pass an exact one).
    """
    check_gamma_start(config, hyper)  # a caller without sampler.step (it checks too)
    if agreements is None:

        def agreements(labels: torch.Tensor) -> float:
            return float(potts_agreements(labels, data.pairs))

    if aux_draw is None:

        def aux_draw(labels: torch.Tensor, proposed: SpCoConfig, gen: torch.Generator):
            return auxiliary_labels(
                labels,
                state,
                data,
                proposed,
                gen,
                hyper.aux_sweeps,
                backend_name,
                hyper.aux_cluster_moves,
            )

    proposed: dict[str, int] = {}
    accepted: dict[str, int] = {}
    before = config
    if hyper.concentrations:
        statistics = concept_statistics(state.labels, data, config)
        held = torch.unique(state.labels[data.obs_cells])  # [G]
        for index, modality in enumerate(data.modalities):
            config, ok = update_concentration(
                data, config, generator, hyper, index, statistics.counts[index][held]
            )
            name = concentration_name(modality.name)
            proposed[name], accepted[name] = hyper.concentration_moves, ok
    exchange = hyper.alpha or hyper.gamma == "exchange"
    exchange = exchange and coin_flip(hyper.exchange_probability, generator)
    if hyper.alpha and exchange:
        config, ok = update_alpha(state, data, config, generator, hyper, aux_draw)
        proposed["alpha"], accepted["alpha"] = 1, int(ok)
    if config != before:  # the blocked updates' second half: the globals given C and the values
        state = state._replace(
            **dict(zip(("log_pi", "log_emissions"),
                       globals_sampler(backend_name)(state.labels, data, config, generator),
                       strict=True))
        )  # fmt: skip
    if hyper.gamma == "exchange" and exchange:
        config, ok = update_gamma_exchange(
            state, data, config, generator, hyper, aux_draw, agreements
        )
        proposed["gamma"], accepted["gamma"] = 1, int(ok)
    elif hyper.gamma == "pseudolikelihood":
        config, count = update_gamma_pseudolikelihood(state, data, config, generator, hyper)
        proposed["gamma"], accepted["gamma"] = hyper.concentration_moves, count
    return state, config, HyperMoves(proposed, accepted)


# -- what a fit reports --------------------------------------------------------------------------


def hyperparameter_summary(
    trace: dict[str, np.ndarray], initial: SpCoConfig, sampled: HyperparameterOptions
) -> dict[str, dict[str, float]]:
    """Per hyperparameter that was sampled: its ``initial`` and ``final`` value and its
    ``posterior_mean`` and ``posterior_sd`` over the second half of the sweeps (``trace``: [S]
    values per name, :attr:`spcopyro.gibbs.run.GibbsRun.hyperparameters`)."""
    names = []
    if sampled.alpha:
        names.append("alpha")
    if sampled.gamma != "fixed":
        names.append("gamma")
    if sampled.concentrations:
        names += [name for name in trace if name not in ("alpha", "gamma")]
    summary = {}
    for name in names:
        values = np.asarray(trace[name], dtype=np.float64)  # [S]
        late = values[len(values) // 2 :]
        summary[name] = {
            "initial": _initial(initial, name),
            "final": float(values[-1]),
            "posterior_mean": float(late.mean()),
            "posterior_sd": float(late.std()),
        }
    return summary


def config_at_posterior_mean(
    config: SpCoConfig, summary: dict[str, dict[str, float]] | None
) -> SpCoConfig:
    """``config`` with every hyperparameter in ``summary`` (:func:`hyperparameter_summary`) set
    to its posterior mean: what a fit's reported tables (posterior means of pi, theta, w given
    the labels) are computed under when the chain sampled them. Unchanged when nothing was."""
    for name, values in (summary or {}).items():
        value = float(values["posterior_mean"])
        if name in HYPERPARAMETER_FIELDS:  # alpha, gamma, chi, beta
            config = config.replace(**{name: value})
        else:  # a further modality's, named as the modality
            config = with_concentration(config, name, value)
    return config


def _initial(config: SpCoConfig, name: str) -> float:
    if name in HYPERPARAMETER_FIELDS:
        return float(getattr(config, name))
    return config.concentration(name)


def describe_hyperparameters(summary: dict[str, dict[str, float]]) -> str:
    """One line: ``name mean +- sd (final F)`` per sampled hyperparameter."""
    return "; ".join(
        f"{name} {v['posterior_mean']:.4g} +- {v['posterior_sd']:.2g} (final {v['final']:.4g})"
        for name, v in summary.items()
    )
