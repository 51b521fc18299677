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
from spcopyro.gibbs.convergence import (
    DEFAULT_BLOCK,
    DEFAULT_CHAINS,
    DEFAULT_MAX_SWEEPS,
    DEFAULT_THRESHOLD,
    ConvergenceDiagnostics,
    run_until_converged,
)
from spcopyro.gibbs.init import kmeans_gaussians, labels_from_gaussians
from spcopyro.model import DTYPE, ModelData, make_model_data
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


def free_cell_positions(house: House) -> torch.Tensor:
    """[N, 2] world (x, y) of every free cell's centre, in free-index order."""
    grid = house.grid
    return torch.as_tensor(grid.cell_to_world(grid.free_cells), dtype=DTYPE)


def gaussian_initial_labels(
    house: House, counts: CellCounts, config: SpCoConfig, generator: torch.Generator
) -> torch.Tensor:
    """[N] labels from Gaussians over the positions of the observed cells (eqs. 21-22).

    A stand-in for spatial-concept pre-learning: k-means with k = L on the observed cells'
    centres, then each free cell takes its most probable Gaussian.
    """
    cell_xy = free_cell_positions(house)  # [N, 2]
    points = cell_xy[torch.as_tensor(counts.cells)]  # [M, 2]
    means, covariances, log_weights = kmeans_gaussians(points, config.num_concepts, generator)
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


def spcoa_initial_labels(house: House, config: SpCoConfig, seed: int) -> torch.Tensor:
    """[N] labels from spatial-concept pre-learning (paper Section 5, eqs. 21-22): the Gaussians
    of a SpCoA fit (:func:`spcopyro.baselines.spcoa.spcoa_gaussians`), at most L of them."""
    from spcopyro.baselines.spcoa import spcoa_gaussians

    cell_xy = free_cell_positions(house)  # [N, 2]
    means, covariances, log_weights = spcoa_gaussians(
        house, num_concepts=config.num_concepts, seed=seed, word_weighting=config.word_weighting
    )
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


def prepare_model_data(
    house: House, config: SpCoConfig, snap_distance: float
) -> tuple[CellCounts, ModelData]:
    """Per-cell counts of the house under the config's scaling/weighting, and the model's tensors
    (warns, through the logger, when gamma is below the critical coupling)."""
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
    return counts, make_model_data(house.grid, counts, config.connectivity)


def _initial_labels(
    house: House,
    counts: CellCounts,
    config: SpCoConfig,
    init: str,
    seed: int,
    generator: torch.Generator,
) -> torch.Tensor | None:
    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    if init == "gaussian":
        return gaussian_initial_labels(house, counts, config, generator)
    if init == "spcoa":
        return spcoa_initial_labels(house, config, seed)
    return None


def fit_house(
    house: House,
    config: SpCoConfig,
    *,
    sweeps: int | str = 5000,
    seed: int = 0,
    init: str = "random",
    backend: str = "auto",
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    progress: bool | None = None,
) -> SpCoResult:
    """Fit SpCoMapping to a house with ``sweeps`` Gibbs iterations (Algorithm 1).

    ``init``: ``"random"`` labels, ``"gaussian"`` (k-means Gaussians over the observed cells,
    eqs. 21-22) or ``"spcoa"`` (the paper's pre-learning: Gaussians of a SpCoA fit).
    ``sweeps="auto"``: :func:`fit_house_converged` with its defaults (4 chains, stop at split
    R-hat < 1.05); the diagnostics are logged at INFO level -- call :func:`fit_house_converged`
    to get them.
    """
    if sweeps == "auto":
        result, diagnostics = fit_house_converged(
            house, config, seed=seed, init=init, backend=backend,
            snap_distance=snap_distance, progress=progress,
        )  # fmt: skip
        logger.info("--sweeps auto: %s", diagnostics.to_json())
        return result
    if isinstance(sweeps, str):
        raise ValueError(f"sweeps must be a positive integer or 'auto', got {sweeps!r}")
    counts, data = prepare_model_data(house, config, snap_distance)
    generator = torch.Generator().manual_seed(int(seed))
    init_labels = _initial_labels(house, counts, config, init, seed, generator)
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


def fit_house_converged(
    house: House,
    config: SpCoConfig,
    *,
    chains: int = DEFAULT_CHAINS,
    block: int = DEFAULT_BLOCK,
    max_sweeps: int = DEFAULT_MAX_SWEEPS,
    threshold: float = DEFAULT_THRESHOLD,
    seed: int = 0,
    init: str = "random",
    backend: str = "auto",
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    progress: bool | None = None,
) -> tuple[SpCoResult, ConvergenceDiagnostics]:
    """Fit with ``chains`` chains (seeds ``seed``, ``seed + 1``, ...) until split R-hat of the
    log joint and of the number of concepts are below ``threshold``, or ``max_sweeps`` sweeps
    (:func:`spcopyro.gibbs.convergence.run_until_converged`). Returns the chain of highest log
    joint as the result, and the diagnostics. Chain k starts from ``init`` drawn with seed
    ``seed + k``.
    """
    counts, data = prepare_model_data(house, config, snap_distance)
    starts = [
        _initial_labels(
            house, counts, config, init, seed + k, torch.Generator().manual_seed(int(seed + k))
        )  # fmt: skip
        for k in range(chains)
    ]
    run, diagnostics = run_until_converged(
        data, config, chains=chains, block=block, max_sweeps=max_sweeps, threshold=threshold,
        seed=seed, init_labels=starts, backend=backend, progress=progress,
    )  # fmt: skip
    result = SpCoResult.from_run(run, house.grid, counts.vocabulary, config, name=house.name)
    return result, diagnostics
