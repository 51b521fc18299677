"""Random draws from an explicit :class:`torch.Generator`, in log space where it matters.

``torch.distributions.Dirichlet`` cannot take a generator, and with the weak-limit DP prior
(concentration alpha/L, possibly far below 1) its draws underflow to exact zeros in float32 and
float64 alike. The sampler therefore keeps pi, theta and w as *log* probabilities, drawn by
:func:`sample_log_dirichlet` from log-gamma variates (Marsaglia & Tsang, 2000, with the
``G(a) = G(a + 1) U^{1/a}`` boost for a < 1, taken in log space).
"""

from __future__ import annotations

import math

import torch

from spcopyro._util.arguments import MAX_SEED
from spcopyro._util.number_checks import is_integer

_MAX_REJECTION_ROUNDS = 64


def check_seed(seed: object, name: str = "seed") -> int:
    """``seed`` as an int in 0 .. :data:`MAX_SEED`, else a ValueError naming ``name`` and the
    value: a float (1.5 seeded as 1), a bool, a string, None or a :class:`torch.Generator` (pass
    it as the ``generator``) is refused rather than truncated or failing deep inside."""
    if not is_integer(seed) or not 0 <= seed <= MAX_SEED:  # type: ignore[operator]
        hint = ": pass a generator as the generator" if isinstance(seed, torch.Generator) else ""
        raise ValueError(f"{name} must be an integer in 0..2**63 - 1, got {seed!r}{hint}")
    return int(seed)


def check_generator(generator: object) -> None:
    """TypeError unless ``generator`` is a :class:`torch.Generator` (a seed given in its place
    failed deep inside a draw)."""
    if not isinstance(generator, torch.Generator):
        raise TypeError(
            f"generator must be a torch.Generator (torch.Generator().manual_seed(seed)), "
            f"got {type(generator).__name__}"
        )


def sample_log_gamma(concentration: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """log G with G ~ Gamma(concentration, 1), elementwise, for any positive concentration.

    Marsaglia-Tsang squeeze-free rejection, vectorised: every round redraws only the rejected
    elements (acceptance is above 95% for every shape, so a handful of rounds suffice).
    """
    a = torch.as_tensor(concentration)
    if not torch.is_floating_point(a):
        a = a.to(torch.float64)
    if (a <= 0).any() or not torch.isfinite(a).all():
        raise ValueError("gamma concentration must be finite and positive")
    boosted = a < 1
    shape = torch.where(boosted, a + 1, a)  # Marsaglia-Tsang needs shape >= 1
    d = shape - 1.0 / 3.0
    c = 1.0 / torch.sqrt(9.0 * d)
    tiny = torch.finfo(a.dtype).tiny

    def propose(d: torch.Tensor, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.randn(d.shape, dtype=a.dtype, generator=generator)
        u = torch.rand(d.shape, dtype=a.dtype, generator=generator)
        v = (1 + c * x) ** 3
        log_v = torch.log(v.clamp_min(tiny))
        accept = (v > 0) & (torch.log(u) < 0.5 * x**2 + d - d * v + d * log_v)
        return accept, torch.log(d) + log_v

    # First round on the whole tensor (no indexing); later rounds only on the rejected few.
    accept, log_g = propose(d, c)
    pending = (~accept).nonzero(as_tuple=True)
    for _ in range(_MAX_REJECTION_ROUNDS):
        if pending[0].numel() == 0:
            break
        accept, proposal = propose(d[pending], c[pending])
        done = tuple(i[accept] for i in pending)
        log_g[done] = proposal[accept]
        pending = tuple(i[~accept] for i in pending)
    else:  # pragma: no cover - probability ~ 0.05 ** 64
        raise RuntimeError("gamma rejection sampler did not converge")
    if boosted.any():
        u = torch.rand(a.shape, dtype=a.dtype, generator=generator)
        log_g = torch.where(boosted, log_g + torch.log(u) / a, log_g)
    return log_g


def sample_log_dirichlet(concentration: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """log p with p ~ Dir(concentration) over the last dim; finite even where p underflows."""
    log_g = sample_log_gamma(concentration, generator)
    return log_g - torch.logsumexp(log_g, dim=-1, keepdim=True)


def sample_categorical_logits(logits: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """One draw per row of a categorical given unnormalised log probabilities (Gumbel-max)."""
    u = torch.rand(logits.shape, dtype=logits.dtype, generator=generator)
    u = u.clamp_min(torch.finfo(logits.dtype).tiny)
    return torch.argmax(logits - torch.log(-torch.log(u)), dim=-1)


def coin_flip(probability: float, generator: torch.Generator) -> bool:
    """True with ``probability``: one float64 uniform draw from ``generator``, but none at all
    when ``probability`` is <= 0 (False) or >= 1 (True), so a move switched fully off or on
    leaves the random stream as it is. How the sampler chooses, independently of the state,
    whether a sweep makes an optional move (cluster, merge, exchange updates)."""
    if probability <= 0.0:
        return False
    if probability >= 1.0:
        return True
    return float(torch.rand((), dtype=torch.float64, generator=generator)) < probability


def metropolis_accept(log_ratio: float, generator: torch.Generator) -> bool:
    """Metropolis-Hastings: True with probability min(1, exp(``log_ratio``)), one float64 uniform
    drawn from ``generator`` only when ``log_ratio`` < 0 (the label moves' convention)."""
    if log_ratio >= 0:
        return True
    return float(torch.rand((), dtype=torch.float64, generator=generator)) < math.exp(log_ratio)
