r"""A Swendsen-Wang cluster move for the labels: whole regions change concept at once.

Single-site Gibbs (eq. 13) changes one cell at a time; above the Potts critical coupling a region
of one concept can only be relabelled by eroding it from its border, which takes many sweeps --
the slow mixing behind the paper's instability. This move is the MRF's classical remedy (Swendsen
& Wang, 1987; with data terms, Higdon, 1998, "partial decoupling"), and plays the part of the
split-merge move named in issue #4: a whole region can merge into a neighbouring concept, take a
new one, or split along weak bonds, in a single exact step.

**The move.** Given pi, theta, w, the labels' conditional is

.. math::

    p(C \mid \pi, \theta, w, \text{data}) \propto \prod_i \phi_i(C_i)
        \prod_{i \sim j} e^{\gamma \delta(C_i, C_j)}, \qquad
    \phi_i(l) = \pi_l \prod_{t \in i} \theta_{l, f_t} \, w_{l, S_t}.

Writing :math:`e^{\gamma\delta} = e^{\gamma}\,[e^{-\gamma} + (1 - e^{-\gamma})\,\delta]` adds a
bond variable per neighbouring pair (Edwards & Sokal, 1988) with

1. bonds: each pair of *agreeing* neighbours is bonded with probability
   :math:`1 - e^{-\gamma}`, disagreeing pairs never;
2. clusters: the connected components of the bonded graph (scipy's ``connected_components``);
3. labels: every cluster :math:`A` draws one concept for all its cells from
   :math:`p(l) \propto \prod_{i \in A} \phi_i(l) = \pi_l^{|A|} \prod_{i \in A\,\text{observed}}
   \theta_{l, f_i} w_{l, S_i}`, independently of the other clusters.

Both steps are exact conditionals of the joint of labels and bonds, so the move leaves the
labels' conditional (and with the Dirichlet draws that follow, the posterior) invariant; the
tests compare it with the enumerated posterior. Cost: O(P) for the bonds and components, plus
O(M L + A L) for the cluster weights (A clusters, M observed cells) -- the pi term is
``size * log pi``, so cells without observations cost nothing per concept.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from spcopyro._util.random_draws import coin_flip, sample_categorical_logits
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.state import GibbsState
from spcopyro.likelihood import observation_log_likelihood
from spcopyro.model import DTYPE, ModelData


def bond_clusters(
    labels: torch.Tensor, pairs: torch.Tensor, gamma: float, generator: torch.Generator
) -> tuple[int, torch.Tensor]:
    """Steps 1-2: (number of clusters A, [N] int64 cluster of every cell)."""
    import scipy.sparse  # here, not at import: a fit without cluster moves skips scipy.sparse
    from scipy.sparse.csgraph import connected_components

    num_cells = labels.shape[0]
    first, second = pairs[:, 0], pairs[:, 1]  # [P]
    uniform = torch.rand(first.shape[0], dtype=DTYPE, generator=generator)  # [P]
    bonded = (labels[first] == labels[second]) & (uniform < -math.expm1(-gamma))  # [P]
    rows, cols = first[bonded].numpy(), second[bonded].numpy()
    graph = scipy.sparse.coo_matrix(
        (np.ones(rows.shape[0], dtype=np.int8), (rows, cols)), shape=(num_cells, num_cells)
    )
    count, cluster = connected_components(graph, directed=False)
    return int(count), torch.from_numpy(cluster.astype(np.int64))


def cluster_log_weights(
    cluster: torch.Tensor, count: int, state: GibbsState, data: ModelData, config: SpCoConfig
) -> torch.Tensor:
    """[A, L] log prod_{i in A} phi_i(l): ``|A| log pi_l`` plus the observed cells' terms."""
    sizes = torch.bincount(cluster, minlength=count).to(DTYPE)  # [A]
    weights = sizes[:, None] * state.log_pi[None, :]  # [A, L]
    observed = observation_log_likelihood(state.log_emissions, data, config)  # [M, L]
    return weights.index_add_(0, cluster[data.obs_cells], observed)


def swendsen_wang_labels(
    state: GibbsState, data: ModelData, config: SpCoConfig, generator: torch.Generator
) -> torch.Tensor:
    """[N] labels after one Swendsen-Wang move given the state's pi, theta and w."""
    count, cluster = bond_clusters(state.labels, data.pairs, config.gamma, generator)
    logits = cluster_log_weights(cluster, count, state, data, config)  # [A, L]
    return sample_categorical_logits(logits, generator)[cluster]  # [N]


def cluster_move(
    state: GibbsState, data: ModelData, config: SpCoConfig, generator: torch.Generator
) -> GibbsState:
    """The state with its labels redrawn by :func:`swendsen_wang_labels` (globals unchanged)."""
    return state._replace(labels=swendsen_wang_labels(state, data, config, generator))


def maybe_cluster_move(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    probability: float,
) -> GibbsState:
    """:func:`cluster_move` with probability ``probability`` (``GibbsOptions.cluster_moves``),
    else ``state`` (draws nothing from ``generator`` when the probability is 0)."""
    if not coin_flip(probability, generator):
        return state
    return cluster_move(state, data, config, generator)
