"""Fitting SpCoMapping to a house: observations -> per-cell counts -> Gibbs run -> result.

This is what ``spcopyro fit`` runs; each step is a public function of its own module, so a user
can replace any of them (see :func:`fit_house`'s body).
"""

from __future__ import annotations

import logging

import torch

from spcopyro.config import SpCoConfig
from spcopyro.data import DEFAULT_SNAP_DISTANCE, CellCounts, House, cell_counts
from spcopyro.gibbs.api import run_gibbs
from spcopyro.gibbs.init import kmeans_gaussians, labels_from_gaussians
from spcopyro.model import DTYPE, make_model_data
from spcopyro.results import SpCoResult

logger = logging.getLogger("spcopyro")

INITS = ("random", "gaussian", "spcoa")


def gamma_warning(config: SpCoConfig) -> str | None:
    """A warning when gamma is below the Potts critical coupling ln(1 + sqrt(L)), else None."""
    if config.gamma >= config.critical_gamma:
        return None
    return (
        f"gamma = {config.gamma:g} is below the Potts critical coupling ln(1 + sqrt(L)) = "
        f"{config.critical_gamma:.3f} for L = {config.num_concepts}: the MRF will not form "
        "regions (labels stay in patches of a few cells); raise --gamma or lower --concepts"
    )


def gaussian_initial_labels(
    house: House, counts: CellCounts, config: SpCoConfig, generator: torch.Generator
) -> torch.Tensor:
    """[N] labels from Gaussians over the positions of the observed cells (eqs. 21-22).

    A stand-in for spatial-concept pre-learning: k-means with k = L on the observed cells'
    centres, then each free cell takes its most probable Gaussian.
    """
    grid = house.grid
    cell_xy = torch.as_tensor(grid.cell_to_world(grid.free_cells), dtype=DTYPE)  # [N, 2]
    points = cell_xy[torch.as_tensor(counts.cells)]  # [M, 2]
    means, covariances, log_weights = kmeans_gaussians(points, config.num_concepts, generator)
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


def spcoa_initial_labels(house: House, config: SpCoConfig, seed: int) -> torch.Tensor:
    """[N] labels from spatial-concept pre-learning (paper Section 5, eqs. 21-22): the Gaussians
    of a SpCoA fit (:func:`spcopyro.baselines.spcoa.spcoa_gaussians`), at most L of them."""
    from spcopyro.baselines.spcoa import spcoa_gaussians

    grid = house.grid
    cell_xy = torch.as_tensor(grid.cell_to_world(grid.free_cells), dtype=DTYPE)  # [N, 2]
    means, covariances, log_weights = spcoa_gaussians(
        house, num_concepts=config.num_concepts, seed=seed, word_weighting=config.word_weighting
    )
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


def fit_house(
    house: House,
    config: SpCoConfig,
    *,
    sweeps: int = 5000,
    seed: int = 0,
    init: str = "random",
    backend: str = "auto",
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    progress: bool | None = None,
) -> SpCoResult:
    """Fit SpCoMapping to a house with ``sweeps`` Gibbs iterations (Algorithm 1).

    ``init``: ``"random"`` labels, ``"gaussian"`` (k-means Gaussians over the observed cells,
    eqs. 21-22) or ``"spcoa"`` (the paper's pre-learning: Gaussians of a SpCoA fit).
    """
    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    warning = gamma_warning(config)
    if warning:
        logger.warning(warning)
    counts = cell_counts(
        house.grid,
        house.observations,
        feature_scaling=config.feature_scaling,
        word_weighting=config.word_weighting,
        snap_distance=snap_distance,
    )
    data = make_model_data(house.grid, counts, config.connectivity)
    generator = torch.Generator().manual_seed(int(seed))
    if init == "gaussian":
        init_labels = gaussian_initial_labels(house, counts, config, generator)
    elif init == "spcoa":
        init_labels = spcoa_initial_labels(house, config, seed)
    else:
        init_labels = None
    run = run_gibbs(
        data,
        config,
        sweeps,
        generator=generator,
        init_labels=init_labels,
        backend=backend,
        progress=progress,
    )
    return SpCoResult.from_run(run, house.grid, counts.vocabulary, config, name=house.name)
