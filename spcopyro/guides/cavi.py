r"""Mean-field coordinate ascent (CAVI) for SpCoMapping: the dense torch reference.

q factorises as q(pi) prod_m prod_l q(phi_ml) prod_i q(C_i). One iteration updates the global
factors from q(C) (:func:`spcopyro.guides.factors.update_factors`, eqs. 14-17 in
expectation), then every cell's q(C_i), colour block by colour block:

.. math::

    \log q(C_i = l) = E[\log\pi_l] + \gamma \sum_{r \sim i} q_r(l)
        + \sum_m x^{(m)}_i \cdot E[\log\phi_{ml}] + \text{const}

-- eq. (13) with every log parameter and every neighbour's label replaced by its expectation.
Cells of one colour share no neighbour pair, so updating a whole colour block at once is the
same as updating its cells one at a time: each block step is exact coordinate ascent and the
ELBO (:mod:`spcopyro.guides.elbo`) never decreases. Updating all cells at once (Jacobi)
would not be: on the bipartite grid it oscillates between two checkerboards.

This module is the readable reference the compiled backend and the tests are checked against;
it costs O(N D L) per iteration. The compiled backend
(:mod:`spcopyro.guides.numba_cavi`, ``VariationalOptions(backend="numba")``, the default
where numba imports) keeps q sparse (small masses dropped, optionally a top-K cap) and shares the
structure of the cells without observations, as the compiled Gibbs sweep does.

**Mean field orders at a weaker coupling than the Potts model.** For the homogeneous L-state
Potts model on a lattice of D neighbours the mean-field fixed point q(l) ∝ exp(γ D q(l)) has

* an ordered solution (one concept with q ≥ 0.73) from γ = 1.14 (L = 10) / 1.92 (L = 120),
  D = 4 (the smallest γ with a solution q_1 > 1/L of
  q_1 / (1 - q_1) (L - 1) = exp(γ D (q_1 - (1 - q_1) / (L - 1))));
* its first-order transition (the ordered solution beats the disordered one) at
  γ D = 2 (L - 1) / (L - 2) ln(L - 1): γ = 1.24 (L = 10), 2.41 (L = 120);
* the disordered solution q = 1/L stable up to γ = L / D: 2.5 (L = 10), 30 (L = 120);

against the exact square-lattice transition ln(1 + sqrt(L)) = 1.43 (L = 10), 2.48 (L = 120)
(Wu 1982). So mean field sees order where the exact model has none (γ between 1.14-1.43 for
L = 10), and, the other way round, a mean-field q started disordered (uniform or soft, or annealed
from γ = 0) stays disordered far above the exact transition unless data break the symmetry,
while one started from a labelling with domains (a Gibbs warm start) freezes into them: at
γ = 4 a cell on a straight domain wall sees 3 neighbours of its own and 1 of the other concept,
a logit gap of 2γ = 8, and mean field has no fluctuation to move the wall (Gibbs does).

With many concepts the dynamics can hide the equilibrium statement: started from random labels,
mean field may need a *stronger* coupling than Gibbs to leave disorder, since its disordered
solution stays stable up to γ = L / D; a top-K cap on q (:mod:`spcopyro.guides.numba_cavi`) makes
it behave as a K-state model. What ``benchmarks/variational.py`` measured on the synthetic house
is in ``docs/variational.md`` ("Where mean field orders").
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import torch

from spcopyro.config import SpCoConfig
from spcopyro.guides.elbo import elbo
from spcopyro.guides.factors import (
    GlobalFactors,
    PiFamily,
    expected_log_emissions,
    expected_log_pi,
    update_factors,
)
from spcopyro.likelihood import concept_statistics, neighbour_field, observation_log_likelihood
from spcopyro.model import DTYPE, ModelData

if TYPE_CHECKING:
    from spcopyro.guides.options import VariationalOptions


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


def num_used(q: torch.Tensor) -> int:
    """How many concepts are some cell's most probable one under q ``[N, L]``."""
    return int(torch.unique(q.argmax(-1)).numel())


class CAVIState(NamedTuple):
    """The state of CAVI: q(C) and the global factors optimal given it."""

    q: torch.Tensor
    """[N, L] float64 q(C_i = l)."""
    factors: GlobalFactors
    """q(pi) and every q(phi_m), from q (:func:`update_globals`)."""


class CAVIInfo(NamedTuple):
    """What one CAVI iteration did (either backend)."""

    objective: float
    """The ELBO after the iteration, at the model's gamma."""
    num_concepts: int
    """Concepts that are some cell's most probable one."""
    gamma: float
    """The coupling the label update used (below the model's while annealing)."""


def init(
    q: torch.Tensor, data: ModelData, config: SpCoConfig, options: VariationalOptions
) -> CAVIState:
    """The state at q ``[N, L]`` (:func:`spcopyro.guides.run.initial_q`): the globals from it."""
    return CAVIState(q, update_globals(q, data, config, options.pi_family))


def step(
    state: CAVIState,
    data: ModelData,
    config: SpCoConfig,
    gamma: float,
    options: VariationalOptions,
) -> tuple[CAVIState, CAVIInfo]:
    """One iteration: every q(C_i) given the globals at coupling ``gamma`` (:func:`update_labels`,
    on a copy: ``state`` is left as it was), then the globals given the new q
    (:func:`update_globals`), then the ELBO at the model's gamma."""
    q = update_labels(state.q.clone(), state.factors, data, config, gamma, options.damping)
    factors = update_globals(q, data, config, options.pi_family)
    value = float(elbo(q, factors, data, config))
    return CAVIState(q, factors), CAVIInfo(value, num_used(q), float(gamma))
