r"""The emission distribution of SpCoMapping: a multinomial whose counts may be real-valued.

The paper emits image features and words by Mult(theta_C) and Mult(w_C) (eqs. 5 and 6), but feeds
them real-valued counts: CNN probabilities (or ``floor(100 f)``) and tf-idf weights (eq. 20).
:class:`MultinomialCounts` keeps the multinomial's log density, extended to real counts through the
gamma function,

.. math::

    \log p(x \mid p) = \log\Gamma(n + 1) - \sum_k \log\Gamma(x_k + 1)
        + \sum_k x_k \log p_k,
    \qquad n = \sum_k x_k,

which equals :class:`torch.distributions.Multinomial` on integer counts. Only the last sum depends
on the concept, so the Gibbs conditionals are those of the paper either way. Unlike torch's
Multinomial, every batch element has its own ``total_count`` (cells hold different numbers of
observations); sampling needs integer totals.
"""

from __future__ import annotations

import torch
from pyro.distributions import TorchDistribution, constraints

from spcopyro._util.multinomial import multinomial_counts_log_prob  # [..., K] -> [...]

__all__ = ["MultinomialCounts", "multinomial_counts_log_prob"]

_EMPTY = torch.Size()


class MultinomialCounts(TorchDistribution):
    """Multinomial over the last dim with per-batch-element totals and real-valued counts allowed.

    Args:
        probs: ``[..., K]`` event probabilities (rows sum to one).
        total_count: ``[...]`` number of trials of each batch element (used for sampling only).
    """

    arg_constraints = {"probs": constraints.simplex}
    support = constraints.independent(constraints.nonnegative, 1)
    has_enumerate_support = False

    def __init__(
        self, probs: torch.Tensor, total_count: torch.Tensor, validate_args: bool | None = None
    ) -> None:
        self.probs = probs  # [..., K]
        self.total_count = torch.as_tensor(total_count, dtype=probs.dtype).expand(
            probs.shape[:-1]
        )  # [...]
        super().__init__(probs.shape[:-1], probs.shape[-1:], validate_args=validate_args)

    def expand(self, batch_shape, _instance=None):
        batch_shape = torch.Size(batch_shape)
        return MultinomialCounts(
            self.probs.expand(batch_shape + self.event_shape),
            self.total_count.expand(batch_shape),
            validate_args=False,
        )

    def log_prob(self, value: torch.Tensor) -> torch.Tensor:
        if self._validate_args:
            self._validate_sample(value)
        return multinomial_counts_log_prob(value, torch.log(self.probs))

    def sample(self, sample_shape: torch.Size = _EMPTY) -> torch.Tensor:
        """Integer counts: each batch element draws ``total_count`` categorical trials."""
        totals = self.total_count
        wrong = (totals != totals.round()) | (totals < 0)
        if wrong.any():
            index = tuple(int(i) for i in torch.nonzero(wrong)[0])
            raise ValueError(
                f"MultinomialCounts.sample needs non-negative whole total_count, got "
                f"{float(totals[index])!r} at batch index {index}: real-valued counts "
                "(probabilities, tf-idf weights) can be scored but not drawn; whole counts "
                "come from e.g. preset('original-code')"
            )
        shape = torch.Size(sample_shape) + self.batch_shape
        probs = self.probs.expand(shape + self.event_shape).reshape(-1, self.event_shape[0])
        n = totals.expand(shape).reshape(-1).long()  # [B]
        max_n = int(n.max()) if n.numel() else 0
        counts = torch.zeros_like(probs)  # [B, K]
        if max_n > 0:
            draws = torch.multinomial(probs, max_n, replacement=True)  # [B, max_n]
            keep = torch.arange(max_n) < n[:, None]  # [B, max_n]
            counts.scatter_add_(1, draws, keep.to(probs.dtype))
        return counts.reshape(shape + self.event_shape)
