r"""Mean-field coordinate ascent (CAVI) for SpCoMapping: the dense torch reference.

q factorises as q(pi) prod_m prod_l q(phi_ml) prod_i q(C_i). One iteration updates the global
factors from q(C) (:func:`spcopyro.variational.factors.update_factors`, eqs. 14-17 in
expectation), then every cell's q(C_i), colour block by colour block:

.. math::

    \log q(C_i = l) = E[\log\pi_l] + \gamma \sum_{r \sim i} q_r(l)
        + \sum_m x^{(m)}_i \cdot E[\log\phi_{ml}] + \text{const}

-- eq. (13) with every log parameter and every neighbour's label replaced by its expectation.
Cells of one colour share no neighbour pair, so updating a whole colour block at once is the
same as updating its cells one at a time: each block step is exact coordinate ascent and the
ELBO (:mod:`spcopyro.variational.elbo`) never decreases. Updating all cells at once (Jacobi)
would not be: on the bipartite grid it oscillates between two checkerboards.

This module is the readable reference the compiled backend and the tests are checked against;
it costs O(N D L) per iteration.
"""

from __future__ import annotations

import torch

from spcopyro.config import SpCoConfig
from spcopyro.likelihood import concept_statistics, neighbour_field, observation_log_likelihood
from spcopyro.model import DTYPE, ModelData
from spcopyro.variational.factors import (
    GlobalFactors,
    PiFamily,
    expected_log_emissions,
    expected_log_pi,
    update_factors,
)


def one_hot(labels: torch.Tensor, num_concepts: int) -> torch.Tensor:
    """[N, L] float64 q(C) putting all mass on the given ``[N]`` labels."""
    return torch.nn.functional.one_hot(labels.long(), num_concepts).to(DTYPE)


def update_globals(
    q: torch.Tensor, data: ModelData, config: SpCoConfig, pi_family: PiFamily = "dirichlet"
) -> GlobalFactors:
    """The optimal global factors given q(C) ``[N, L]``."""
    return update_factors(concept_statistics(q, data, config), data, config, pi_family)


def update_labels(
    q: torch.Tensor,
    factors: GlobalFactors,
    data: ModelData,
    config: SpCoConfig,
    gamma: float | None = None,
    damping: float = 0.0,
) -> torch.Tensor:
    """Update q(C) ``[N, L]`` in place, colour block by colour block (module docstring); the
    coupling ``gamma`` defaults to the model's."""
    gamma = config.gamma if gamma is None else gamma
    log_pi = expected_log_pi(factors)  # [L]
    loglik = observation_log_likelihood(expected_log_emissions(factors), data, config)  # [M, L]
    rows = data.observation_rows()  # [N]
    L = q.shape[1]
    for cells in data.colours:
        logits = log_pi + gamma * neighbour_field(q, data.neighbours[cells], L)  # [n, L]
        block_rows = rows[cells]  # [n]
        observed = block_rows >= 0
        logits[observed] += loglik[block_rows[observed]]
        new = torch.softmax(logits, dim=-1)  # [n, L]
        if damping:
            new = (1 - damping) * new + damping * q[cells]
        q[cells] = new
    return q
