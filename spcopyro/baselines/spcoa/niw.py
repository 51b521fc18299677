r"""Normal-inverse-Wishart conjugate pieces of the SpCoA baseline's position Gaussians.

NIW: Sigma ~ IW(Psi_0, nu_0), mu | Sigma ~ N(m_0, Sigma / kappa_0). Given n_l events of concept l
with mean xbar_l and scatter S = sum (x - xbar)(x - xbar)^T, the posterior (Murphy, 2007,
"Conjugate Bayesian analysis of the Gaussian distribution", eqs. 250-254) is::

    kappa_n = kappa_0 + n_l,    nu_n = nu_0 + n_l,    m_n = (kappa_0 m_0 + n_l xbar_l) / kappa_n
    Psi_n   = Psi_0 + S + kappa_0 n_l / kappa_n (xbar_l - m_0)(xbar_l - m_0)^T          (C6)

(:func:`niw_posterior`). Sigma_l is drawn from IW(Psi_n, nu_n) by the Bartlett decomposition of
its inverse, a Wishart W(Psi_n^{-1}, nu_n), and mu_l ~ N(m_n, Sigma_l / kappa_n)
(:func:`sample_niw`). :func:`niw_log_marginal` is the marginal likelihood of a concept's
positions with (mu_l, Sigma_l) integrated out (Murphy eq. 266).
"""

from __future__ import annotations

import math

import torch

from spcopyro._util.random_draws import sample_log_gamma
from spcopyro.model import DTYPE

__all__ = ["DIM", "niw_log_marginal", "niw_posterior", "sample_niw"]

DIM = 2  # d: positions are world (x, y)


def _check_assignments(assignments: torch.Tensor, num_events: int, num_concepts: int) -> None:
    if assignments.shape != (num_events,):
        raise ValueError(
            f"assignments must have shape ({num_events},), got {tuple(assignments.shape)}"
        )
    if assignments.numel() and (assignments.min() < 0 or assignments.max() >= num_concepts):
        raise ValueError(
            f"assignments must lie in [0, {num_concepts}), got values in "
            f"[{int(assignments.min())}, {int(assignments.max())}]"
        )


def niw_posterior(
    xy: torch.Tensor,
    assignments: torch.Tensor,
    num_concepts: int,
    mu0: torch.Tensor,
    kappa0: float,
    nu0: float,
    psi0: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """NIW posterior of every concept's Gaussian given its events, eq. (C6), vectorised.

    Uses the identity Psi_n = Psi_0 + sum_t x_t x_t^T + kappa_0 m_0 m_0^T - kappa_n m_n m_n^T,
    equal to (C6). A concept with no events keeps the prior.

    Args:
        xy: [T, 2] positions; assignments: [T] int64 concepts in [0, L); num_concepts: L.
        mu0: [2]; kappa0, nu0: floats; psi0: [2, 2].

    Returns:
        m_n [L, 2], kappa_n [L], nu_n [L], Psi_n [L, 2, 2].
    """
    xy = xy.to(DTYPE)
    _check_assignments(assignments, xy.shape[0], num_concepts)
    count = torch.bincount(assignments, minlength=num_concepts).to(DTYPE)  # [L]
    sum_x = _summed_counts(assignments, xy, num_concepts)  # [L, 2]
    outer = (xy[:, :, None] * xy[:, None, :]).reshape(-1, DIM * DIM)  # [T, 4]
    sum_xx = _summed_counts(assignments, outer, num_concepts).reshape(-1, DIM, DIM)  # [L, 2, 2]
    mu0 = mu0.to(DTYPE)
    kappa_n = kappa0 + count  # [L]
    nu_n = nu0 + count  # [L]
    m_n = (kappa0 * mu0 + sum_x) / kappa_n[:, None]  # [L, 2]
    prior_outer = kappa0 * mu0[:, None] * mu0[None, :]  # [2, 2]
    post_outer = kappa_n[:, None, None] * m_n[:, :, None] * m_n[:, None, :]  # [L, 2, 2]
    psi_n = psi0.to(DTYPE) + sum_xx + prior_outer - post_outer  # [L, 2, 2]
    psi_n = 0.5 * (psi_n + psi_n.transpose(-1, -2))  # exact symmetry against rounding
    return m_n, kappa_n, nu_n, psi_n


def niw_log_marginal(
    count: torch.Tensor,
    kappa_n: torch.Tensor,
    nu_n: torch.Tensor,
    psi_n: torch.Tensor,
    kappa0: float,
    nu0: float,
    psi0: torch.Tensor,
) -> torch.Tensor:
    """[L] log p(x_{t: C_t = l}) with (mu_l, Sigma_l) integrated out (Murphy 2007, eq. 266)::

        log p(X) = -n d/2 log pi + log Gamma_d(nu_n/2) - log Gamma_d(nu_0/2)
                   + nu_0/2 log|Psi_0| - nu_n/2 log|Psi_n| + d/2 (log kappa_0 - log kappa_n)

    0 for a concept with no events.
    """
    count = count.to(DTYPE)
    log_det0 = torch.logdet(psi0.to(DTYPE))
    return (
        -0.5 * count * DIM * math.log(math.pi)
        + torch.special.multigammaln(0.5 * nu_n, DIM)
        - torch.special.multigammaln(torch.tensor(0.5 * nu0, dtype=DTYPE), DIM)
        + 0.5 * nu0 * log_det0
        - 0.5 * nu_n * torch.logdet(psi_n)
        + 0.5 * DIM * (math.log(kappa0) - torch.log(kappa_n))
    )


def sample_niw(
    m_n: torch.Tensor,
    kappa_n: torch.Tensor,
    nu_n: torch.Tensor,
    psi_n: torch.Tensor,
    generator: torch.Generator,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One draw per concept of (mu_l [L, 2], Sigma_l [L, 2, 2]) from NIW(m_n, kappa_n, nu_n, Psi_n).

    Sigma^{-1} ~ Wishart(Psi_n^{-1}, nu_n) by the Bartlett decomposition: with Psi_n^{-1} = B B^T
    and A lower triangular, A_11^2 ~ chi2(nu_n), A_22^2 ~ chi2(nu_n - 1), A_21 ~ N(0, 1),
    Sigma^{-1} = B A A^T B^T. Then mu ~ N(m_n, Sigma / kappa_n). chi2(k) = 2 Gamma(k / 2, 1).
    """
    num = m_n.shape[0]
    shapes = 0.5 * torch.stack([nu_n, nu_n - 1.0], dim=-1).to(DTYPE)  # [L, 2]
    diagonal = torch.sqrt(2.0 * sample_log_gamma(shapes, generator).exp())  # [L, 2]
    below = torch.randn(num, dtype=DTYPE, generator=generator)  # [L]
    bartlett = torch.diag_embed(diagonal)  # [L, 2, 2]
    bartlett[:, 1, 0] = below
    root = torch.linalg.cholesky(torch.linalg.inv(psi_n.to(DTYPE)))  # [L, 2, 2] B
    factor = root @ bartlett  # [L, 2, 2] B A
    precision = factor @ factor.transpose(-1, -2)  # [L, 2, 2]
    sigma = torch.linalg.inv(precision)
    sigma = 0.5 * (sigma + sigma.transpose(-1, -2))  # [L, 2, 2]
    noise = torch.randn(num, DIM, dtype=DTYPE, generator=generator)  # [L, 2]
    chol = torch.linalg.cholesky(sigma / kappa_n.to(DTYPE)[:, None, None])  # [L, 2, 2]
    mu = m_n.to(DTYPE) + (chol @ noise[:, :, None])[:, :, 0]  # [L, 2]
    return mu, sigma


def _summed_counts(
    assignments: torch.Tensor, counts: torch.Tensor, num_concepts: int
) -> torch.Tensor:
    """[L, D] sum of the [T, D] rows per concept.

    A one-hot matrix product rather than ``index_add_``: on these small tensors the latter runs
    a parallel loop whose threads, on a busy machine, cost more than the sum itself.
    """
    one_hot = torch.nn.functional.one_hot(assignments, num_concepts).to(DTYPE)  # [T, L]
    return one_hot.T @ counts.to(DTYPE)  # [L, D]
