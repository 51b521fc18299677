r"""The evidence lower bound of SpCoMapping's unnormalised joint under a mean-field q.

.. math::

    \mathcal{L}(q) = E_q[\log p^*(C, x \mid \pi, \phi)] - \mathrm{KL}(q(\pi) \,\|\, p(\pi))
        - \sum_{m,l} \mathrm{KL}(q(\phi_{ml}) \,\|\, p(\phi_{ml})) + H[q(C)],

    E_q[\log p^*(C, x \mid \pi, \phi)] = \sum_{i,l} q_i(l) E[\log\pi_l]
        + \gamma \sum_{(a,b)} \sum_l q_a(l) q_b(l)
        + \sum_{i \in \mathrm{obs}} \sum_l q_i(l)\, \ell_{il} + \text{multinomial coefficients},

with :math:`\ell_{il}` eq. (13)'s observation term at E[log phi]. As in the model's density
(:func:`spcopyro.model.spcomapping_model`), the Potts normaliser Z(pi, gamma) is left out, so
this bounds the log of the *unnormalised* evidence :math:`\log \sum_C \int p^*`. Both this
bound and the Gibbs trace's log joint are on the scale of log p*, but they are not the same
quantity: the log joint is a density at one state, not a bound on the evidence, and a chain's
log joint mostly lies above the evidence (notebook 03's 3 x 3 map: a mean of +1.8 against an
exact log evidence of -8.5). On a tiny map the bound is checked against that evidence computed
by enumeration.
"""

from __future__ import annotations

import torch

from spcopyro.config import SpCoConfig
from spcopyro.guides.factors import (
    GlobalFactors,
    expected_log_emissions,
    expected_log_pi,
    kl_to_prior,
)
from spcopyro.likelihood import (
    expected_agreements,
    multinomial_coefficients,
    observation_log_likelihood,
)
from spcopyro.model import ModelData


def label_entropy(q: torch.Tensor) -> torch.Tensor:
    """H[q(C)] = -sum_i sum_l q_i(l) log q_i(l) (0 log 0 = 0); ``q`` is ``[N, L]``."""
    return -torch.special.xlogy(q, q).sum()


def expected_log_likelihood(
    q: torch.Tensor,
    factors: GlobalFactors,
    data: ModelData,
    config: SpCoConfig,
    gamma: float | None = None,
) -> torch.Tensor:
    """E_q[log p*(C, x | pi, phi)]: the label, Potts and observation terms in expectation."""
    gamma = config.gamma if gamma is None else gamma
    log_pi = expected_log_pi(factors)  # [L]
    loglik = observation_log_likelihood(expected_log_emissions(factors), data, config)  # [M, L]
    total = (q.sum(0) * log_pi).sum() + gamma * expected_agreements(q, data.pairs)
    return total + (q[data.obs_cells] * loglik).sum() + multinomial_coefficients(data, config)


def elbo(
    q: torch.Tensor,
    factors: GlobalFactors,
    data: ModelData,
    config: SpCoConfig,
    gamma: float | None = None,
) -> torch.Tensor:
    """The ELBO (module docstring) of q = (q(C) ``[N, L]``, the global ``factors``); ``gamma``
    replaces the model's coupling (annealing scores each stage's own objective)."""
    return (
        expected_log_likelihood(q, factors, data, config, gamma)
        - kl_to_prior(factors, data, config)
        + label_entropy(q)
    )
