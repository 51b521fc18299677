r"""Exact answers on tiny maps, by enumerating all L^N labellings: the oracle for the
approximate label-field methods (mean field, loopy BP, Gibbs) and for the ELBO.

With N free cells and L concepts there are L^N labellings C; for N <= ~10 and small L they can
all be listed (3^9 = 19683 for a 3x3 map). Three exact quantities follow.

**(a) Label marginals with the globals fixed.** With log pi and each modality's log phi given,
the model's unnormalised joint (:func:`spcopyro.model.spcomapping_model`) is, as a function of
C, the Potts-coupled field

.. math::

    \log p^*(\pi, \phi, C, x) = \sum_i \log\pi_{C_i} + \gamma E(C)
        + \sum_{i \in \mathrm{obs}} \sum_m x^{(m)}_i \cdot \log\phi_{m, C_i} + \text{const},

(eqs. 5-10), so p(C | x, pi, phi) is its softmax over labellings and
p(C_i = l | x, pi, phi) a sum of that softmax. :func:`labelling_log_joint` is the whole log p*,
constants included, and is tested equal to the Pyro model's own ``log_prob_sum`` at every
labelling of a small map.

**(b) The log evidence of the unnormalised joint.** Given C the globals integrate in closed form
(conjugacy, eqs. 14-17): with concept sizes n_l and per-concept counts X_{ml} = sum of the
observed counts of the cells labelled l (real-valued counts allowed, hence lgamma),

.. math::

    \int p^*(\pi, \phi, C, x)\, d\pi\, d\phi = e^{\gamma E(C)}
        \frac{B(a_\pi + n)}{B(a_\pi)}
        \prod_{m \text{ in use}} \Big[\prod_{i \in \mathrm{obs}}
            \frac{\Gamma(|x^{(m)}_i| + 1)}{\prod_k \Gamma(x^{(m)}_{ik} + 1)}
            \prod_l \frac{B(a_m + X_{ml})}{B(a_m)}\Big],

B the multivariate Beta function (the Dirichlet-multinomial marginals). The log evidence
:math:`\log \sum_C \int p^*` is the quantity every ELBO of :mod:`spcopyro.guides.elbo`
bounds from below (the Potts normaliser Z(pi, gamma) is left out in both, as in the model).

**(c) Posterior label marginals with the globals integrated out.** The softmax of (b)'s
per-labelling terms. With the model's symmetric priors the integrated posterior is invariant
under relabelling the concepts, so every single-cell marginal p(C_i = l | x) is exactly 1/L
(label switching); the informative exact quantity is the **co-assignment** p(C_i = C_j | x),
which :func:`exact_posterior` returns too.

:func:`spcopyro.guides.tiny_maps.compare_on_tiny_map` puts mean field, loopy BP and the
exact marginals side by side.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch

from spcopyro.config import SpCoConfig
from spcopyro.likelihood import (
    dirichlet_multinomial_log_marginals,
    log_joint_constant,
    multinomial_coefficients,
    observation_log_likelihood,
)
from spcopyro.model import DTYPE, ModelData, potts_agreements

MAX_LABELLINGS = 2_000_000
"""The most labellings the enumerator will list (L^N; 3^13 is 1.6 million)."""

_CHUNK = 65_536  # labellings scored at once (bounds the [S, M, L] one-hot's memory)


def all_labellings(num_cells: int, num_concepts: int) -> torch.Tensor:
    """[L^N, N] int64 every labelling of N cells with L concepts, in lexicographic order
    (cell 0 the most significant digit)."""
    total = num_concepts**num_cells
    if total > MAX_LABELLINGS:
        raise ValueError(
            f"{num_concepts}^{num_cells} = {total} labellings is too many to enumerate "
            f"(at most {MAX_LABELLINGS}); exact answers are for tiny maps (N <= ~10 free cells)"
        )
    index = torch.arange(total)  # [S]
    powers = num_concepts ** torch.arange(num_cells - 1, -1, -1)  # [N]
    return (index[:, None] // powers) % num_concepts  # [S, N]


def _check_globals(
    log_pi: torch.Tensor, log_emissions: Sequence[torch.Tensor], data: ModelData, config: SpCoConfig
) -> None:
    L = config.num_concepts
    if log_pi.shape != (L,):
        raise ValueError(f"log_pi must be [{L}], got {tuple(log_pi.shape)}")
    if len(log_emissions) != len(data.modalities):
        raise ValueError(
            f"{len(log_emissions)} log-emission tables for {len(data.modalities)} modalities"
        )
    for modality, table in zip(data.modalities, log_emissions, strict=True):
        K = modality.counts.shape[-1]
        if table.shape != (L, K):
            raise ValueError(
                f"log {modality.parameter} must be [{L}, {K}], got {tuple(table.shape)}"
            )


def labelling_log_joint(
    labellings: torch.Tensor,
    log_pi: torch.Tensor,
    log_emissions: Sequence[torch.Tensor],
    data: ModelData,
    config: SpCoConfig,
) -> torch.Tensor:
    """[S] the model's whole log p*(pi, phi, C, x) at each of ``labellings`` ``[S, N]`` with the
    globals fixed (``log_pi`` [L], one ``[L, K_m]`` log table per modality): priors, Dirichlet
    normalisers and multinomial coefficients included, so it equals the Pyro model's
    ``log_prob_sum`` (tested)."""
    _check_globals(log_pi, log_emissions, data, config)
    fixed = log_joint_constant(data, config) + (config.pi_concentration - 1) * log_pi.sum()
    for modality, log_phi in zip(data.modalities, log_emissions, strict=True):
        fixed = fixed + (config.concentration(modality.name) - 1) * log_phi.sum()
    loglik = observation_log_likelihood(log_emissions, data, config)  # [M, L]
    rows = torch.arange(data.obs_cells.shape[0])  # [M]
    values = []
    for chunk in labellings.split(_CHUNK):
        value = log_pi[chunk].sum(-1) + config.gamma * potts_agreements(chunk, data.pairs)  # [s]
        value = value + loglik[rows, chunk[:, data.obs_cells]].sum(-1)  # [s, M] -> [s]
        values.append(value + fixed)
    return torch.cat(values)


def labelling_log_evidence(
    labellings: torch.Tensor, data: ModelData, config: SpCoConfig
) -> torch.Tensor:
    """[S] log of the integral of p*(pi, phi, C, x) over pi and phi at each labelling
    ``[S, N]``: the Dirichlet-multinomial marginals of the module docstring, plus gamma E(C)."""
    L = config.num_concepts
    coefficients = multinomial_coefficients(data, config)
    values = []
    for chunk in labellings.split(_CHUNK):
        one_hot = torch.nn.functional.one_hot(chunk, L).to(DTYPE)  # [s, N, L]
        value = dirichlet_multinomial_log_marginals(config.pi_concentration, one_hot.sum(1))  # [s]
        value = value + config.gamma * potts_agreements(chunk, data.pairs)
        observed = one_hot[:, data.obs_cells]  # [s, M, L]
        for modality in data.modalities:
            if config.uses(modality.name):
                per_concept = torch.einsum("sml,mk->slk", observed, modality.counts)  # [s, L, K]
                a = config.concentration(modality.name)
                value = value + dirichlet_multinomial_log_marginals(a, per_concept).sum(-1)
        values.append(value + coefficients)
    return torch.cat(values)


def _marginals(labellings: torch.Tensor, log_weights: torch.Tensor, L: int) -> torch.Tensor:
    """[N, L] sum over labellings of softmax(log_weights) one_hot(C_i = l)."""
    weights = torch.softmax(log_weights, 0)  # [S]
    S, N = labellings.shape
    marginals = torch.zeros(N * L, dtype=DTYPE)
    flat = labellings + L * torch.arange(N)  # [S, N] index of (i, C_i) in [N * L]
    marginals.index_add_(0, flat.reshape(-1), weights[:, None].expand(S, N).reshape(-1))
    return marginals.reshape(N, L)


def exact_marginals(
    data: ModelData,
    config: SpCoConfig,
    log_pi: torch.Tensor,
    log_emissions: Sequence[torch.Tensor],
) -> torch.Tensor:
    """[N, L] p(C_i = l | x, pi, phi) with the globals fixed (module docstring, (a)).

    ``log_pi`` and the log emissions need not be normalised: an expected log parameter under a
    variational factor (E[log pi], E[log phi]) defines the field a mean-field or BP label update
    targets, and its exact marginals are what those updates approximate.
    """
    labellings = all_labellings(data.num_free, config.num_concepts)
    log_weights = labelling_log_joint(labellings, log_pi, log_emissions, data, config)
    return _marginals(labellings, log_weights, config.num_concepts)


def exact_log_partition(
    data: ModelData,
    config: SpCoConfig,
    log_pi: torch.Tensor,
    log_emissions: Sequence[torch.Tensor],
    gamma: float | None = None,
) -> torch.Tensor:
    """log sum_C exp(sum_i log pi_{C_i} + gamma E(C) + sum_obs x_i . log phi_{C_i}): the label
    field's log partition function with the globals fixed (no priors, no constants)."""
    _check_globals(log_pi, log_emissions, data, config)
    gamma = config.gamma if gamma is None else gamma
    labellings = all_labellings(data.num_free, config.num_concepts)
    loglik = observation_log_likelihood(log_emissions, data, config)  # [M, L]
    rows = torch.arange(data.obs_cells.shape[0])
    values = log_pi[labellings].sum(-1) + gamma * potts_agreements(labellings, data.pairs)
    values = values + loglik[rows, labellings[:, data.obs_cells]].sum(-1)  # [S]
    return torch.logsumexp(values, 0)


class ExactPosterior(NamedTuple):
    """The exact posterior over labels with pi and phi integrated out (module docstring)."""

    log_evidence: torch.Tensor
    """[] log sum_C integral p*(pi, phi, C, x): what every ELBO is below."""
    marginals: torch.Tensor
    """[N, L] p(C_i = l | x): exactly 1/L under the model's symmetric priors (label switching)."""
    coassignment: torch.Tensor
    """[N, N] p(C_i = C_j | x): the label-invariant exact answer (1 on the diagonal)."""


def exact_posterior(data: ModelData, config: SpCoConfig) -> ExactPosterior:
    """The exact log evidence and label posterior with the globals integrated out ((b), (c))."""
    L = config.num_concepts
    labellings = all_labellings(data.num_free, L)
    log_weights = labelling_log_evidence(labellings, data, config)  # [S]
    weights = torch.softmax(log_weights, 0)  # [S]
    coassignment = torch.zeros(data.num_free, data.num_free, dtype=DTYPE)  # [N, N]
    for chunk, w in zip(labellings.split(_CHUNK), weights.split(_CHUNK), strict=True):
        same = (chunk[:, :, None] == chunk[:, None, :]).to(DTYPE)  # [s, N, N]
        coassignment += torch.einsum("s,sij->ij", w, same)
    return ExactPosterior(
        torch.logsumexp(log_weights, 0), _marginals(labellings, log_weights, L), coassignment
    )


def exact_log_evidence(data: ModelData, config: SpCoConfig) -> torch.Tensor:
    """[] log sum_C integral p*(pi, phi, C, x) d pi d phi (module docstring, (b))."""
    labellings = all_labellings(data.num_free, config.num_concepts)
    return torch.logsumexp(labelling_log_evidence(labellings, data, config), 0)
