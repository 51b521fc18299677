r"""The model's per-cell math, for any inference method: hard labels or soft assignments.

Gibbs sampling (:mod:`spcopyro.gibbs`) evaluates these terms at one state: integer labels
``[N]`` and log parameters (log pi, and each modality's log distributions ``[L, K_m]``). A
mean-field or belief-propagation method evaluates the same terms in expectation: soft
assignments ``q`` ``[N, L]`` (rows sum to 1) and *expected* log parameters
(E[log theta], E[log w], ...). Every function here takes either; a label vector is the one-hot
special case of ``q`` (tested equal).

With :math:`n_l(i) = \sum_{r \sim i} q_r(l)` the neighbour field and
:math:`\ell_{ml} = \sum_m \sum_k x^{(m)}_{ik} \log\phi^{(m)}_{lk}` the observed cell's
log-likelihood under concept l (the concept-dependent part of eqs. 5 and 6, summed over the
modalities in use), the full conditional of a cell label (eq. 13) and the mean-field update of
q(C_i) share one form:

.. math::

    \log p(C_i = l \mid \cdot) \text{ or } \log q(C_i = l) =
        \log\pi_l + \gamma\, n_l(i) + \ell_{il} + \text{const},

with point values (Gibbs) or expectations (variational) of :math:`\log\pi, \log\phi`. The
conjugate updates of the globals (eqs. 14-17) read the sufficient statistics of
:func:`concept_statistics`: concept sizes and each modality's counts per concept.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch

from spcopyro._util.multinomial import multinomial_counts_log_prob
from spcopyro.config import SpCoConfig
from spcopyro.model import DTYPE, ModelData, potts_agreements


def _is_hard(assignments: torch.Tensor) -> bool:
    """Integer ``[N]`` labels (True) or float ``[N, L]`` soft assignments (False)."""
    if torch.is_floating_point(assignments):
        if assignments.dim() != 2:
            raise ValueError(f"soft assignments must be [N, L], got {tuple(assignments.shape)}")
        return False
    if assignments.dim() != 1:
        raise ValueError(f"labels must be [N], got {tuple(assignments.shape)}")
    return True


def observation_log_likelihood(
    log_parameters: Sequence[torch.Tensor], data: ModelData, config: SpCoConfig
) -> torch.Tensor:
    """[M, L] each observed cell's log-likelihood under each concept (up to constants):
    sum over the modalities in use of counts_m @ log_phi_m^T (eqs. 5, 6).

    ``log_parameters``: one ``[L, K_m]`` tensor per modality of ``data.modalities`` (log
    distributions for Gibbs, E[log phi] under q(phi) for variational inference).
    """
    if len(log_parameters) != len(data.modalities):
        raise ValueError(
            f"{len(log_parameters)} log-parameter tables for {len(data.modalities)} modalities"
        )
    M, L = data.obs_cells.shape[0], log_parameters[0].shape[0]
    loglik = torch.zeros(M, L, dtype=DTYPE)
    for modality, log_phi in zip(data.modalities, log_parameters, strict=True):
        if config.uses(modality.name):
            loglik += modality.counts @ log_phi.T  # [M, K_m] @ [K_m, L]
    return loglik


def neighbour_agreements(neighbour_labels: torch.Tensor, num_concepts: int) -> torch.Tensor:
    """[n, L] n_l(i): how many of each cell's neighbours carry label l (``-1`` = no neighbour)."""
    valid = neighbour_labels >= 0  # [n, D]
    agree = torch.zeros(neighbour_labels.shape[0], num_concepts, dtype=DTYPE)
    return agree.scatter_add_(1, neighbour_labels.clamp_min(0), valid.to(DTYPE))


def neighbour_field(
    assignments: torch.Tensor, neighbours: torch.Tensor, num_concepts: int
) -> torch.Tensor:
    """[n, L] n_l(i) = sum over the neighbours r of cell i of q_r(l).

    ``assignments``: ``[N]`` labels (then n_l(i) counts neighbours labelled l) or ``[N, L]``
    soft assignments; ``neighbours``: ``[n, D]`` rows of the neighbour table, -1 for none.
    """
    if _is_hard(assignments):
        labels = torch.where(neighbours >= 0, assignments[neighbours.clamp_min(0)], -1)
        return neighbour_agreements(labels, num_concepts)  # [n, L]
    padded = torch.cat([assignments.to(DTYPE), assignments.new_zeros(1, assignments.shape[1])])
    index = torch.where(neighbours >= 0, neighbours, assignments.shape[0])  # [n, D]
    return padded[index].sum(1)  # [n, D, L] -> [n, L]


def expected_agreements(assignments: torch.Tensor, pairs: torch.Tensor) -> torch.Tensor:
    """E_q[E(C)] = sum over neighbour pairs (a, b) of sum_l q_a(l) q_b(l); E(C) for labels."""
    if _is_hard(assignments):
        return potts_agreements(assignments, pairs)
    # index_select, not assignments[pairs[:, 0]]: the same [P, L] rows, and its gradient is an
    # index_add_ (rows added in the same order, so the same bits) where advanced indexing's is an
    # index_put_ with accumulate, the slower of the two (SVI's backward through q, 2026-12-06)
    first = assignments.index_select(0, pairs[:, 0])  # [P, L]
    return (first * assignments.index_select(0, pairs[:, 1])).sum().to(DTYPE)


class ConceptStatistics(NamedTuple):
    """Sufficient statistics of the globals' conditionals (eqs. 14-17) or variational updates."""

    cells: torch.Tensor
    """[L] (expected) number of cells of each concept."""
    counts: tuple[torch.Tensor, ...]
    """Per modality, [L, K_m] (expected) counts of the cells of each concept (zeros for a
    modality that is switched off)."""


def concept_statistics(
    assignments: torch.Tensor, data: ModelData, config: SpCoConfig
) -> ConceptStatistics:
    """Concept sizes and per-concept counts of every modality, from ``[N]`` labels or ``[N, L]``
    soft assignments (then expectations under q)."""
    L = config.num_concepts
    hard = _is_hard(assignments)
    if hard:
        cells = torch.bincount(assignments, minlength=L).to(DTYPE)  # [L]
        observed_labels = assignments[data.obs_cells]  # [M]
    else:
        cells = assignments.sum(0).to(DTYPE)  # [L]
        observed_q = assignments[data.obs_cells].to(DTYPE)  # [M, L]
    counts = []
    for modality in data.modalities:
        per_concept = torch.zeros(L, modality.counts.shape[-1], dtype=DTYPE)  # [L, K_m]
        if config.uses(modality.name):
            if hard:
                per_concept.index_add_(0, observed_labels, modality.counts)
            else:
                per_concept = observed_q.T @ modality.counts  # [L, M] @ [M, K_m]
        counts.append(per_concept)
    return ConceptStatistics(cells, tuple(counts))


def _dirichlet_log_normaliser(rows: int, size: int, concentration: float) -> torch.Tensor:
    """rows * (log Gamma(K a) - K log Gamma(a)): normaliser of ``rows`` symmetric Dir(a) of
    size K; 0 for K = 0 (a Dirichlet over no items is the point mass on the empty vector: the
    words of a house where none was heard)."""
    if size == 0:  # lgamma(0) is inf
        return torch.zeros((), dtype=DTYPE)
    a = torch.tensor(concentration, dtype=DTYPE)
    return rows * (torch.lgamma(a * size) - size * torch.lgamma(a))


def dirichlet_multinomial_log_marginals(concentration: float, counts: torch.Tensor) -> torch.Tensor:
    """[...] log B(a + n) - log B(a) along the last axis of ``counts`` n ``[..., K]`` (symmetric
    Dir(a), real counts >= 0 allowed): each row's Dirichlet-multinomial log marginal without the
    multinomial coefficient (free of a); a row of zeros gives 0. 0 for K = 0, as in
    the Dirichlet's normaliser (lgamma(0 a) is inf, and inf - inf made it nan)."""
    size = counts.shape[-1]
    if size == 0:
        return torch.zeros(counts.shape[:-1], dtype=DTYPE)
    a = torch.tensor(concentration, dtype=DTYPE)
    posterior = torch.lgamma(a + counts).sum(-1) - torch.lgamma(size * a + counts.sum(-1))
    return posterior - (size * torch.lgamma(a) - torch.lgamma(size * a))


def multinomial_coefficients(data: ModelData, config: SpCoConfig) -> torch.Tensor:
    """sum over the modalities in use of the observed counts' multinomial coefficients
    lgamma(n + 1) - sum lgamma(x + 1) (no label or parameter changes them)."""
    total = torch.zeros((), dtype=DTYPE)
    for modality in data.modalities:
        if config.uses(modality.name):
            zeros = torch.zeros_like(modality.counts)
            total = total + multinomial_counts_log_prob(modality.counts, zeros).sum()
    return total


def log_joint_constant(data: ModelData, config: SpCoConfig) -> torch.Tensor:
    """The terms of the log joint that no label or parameter value changes: the Dirichlet
    normalisers and the multinomial coefficients (:func:`multinomial_coefficients`)."""
    L = config.num_concepts
    total = _dirichlet_log_normaliser(1, L, config.pi_concentration)
    for modality in data.modalities:
        size = modality.counts.shape[-1]
        total = total + _dirichlet_log_normaliser(L, size, config.concentration(modality.name))
    return total + multinomial_coefficients(data, config)


def log_joint_variable(
    labels: torch.Tensor,
    log_pi: torch.Tensor,
    log_parameters: Sequence[torch.Tensor],
    data: ModelData,
    config: SpCoConfig,
    label_counts: torch.Tensor | None = None,
    agreements: torch.Tensor | None = None,
) -> torch.Tensor:
    """The terms of the log joint that depend on the labels and parameters.

    For ``[N]`` labels: sum_l (a_pi - 1) log pi_l + sum_m sum_lk (a_m - 1) log phi_mlk
    + sum_i log pi_{C_i} + gamma E(C) + sum_m sum_i x_i . log phi_{m, C_i}. For ``[N, L]``
    soft assignments q, the same with the label terms in expectation under q (log pi and log
    phi as given: pass E[log pi], E[log phi] for the variational bound's expected log joint).
    ``label_counts`` ([L] cells per concept) and ``agreements`` (E(C)) may be passed in when
    the caller has them already (the Gibbs run loop does, to keep the per-sweep trace cheap).
    """
    hard = _is_hard(labels)
    if label_counts is None:
        label_counts = (
            torch.bincount(labels, minlength=config.num_concepts) if hard else labels.sum(0)
        )
    if agreements is None:
        agreements = expected_agreements(labels, data.pairs)
    total = (config.pi_concentration - 1) * log_pi.sum()
    for modality, log_phi in zip(data.modalities, log_parameters, strict=True):
        total = total + (config.concentration(modality.name) - 1) * log_phi.sum()
    total = total + (label_counts.to(DTYPE) * log_pi).sum()  # sum_i log pi_{C_i}
    total = total + config.gamma * agreements
    if hard:
        observed_labels = labels[data.obs_cells]
        for modality, log_phi in zip(data.modalities, log_parameters, strict=True):
            if config.uses(modality.name):
                total = total + (modality.counts * log_phi[observed_labels]).sum()
    else:
        observed_q = labels[data.obs_cells].to(DTYPE)  # [M, L]
        loglik = observation_log_likelihood(log_parameters, data, config)  # [M, L]
        total = total + (observed_q * loglik).sum()
    return total


def check_model_density(
    model_log_density: float,
    labels: torch.Tensor,
    log_pi: torch.Tensor,
    log_parameters: Sequence[torch.Tensor],
    data: ModelData,
    config: SpCoConfig,
    *,
    at: str,
    why: str,
    refusal: str,
    constant: float | None = None,
) -> None:
    """ValueError unless ``model_log_density`` (a model's ``log_prob_sum`` at these labels and
    parameters) is :func:`~spcopyro.model.spcomapping_model`'s log joint there
    (:func:`log_joint_constant` + :func:`log_joint_variable`), to rounding (1e-11 of the
    terms' size). An inference method that takes that model's terms from here (the Gibbs
    kernel's conditionals, MeanFieldELBO's closed-form label terms) would otherwise treat
    another model (a changed prior, coupling or likelihood) as this one, silently. ``at``
    names the point compared, ``why`` what the caller takes from this model, ``refusal`` what
    it cannot do; ``constant``, when the caller has it, is ``log_joint_constant(data, config)``
    (its multinomial coefficients cost a pass over every count)."""
    if constant is None:
        constant = float(log_joint_constant(data, config))
    own = constant + float(log_joint_variable(labels, log_pi, log_parameters, data, config))
    if not abs(model_log_density - own) <= 1e-11 * (abs(own) + abs(constant)) + 1e-9:
        raise ValueError(
            f"the model's log density {at} is {model_log_density!r} where spcomapping_model's, "
            f"{why}, is {own!r}: {refusal} (change the model through "
            "SpCoConfig and ModelData.modalities, which it reads)"
        )


def log_joint_terms(
    labels: torch.Tensor,
    log_pi: torch.Tensor,
    log_parameters: Sequence[torch.Tensor],
    data: ModelData,
    config: SpCoConfig,
) -> dict[str, float]:
    """The log joint at ``[N]`` labels, term by term, to tell which one is not finite.

    Their sum is :func:`log_joint_constant` + :func:`log_joint_variable` (up to rounding):
    ``"normalisers"`` (the Dirichlet normalisers), ``"<m> coefficients"`` (the multinomial
    coefficients of modality m's counts), ``"pi prior"`` (a_pi - 1) sum_l log pi_l,
    ``"<m> prior"`` (a_m - 1) sum_lk log phi_mlk, ``"labels"`` sum_i log pi_{C_i},
    ``"potts"`` gamma E(C) and ``"<m> data"`` sum_i x_i . log phi_{m, C_i} (modalities in use).
    """
    L = config.num_concepts
    normalisers = _dirichlet_log_normaliser(1, L, config.pi_concentration)
    for modality in data.modalities:
        size = modality.counts.shape[-1]
        normalisers = normalisers + _dirichlet_log_normaliser(
            L, size, config.concentration(modality.name)
        )
    terms = {"normalisers": float(normalisers)}
    used = [m for m in data.modalities if config.uses(m.name)]
    for modality in used:
        coefficient = multinomial_counts_log_prob(
            modality.counts, torch.zeros_like(modality.counts)
        )
        terms[f"{modality.name} coefficients"] = float(coefficient.sum())
    terms["pi prior"] = float((config.pi_concentration - 1) * log_pi.sum())
    for modality, log_phi in zip(data.modalities, log_parameters, strict=True):
        prior = (config.concentration(modality.name) - 1) * log_phi.sum()
        terms[f"{modality.name} prior"] = float(prior)
    label_counts = torch.bincount(labels, minlength=L).to(DTYPE)  # [L]
    terms["labels"] = float((label_counts * log_pi).sum())
    terms["potts"] = float(config.gamma * potts_agreements(labels, data.pairs))
    observed_labels = labels[data.obs_cells]  # [M]
    for modality, log_phi in zip(data.modalities, log_parameters, strict=True):
        if config.uses(modality.name):
            data_term = (modality.counts * log_phi[observed_labels]).sum()  # [M, K_m] -> []
            terms[f"{modality.name} data"] = float(data_term)
    return terms


def num_concepts_in_use(labels: torch.Tensor, num_concepts: int) -> int:
    """How many distinct concepts label at least one cell."""
    return int((torch.bincount(labels, minlength=num_concepts) > 0).sum())
