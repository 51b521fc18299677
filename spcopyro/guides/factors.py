r"""The variational factors of the global parameters: q(pi) and q(phi_m) per modality.

Mean field over the globals (Blei, Kucukelbir & McAuliffe 2017, Section 4) factorises
``q(pi) prod_m prod_l q(phi_ml)``. Every complete conditional of the model is a Dirichlet
(eqs. 14-17), so each optimal factor is the Dirichlet with the conditional's parameters, the
counts replaced by their expectations under q(C):

.. math::

    q(\pi) = \mathrm{Dir}(a_\pi + \textstyle\sum_i q_i), \qquad
    q(\phi_{ml}) = \mathrm{Dir}(a_m + \textstyle\sum_{i \in \mathrm{obs}} q_i(l)\, x^{(m)}_i),

with a_pi = alpha / L (weak-limit DP) or alpha, a_m = chi (images), beta (words) or the
modality's concentration. The expectations a CAVI label update reads are
:math:`E[\log\pi_l] = \psi(a_l) - \psi(\sum a)` and the same for every phi.

**Stick-breaking option** (Blei & Jordan 2006): the truncated DP pi_l = v_l prod_{j<l}(1 - v_j),
v_l ~ Beta(1, alpha), v_L = 1, with q(v_l) = Beta(1 + N_l, alpha + sum_{j>l} N_j). This is a
different prior over pi from the weak-limit Dirichlet (its concepts are ordered by expected size),
so its ELBO is not comparable with the Dirichlet one's; use it to compare the two DP
approximations, not to score the paper's model.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple

import torch

from spcopyro._util.messages import setting, warn_once
from spcopyro.config import SpCoConfig
from spcopyro.likelihood import ConceptStatistics
from spcopyro.model import DTYPE, ModelData

PiFamily = Literal["dirichlet", "stick-breaking"]
"""q(pi) as the model states it (Dirichlet) or the truncated stick-breaking DP."""


class GlobalFactors(NamedTuple):
    """The parameters of q(pi) and q(phi_m): everything of q that is not a cell label.

    For ``pi_family="dirichlet"`` ``pi`` is q(pi)'s Dirichlet concentration ``[L]``; for
    ``"stick-breaking"`` it is ``[L - 1, 2]``, the Beta(a, b) of each stick fraction v_l.
    """

    pi: torch.Tensor
    emissions: tuple[torch.Tensor, ...]
    """Per modality of the data, ``[L, K_m]`` Dirichlet concentrations of q(phi_ml)."""
    pi_family: PiFamily = "dirichlet"


def _check_family(pi_family: str) -> None:
    if pi_family not in ("dirichlet", "stick-breaking"):
        raise ValueError(f"pi_family must be 'dirichlet' or 'stick-breaking', got {pi_family!r}")


def stick_breaking_warning(config: SpCoConfig) -> str | None:
    """Why the truncated stick-breaking prior is degenerate at ``config``'s alpha and L, else
    None: its last concept takes the remainder of every stick, E[pi_L] = (alpha / (1 + alpha))^
    (L - 1), most of the mass at the weak-limit alpha of the presets (1e7-1e8), so every cell
    goes to it (measured: one concept, ARI 0, on the synthetic house; alpha 1 or 10: 9)."""
    last = (config.alpha / (1.0 + config.alpha)) ** (config.num_concepts - 1)
    if last <= 0.5 or config.num_concepts == 1:  # L = 1: pi = 1 whatever alpha; no advice
        return None
    # 1 - last without the cancellation: (1 - 1 / (1 + alpha))^(L - 1) = exp((L - 1) log1p(-..))
    rest = -math.expm1((config.num_concepts - 1) * math.log1p(-1.0 / (1.0 + config.alpha)))
    return (
        f"pi_family='stick-breaking' with alpha = {config.alpha:g} and L = "
        f"{config.num_concepts}: the truncated prior puts {_share(last, rest)} of pi's mass on "
        "the last concept (the sticks' remainder), which then takes every cell; this alpha is "
        f"the weak-limit Dirichlet's: give the stick-breaking one an "
        f"{setting('alpha', '--alpha')} of order 1-10"
    )


def _share(fraction: float, rest: float) -> str:
    """``fraction`` as a percentage that never rounds up to 100% while ``rest`` (1 - fraction,
    computed apart) is above 0: 99.7% was printed "100%". Whole percents below 99.5%, more
    digits above, "more than 99.9999%" beyond them."""
    if rest <= 0.0:
        return "100%"
    for digits in range(5):
        shown = f"{100 * fraction:.{digits}f}"
        if float(shown) < 100.0:
            return f"{shown}%"
    return "more than 99.9999%"


def prior_factors(
    data: ModelData, config: SpCoConfig, pi_family: PiFamily = "dirichlet"
) -> GlobalFactors:
    """The prior's own parameters as factors (what q is before it has seen a cell)."""
    _check_family(pi_family)
    L = config.num_concepts
    if pi_family == "dirichlet":
        pi = torch.full((L,), config.pi_concentration, dtype=DTYPE)
    else:
        pi = torch.tensor([1.0, config.alpha], dtype=DTYPE).expand(L - 1, 2).clone()
        warning = stick_breaking_warning(config)
        if warning:
            warn_once(("stick-breaking", config.alpha, L), warning)
    emissions = tuple(
        torch.full((L, m.counts.shape[-1]), config.concentration(m.name), dtype=DTYPE)
        for m in data.modalities
    )
    return GlobalFactors(pi, emissions, pi_family)


def update_factors(
    statistics: ConceptStatistics,
    data: ModelData,
    config: SpCoConfig,
    pi_family: PiFamily = "dirichlet",
) -> GlobalFactors:
    """The optimal q(pi), q(phi) given q(C)'s expected statistics (eqs. 14-17 in expectation).

    ``statistics``: :func:`spcopyro.likelihood.concept_statistics` of q(C) (expected concept sizes
    and per-concept counts; a switched-off modality has zero counts, so its factor is its prior).
    """
    prior = prior_factors(data, config, pi_family)
    sizes = statistics.cells.to(DTYPE)  # [L]
    if pi_family == "dirichlet":
        pi = prior.pi + sizes
    else:
        later = sizes.flip(0).cumsum(0).flip(0)  # [L] sum_{j >= l} N_j
        pi = torch.stack([1.0 + sizes[:-1], config.alpha + later[1:]], dim=-1)  # [L-1, 2]
    emissions = tuple(
        a + counts for a, counts in zip(prior.emissions, statistics.counts, strict=True)
    )
    return GlobalFactors(pi, emissions, pi_family)


def _dirichlet_expected_log(concentration: torch.Tensor) -> torch.Tensor:
    """E[log x] under Dir(concentration) along the last dimension."""
    return torch.digamma(concentration) - torch.digamma(concentration.sum(-1, keepdim=True))


def expected_log_pi(factors: GlobalFactors) -> torch.Tensor:
    """[L] E_q[log pi_l]."""
    if factors.pi_family == "dirichlet":
        return _dirichlet_expected_log(factors.pi)
    a, b = factors.pi[:, 0], factors.pi[:, 1]  # [L-1]
    total = torch.digamma(a + b)
    log_v = torch.digamma(a) - total  # E log v_l
    log_rest = torch.digamma(b) - total  # E log (1 - v_l)
    before = torch.cat([log_rest.new_zeros(1), log_rest.cumsum(0)])  # [L] sum_{j<l}
    return before + torch.cat([log_v, log_v.new_zeros(1)])  # v_L = 1


def expected_log_emissions(factors: GlobalFactors) -> tuple[torch.Tensor, ...]:
    """Per modality ``[L, K_m]`` E_q[log phi_mlk]."""
    return tuple(_dirichlet_expected_log(a) for a in factors.emissions)


def mean_pi(factors: GlobalFactors) -> torch.Tensor:
    """[L] E_q[pi]."""
    if factors.pi_family == "dirichlet":
        return factors.pi / factors.pi.sum()
    a, b = factors.pi[:, 0], factors.pi[:, 1]
    v = a / (a + b)  # [L-1] E v_l (the v_l are independent under q)
    rest = torch.cat([v.new_ones(1), (1 - v).cumprod(0)])  # [L] E prod_{j<l} (1 - v_j)
    return rest * torch.cat([v, v.new_ones(1)])


def mean_emissions(factors: GlobalFactors) -> tuple[torch.Tensor, ...]:
    """Per modality ``[L, K_m]`` E_q[phi_ml]."""
    return tuple(a / a.sum(-1, keepdim=True) for a in factors.emissions)


def kl_to_prior(factors: GlobalFactors, data: ModelData, config: SpCoConfig) -> torch.Tensor:
    """KL(q(pi) || p(pi)) + sum_m sum_l KL(q(phi_ml) || p(phi_ml)), in closed form."""
    prior = prior_factors(data, config, factors.pi_family)
    # Dirichlet: [L] each. Stick-breaking: [L - 1, 2] each, a Beta(a, b) being Dir over (a, b),
    # so the rows' sum is the sum over the sticks; L = 1 has none (pi = 1) and a KL of 0.
    total = dirichlet_kl(factors.pi, prior.pi)
    for q_phi, p_phi in zip(factors.emissions, prior.emissions, strict=True):
        total = total + dirichlet_kl(q_phi, p_phi)
    return total


def dirichlet_kl(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    r"""Sum over the rows of KL(Dir(a) || Dir(b)) (``[..., K]`` concentrations, b broadcast to
    a), in closed form, over the entries where a differs from b only:

    .. math::

        \sum_{\text{rows}} \Big[\log\Gamma(a_0) - \log\Gamma(b_0) - (a_0 - b_0)\psi(a_0)\Big]
        + \sum_{k:\, a_k \ne b_k} \Big[\log\Gamma(b_k) - \log\Gamma(a_k)
        + (a_k - b_k)\psi(a_k)\Big],

    which is the usual form (``torch.distributions.kl_divergence``) with the entries a_k = b_k,
    whose terms are exactly zero, left out: a factor q(phi_ml) differs from its prior only where
    concept l has expected counts, a few of the L x K_m entries (room2ldk4: 2 ms down to ~0.2)."""
    b = b.expand_as(a)
    if a.shape[-1] == 0:  # over no items (a house without words): q and prior are one point
        return torch.zeros((), dtype=a.dtype)
    a0, b0 = a.sum(-1), b.sum(-1)
    rows = torch.lgamma(a0) - torch.lgamma(b0) - (a0 - b0) * torch.digamma(a0)
    differ = a != b
    ad, bd = a[differ], b[differ]
    entries = torch.lgamma(bd) - torch.lgamma(ad) + (ad - bd) * torch.digamma(ad)
    return rows.sum() + entries.sum()
