r"""Loopy belief propagation (Bethe) for the label field, alternating with the Dirichlet updates
of the global factors.

Given the global factors q(pi), q(phi) the label field is a pairwise MRF with node potentials
:math:`\psi_i(l) = \exp h_i(l)`, :math:`h_i(l) = E[\log\pi_l] + \ell_{il}` (the observed cell's
expected log-likelihood, eq. 13 in expectation; 0 for cells without observations) and Potts pair
potentials :math:`\exp(\gamma\,\delta(k, l))` (eqs. 8-9). Sum-product sends, along every directed
edge i -> j,

.. math::

    m_{i \to j}(l) \propto \sum_k b_{i \setminus j}(k)\, e^{\gamma \delta(k, l)}
        = S + (e^\gamma - 1)\, b_{i \setminus j}(l), \qquad
    b_{i \setminus j}(k) \propto \psi_i(k) \prod_{r \sim i,\, r \ne j} m_{r \to i}(k),

with S = sum_k b(k): O(L) per message thanks to the Potts structure (Yedidia, Freeman & Weiss
2005; for hidden Potts models e.g. Forbes & Peyrard 2003). With the cavity belief b normalised
(S = 1) the message is normalised by dividing by L + e^gamma - 1, so every message lies in
[1, e^gamma] / (L + e^gamma - 1) and stays finite; messages are stored as logs, and the products
of a cell's incoming messages are sums of logs.

**Schedule.** Messages go out of one colour class at a time (the Gibbs sweep's colouring): cells
of one class share no edge, so a class's outgoing messages read only messages that the other
classes sent. **Damping** mixes each new message with the old one,
``m <- (1 - damping) m_new + damping m_old`` (in probability space), which calms the oscillations
loopy BP can have on a grid. Messages persist across outer iterations: each outer iteration
(:func:`spcopyro.guides.lbp_method.step`, run by :func:`spcopyro.inference.driver.drive`) updates
the global factors from the beliefs, then runs ``passes`` message passes under the new node
potentials, starting from the previous messages. **Beliefs** are q(C):
:math:`q_i(l) \propto \psi_i(l) \prod_{r \sim i} m_{r \to i}(l)`.

**The objective traced is the Bethe approximation of the ELBO** (:func:`bethe_objective`), the
mean-field ELBO (:mod:`spcopyro.guides.elbo`) with two terms replaced: the Potts energy's
expectation under the pairwise beliefs :math:`b_{ij}(k, l) \propto b_{i \setminus j}(k)\,
b_{j \setminus i}(l)\, e^{\gamma\delta(k, l)}` instead of the product of node beliefs, and the
Bethe entropy :math:`\sum_{(i,j)} H[b_{ij}] - \sum_i (d_i - 1) H[b_i]` instead of the sum of node
entropies. Why this one: fixed points of LBP are exactly the stationary points of the Bethe free
energy (Yedidia et al. 2005), and the Dirichlet update of the globals maximises this same
objective given the beliefs (it reads only the node beliefs' expected statistics, as in mean
field), so both steps of the alternation are steps on one objective, and on a tree (a 1 x N
corridor) its label part equals the exact log partition function (tested). The mean-field ELBO of
the beliefs would be a true lower bound on the log evidence but LBP does not ascend it; the Bethe
value is *not* a bound on a loopy grid (it can lie above or below the log evidence). The
mean-field ELBO of the final beliefs is still available as
:func:`spcopyro.guides.elbo.elbo` for anyone who needs a bound.

Cost: O(N D L) time per message pass and O(N D L) memory for the messages (D = 4 or 8), the
same order as a dense mean-field iteration.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

from spcopyro._util.number_checks import is_int, is_number
from spcopyro.config import SpCoConfig
from spcopyro.guides.factors import (
    GlobalFactors,
    expected_log_emissions,
    expected_log_pi,
    kl_to_prior,
)
from spcopyro.likelihood import multinomial_coefficients, observation_log_likelihood
from spcopyro.model import DTYPE, ModelData


class MessageGraph(NamedTuple):
    """Index bookkeeping of the directed edges, derived from :class:`~spcopyro.model.ModelData`."""

    neighbours: torch.Tensor
    """[N, D] int64 free index of each cell's neighbour in slot d, -1 where none."""
    reverse: torch.Tensor
    """[N, D] int64 the slot of cell i in its slot-d neighbour's row (-1 where no neighbour):
    the message i -> neighbours[i, d] is stored at ``[neighbours[i, d], reverse[i, d]]``."""
    degree: torch.Tensor
    """[N] float64 number of neighbours."""
    pair_slots: torch.Tensor
    """[P, 2] int64 for each pair (a, b) of ``data.pairs``: b's slot in a's row, a's in b's."""


def message_graph(data: ModelData) -> MessageGraph:
    """The directed-edge indices of the map's neighbour graph (checked symmetric)."""
    neighbours = data.neighbours
    N, D = neighbours.shape
    valid = neighbours >= 0  # [N, D]
    back = neighbours[neighbours.clamp_min(0)]  # [N, D, D] the neighbours' neighbour rows
    match = (back == torch.arange(N)[:, None, None]) & valid[:, :, None]  # [N, D, D]
    if not torch.equal(match.any(-1), valid):
        raise ValueError("the neighbour table is not symmetric: BP needs undirected edges")
    reverse = torch.where(valid, match.to(torch.int8).argmax(-1), -1)  # [N, D]
    a, b = data.pairs[:, 0], data.pairs[:, 1]
    slot_ab = (neighbours[a] == b[:, None]).to(torch.int8).argmax(-1)  # [P]
    slot_ba = (neighbours[b] == a[:, None]).to(torch.int8).argmax(-1)  # [P]
    return MessageGraph(
        neighbours, reverse, valid.sum(-1).to(DTYPE), torch.stack([slot_ab, slot_ba], -1)
    )


def node_log_potentials(
    factors: GlobalFactors, data: ModelData, config: SpCoConfig
) -> torch.Tensor:
    """[N, L] h_i(l) = E[log pi_l] + the observed cell's E-log-likelihood (eq. 13's node terms)."""
    log_pi = expected_log_pi(factors)  # [L]
    loglik = observation_log_likelihood(expected_log_emissions(factors), data, config)  # [M, L]
    h = log_pi.expand(data.num_free, -1).clone()  # [N, L]
    h[data.obs_cells] += loglik
    return h


def potts_log_message(cavity: torch.Tensor, gamma: float) -> torch.Tensor:
    """[..., L] log of the normalised Potts message from a normalised cavity belief ``[..., L]``:
    log(1 + (e^gamma - 1) b(l)) - log(L + e^gamma - 1)."""
    scale = math.expm1(gamma)
    L = cavity.shape[-1]
    return torch.log1p(scale * cavity) - math.log(L + scale)


class LoopyBP:
    """The messages of loopy BP on one map, and the updates that change them.

    ``log_messages`` ``[N, D, L]`` holds, at ``[i, d]``, the log of the normalised message from
    neighbour ``neighbours[i, d]`` into cell i (0 where there is no neighbour). Built uniform, or
    from a starting q(C) (:meth:`start_from`), and kept across outer iterations.
    """

    def __init__(self, data: ModelData, config: SpCoConfig, damping: float = 0.5, passes: int = 1):
        if not (is_number(damping) and 0 <= damping < 1):
            raise ValueError(f"damping must lie in [0, 1), got {damping!r}")
        if not is_int(passes) or passes < 1:
            raise ValueError(f"passes must be an integer >= 1, got {passes!r}")
        self.data, self.config = data, config
        self.damping, self.passes = float(damping), passes
        self.graph = message_graph(data)
        N, D = data.neighbours.shape
        L = config.num_concepts
        self._valid = data.neighbours >= 0  # [N, D]
        # Flat storage: row i * D + d holds [i, d]; one extra sink row takes the "messages"
        # along missing edges, so a colour class writes all its [n * D] rows in one index_copy_.
        self._store = torch.zeros(N * D + 1, L, dtype=DTYPE)  # [N * D + 1, L]
        self.log_messages = self._store[: N * D].view(N, D, L)  # [N, D, L]
        self.log_messages[self._valid] = -math.log(L)
        sink = torch.full_like(data.neighbours, N * D)
        destination = torch.where(
            self._valid, self.graph.neighbours * D + self.graph.reverse, sink
        )  # [N, D] the flat row that receives the message i -> neighbours[i, d]
        self._destinations = tuple(destination[cells].reshape(-1) for cells in data.colours)
        self.h: torch.Tensor | None = None  # [N, L] the node potentials of the last pass
        self.gamma = config.gamma  # the coupling of the last pass

    def start_from(self, q: torch.Tensor, gamma: float) -> None:
        """Set every message i -> j to the one a cell whose cavity belief is q_i would send:
        a warm start from a mean-field q or a Gibbs state's one-hot labels."""
        nb = self.graph.neighbours
        valid = self._valid
        sent = potts_log_message(q.to(DTYPE), gamma)  # [N, L] the message each cell sends
        self.log_messages[valid] = sent[nb[valid]]

    def incoming_total(self, h: torch.Tensor) -> torch.Tensor:
        """[N, L] h_i(l) + sum over neighbours of log m_{r -> i}(l): the unnormalised log
        belief."""
        return h + self.log_messages.sum(1)

    def beliefs(self, h: torch.Tensor) -> torch.Tensor:
        """[N, L] q_i(l) proportional to psi_i(l) prod_r m_{r -> i}(l)."""
        return torch.softmax(self.incoming_total(h), -1)

    def send(self, cells: torch.Tensor, h: torch.Tensor, gamma: float, colour: int) -> None:
        """Update the messages out of ``cells`` (colour class ``colour`` of ``data.colours``) to
        all their neighbours."""
        log_in = self.log_messages[cells]  # [n, D, L]
        total = h[cells] + log_in.sum(1)  # [n, L]
        cavity = torch.softmax(total[:, None, :] - log_in, -1)  # [n, D, L], rows sum to 1
        new = potts_log_message(cavity, gamma).reshape(-1, cavity.shape[-1])  # [n * D, L]
        destination = self._destinations[colour]  # [n * D]
        if self.damping:
            old = self._store.index_select(0, destination)  # [n * D, L]
            new = torch.logaddexp(
                new + math.log1p(-self.damping), old + math.log(self.damping)
            )  # still normalised: a mixture of two normalised messages
        self._store.index_copy_(0, destination, new)

    def message_pass(self, h: torch.Tensor, gamma: float) -> None:
        """One pass: the messages out of every colour class, one class after the other."""
        for colour, cells in enumerate(self.data.colours):
            self.send(cells, h, gamma, colour)

    def run(self, h: torch.Tensor, gamma: float, passes: int | None = None) -> torch.Tensor:
        """``passes`` message passes (default: this object's) under node potentials ``h``
        ``[N, L]``; returns the beliefs ``[N, L]``."""
        for _ in range(self.passes if passes is None else passes):
            self.message_pass(h, gamma)
        self.h, self.gamma = h, gamma
        return self.beliefs(h)

    def update(self, q: torch.Tensor, factors: GlobalFactors, gamma: float) -> torch.Tensor:
        """A label update in place: node potentials from the global factors, ``passes`` message
        passes, beliefs written into ``q``."""
        if self.h is None:  # the first call: start the messages from the run's initial q
            self.start_from(q, gamma)
        q[:] = self.run(node_log_potentials(factors, self.data, self.config), gamma)
        return q

    def pairwise(self, h: torch.Tensor, gamma: float) -> tuple[torch.Tensor, torch.Tensor]:
        """Per pair (a, b) of ``data.pairs``, the expected agreement E_{b_ab}[delta] ``[P]`` and
        the entropy H[b_ab] ``[P]`` of the pairwise belief
        b_ab(k, l) = u(k) v(l) (1 + (e^gamma - 1) delta(k, l)) / Z, with u, v the normalised
        cavity beliefs of a without b and of b without a: O(L) per pair, never [L, L]."""
        total = self.incoming_total(h)  # [N, L]
        a, b = self.data.pairs[:, 0], self.data.pairs[:, 1]
        slot_ab, slot_ba = self.graph.pair_slots[:, 0], self.graph.pair_slots[:, 1]
        log_u = torch.log_softmax(total[a] - self.log_messages[a, slot_ab], -1)  # [P, L]
        log_v = torch.log_softmax(total[b] - self.log_messages[b, slot_ba], -1)  # [P, L]
        u, v = log_u.exp(), log_v.exp()
        scale = math.expm1(gamma)
        overlap = (u * v).sum(-1)  # [P] sum_l u(l) v(l)
        log_z = torch.log1p(scale * overlap)  # [P]
        agreement = math.exp(gamma) * overlap / log_z.exp()  # [P] E[delta]
        # E_b[log u(k)] = sum_k u log u (1 + scale v(k)) / Z, and the same for v.
        e_log_u = (torch.special.xlogy(u, u) * (1 + scale * v)).sum(-1) / log_z.exp()
        e_log_v = (torch.special.xlogy(v, v) * (1 + scale * u)).sum(-1) / log_z.exp()
        entropy = -e_log_u - e_log_v - gamma * agreement + log_z  # [P]
        return agreement, entropy


def bethe_label_objective(
    bp: LoopyBP, h: torch.Tensor | None = None, gamma: float | None = None
) -> torch.Tensor:
    """[] the negative Bethe free energy of the label field at the current beliefs:
    sum_i E_{b_i}[h_i] + gamma sum_(a,b) E_{b_ab}[delta] + H_Bethe.

    The node and pairwise beliefs are the ones the messages define under the node potentials and
    coupling of the last pass (``bp.h``, ``bp.gamma``); ``h`` ``[N, L]`` and ``gamma`` score the
    energy (default: the same). At a BP fixed point on a tree, with the defaults, it equals the
    exact log partition function log sum_C exp(sum_i h_i(C_i) + gamma E(C)).
    """
    if bp.h is None:
        raise ValueError("no beliefs yet: run a message pass first")
    h = bp.h if h is None else h
    gamma = bp.gamma if gamma is None else gamma
    q = bp.beliefs(bp.h)  # [N, L]
    agreement, pair_entropy = bp.pairwise(bp.h, bp.gamma)  # [P], [P]
    node_entropy = -torch.special.xlogy(q, q).sum(-1)  # [N]
    bethe_entropy = pair_entropy.sum() - ((bp.graph.degree - 1) * node_entropy).sum()
    return (q * h).sum() + gamma * agreement.sum() + bethe_entropy


def bethe_objective(
    bp: LoopyBP,
    factors: GlobalFactors,
    data: ModelData,
    config: SpCoConfig,
    gamma: float | None = None,
) -> torch.Tensor:
    """[] the Bethe approximation of the ELBO (module docstring) of the current beliefs and the
    global ``factors``: the label field's Bethe objective with the energy under the factors'
    expected log parameters at coupling ``gamma`` (default: the model's), plus the multinomial
    coefficients, minus the globals' KL to their prior. Comparable with
    :func:`spcopyro.guides.elbo.elbo` (same terms, Potts normaliser left out), but not a
    bound on a loopy graph."""
    gamma = config.gamma if gamma is None else gamma
    h = node_log_potentials(factors, data, config)  # [N, L]
    labels = bethe_label_objective(bp, h, gamma)
    return labels + multinomial_coefficients(data, config) - kl_to_prior(factors, data, config)
