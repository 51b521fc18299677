r"""Which hyperparameters the Gibbs sampler infers, under which hyperpriors, with which moves.

The field ``GibbsOptions.hyper`` (``spcopyro fit --method-option hyper.alpha=true``, ...). The
updates themselves are :mod:`spcopyro.gibbs.hyperparameters`; their log targets
:mod:`spcopyro.gibbs.hyper_targets`.

**Hyperpriors** (vague, all on the log scale, all independent):

.. math::

    \log\alpha \sim \mathcal N(\mu_\alpha, \sigma_\alpha^2), \quad
    \log a_m \sim \mathcal N(\mu_a, \sigma_a^2) \text{ for every modality's } a_m
    \;(\chi, \beta, \dots), \quad
    \log\gamma \sim \mathcal N(\mu_\gamma, \sigma_\gamma^2),

by default :math:`\mathcal N(0, 5^2)` for alpha and the concentrations (a 95% interval of
5e-5 .. 2e4) and :math:`\mathcal N(0, 1)` for gamma (0.14 .. 7.1: the Potts coupling matters
over a narrow range around its critical value ln(1 + sqrt(L)), 1.0-2.5 for L = 2..120).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from spcopyro._util.number_checks import is_finite_number, is_int, is_number, is_positive_number

GAMMA_MODES = ("fixed", "exchange", "pseudolikelihood")


@dataclass(frozen=True)
class HyperparameterOptions:
    """Hyperparameters sampled inside the Gibbs chain (all off by default: the model's values
    stay fixed, as in the paper).

    Attributes:
        alpha: sample alpha (the concentration of pi's prior) by an exchange update
            (:func:`spcopyro.gibbs.hyperparameters.update_alpha`).
        concentrations: sample chi, beta and every further modality's concentration, each by
            Metropolis-Hastings on its log with the emission distributions integrated out
            (:func:`spcopyro.gibbs.hyperparameters.update_concentration`).
        gamma: ``"fixed"`` (default), ``"exchange"`` (the exchange algorithm: targets the
            model's own posterior of gamma, up to the approximate auxiliary draw; the one to
            use when gamma is inferred) or ``"pseudolikelihood"`` (Besag's pseudo-posterior:
            cheaper, no auxiliary draw, not the model's posterior); see
            :mod:`spcopyro.gibbs.hyperparameters`. ``"fixed"`` is the default because sampled
            alone from ``paper-dp`` (alpha 1e8, L 120), gamma settles just above the critical
            coupling (2.55-2.7 measured on the synthetic house and room1dk5), where the map stays
            a mosaic of 120 concepts: the paper's fixed 4.0 makes better maps there.
        log_alpha_mean, log_alpha_sd: the normal prior of log alpha.
        log_concentration_mean, log_concentration_sd: the normal prior of each log
            concentration (chi, beta, ...).
        log_gamma_mean, log_gamma_sd: the normal prior of log gamma.
        alpha_step: the random-walk proposal's standard deviation on log alpha.
        concentration_step: the proposal's standard deviation on each log concentration.
        gamma_step: the proposal's standard deviation on log gamma, in units of 1/sqrt(P) (P the
            number of neighbour pairs: gamma's posterior narrows as 1/sqrt(P)).
        concentration_moves: Metropolis-Hastings steps per sweep and concentration (each costs
            O(G K_m) lgamma calls, G the concepts that hold observations).
        aux_sweeps: sweeps of the auxiliary label chain of an exchange update (each: pi from
            its conditional, then a single-site sweep with no observations).
        aux_cluster_moves: start every auxiliary sweep with a Swendsen-Wang move too (better
            mixing of whole regions; about 5x the cost of a compiled single-site sweep).
        exchange_probability: the probability that a sweep makes the exchange updates (of
            alpha, and of gamma under ``"exchange"``): a choice made independently of the
            state, so any value in (0, 1] keeps the chain's target; a small one saves time.
    """

    alpha: bool = False
    concentrations: bool = False
    gamma: str = "fixed"
    log_alpha_mean: float = 0.0
    log_alpha_sd: float = 5.0
    log_concentration_mean: float = 0.0
    log_concentration_sd: float = 5.0
    log_gamma_mean: float = 0.0
    log_gamma_sd: float = 1.0
    alpha_step: float = 0.5
    concentration_step: float = 0.2
    gamma_step: float = 2.0
    concentration_moves: int = 3
    aux_sweeps: int = 3
    aux_cluster_moves: bool = False
    exchange_probability: float = 1.0

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"HyperparameterOptions.{name}={getattr(self, name)!r}: {why}")

        for name in ("alpha", "concentrations", "aux_cluster_moves"):
            if not isinstance(getattr(self, name), bool):
                raise bad(name, "must be true or false")
        if self.gamma not in GAMMA_MODES:
            raise bad("gamma", f"choose one of {GAMMA_MODES}")
        for name in ("log_alpha_mean", "log_concentration_mean", "log_gamma_mean"):
            value = getattr(self, name)
            if not is_finite_number(value):
                raise bad(name, "must be a finite number")
        positive = ("log_alpha_sd", "log_concentration_sd", "log_gamma_sd", "alpha_step",
                    "concentration_step", "gamma_step")  # fmt: skip
        for name in positive:
            value = getattr(self, name)
            if not is_positive_number(value):
                raise bad(name, "must be a finite positive number")
        for name in ("concentration_moves", "aux_sweeps"):
            value = getattr(self, name)
            if not (is_int(value) and value >= 1):
                raise bad(name, "must be an integer >= 1")
        p = self.exchange_probability
        if not (is_number(p) and 0.0 < p <= 1.0):
            raise bad("exchange_probability", "must be a probability in (0, 1]")

    @property
    def active(self) -> bool:
        """Whether any hyperparameter is sampled."""
        return self.alpha or self.concentrations or self.gamma != "fixed"

    def unused(self) -> list[str]:
        """The tuning fields no sampled hyperparameter reads (setting them changes nothing): a
        prior or step of alpha, the concentrations or gamma while it is not sampled, and the
        exchange updates' (``aux_*``, ``exchange_probability``) without alpha or gamma by
        exchange."""
        exchange = self.alpha or self.gamma == "exchange"
        gamma = self.gamma != "fixed"
        reads = {"log_alpha_mean": self.alpha, "log_alpha_sd": self.alpha,
                 "alpha_step": self.alpha, "log_concentration_mean": self.concentrations,
                 "log_concentration_sd": self.concentrations,
                 "concentration_step": self.concentrations,
                 "concentration_moves": self.concentrations or self.gamma == "pseudolikelihood",
                 "log_gamma_mean": gamma, "log_gamma_sd": gamma, "gamma_step": gamma,
                 "aux_sweeps": exchange, "aux_cluster_moves": exchange,
                 "exchange_probability": exchange}  # fmt: skip
        return [name for name, read in reads.items() if not read]

    def replace(self, **changes: object) -> HyperparameterOptions:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def as_hyper_options(value: object) -> HyperparameterOptions:
    """``value`` as :class:`HyperparameterOptions` (a mapping, e.g. read back from JSON, is
    accepted)."""
    if isinstance(value, HyperparameterOptions):
        return value
    if isinstance(value, dict):
        return HyperparameterOptions(**value)
    raise ValueError(f"GibbsOptions.hyper={value!r}: must be HyperparameterOptions")
