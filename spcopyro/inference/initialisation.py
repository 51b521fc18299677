r"""Starting labels for any inference method: random, given, or from per-concept Gaussians.

The Gaussian start is the paper's pre-learning initialisation (Section 5, eqs. 21-22): given
Gaussians N(mu_l, Sigma_l) over positions (from a spatial-concept model learnt beforehand), every
free cell starts in

.. math::

    C_{ij} = \arg\max_l \; \log \phi_l + \log \mathcal{N}(x_{ij} \mid \mu_l, \Sigma_l),

x_ij being the cell centre's world position. :func:`kmeans_gaussians` provides such Gaussians
without a pre-learnt model (k-means on the observation positions); a spatial-concept learner can
pass its own to :func:`labels_from_gaussians`.

These helpers depend on neither the sampler nor its state: the Gibbs start
(:func:`spcopyro.gibbs.sampler.init`) and the SpCoA baseline
(:mod:`spcopyro.baselines.spcoa`, which labels map cells with :func:`labels_from_gaussians`)
both use them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from spcopyro._util.messages import setting
from spcopyro.inference.names import INITS
from spcopyro.model import DTYPE

if TYPE_CHECKING:
    from spcopyro.config import SpCoConfig

__all__ = [
    "INITS", "check_labels", "kmeans_gaussians", "labels_from_gaussians", "more_concepts_remedy",
    "random_labels",
]  # fmt: skip


def random_labels(num_free: int, config: SpCoConfig, generator: torch.Generator) -> torch.Tensor:
    """[N] labels drawn uniformly from the L concepts."""
    return torch.randint(config.num_concepts, (num_free,), generator=generator)


def check_labels(labels: torch.Tensor, num_free: int, config: SpCoConfig) -> torch.Tensor:
    """Validate a user-given [N] label vector (free-index order) and return it as int64."""
    labels = torch.as_tensor(labels)
    if labels.shape != (num_free,):
        raise ValueError(f"initial labels must have shape ({num_free},), got {tuple(labels.shape)}")
    if torch.is_floating_point(labels) or labels.dtype == torch.bool:
        raise ValueError(f"initial labels must be integers, got {labels.dtype}")
    labels = labels.to(torch.long)
    if labels.numel() and (labels.min() < 0 or labels.max() >= config.num_concepts):
        beyond = labels.min() >= 0  # only too high: more concepts, or renumbered, would do
        remedy = f": {more_concepts_remedy(labels, config.num_concepts, _TENSOR)}" if beyond else ""
        raise ValueError(
            f"initial labels must lie in [0, {config.num_concepts}), "
            f"got values in [{int(labels.min())}, {int(labels.max())}]{remedy}"
        )
    return labels


_TENSOR = "torch.unique(labels, return_inverse=True)[1]"
"""How a start given as labels is renumbered to its concepts' ranks (:func:`check_labels`)."""


def more_concepts_remedy(labels: object, num_concepts: int, renumber: str) -> str:
    """What to do about a start whose labels (``[N]``, NumPy or torch, none negative) use a
    concept >= ``num_concepts``: fit with as many concepts as its highest number needs, e.g.
    ``"fit with num_concepts=120 (fit's --concepts 120) or more"``, or, when its distinct
    concepts are no more than ``num_concepts``, renumber them to 0..k-1 (``renumber``: how,
    e.g. the package's :func:`~spcopyro.results.renumber.renumbered` for a fit's result)."""
    used = torch.unique(torch.as_tensor(labels))  # [k] ascending
    need = int(used.max()) + 1
    text = f"fit with {setting(f'num_concepts={need}', f'--concepts {need}')} or more"
    if len(used) <= num_concepts:
        text += f", or renumber its {len(used)} concepts to 0..{len(used) - 1} ({renumber})"
    return text


def labels_from_gaussians(
    cell_xy: torch.Tensor,
    means: torch.Tensor,
    covariances: torch.Tensor,
    log_weights: torch.Tensor | None = None,
) -> torch.Tensor:
    """[N] argmax_l log phi_l + log N(x_i | mu_l, Sigma_l) (eqs. 21-22).

    Args:
        cell_xy: [N, 2] world positions of the free cells.
        means: [G, 2]; covariances: [G, 2, 2]; log_weights: [G] (uniform if None).
    """
    gaussians = torch.distributions.MultivariateNormal(
        means.to(DTYPE), covariance_matrix=covariances.to(DTYPE)
    )
    log_density = gaussians.log_prob(cell_xy.to(DTYPE)[:, None, :])  # [N, G]
    if log_weights is not None:
        log_density = log_density + log_weights.to(DTYPE)
    return log_density.argmax(-1)


def kmeans_gaussians(
    points: torch.Tensor,
    num_clusters: int,
    generator: torch.Generator,
    iterations: int = 25,
    min_variance: float = 0.05,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Gaussians (means [G, 2], covariances [G, 2, 2], log weights [G]) from k-means of points.

    A stand-in for spatial-concept pre-learning. ``min_variance`` (m^2) keeps covariances of
    clusters with few or collinear points well conditioned. G = min(num_clusters, #points).
    """
    points = points.to(DTYPE)  # [T, 2]
    G = min(num_clusters, points.shape[0])
    if G < 1:
        raise ValueError("k-means initialisation needs at least one observation position")
    centres = points[torch.randperm(points.shape[0], generator=generator)[:G]].clone()  # [G, 2]
    for _ in range(iterations):
        assign = torch.cdist(points, centres).argmin(-1)  # [T]
        sums = torch.zeros_like(centres).index_add_(0, assign, points)
        sizes = torch.bincount(assign, minlength=G).to(DTYPE)  # [G]
        centres = torch.where(sizes[:, None] > 0, sums / sizes.clamp_min(1)[:, None], centres)
    assign = torch.cdist(points, centres).argmin(-1)
    sizes = torch.bincount(assign, minlength=G).to(DTYPE)
    diffs = points - centres[assign]  # [T, 2]
    outer = diffs[:, :, None] * diffs[:, None, :]  # [T, 2, 2]
    scatter = torch.zeros(G, 2, 2, dtype=DTYPE).index_add_(0, assign, outer)
    covariances = scatter / sizes.clamp_min(1)[:, None, None] + min_variance * torch.eye(
        2, dtype=DTYPE
    )
    log_weights = torch.log((sizes + 1) / (sizes + 1).sum())
    return centres, covariances, log_weights
