"""Fitting SpCoMapping to a house: observations -> per-cell counts -> Gibbs run -> result.

This is what ``spcopyro fit`` runs; each step is a public function of its own module, so a user
can replace any of them (see :func:`fit_house`'s body).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
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


def best_chain(results: Sequence[SpCoResult]) -> int:
    """Index of the chain whose MAP-visited state has the highest log joint
    (``result.best_log_joint``; the first one on ties)."""
    if not results:
        raise ValueError("best_chain needs at least one chain")
    return int(np.argmax([r.best_log_joint for r in results]))


def fit_house_chains(
    house: House,
    config: SpCoConfig,
    *,
    sweeps: int = 5000,
    seeds: Sequence[int] = (0,),
    init: str = "random",
    backend: str = "auto",
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    progress: bool | None = None,
    anneal_sweeps: int = 0,
) -> list[SpCoResult]:
    """One :class:`SpCoResult` per seed: a chain of ``sweeps`` Gibbs iterations (Algorithm 1)
    from ``init`` drawn with that seed. The house's counts are computed once for all chains.
    See :func:`fit_house` for the arguments; :func:`best_chain` picks the one to keep."""
    if isinstance(sweeps, bool) or not isinstance(sweeps, int | np.integer) or sweeps < 1:
        raise ValueError(f"sweeps must be a positive integer or 'auto', got {sweeps!r}")
    if len(seeds) == 0:
        raise ValueError("seeds must name at least one chain")
    counts, data = prepare_model_data(house, config, snap_distance)
    results = []
    for seed in seeds:
        generator = torch.Generator().manual_seed(int(seed))
        init_labels = _initial_labels(house, counts, config, init, int(seed), generator)
        run = run_gibbs(
            data,
            config,
            sweeps,
            generator=generator,
            init_labels=init_labels,
            backend=backend,
            progress=progress,
            anneal_sweeps=anneal_sweeps,
        )
        results.append(
            SpCoResult.from_run(run, house.grid, counts.vocabulary, config, name=house.name)
        )
    return results


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
    chains: int = 1,
    anneal_sweeps: int = 0,
) -> SpCoResult:
    """Fit SpCoMapping to a house with ``sweeps`` Gibbs iterations (Algorithm 1).

    ``init``: ``"random"`` labels, ``"gaussian"`` (k-means Gaussians over the observed cells,
    eqs. 21-22) or ``"spcoa"`` (the paper's pre-learning: Gaussians of a SpCoA fit).
    ``chains``: run that many chains (seeds ``seed``, ``seed + 1``, ...) and keep the one whose
    MAP-visited state has the highest log joint ("best of K chains", the remedy for the DP
    variant's instability measured in :mod:`spcopyro.experiments.robustness`).
    ``anneal_sweeps``: ramp gamma up over the first sweeps (:mod:`spcopyro.gibbs.anneal`).
    ``sweeps="auto"``: :func:`fit_house_converged` (``chains`` chains, at least 2; 4 if
    ``chains`` is 1) until split R-hat < 1.05; the diagnostics are logged at INFO level -- call
    :func:`fit_house_converged` to get them.
    """
    if not isinstance(chains, int) or chains < 1:
        raise ValueError(f"chains must be a positive integer, got {chains!r}")
    if sweeps == "auto":
        result, diagnostics = fit_house_converged(
            house, config, chains=chains if chains > 1 else DEFAULT_CHAINS, seed=seed,
            init=init, backend=backend, snap_distance=snap_distance, progress=progress,
            anneal_sweeps=anneal_sweeps,
        )  # fmt: skip
        logger.info("--sweeps auto: %s", diagnostics.to_json())
        return result
    results = fit_house_chains(
        house, config, sweeps=sweeps, seeds=[seed + k for k in range(chains)], init=init,
        backend=backend, snap_distance=snap_distance, progress=progress,
        anneal_sweeps=anneal_sweeps,
    )  # fmt: skip
    kept = best_chain(results)
    if chains > 1:
        logger.info(
            "best of %d chains: kept chain %d (seed %d); best log joints %s", chains, kept,
            seed + kept, [round(r.best_log_joint, 1) for r in results],
        )  # fmt: skip
    return results[kept]


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
    anneal_sweeps: int = 0,
) -> tuple[SpCoResult, ConvergenceDiagnostics]:
    """Fit with ``chains`` chains (seeds ``seed``, ``seed + 1``, ...) until split R-hat of the
    log joint and of the number of concepts are below ``threshold``, or ``max_sweeps`` sweeps
    (:func:`spcopyro.gibbs.convergence.run_until_converged`). Returns the chain of highest log
    joint as the result, and the diagnostics. Chain k starts from ``init`` drawn with seed
    ``seed + k``; ``anneal_sweeps`` of gamma annealing come first (burn-in).
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
        anneal_sweeps=anneal_sweeps,
    )  # fmt: skip
    result = SpCoResult.from_run(run, house.grid, counts.vocabulary, config, name=house.name)
    return result, diagnostics
