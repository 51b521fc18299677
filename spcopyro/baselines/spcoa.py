r"""Baseline (C): spatial concept formation with words and images (SpCoA style).

The comparison method (C) of SpCoMapping (Katsumata et al., 2019, Table 4): a mixture over
*observations*, not map cells, as in

* Ishibushi, Taniguchi, Takano, Hagiwara and Inamura (2015), "Statistical localization exploiting
  convolutional neural network for an autonomous vehicle", IECON 2015 (spatial concepts with CNN
  place-class features), and
* Taniguchi, Hagiwara, Taniguchi and Inamura (2016), "Online spatial concept and lexical
  acquisition with simultaneous localization and mapping" / SpCoA (Nonparametric Bayesian spatial
  concept acquisition, IROS 2016): concepts with a Gaussian position distribution and
  multinomial word emissions.

Observation events
------------------
Every image is one event t with its world position x_t, its place-class histogram f_t ([K], scaled
by :func:`spcopyro.data.scale_features`) and the words s_t ([V]) heard there. Each utterance is
paired with the *nearest image of the same trial* when that image is at most ``pair_distance``
metres away (in the public dataset and the synthetic houses every utterance is spoken exactly at
an image position), its word counts (or tf-idf weights, paper eq. 20) added to that event's s_t;
an utterance with no image that near becomes an event of its own, with its position, its words
and no image (f_t = 0). Nothing is dropped. The events live in continuous world coordinates: the
map is used only to label its cells afterwards.

Generative model
----------------
T events, L concepts (the weak-limit upper bound), K image classes, V words, d = 2::

    pi                ~ Dir(alpha/L, ..., alpha/L)                         (C1) weak-limit DP
    mu_l, Sigma_l     ~ NIW(m_0, kappa_0, nu_0, Psi_0)                     (C2)
    theta_l           ~ Dir(chi 1_K),    w_l ~ Dir(beta 1_V)               (C3)
    C_t               ~ Cat(pi)                                            (C4)
    x_t ~ N(mu_{C_t}, Sigma_{C_t}),  f_t ~ Mult(theta_{C_t}),  s_t ~ Mult(w_{C_t})

NIW: Sigma ~ IW(Psi_0, nu_0), mu | Sigma ~ N(m_0, Sigma / kappa_0). The image and word counts may
be fractional (probability histograms, tf-idf weights); their likelihood is
prod_k theta_lk^{f_tk}, the multinomial coefficient being a constant of the data.

Blocked Gibbs sampling (uncollapsed, every step vectorised over events and concepts)
-----------------------------------------------------------------------------------
Given the globals the C_t are independent:

.. math::

    p(C_t = l \mid \cdot) \propto \pi_l \, \mathcal N(x_t \mid \mu_l, \Sigma_l)
        \prod_k \theta_{lk}^{f_{tk}} \prod_v w_{lv}^{s_{tv}}                   \qquad (C5)

and given the assignments the globals have conjugate posteriors: pi ~ Dir(alpha/L + n_l),
theta_l ~ Dir(chi + F_l), w_l ~ Dir(beta + S_l) (F_l, S_l the summed counts of concept l) and the
NIW posterior (Murphy, 2007, "Conjugate Bayesian analysis of the Gaussian distribution", eqs.
250-254), with n_l events of mean xbar_l and scatter S = sum (x - xbar)(x - xbar)^T::

    kappa_n = kappa_0 + n_l,    nu_n = nu_0 + n_l,    m_n = (kappa_0 m_0 + n_l xbar_l) / kappa_n
    Psi_n   = Psi_0 + S + kappa_0 n_l / kappa_n (xbar_l - m_0)(xbar_l - m_0)^T          (C6)

Sigma_l is drawn from IW(Psi_n, nu_n) by the Bartlett decomposition of its inverse, a Wishart
W(Psi_n^{-1}, nu_n), and mu_l ~ N(m_n, Sigma_l / kappa_n).

Each sweep's assignments are scored by the collapsed log joint log p(C, x, f, s) (all globals
integrated out: the Dirichlet-multinomial of C under (C1), the NIW marginal likelihood of each
concept's positions, Murphy eq. 266, and the Dirichlet-multinomials of the counts), which does
not care how concepts are numbered. The result keeps the visited assignment of highest collapsed
log joint and the posterior means of the globals given it (E[Sigma] = Psi_n / (nu_n - d - 1)).

The semantic map (paper eqs. 21-22)
-----------------------------------
Each free cell, at world position x_ij (its centre), gets the concept
argmax_l log pi_l + log N(x_ij | mu_l, Sigma_l) over the concepts that hold at least one event
(exactly :func:`spcopyro.gibbs.init.labels_from_gaussians`); these Gaussians are also the
pre-learning initialisation of SpCoMapping (paper Section 5): :func:`spcoa_gaussians`.
"Where is WORD?" is the eq. (19) analogue argmax_l pi_l w_{l,WORD}, taken over the concepts that
label at least one cell, and p(word | cell) = sum_l p(l | x_cell) w_l with
p(l | x) proportional to pi_l N(x | mu_l, Sigma_l).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
import torch
from scipy.spatial import cKDTree

from spcopyro.data import (
    FeatureScaling,
    House,
    Observations,
    WordWeighting,
    scale_features,
    tfidf_weights,
    word_matrix,
)
from spcopyro.gibbs.init import labels_from_gaussians
from spcopyro.gibbs.random import (
    sample_categorical_logits,
    sample_log_dirichlet,
    sample_log_gamma,
)
from spcopyro.maps import OccupancyGrid
from spcopyro.model import DTYPE
from spcopyro.results import word_index

__all__ = [
    "DEFAULT_PAIR_DISTANCE",
    "EventTensors",
    "SpCoAData",
    "SpCoAHyperparameters",
    "SpCoAParameters",
    "SpCoAResult",
    "assignment_logits",
    "collapsed_log_joint",
    "fit_spcoa",
    "niw_log_marginal",
    "niw_posterior",
    "sample_globals",
    "sample_niw",
    "spcoa_data",
    "spcoa_gaussians",
]

DIM = 2  # d: positions are world (x, y)
DEFAULT_PAIR_DISTANCE = 0.5  # metres: an utterance joins the nearest image of its trial this near
_PAIR_EPS = 1e-9  # metres: tolerance on pair_distance


# ---------------------------------------------------------------------------------------------
# Events and hyperparameters
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SpCoAData:
    """The observation events the mixture clusters (see the module docstring).

    T events (the images first, in image order, then the utterances that no image was near,
    in utterance order), K image classes, V words.
    """

    xy: np.ndarray  # [T, 2] float64 world metres
    features: np.ndarray  # [T, K] float64 scaled image counts (0 for word-only events)
    words: np.ndarray  # [T, V] float64 word counts or tf-idf weights
    vocabulary: tuple[str, ...]  # [V]
    image_event: np.ndarray  # [num_images] int64 event of each image (= its index)
    utterance_event: np.ndarray  # [U] int64 event each utterance was added to

    @property
    def num_events(self) -> int:
        """T."""
        return int(self.xy.shape[0])


def spcoa_data(
    observations: Observations,
    *,
    feature_scaling: FeatureScaling = "probability",
    word_weighting: WordWeighting = "count",
    pair_distance: float = DEFAULT_PAIR_DISTANCE,
) -> SpCoAData:
    """The events of ``observations``: images, with each utterance paired to the nearest image of
    its trial within ``pair_distance`` metres, and word-only events for the rest.

    Raises ValueError when there is nothing to cluster (no images and no utterances) or
    ``pair_distance`` is not a finite number >= 0.
    """
    if not (
        isinstance(pair_distance, (int, float))
        and not isinstance(pair_distance, bool)
        and math.isfinite(pair_distance)
        and pair_distance >= 0
    ):
        raise ValueError(f"pair_distance={pair_distance!r}: must be a finite number >= 0 metres")
    if word_weighting not in ("count", "tfidf"):
        raise ValueError(f"word_weighting={word_weighting!r}: must be 'count' or 'tfidf'")
    num_images, num_utterances = observations.num_images, observations.num_utterances
    if num_images + num_utterances == 0:
        raise ValueError("spcoa: the observations hold no images and no utterances")
    features = scale_features(observations.image_features, feature_scaling)  # [I, K]
    vocabulary = observations.vocabulary
    if num_utterances == 0:
        utterance_words = np.zeros((0, 0), dtype=np.float64)  # [0, 0]
    elif word_weighting == "count":
        utterance_words = word_matrix(observations.utterances, vocabulary)  # [U, V]
    else:
        utterance_words = tfidf_weights(observations.utterances, vocabulary)  # [U, V]

    # Pair each utterance with the nearest image of its trial (a k-d tree per trial).
    utterance_event = np.full(num_utterances, -1, dtype=np.int64)  # [U]
    for trial in observations.trials:
        images = np.flatnonzero(observations.image_trial == trial)  # [I_k]
        spoken = np.flatnonzero(observations.word_trial == trial)  # [U_k]
        if images.size == 0 or spoken.size == 0:
            continue
        distance, nearest = cKDTree(observations.image_xy[images]).query(
            observations.word_xy[spoken]
        )  # [U_k] x2
        near = distance <= pair_distance + _PAIR_EPS  # [U_k] bool
        utterance_event[spoken[near]] = images[nearest[near]]
    alone = np.flatnonzero(utterance_event < 0)  # [U_0] utterances that become events
    utterance_event[alone] = num_images + np.arange(alone.size)

    num_events = num_images + alone.size
    xy = np.concatenate([observations.image_xy, observations.word_xy[alone]])  # [T, 2]
    event_features = np.zeros((num_events, features.shape[1]), dtype=np.float64)  # [T, K]
    event_features[:num_images] = features
    words = np.zeros((num_events, len(vocabulary)), dtype=np.float64)  # [T, V]
    np.add.at(words, utterance_event, utterance_words)
    return SpCoAData(
        xy=xy,
        features=event_features,
        words=words,
        vocabulary=vocabulary,
        image_event=np.arange(num_images, dtype=np.int64),
        utterance_event=utterance_event,
    )


@dataclass(frozen=True)
class SpCoAHyperparameters:
    """Priors (C1)-(C3) of the module docstring; validated on construction.

    Attributes:
        num_concepts: L, the weak-limit upper bound on the number of concepts.
        alpha: DP concentration; pi ~ Dir(alpha / L).
        beta: symmetric Dirichlet concentration of each word distribution w_l.
        chi: symmetric Dirichlet concentration of each image-class distribution theta_l.
        kappa0: NIW prior strength on the mean (mu ~ N(m_0, Sigma / kappa_0)).
        nu0: NIW degrees of freedom, > d + 1 = 3 so that E[Sigma] exists.
        psi0: Psi_0 = psi0 * I (m^2); the prior mean of Sigma is Psi_0 / (nu0 - 3).
        mu0: m_0, world (x, y); None: the mean of the event positions.
    """

    num_concepts: int = 20
    alpha: float = 1.0
    beta: float = 0.1
    chi: float = 0.1
    kappa0: float = 0.01
    nu0: float = 4.0
    psi0: float = 1.0
    mu0: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"SpCoA {name}={getattr(self, name)!r}: {why}")

        if isinstance(self.num_concepts, bool) or not isinstance(self.num_concepts, int):
            raise bad("num_concepts", "must be a positive integer")
        if self.num_concepts < 1:
            raise bad("num_concepts", "must be a positive integer")
        for name in ("alpha", "beta", "chi", "kappa0", "psi0"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise bad(name, "must be a finite positive number")
            if not (math.isfinite(value) and value > 0):
                raise bad(name, "must be a finite positive number")
        nu0 = self.nu0
        if isinstance(nu0, bool) or not isinstance(nu0, (int, float)) or not math.isfinite(nu0):
            raise bad("nu0", f"must be a finite number > {DIM + 1}")
        if nu0 <= DIM + 1:
            raise bad("nu0", f"must be > d + 1 = {DIM + 1} (so that E[Sigma] exists)")
        if self.mu0 is not None:
            try:
                mu0 = tuple(float(v) for v in self.mu0)
            except (TypeError, ValueError):
                raise bad("mu0", "must be None or two numbers (x, y)") from None
            if len(mu0) != DIM or not all(math.isfinite(v) for v in mu0):
                raise bad("mu0", "must be None or two finite numbers (x, y)")
            object.__setattr__(self, "mu0", mu0)


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
# Conjugate pieces
# ---------------------------------------------------------------------------------------------


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
    """[T, L] unnormalised log p(C_t = l | x_t, f_t, s_t, globals), eq. (C5)::

    log pi_l + log N(x_t | mu_l, Sigma_l) + sum_k f_tk log theta_lk + sum_v s_tv log w_lv
    """
    gaussians = torch.distributions.MultivariateNormal(
        params.means, covariance_matrix=params.covariances
    )
    logits = params.log_pi + gaussians.log_prob(xy.to(DTYPE)[:, None, :])  # [T, L]
    if features.shape[1]:
        logits = logits + features.to(DTYPE) @ params.log_theta.T  # [T, L]
    if words.shape[1]:
        logits = logits + words.to(DTYPE) @ params.log_w.T  # [T, L]
    return logits


def _summed_counts(
    assignments: torch.Tensor, counts: torch.Tensor, num_concepts: int
) -> torch.Tensor:
    """[L, D] sum of the [T, D] rows per concept.

    A one-hot matrix product rather than ``index_add_``: on these small tensors the latter runs
    a parallel loop whose threads, on a busy machine, cost more than the sum itself.
    """
    one_hot = torch.nn.functional.one_hot(assignments, num_concepts).to(DTYPE)  # [T, L]
    return one_hot.T @ counts.to(DTYPE)  # [L, D]


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
# The fitted model
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SpCoAResult:
    """A fitted SpCoA mixture on a map: Gaussians, emissions, and the semantic map they make.

    L concepts (``hyperparameters.num_concepts``), K image classes, V words, T events, S sweeps.
    The globals are the posterior means given the assignments of highest collapsed log joint.
    """

    grid: OccupancyGrid
    vocabulary: tuple[str, ...]  # [V]
    hyperparameters: SpCoAHyperparameters
    data: SpCoAData
    assignments: np.ndarray  # [T] int64 concept of each event (best visited)
    pi: np.ndarray  # [L] E[pi | C]
    means: np.ndarray  # [L, 2] E[mu | C] = m_n
    covariances: np.ndarray  # [L, 2, 2] E[Sigma | C] = Psi_n / (nu_n - 3)
    theta: np.ndarray  # [L, K] E[theta | C]
    w: np.ndarray  # [L, V] E[w | C]
    log_joint: np.ndarray  # [S] collapsed log p(C, data) after each sweep
    num_concepts: np.ndarray  # [S] int64 concepts holding events after each sweep
    best_sweep: int  # 0-based sweep of ``assignments``
    name: str = ""

    # -- concepts and the map ----------------------------------------------------------------

    @cached_property
    def event_counts(self) -> np.ndarray:
        """[L] int64 events assigned to each concept."""
        return np.bincount(self.assignments, minlength=self.pi.shape[0]).astype(np.int64)

    def concepts_in_use(self) -> np.ndarray:
        """[G] int64 ascending ids of the concepts holding at least one event."""
        return np.flatnonzero(self.event_counts > 0).astype(np.int64)

    def gaussians(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The concepts in use as eqs. 21-22 want them, float64 tensors.

        Returns:
            means [G, 2], covariances [G, 2, 2], log_weights [G] (log pi, renormalised over the
            G concepts), in :meth:`concepts_in_use` order.
        """
        used = self.concepts_in_use()  # [G]
        weights = self.pi[used] / self.pi[used].sum()  # [G]
        return (
            torch.as_tensor(self.means[used], dtype=DTYPE),
            torch.as_tensor(self.covariances[used], dtype=DTYPE),
            torch.log(torch.as_tensor(weights, dtype=DTYPE)),
        )

    def _cell_xy(self, cells: np.ndarray) -> np.ndarray:
        """[n, 2] world centres of ``[n]`` int free-cell indices (``grid.free_index`` order)."""
        index = np.asarray(cells)
        if index.ndim != 1 or (index.size and index.dtype.kind not in "iu"):
            raise ValueError(
                f"cells must be a 1-D integer array of free-cell indices, got shape "
                f"{index.shape} dtype {index.dtype}"
            )
        index = index.astype(np.int64, copy=False)  # [n]
        bad = (index < 0) | (index >= self.grid.num_free)  # [n] bool
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"cells[{first}] = {int(index[first])} is not a free-cell index (the grid has "
                f"{self.grid.num_free} free cells)"
            )
        return self.grid.cell_to_world(self.grid.free_cells[index])  # [n, 2]

    def cell_log_posterior(self, cells: np.ndarray) -> np.ndarray:
        """[n, L] log p(C = l | x_cell), proportional to pi_l N(x_cell | mu_l, Sigma_l), over the
        concepts in use (-inf for the others), for ``[n]`` int free-cell indices."""
        xy = torch.as_tensor(self._cell_xy(cells), dtype=DTYPE)  # [n, 2]
        means, covariances, log_weights = self.gaussians()
        gaussians = torch.distributions.MultivariateNormal(means, covariance_matrix=covariances)
        score = log_weights + gaussians.log_prob(xy[:, None, :])  # [n, G]
        score = score - torch.logsumexp(score, dim=-1, keepdim=True)
        out = np.full((xy.shape[0], self.pi.shape[0]), -np.inf)  # [n, L]
        out[:, self.concepts_in_use()] = score.numpy()
        return out

    @cached_property
    def _labels(self) -> np.ndarray:
        """[N] concept of each free cell (eqs. 21-22), free_index order."""
        means, covariances, log_weights = self.gaussians()
        cell_xy = torch.as_tensor(self.grid.cell_to_world(self.grid.free_cells), dtype=DTYPE)
        best = labels_from_gaussians(cell_xy, means, covariances, log_weights)  # [N] in [0, G)
        return self.concepts_in_use()[best.numpy()]

    def label_image(self) -> np.ndarray:
        """[H, W] int64 concept argmax_l pi_l N(x_cell | mu_l, Sigma_l) of every free cell
        (paper eqs. 21-22), -1 elsewhere (map image row order)."""
        image = np.full(self.grid.shape, -1, dtype=np.int64)  # [H, W]
        image[self.grid.free] = self._labels  # free cells in raster = free_index order
        return image

    # -- words ---------------------------------------------------------------------------------

    def concept_given_word(self, word: str) -> np.ndarray:
        """[L] p(C = l | word) proportional to pi_l w_{l,word} (eq. 19 analogue), over the
        concepts that label at least one free cell (0 for the others)."""
        v = word_index(self.vocabulary, word)
        labelling = np.bincount(self._labels, minlength=self.pi.shape[0]) > 0  # [L] bool
        score = np.where(labelling, self.pi * self.w[:, v], 0.0)  # [L]
        return score / score.sum()

    def region(self, word: str) -> np.ndarray:
        """[H, W] bool: the cells labelled with argmax_l pi_l w_{l,word} (eq. 19 analogue).

        Raises :class:`~spcopyro.results.UnknownWordError` (a KeyError) for a word outside
        :attr:`vocabulary`.
        """
        concept = int(np.argmax(self.concept_given_word(word)))
        return self.label_image() == concept

    def word_distribution(self, cells: np.ndarray) -> np.ndarray:
        """[n, V] p(word | cell) = sum_l p(C = l | x_cell) w_l for ``[n]`` int free-cell indices
        (``grid.free_index`` order; :meth:`cell_log_posterior`); rows sum to 1."""
        posterior = np.exp(self.cell_log_posterior(cells))  # [n, L]
        return posterior @ self.w  # [n, V]


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
    word_weighting: WordWeighting = "count",
    pair_distance: float = DEFAULT_PAIR_DISTANCE,
) -> SpCoAResult:
    """Fit the SpCoA-style mixture to ``house`` by ``iterations`` blocked Gibbs sweeps.

    Starts from uniformly random assignments (drawn from ``torch.Generator().manual_seed(seed)``,
    so a seed gives the same result every time), then alternates (C5) and the conjugate draws of
    the globals; keeps the assignments of highest collapsed log joint. The hyperparameters are
    those of :class:`SpCoAHyperparameters`; ``feature_scaling`` turns each image histogram into
    counts (:func:`spcopyro.data.scale_features`: the default 10 gives an image the weight of
    ten class draws), ``word_weighting`` is ``"count"`` or ``"tfidf"`` (eq. 20) and
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
    labels of :func:`spcopyro.gibbs.init.labels_from_gaussians` (indices into the G <= L
    Gaussians) are valid concepts.

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
