"""The benchmark's baseline: one iteration of Algorithm 1 as a per-cell Python loop (numpy).

:func:`per_cell_sweep` is a straightforward implementation of the sweep the library vectorises:
a Python loop over the free cells in raster order, as the released code works, each cell's label
drawn from eq. (13) given the labels drawn so far, then pi, theta and w from eqs. (14)-(17).
``benchmarks/gibbs.py`` times it against the library's sweep backends.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from spcopyro.config import SpCoConfig
from spcopyro.model import ModelData


class PerCellState(NamedTuple):
    """The baseline's chain state (numpy). N cells, L concepts, K classes, V words."""

    labels: np.ndarray  # [N] int64
    log_pi: np.ndarray  # [L] float64
    log_theta: np.ndarray  # [L, K] float64
    log_w: np.ndarray  # [L, V] float64


@dataclass(frozen=True)
class PerCellProblem:
    """The map and observations as plain numpy arrays (M observed cells)."""

    neighbours: np.ndarray  # [N, D] int64, -1 where no free neighbour
    obs_cells: np.ndarray  # [M] int64 free index of each observed cell
    obs_row: np.ndarray  # [N] int64 row of each cell in the count arrays, -1 if unobserved
    image_counts: np.ndarray  # [M, K] float64
    word_counts: np.ndarray  # [M, V] float64

    @classmethod
    def from_model_data(cls, data: ModelData) -> PerCellProblem:
        return cls(
            neighbours=data.neighbours.numpy().copy(),
            obs_cells=data.obs_cells.numpy().copy(),
            obs_row=data.observation_rows().numpy().copy(),
            image_counts=data.image_counts.numpy().copy(),
            word_counts=data.word_counts.numpy().copy(),
        )


def _log_dirichlet_rows(concentration: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """log p, p ~ Dir(concentration) along the last axis (normalised gamma draws)."""
    gammas = rng.standard_gamma(concentration)
    log_g = np.log(np.maximum(gammas, np.finfo(np.float64).tiny))
    peak = log_g.max(axis=-1, keepdims=True)
    return log_g - (peak + np.log(np.exp(log_g - peak).sum(axis=-1, keepdims=True)))


def per_cell_sweep(
    state: PerCellState, problem: PerCellProblem, config: SpCoConfig, rng: np.random.Generator
) -> PerCellState:
    """One iteration of Algorithm 1, cell by cell: the benchmark's baseline.

    For each free cell i in raster order (free-index order), with the labels drawn so far::

        logits_l = log pi_l + gamma * #{j ~ i : C_j = l} + [i observed] loglik(i, l)   (eq. 13)
        C_i ~ softmax(logits)

    where loglik(i, l) = sum_k f_ik log theta_lk + sum_v S_iv log w_lv is computed once per sweep
    for the observed cells (a [M, L] matrix product); the L-vector work per cell is numpy, the
    loop over cells is Python. Then pi, theta and w are drawn from eqs. (14)-(17) by normalised
    gamma variates. Returns the new state; ``state`` is not modified.
    """
    L = config.num_concepts
    gamma = float(config.gamma)
    log_pi = state.log_pi  # [L]
    loglik = np.zeros((problem.obs_cells.shape[0], L))  # [M, L]
    if config.use_images:
        loglik += problem.image_counts @ state.log_theta.T
    if config.use_words:
        loglik += problem.word_counts @ state.log_w.T
    labels = state.labels.copy()  # [N]
    neighbours = problem.neighbours.tolist()  # N lists of D ints
    obs_row = problem.obs_row.tolist()  # [N]
    uniforms = rng.random(labels.shape[0])  # [N]
    for i, cell_neighbours in enumerate(neighbours):
        logits = log_pi.copy()  # [L]
        for j in cell_neighbours:
            if j >= 0:
                logits[labels[j]] += gamma
        row = obs_row[i]
        if row >= 0:
            logits += loglik[row]
        weights = np.exp(logits - logits.max())  # [L]
        cdf = np.cumsum(weights)  # [L]
        labels[i] = min(int(np.searchsorted(cdf, uniforms[i] * cdf[-1], side="right")), L - 1)

    cells_per_concept = np.bincount(labels, minlength=L).astype(np.float64)  # [L]
    observed_labels = labels[problem.obs_cells]  # [M]
    images = np.zeros((L, problem.image_counts.shape[1]))  # [L, K]
    words = np.zeros((L, problem.word_counts.shape[1]))  # [L, V]
    if config.use_images:
        np.add.at(images, observed_labels, problem.image_counts)
    if config.use_words:
        np.add.at(words, observed_labels, problem.word_counts)
    return PerCellState(
        labels=labels,
        log_pi=_log_dirichlet_rows(config.pi_concentration + cells_per_concept, rng),
        log_theta=_log_dirichlet_rows(config.chi + images, rng),
        log_w=_log_dirichlet_rows(config.beta + words, rng),
    )
