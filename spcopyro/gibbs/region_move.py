r"""A region relabel move: one Swendsen-Wang cluster changes concept, parameters integrated out.

A room carried by two concepts (each half its own concept, each half's words and images fitting
its own parameters) is the sampler failure issue 21 found on simulated maps: single-site Gibbs
undoes it only by moving the border cell by cell, over thousands of sweeps. The split-merge move
(:mod:`spcopyro.gibbs.merge`) proposes the right merge, but its reverse -- the restricted scans
landing on the current two halves exactly -- is improbable when the halves are hundreds of cells
with a ragged border, so the merge is rarely accepted. The Swendsen-Wang move
(:mod:`spcopyro.gibbs.cluster`) relabels whole regions, but given each concept's parameters,
under which each half's data prefer its own concept.

This move relabels a whole region against the collapsed posterior p(C | x) (pi, theta and w
integrated out, as the split-merge move's target), by the Swendsen-Wang cut of Barbu & Zhu
(2005, "Generalizing Swendsen-Wang to sampling arbitrary posterior probabilities", IEEE TPAMI
27(8)), a Metropolis-Hastings step:

1. **bonds** (as :func:`~spcopyro.gibbs.cluster.bond_clusters`): each agreeing neighbour pair
   is bonded with probability :math:`q = 1 - e^{-\lambda\gamma}`, :math:`\lambda` =
   :data:`BOND_SHARE` (Higdon's 1998 partial decoupling: the bonds carry that share of the
   coupling, the acceptance the rest); the clusters are the connected components;
2. **the region** :math:`V_0`: the cluster of a cell drawn uniformly, of concept b;
3. **its new concept** a, drawn from three groups of labels, each with a fixed weight among the
   groups that are not empty, uniformly within its group: the concepts adjacent to
   :math:`V_0` (of a cell outside :math:`V_0` neighbouring it) other than b, weight
   :data:`GROUP_WEIGHTS` ``[0]``; the empty labels, ``[1]`` (a region becomes a new concept);
   the other concepts in use, ``[2]`` (two places far apart that share a concept, or not);
4. accept :math:`C \to C'` (:math:`V_0` relabelled a) with probability min(1, r).

**Acceptance.** :math:`V_0` is the seed's cluster in C with probability
:math:`\frac{|V_0|}{N}\,\mathrm{Conn}(V_0)\, e^{-\lambda\gamma n_b}`: its inner bonds connect
it (the same in C and C', all of :math:`V_0` agreeing in both) and none of the :math:`n_b` pairs
from :math:`V_0` to cells of concept b outside it is bonded; in C' the cut pairs are the
:math:`n_a` to concept a. The Potts factor changes by :math:`e^{\gamma(n_a - n_b)}`, of which the
cut's ratio :math:`e^{-\lambda\gamma (n_a - n_b)}` cancels the share :math:`\lambda`, so

.. math::

    \log r = \sum_{l \in \{a, b\}} \big[M_l(C') - M_l(C)\big]
        + (1 - \lambda)\,\gamma\,(n_a - n_b)
        + \log g(b \mid V_0, C') - \log g(a \mid V_0, C),

with :math:`M_l = \log\Gamma(a_\pi + m_l) + \sum_u \log B(a_u \mathbf{1} + n^u_l) - \log
B(a_u \mathbf{1})` each concept's collapsed term (:func:`~spcopyro.gibbs.merge.
concept_log_marginals`; the split-merge module's target) and g the label proposal of step 3:
the reverse draws b for :math:`V_0` in C' -- from the adjacent group when cells of b still
touch :math:`V_0`, from the empty labels when :math:`V_0` held all of b, else from the other
concepts in use. With :math:`\lambda = 1` (Barbu & Zhu's cut) the Potts coupling enters only
through the bonds, and a region is relabelled on its data alone: a merge the border's Potts
agreements favour but the data do not is then as improbable as its reverse, the region cut
out again exactly. :math:`\lambda` = 1/2 keeps the clusters whole regions above the critical
coupling (bond probability 0.78 at gamma 3) and lets half the border's agreements count.

If accepted, pi, theta and w are redrawn from their conditionals given the new labels (eqs.
14-17); the acceptance does not look at them, so keeping them on a rejection is exact
(the split-merge module's argument). The tests compare the move's exact transition
probabilities, enumerated over bonds, seeds and labels on a tiny map, with detailed balance
against the enumerated posterior, and its draws with those probabilities.

Cost: the numba backend grows the seed's cluster alone (:mod:`spcopyro.gibbs.region_numba`,
O(region)); the torch reference draws every pair's bond and takes the components (O(P), scipy).
Then O(N) for the two concepts' statistics.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch

from spcopyro._util.random_draws import coin_flip, metropolis_accept
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.cluster import bond_clusters
from spcopyro.gibbs.merge import (
    Counts,
    MoveInfo,
    concept_log_marginals,
    two_concepts,
    used_modalities,
    with_globals_redrawn,
)
from spcopyro.gibbs.state import GibbsState
from spcopyro.model import DTYPE, ModelData

BOND_SHARE = 0.5
"""lambda: the share of the coupling the bonds carry (module doc); 1 is the pure Swendsen-Wang
cut, 0 single cells."""

GROUP_WEIGHTS = (0.6, 0.2, 0.2)
"""Weights of step 3's label groups: adjacent concepts, empty labels, other concepts in use
(renormalised over the groups that are not empty)."""


class LabelGroups(NamedTuple):
    """Step 3's groups for a region of concept ``current`` ([L] masks, disjoint)."""

    adjacent: torch.Tensor
    empty: torch.Tensor
    other: torch.Tensor

    def log_probability(self, label: int) -> float:
        """log g(label): the group's renormalised weight over its size; -inf if in none."""
        groups = (self.adjacent, self.empty, self.other)
        sizes = [int(group.sum()) for group in groups]
        total = sum(w for w, size in zip(GROUP_WEIGHTS, sizes, strict=True) if size > 0)
        for weight, size, group in zip(GROUP_WEIGHTS, sizes, groups, strict=True):
            if size > 0 and bool(group[label]):
                return math.log(weight / total) - math.log(size)
        return -math.inf

    def draw(self, generator: torch.Generator) -> int | None:
        """A label drawn from g, or None when every group is empty."""
        groups = (self.adjacent, self.empty, self.other)
        weights = torch.tensor(
            [w if bool(g.any()) else 0.0 for w, g in zip(GROUP_WEIGHTS, groups, strict=True)],
            dtype=DTYPE,
        )  # [3]
        if float(weights.sum()) == 0.0:
            return None
        group = groups[int(torch.multinomial(weights, 1, generator=generator))]
        members = group.nonzero(as_tuple=True)[0]
        return int(members[int(torch.randint(members.numel(), (), generator=generator))])


def label_groups(
    labels: torch.Tensor, touching: torch.Tensor, current: int, num_concepts: int
) -> LabelGroups:
    """Step 3's groups in the labelling ``labels`` [N] for a region of label ``current`` whose
    outside neighbours carry the labels ``touching`` (1-D)."""
    used = torch.bincount(labels, minlength=num_concepts) > 0  # [L]
    adjacent = torch.zeros(num_concepts, dtype=torch.bool)  # [L]
    adjacent[touching] = True
    adjacent[current] = False
    empty = ~used
    other = used & ~adjacent
    other[current] = False
    return LabelGroups(adjacent, empty, other)


def border_labels(region: torch.Tensor, labels: torch.Tensor, pairs: torch.Tensor) -> torch.Tensor:
    """[B] the label outside ``region`` [N] (bool) of every neighbour pair across its border."""
    inside_first, inside_second = region[pairs[:, 0]], region[pairs[:, 1]]  # [P]
    cross = inside_first ^ inside_second  # [P]
    return labels[torch.where(inside_first, pairs[:, 1], pairs[:, 0])[cross]]


def _moved_terms(
    labels: torch.Tensor, region: torch.Tensor, data: ModelData, config: SpCoConfig, a: int, b: int
) -> float:
    """sum over concepts a, b of M_l(C') - M_l(C) when ``region`` moves from b to a."""
    sizes, before = two_concepts(labels, data, config, b, a)  # [2]; [2, K_u] each
    size = region.sum()
    moved_sizes = sizes + torch.stack([-size, size])  # [2]
    in_region = region[data.obs_cells]  # [M]
    after: Counts = []
    for (concentration, per), (modality_counts, _) in zip(
        before, used_modalities(data, config), strict=True
    ):
        shift = modality_counts[in_region].sum(0)  # [K_u]
        after.append((concentration, per + torch.stack([-shift, shift])))
    return float(
        (
            concept_log_marginals(moved_sizes, after, config)
            - concept_log_marginals(sizes, before, config)
        ).sum()
    )


def relabel_log_ratio(
    labels: torch.Tensor,
    region: torch.Tensor,
    a: int,
    border: torch.Tensor,
    data: ModelData,
    config: SpCoConfig,
    bond_share: float = BOND_SHARE,
    forward: LabelGroups | None = None,
) -> float:
    """log r of relabelling ``region`` [N] (bool, one concept b) as ``a`` (module doc): the two
    concepts' collapsed terms, the Potts share the bonds do not carry and the label proposal's
    asymmetry; ``border``: :func:`border_labels` of the region; ``forward``: the region's
    :func:`label_groups` in ``labels`` where the caller has them (else built here)."""
    b = int(labels[region.nonzero()[0, 0]])
    L = config.num_concepts
    touching = torch.unique(border)
    if forward is None:
        forward = label_groups(labels, touching, b, L)
    reverse = label_groups(torch.where(region, a, labels), touching, a, L)
    agreements = int((border == a).sum()) - int((border == b).sum())  # n_a - n_b
    potts = (1.0 - bond_share) * config.gamma * agreements
    return _log_acceptance_ratio(
        _moved_terms(labels, region, data, config, a, b) + potts,
        forward.log_probability(a),
        reverse.log_probability(b),
    )


def _log_acceptance_ratio(delta_log_target: float, log_forward: float, log_reverse: float) -> float:
    """log r = log p(C')/p(C) + log g(b | C') - log g(a | C) (the cut's and Potts' cancel)."""
    return delta_log_target + log_reverse - log_forward


def _grown_region(
    labels: torch.Tensor, data: ModelData, coupling: float, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """(region [N] bool, its :func:`border_labels`) of steps 1-2 with bonds of probability
    1 - exp(-coupling), grown from the seed by :func:`~spcopyro.gibbs.region_numba.grow_region`
    from one seed drawn from ``generator``."""
    from spcopyro.gibbs.numba_random import draw_seed, rng_state
    from spcopyro.gibbs.region_numba import grow_region

    rng = rng_state(draw_seed(generator))
    region, border = grow_region(
        np.ascontiguousarray(labels.numpy()), _neighbour_array(data), -math.expm1(-coupling), rng
    )
    return torch.from_numpy(region), torch.from_numpy(border)


def _neighbour_array(data: ModelData) -> np.ndarray:
    """``data.neighbours`` [N, D] as a contiguous int64 array (a view where it already is one)."""
    return np.ascontiguousarray(data.neighbours.numpy(), dtype=np.int64)


def region_relabel_labels(
    labels: torch.Tensor,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    bond_share: float = BOND_SHARE,
    compiled: bool = False,
) -> tuple[torch.Tensor, MoveInfo]:
    """One region relabel Metropolis-Hastings step on ``labels`` [N] targeting p(C | x) (module
    doc). Returns the new labels (``labels`` itself when nothing changes) and what happened.

    ``compiled``: steps 1-2 by :func:`spcopyro.gibbs.region_numba.grow_region` (the seed's
    cluster grown alone, from the compiled sampler's stream: the same distribution, other
    draws; the numba backend's chains use it), else every pair's bond and the components."""
    L = config.num_concepts
    if compiled:
        region, border = _grown_region(labels, data, bond_share * config.gamma, generator)
    else:
        _, cluster = bond_clusters(labels, data.pairs, bond_share * config.gamma, generator)
        seed = int(torch.randint(labels.shape[0], (), generator=generator))
        region = cluster == cluster[seed]  # [N]
        border = border_labels(region, labels, data.pairs)
    b = int(labels[region.nonzero()[0, 0]])
    forward = label_groups(labels, torch.unique(border), b, L)
    a = forward.draw(generator)
    if a is None:
        return labels, MoveInfo("relabel", False, -math.inf)
    log_ratio = relabel_log_ratio(labels, region, a, border, data, config, bond_share, forward)
    proposed = torch.where(region, a, labels)  # [N]
    accept = metropolis_accept(log_ratio, generator)
    return (proposed if accept else labels), MoveInfo("relabel", bool(accept), log_ratio)


def region_move(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    compiled: bool = False,
) -> tuple[GibbsState, MoveInfo]:
    """:func:`region_relabel_labels`, then (if accepted) pi, theta and w redrawn given the labels
    (by the compiled sampler's draws when ``compiled``)."""
    labels, info = region_relabel_labels(state.labels, data, config, generator, compiled=compiled)
    return with_globals_redrawn(state, labels, info, data, config, generator, compiled), info


def maybe_region_move(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    probability: float,
    compiled: bool = False,
) -> GibbsState:
    """:func:`region_move` with probability ``probability`` (``GibbsOptions.region_moves``),
    else ``state`` (draws nothing from ``generator`` when the probability is 0)."""
    if not coin_flip(probability, generator):
        return state
    return region_move(state, data, config, generator, compiled=compiled)[0]
