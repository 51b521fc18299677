r"""The log targets of the hyperparameter updates (:mod:`spcopyro.gibbs.hyperparameters`).

**The joint the sampler targets.** The model (:func:`spcopyro.model.spcomapping_model`) scores
:math:`\mathrm{Dir}(\pi; a_\pi)\prod_i \pi_{C_i}\, e^{\gamma E(C)}` for pi and the labels. As a
distribution over :math:`(\pi, C)` this is normalised *jointly*, by

.. math::

    Z(\gamma, \alpha) = \sum_C e^{\gamma E(C)} \frac{B(a_\pi + n(C))}{B(a_\pi)}, \qquad
    a_\pi = \alpha / L \text{ (DP) or } \alpha,

(:math:`n(C)` the label counts, B the multivariate beta function): this is the joint whose
conditionals the sampler draws (pi | C is Dir(a_pi + n(C)), eqs. 14-15), and the one the
joint-distribution tests enumerate. (A conditional MRF :math:`p(C \mid \pi) = \prod \pi_{C_i}
e^{\gamma E} / Z(\gamma, \pi)` would change pi's conditional by :math:`1/Z(\gamma, \pi)`;
that is not this model.) Note that Z depends on alpha as well as on gamma (a concentrated pi
makes agreeing neighbours likelier), and on nothing else. With hyperpriors
:math:`p(\alpha), p(\gamma)` the conditionals of the hyperparameters are therefore

.. math::

    p(\gamma \mid C, \alpha) &\propto p(\gamma)\, e^{\gamma E(C)} / Z(\gamma, \alpha), \\
    p(\alpha \mid C, \gamma) &\propto p(\alpha)\, \frac{B(a_\pi + n(C))}{B(a_\pi)}
        / Z(\gamma, \alpha) \quad (\pi \text{ integrated out}), \\
    p(a_m \mid C, \text{data}) &\propto p(a_m) \prod_l \frac{\Gamma(K_m a_m)}
        {\Gamma(K_m a_m + x_{l\cdot})} \prod_k \frac{\Gamma(a_m + x_{lk})}{\Gamma(a_m)}
        \quad (\phi_m \text{ integrated out}),

the last the Dirichlet-multinomial marginal of each concept's counts :math:`x_{lk}` of
modality m (chi for images, beta for words): valid for real-valued counts (tf-idf, image
histograms) as well, since :math:`\int \mathrm{Dir}(\phi; a) \prod_k \phi_k^{x_k} d\phi =
B(a + x) / B(a)` for any :math:`x_k \geq 0`. Z is intractable (a sum over :math:`L^N`
labelings), so gamma and alpha are updated by the exchange algorithm (Murray, Ghahramani &
MacKay, 2006), whose acceptance ratio needs only the unnormalised :math:`f(C; \gamma, \alpha)
= e^{\gamma E(C)} B(a_\pi + n(C)) / B(a_\pi)`: Z cancels between the data C and an auxiliary
C' drawn under the proposed value (:func:`exchange_log_ratio`).

All hyperpriors are normal on the log scale (:mod:`spcopyro.gibbs.hyper_options`), and the
random-walk proposals are symmetric on the log scale, so every ratio here is one of densities
of the *log* hyperparameters (no Jacobian terms).
"""

from __future__ import annotations

import math

import torch

from spcopyro.likelihood import dirichlet_multinomial_log_marginals
from spcopyro.model import DTYPE

LOG_SQRT_2PI = 0.5 * math.log(2 * math.pi)


def log_normal_prior(log_value: float, mean: float, sd: float) -> float:
    """log N(log_value; mean, sd^2): the density of a log hyperparameter."""
    z = (log_value - mean) / sd
    return -0.5 * z * z - math.log(sd) - LOG_SQRT_2PI


def dirichlet_multinomial_log_marginal(counts: torch.Tensor, concentration: float) -> float:
    r"""sum over the rows l of log B(a + x_l) / B(a) for a symmetric Dir(a) of size K:
    :math:`\sum_l [\log\Gamma(Ka) - \log\Gamma(Ka + x_{l\cdot}) + \sum_k \log\Gamma(a + x_{lk})
    - \log\Gamma(a)]`. ``counts`` is ``[G, K]`` (real values >= 0 allowed); a row of zeros adds
    0, so passing only the concepts that hold counts is enough. The multinomial coefficients
    (free of a) are left out; K = 0 gives 0 (the words of a house where none was heard: their
    concentration's target is then its prior alone)."""
    return float(dirichlet_multinomial_log_marginals(float(concentration), counts).sum())


def label_log_marginal(label_counts: torch.Tensor, pi_concentration: float) -> float:
    """log B(a_pi + n) / B(a_pi): the labels' probability with pi integrated out, up to the
    Potts factor (``label_counts`` [L] the cells per concept)."""
    return dirichlet_multinomial_log_marginal(label_counts.to(DTYPE)[None], pi_concentration)


def exchange_log_ratio(
    log_prior_new: float,
    log_prior_old: float,
    log_f_data_new: float,
    log_f_data_old: float,
    log_f_aux_new: float,
    log_f_aux_old: float,
) -> float:
    r"""The exchange algorithm's log acceptance ratio for a symmetric proposal
    :math:`\theta \to \theta'` with an auxiliary draw
    :math:`C' \sim f(\cdot; \theta') / Z(\theta')`:

    .. math::

        \log \frac{p(\theta')\, f(C; \theta')\, f(C'; \theta)}{p(\theta)\, f(C; \theta)\,
        f(C'; \theta')},

    ``log_f_data_*`` = log f(C; .), ``log_f_aux_*`` = log f(C'; .), under the new and old value.
    For gamma this is :math:`\log p(\gamma') - \log p(\gamma) + (\gamma' - \gamma)(E(C) - E(C'))`.
    """
    return (
        log_prior_new - log_prior_old
        + log_f_data_new - log_f_data_old
        + log_f_aux_old - log_f_aux_new
    )  # fmt: skip


class PseudoLikelihood:
    r"""Besag's pseudo-log-likelihood of gamma at fixed labels C and pi, as a function of gamma:

    .. math::

        \mathrm{PL}(\gamma) = \sum_i \log p(C_i \mid C_{-i}, \pi, \gamma)
        = \sum_i \Big[\log \pi_{C_i} + \gamma\, n_{C_i}(i)
          - \log \sum_l \pi_l\, e^{\gamma n_l(i)}\Big],

    the prior part of eq. (13) (the Potts prior with field pi, no observations). With the
    labels' own terms constant in gamma and :math:`\sum_l \pi_l = 1`, the normaliser is
    :math:`1 + \sum_{d} \pi_{l_d}\, \mathrm{expm1}(\gamma m_d) / m_d` over the D neighbour slots
    d of cell i, :math:`l_d` the slot's label and :math:`m_d` how many slots carry it (so each
    distinct neighbour label counts once): O(N D) per evaluation, whatever L.
    """

    def __init__(self, labels: torch.Tensor, log_pi: torch.Tensor, neighbours: torch.Tensor):
        valid = neighbours >= 0  # [N, D]
        nb = torch.where(valid, labels[neighbours.clamp_min(0)], -1)  # [N, D]
        same = (nb[:, :, None] == nb[:, None, :]) & valid[:, :, None]  # [N, D, D]
        self.multiplicity = same.sum(-1).clamp_min(1).to(DTYPE)  # [N, D] m_d
        pi = torch.exp(log_pi - torch.logsumexp(log_pi, 0))  # [L]
        self.weight = torch.where(valid, pi[nb.clamp_min(0)], 0.0) / self.multiplicity  # [N, D]
        self.agreements = float((nb == labels[:, None]).sum())  # sum_i n_{C_i}(i) = 2 E(C)

    def __call__(self, gamma: float) -> float:
        """PL(gamma) up to the gamma-free sum of log pi_{C_i}."""
        tilt = torch.expm1(gamma * self.multiplicity)  # [N, D]
        normaliser = torch.log1p((self.weight * tilt).sum(-1))  # [N]
        return gamma * self.agreements - float(normaliser.sum())
