r"""The fitted SpCoA baseline and the semantic map it makes (paper eqs. 21-22).

Each free cell, at world position x_ij (its centre), gets the concept
argmax_l log pi_l + log N(x_ij | mu_l, Sigma_l) over the concepts that hold at least one event
(exactly :func:`spcopyro.inference.initialisation.labels_from_gaussians`); these Gaussians are also
the pre-learning initialisation of SpCoMapping (paper Section 5):
:func:`~spcopyro.baselines.spcoa.spcoa_gaussians`.
"Where is WORD?" is the eq. (19) analogue argmax_l pi_l w_{l,WORD}, taken over the concepts that
label at least one cell, and p(word | cell) = sum_l p(l | x_cell) w_l with
p(l | x) proportional to pi_l N(x | mu_l, Sigma_l).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import torch

from spcopyro.inference.initialisation import labels_from_gaussians
from spcopyro.maps import OccupancyGrid
from spcopyro.model import DTYPE
from spcopyro.results.semantic_map import word_index

if TYPE_CHECKING:
    from spcopyro.baselines.spcoa.events import SpCoAData
    from spcopyro.baselines.spcoa.hyperparameters import SpCoAHyperparameters

__all__ = ["SpCoAResult"]


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

        Raises :class:`~spcopyro.results.semantic_map.UnknownWordError` (a KeyError) for a word
        outside
        :attr:`vocabulary`.
        """
        concept = int(np.argmax(self.concept_given_word(word)))
        return self.label_image() == concept

    def word_distribution(self, cells: np.ndarray) -> np.ndarray:
        """[n, V] p(word | cell) = sum_l p(C = l | x_cell) w_l for ``[n]`` int free-cell indices
        (``grid.free_index`` order; :meth:`cell_log_posterior`); rows sum to 1."""
        posterior = np.exp(self.cell_log_posterior(cells))  # [n, L]
        return posterior @ self.w  # [n, V]
