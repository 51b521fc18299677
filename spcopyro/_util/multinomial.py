r"""The log density of a multinomial over real-valued counts, in torch alone (no Pyro).

:class:`spcopyro.distributions.MultinomialCounts` (a Pyro distribution) scores counts with it, and
:mod:`spcopyro.likelihood` takes the observed counts' multinomial coefficients from it: here, so
that the sampler's path (a Gibbs fit) does not import Pyro for one formula (``import pyro`` loads
about 200 modules: 0.05-0.1 s of every fit's start-up). The formula and why real counts are
allowed: :mod:`spcopyro.distributions`.
"""

from __future__ import annotations

import torch


def multinomial_counts_log_prob(value: torch.Tensor, log_probs: torch.Tensor) -> torch.Tensor:
    """The log density of :mod:`spcopyro.distributions` for counts ``value`` ``[..., K]`` and
    ``log_probs`` ``[..., K]``: ``[...]``."""
    # 0 * log 0 = 0: a zero count contributes nothing even where p_k = 0.
    dot = torch.where(value > 0, value * log_probs, torch.zeros_like(log_probs)).sum(-1)
    n = value.sum(-1)
    return torch.lgamma(n + 1) - torch.lgamma(value + 1).sum(-1) + dot
