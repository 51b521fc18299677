r"""The SpCoA baseline's generative model and its blocked Gibbs sampler.

Generative model
----------------
T events (:mod:`~spcopyro.baselines.spcoa.events`), L concepts (the weak-limit upper bound), K
image classes, V words, d = 2::

    pi                ~ Dir(alpha/L, ..., alpha/L)                         (C1) weak-limit DP
    mu_l, Sigma_l     ~ NIW(m_0, kappa_0, nu_0, Psi_0)                     (C2)
    theta_l           ~ Dir(chi 1_K),    w_l ~ Dir(beta 1_V)               (C3)
    C_t               ~ Cat(pi)                                            (C4)
    x_t ~ N(mu_{C_t}, Sigma_{C_t}),  f_t ~ Mult(theta_{C_t}),  s_t ~ Mult(w_{C_t})

NIW: Sigma ~ IW(Psi_0, nu_0), mu | Sigma ~ N(m_0, Sigma / kappa_0). The image and word counts may
be fractional (probability histograms, tf-idf weights); their likelihood is
prod_k theta_lk^{f_tk}, the multinomial coefficient being a constant of the data.

Blocked Gibbs sampling (uncollapsed, every step vectorised over events and concepts)
------------------------------------------------------------------------------------
Given the globals the C_t are independent:

.. math::

    p(C_t = l \mid \cdot) \propto \pi_l \, \mathcal N(x_t \mid \mu_l, \Sigma_l)
        \prod_k \theta_{lk}^{f_{tk}} \prod_v w_{lv}^{s_{tv}}                   \qquad (C5)

and given the assignments the globals have conjugate posteriors: pi ~ Dir(alpha/L + n_l),
theta_l ~ Dir(chi + F_l), w_l ~ Dir(beta + S_l) (F_l, S_l the summed counts of concept l) and the
NIW posterior (C6) of :mod:`~spcopyro.baselines.spcoa.niw`.

Each sweep's assignments are scored by the collapsed log joint log p(C, x, f, s) (all globals
integrated out: the Dirichlet-multinomial of C under (C1), the NIW marginal likelihood of each
concept's positions, Murphy eq. 266, and the Dirichlet-multinomials of the counts), which does
not care how concepts are numbered. The result (:class:`~spcopyro.baselines.spcoa.SpCoAResult`)
keeps the visited assignment of highest collapsed log joint and the posterior means of the
globals given it (E[Sigma] = Psi_n / (nu_n - d - 1)).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch

from spcopyro._util.random_draws import sample_categorical_logits, sample_log_dirichlet
from spcopyro.baselines.spcoa.events import DEFAULT_PAIR_DISTANCE, SpCoAData, spcoa_data
from spcopyro.baselines.spcoa.hyperparameters import SpCoAHyperparameters
from spcopyro.baselines.spcoa.niw import (
    DIM,
    _summed_counts,
    niw_log_marginal,
    niw_posterior,
    sample_niw,
)
from spcopyro.baselines.spcoa.result import SpCoAResult
from spcopyro.config import WordWeightingSetting
from spcopyro.data import FeatureScaling, House
from spcopyro.model import DTYPE

__all__ = [
    "EventTensors",
    "SpCoAHyperparameters",
    "SpCoAParameters",
    "assignment_logits",
    "collapsed_log_joint",
    "fit_spcoa",
    "sample_globals",
    "spcoa_gaussians",
]


# ---------------------------------------------------------------------------------------------
# Hyperparameters and the events as tensors
# ---------------------------------------------------------------------------------------------


class EventTensors(NamedTuple):
    """The events as float64 tensors, with the prior's m_0 and Psi_0 resolved."""

    xy: torch.Tensor  # [T, 2]
    features: torch.Tensor  # [T, K]
    words: torch.Tensor  # [T, V]
    mu0: torch.Tensor  # [2] m_0
    psi0: torch.Tensor  # [2, 2] Psi_0 = psi0 I

    @classmethod
    def from_data(cls, data: SpCoAData, prior: SpCoAHyperparameters) -> EventTensors:
        """Tensors of ``data``; m_0 = ``prior.mu0``, or the mean event position when None."""
        xy = torch.as_tensor(data.xy, dtype=DTYPE)  # [T, 2]
        mu0 = xy.mean(0) if prior.mu0 is None else torch.tensor(prior.mu0, dtype=DTYPE)  # [2]
        return cls(
            xy=xy,
            features=torch.as_tensor(data.features, dtype=DTYPE),
            words=torch.as_tensor(data.words, dtype=DTYPE),
            mu0=mu0,
            psi0=prior.psi0 * torch.eye(DIM, dtype=DTYPE),
        )


# ---------------------------------------------------------------------------------------------
# The Gibbs conditionals and the collapsed log joint
# ---------------------------------------------------------------------------------------------


class SpCoAParameters(NamedTuple):
    """The globals of the mixture (probabilities in log space)."""

    log_pi: torch.Tensor  # [L]
    means: torch.Tensor  # [L, 2]
    covariances: torch.Tensor  # [L, 2, 2]
    log_theta: torch.Tensor  # [L, K]
    log_w: torch.Tensor  # [L, V]


def assignment_logits(
    xy: torch.Tensor, features: torch.Tensor, words: torch.Tensor, params: SpCoAParameters
) -> torch.Tensor:
    """[T, L] unnormalised log p(C_t = l | x_t, f_t, s_t, globals), eq. (C5):
    ``log pi_l + log N(x_t | mu_l, Sigma_l) + sum_k f_tk log theta_lk + sum_v s_tv log w_lv``."""
    gaussians = torch.distributions.MultivariateNormal(
        params.means, covariance_matrix=params.covariances
    )
    logits = params.log_pi + gaussians.log_prob(xy.to(DTYPE)[:, None, :])  # [T, L]
    if features.shape[1]:
        logits = logits + features.to(DTYPE) @ params.log_theta.T  # [T, L]
    if words.shape[1]:
        logits = logits + words.to(DTYPE) @ params.log_w.T  # [T, L]
    return logits


def sample_globals(
    assignments: torch.Tensor,
    tensors: EventTensors,
    prior: SpCoAHyperparameters,
    generator: torch.Generator,
) -> SpCoAParameters:
    """Draw pi, (mu, Sigma), theta, w given the assignments from their conjugate posteriors."""
    L = prior.num_concepts
    count = torch.bincount(assignments, minlength=L).to(DTYPE)  # [L]
    log_pi = sample_log_dirichlet(prior.alpha / L + count, generator)  # [L]
    m_n, kappa_n, nu_n, psi_n = niw_posterior(
        tensors.xy, assignments, L, tensors.mu0, prior.kappa0, prior.nu0, tensors.psi0
    )
    means, covariances = sample_niw(m_n, kappa_n, nu_n, psi_n, generator)
    image_sums = _summed_counts(assignments, tensors.features, L)  # [L, K]
    word_sums = _summed_counts(assignments, tensors.words, L)  # [L, V]
    # A modality with no classes (K = 0 or V = 0) has nothing to draw.
    log_theta = image_sums  # [L, K]
    if image_sums.shape[1]:
        log_theta = sample_log_dirichlet(prior.chi + image_sums, generator)
    log_w = word_sums  # [L, V]
    if word_sums.shape[1]:
        log_w = sample_log_dirichlet(prior.beta + word_sums, generator)
    return SpCoAParameters(log_pi, means, covariances, log_theta, log_w)


def _dirichlet_multinomial(sums: torch.Tensor, concentration: float) -> torch.Tensor:
    """[L] log int prod_k theta_k^{n_k} Dir(theta | a 1_K) d theta for [L, K] summed counts n."""
    if sums.shape[1] == 0:
        return torch.zeros(sums.shape[0], dtype=DTYPE)
    size = sums.shape[1]
    a = torch.tensor(concentration, dtype=DTYPE)
    return (
        torch.lgamma(size * a)
        - torch.lgamma(size * a + sums.sum(-1))
        + (torch.lgamma(a + sums) - torch.lgamma(a)).sum(-1)
    )


def collapsed_log_joint(
    assignments: torch.Tensor, tensors: EventTensors, prior: SpCoAHyperparameters
) -> float:
    """log p(C, x, f, s) with every global integrated out (up to a constant of the data)::

        log Gamma(alpha) - log Gamma(alpha + T) + sum_l [log Gamma(alpha/L + n_l)
            - log Gamma(alpha/L)]                                   (C under (C1))
        + sum_l NIW marginal of concept l's positions               (niw_log_marginal)
        + sum_l DirMult(F_l; chi) + sum_l DirMult(S_l; beta)

    Invariant under renumbering the concepts.
    """
    L = prior.num_concepts
    count = torch.bincount(assignments, minlength=L).to(DTYPE)  # [L]
    a = torch.tensor(prior.alpha / L, dtype=DTYPE)
    log_labels = (
        torch.lgamma(torch.tensor(prior.alpha, dtype=DTYPE))
        - torch.lgamma(prior.alpha + count.sum())
        + (torch.lgamma(a + count) - torch.lgamma(a)).sum()
    )
    _, kappa_n, nu_n, psi_n = niw_posterior(
        tensors.xy, assignments, L, tensors.mu0, prior.kappa0, prior.nu0, tensors.psi0
    )
    log_positions = niw_log_marginal(
        count, kappa_n, nu_n, psi_n, prior.kappa0, prior.nu0, tensors.psi0
    ).sum()
    log_images = _dirichlet_multinomial(
        _summed_counts(assignments, tensors.features, L), prior.chi
    ).sum()
    log_words = _dirichlet_multinomial(
        _summed_counts(assignments, tensors.words, L), prior.beta
    ).sum()
    return float(log_labels + log_positions + log_images + log_words)


# ---------------------------------------------------------------------------------------------
# Fitting
# ---------------------------------------------------------------------------------------------


def _posterior_means(
    assignments: torch.Tensor, tensors: EventTensors, prior: SpCoAHyperparameters
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """E[pi], E[mu], E[Sigma], E[theta], E[w] given the assignments: pi, means, covariances,
    theta, w as numpy arrays."""
    L = prior.num_concepts
    count = torch.bincount(assignments, minlength=L).to(DTYPE)  # [L]
    pi = (prior.alpha / L + count) / (prior.alpha + count.sum())  # [L]
    m_n, _, nu_n, psi_n = niw_posterior(
        tensors.xy, assignments, L, tensors.mu0, prior.kappa0, prior.nu0, tensors.psi0
    )
    covariances = psi_n / (nu_n - DIM - 1)[:, None, None]  # [L, 2, 2]

    def mean_dirichlet(sums: torch.Tensor, concentration: float) -> torch.Tensor:
        posterior = concentration + sums  # [L, D]
        return posterior / posterior.sum(-1, keepdim=True)

    theta = mean_dirichlet(_summed_counts(assignments, tensors.features, L), prior.chi)
    w = mean_dirichlet(_summed_counts(assignments, tensors.words, L), prior.beta)
    return pi.numpy(), m_n.numpy(), covariances.numpy(), theta.numpy(), w.numpy()


def fit_spcoa(
    house: House,
    *,
    num_concepts: int = 20,
    iterations: int = 200,
    seed: int = 0,
    alpha: float = 1.0,
    beta: float = 0.1,
    chi: float = 0.1,
    kappa0: float = 0.01,
    nu0: float = 4.0,
    psi0: float = 1.0,
    mu0: tuple[float, float] | None = None,
    feature_scaling: FeatureScaling = 10.0,
    word_weighting: WordWeightingSetting = "auto",
    pair_distance: float = DEFAULT_PAIR_DISTANCE,
) -> SpCoAResult:
    """Fit the SpCoA-style mixture to ``house`` by ``iterations`` blocked Gibbs sweeps.

    Starts from uniformly random assignments (drawn from ``torch.Generator().manual_seed(seed)``,
    so a seed gives the same result every time), then alternates (C5) and the conjugate draws of
    the globals; keeps the assignments of highest collapsed log joint. The hyperparameters are
    those of :class:`SpCoAHyperparameters`; ``feature_scaling`` turns each image histogram into
    counts (:func:`spcopyro.data.scale_features`: the default 10 gives an image the weight of
    ten class draws), ``word_weighting`` is ``"count"``, ``"tfidf"`` (eq. 20) or ``"auto"``
    (tf-idf when at least 30% of the utterances are sentences, as SpCoMapping's fit:
    :mod:`spcopyro.data.word_weighting`) and
    ``pair_distance`` pairs utterances with images (:func:`spcoa_data`).

    Raises ValueError for a bad hyperparameter, a non-positive ``iterations``, a negative
    ``seed`` or observations holding nothing to cluster.
    """
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"iterations={iterations!r}: must be a positive integer")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed={seed!r}: must be a non-negative integer")
    prior = SpCoAHyperparameters(
        num_concepts=num_concepts,
        alpha=alpha,
        beta=beta,
        chi=chi,
        kappa0=kappa0,
        nu0=nu0,
        psi0=psi0,
        mu0=mu0,
    )
    data = spcoa_data(
        house.observations,
        feature_scaling=feature_scaling,
        word_weighting=word_weighting,
        pair_distance=pair_distance,
    )
    tensors = EventTensors.from_data(data, prior)
    generator = torch.Generator().manual_seed(seed)

    assignments = torch.randint(num_concepts, (data.num_events,), generator=generator)  # [T]
    params = sample_globals(assignments, tensors, prior, generator)
    log_joint = np.empty(iterations)  # [S]
    in_use = np.empty(iterations, dtype=np.int64)  # [S]
    best, best_sweep = assignments, -1
    for sweep in range(iterations):
        logits = assignment_logits(tensors.xy, tensors.features, tensors.words, params)  # [T, L]
        assignments = sample_categorical_logits(logits, generator)  # [T]
        params = sample_globals(assignments, tensors, prior, generator)
        log_joint[sweep] = collapsed_log_joint(assignments, tensors, prior)
        in_use[sweep] = int(torch.unique(assignments).numel())
        if best_sweep < 0 or log_joint[sweep] > log_joint[best_sweep]:
            best, best_sweep = assignments, sweep

    pi, means, covariances, theta, w = _posterior_means(best, tensors, prior)
    return SpCoAResult(
        grid=house.grid,
        vocabulary=data.vocabulary,
        hyperparameters=prior,
        data=data,
        assignments=best.numpy().astype(np.int64),
        pi=pi,
        means=means,
        covariances=covariances,
        theta=theta,
        w=w,
        log_joint=log_joint,
        num_concepts=in_use,
        best_sweep=best_sweep,
        name=house.name,
    )


def spcoa_gaussians(
    house: House, *, num_concepts: int = 20, iterations: int = 200, seed: int = 0, **options: object
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Pre-learning for SpCoMapping (paper Section 5): fit SpCoA, return its Gaussians.

    ``options`` go to :func:`fit_spcoa`. Pass SpCoMapping's L as ``num_concepts`` so that the
    labels of :func:`spcopyro.inference.initialisation.labels_from_gaussians` (indices into the G
    <= L Gaussians) are valid concepts.

    Returns:
        means [G, 2], covariances [G, 2, 2], log_weights [G] (float64) of the G concepts in use.
    """
    result = fit_spcoa(
        house,
        num_concepts=num_concepts,
        iterations=iterations,
        seed=seed,
        **options,  # type: ignore[arg-type]
    )
    return result.gaussians()
