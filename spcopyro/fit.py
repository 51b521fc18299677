"""Fitting SpCoMapping to a house: observations -> per-cell counts -> inference -> result.

This is what ``spcopyro fit`` runs; each step is a public function of its own module, so a user
can replace any of them (see :func:`fit_house_chains`' body). The inference method is looked up
by name in :mod:`spcopyro.registry` (``"gibbs"``: Algorithm 1); ``--sweeps auto``
(:func:`fit_house_converged`) is Gibbs-specific.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import torch

from spcopyro.config import WORDS, SpCoConfig, SpCoSettings, preset
from spcopyro.data import CellCounts, House, cell_counts
from spcopyro.gibbs.convergence import (
    DEFAULT_BLOCK,
    DEFAULT_CHAINS,
    DEFAULT_MAX_SWEEPS,
    DEFAULT_THRESHOLD,
    ConvergenceDiagnostics,
    run_until_converged,
)
from spcopyro.gibbs.method import output_from_run
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.inference import InferenceOutput
from spcopyro.initialisation import kmeans_gaussians, labels_from_gaussians
from spcopyro.model import DTYPE, ModelData, make_model_data
from spcopyro.registry import DEFAULT_METHOD, get_method
from spcopyro.results import SpCoResult
from spcopyro.threads import AUTO, describe_threads, resolve_threads, torch_threads

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


def spcoa_initial_labels(house: House, settings: SpCoSettings, seed: int) -> torch.Tensor:
    """[N] labels from spatial-concept pre-learning (paper Section 5, eqs. 21-22): the Gaussians
    of a SpCoA fit (:func:`spcopyro.baselines.spcoa.spcoa_gaussians`), at most L of them."""
    from spcopyro.baselines.spcoa import spcoa_gaussians

    cell_xy = free_cell_positions(house)  # [N, 2]
    means, covariances, log_weights = spcoa_gaussians(
        house, num_concepts=settings.model.num_concepts, seed=seed,
        word_weighting=settings.data.word_weighting,
    )  # fmt: skip
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


def prepare_model_data(house: House, settings: SpCoSettings) -> tuple[CellCounts, ModelData]:
    """Per-cell counts of the house under the settings' data preparation, and the model's
    tensors (warns, through the logger, when gamma is below the critical coupling)."""
    warning = gamma_warning(settings.model)
    if warning:
        logger.warning(warning)
    counts = cell_counts(
        house.grid,
        house.observations,
        feature_scaling=settings.data.feature_scaling,
        word_weighting=settings.data.word_weighting,
        snap_distance=settings.data.snap_distance,
    )
    data = make_model_data(house.grid, counts, settings.model.connectivity)
    for modality in data.modalities:
        settings.model.concentration(modality.name)  # ValueError if a further one has none
    return counts, data


def modality_items(counts: CellCounts, data: ModelData) -> dict[str, tuple[str, ...]]:
    """The item names of each modality: the vocabulary for words, each further modality's
    item names (images keep their class numbers)."""
    items = {WORDS: tuple(counts.vocabulary)}
    for modality in getattr(counts, "modalities", ()):
        items[modality.name] = tuple(modality.items)
    return {m.name: items[m.name] for m in data.modalities if m.name in items}


def result_of(
    output: InferenceOutput,
    house: House,
    counts: CellCounts,
    data: ModelData,
    settings: SpCoSettings,
    method: str,
) -> SpCoResult:
    """The :class:`SpCoResult` of an inference output on ``house``."""
    return SpCoResult.from_output(
        output, house.grid, modality_items(counts, data), settings.model,
        modalities=tuple(m.name for m in data.modalities), method=method,
        preparation=settings.data, name=house.name,
    )  # fmt: skip


def initial_labels(
    house: House,
    counts: CellCounts,
    settings: SpCoSettings,
    init: str,
    seed: int,
    generator: torch.Generator,
) -> torch.Tensor | None:
    """[N] starting labels: None for ``"random"`` (the method draws them), else ``"gaussian"``
    (k-means Gaussians over the observed cells) or ``"spcoa"`` (a SpCoA fit's Gaussians)."""
    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    if init == "gaussian":
        return gaussian_initial_labels(house, counts, settings.model, generator)
    if init == "spcoa":
        return spcoa_initial_labels(house, settings, seed)
    return None


def best_chain(results: Sequence[SpCoResult]) -> int:
    """Index of the chain whose point estimate has the highest objective
    (``result.best_objective``: the MAP-visited state's log joint for Gibbs; the first on ties)."""
    if not results:
        raise ValueError("best_chain needs at least one chain")
    return int(np.argmax([r.best_objective for r in results]))


def fit_house_chains(
    house: House,
    settings: SpCoSettings | None = None,
    *,
    method: str = DEFAULT_METHOD,
    options: object | None = None,
    sweeps: int = 5000,
    seeds: Sequence[int] = (0,),
    init: str = "random",
    progress: bool | None = None,
    threads: int | str | None = AUTO,
) -> list[SpCoResult]:
    """One :class:`SpCoResult` per seed: ``sweeps`` iterations of the inference method from
    ``init`` drawn with that seed. The house's counts are computed once for all chains. See
    :func:`fit_house` for the arguments; :func:`best_chain` picks the one to keep."""
    if isinstance(sweeps, bool) or not isinstance(sweeps, int | np.integer) or sweeps < 1:
        raise ValueError(f"sweeps must be a positive integer or 'auto', got {sweeps!r}")
    if len(seeds) == 0:
        raise ValueError("seeds must name at least one chain")
    settings = preset() if settings is None else settings
    inference = get_method(method)
    count = resolve_threads(threads, house.grid.num_free)
    counts, data = prepare_model_data(house, settings)
    logger.info("threads: %s", describe_threads(threads, house.grid.num_free))
    fits = []
    with torch_threads(count):
        for seed in seeds:
            generator = torch.Generator().manual_seed(int(seed))
            start = initial_labels(house, counts, settings, init, int(seed), generator)
            output = inference.run(
                data, settings.model, iterations=int(sweeps), generator=generator,
                init_labels=start, options=options, progress=progress,
            )  # fmt: skip
            output.options.update(seed=int(seed), init=init)
            fits.append(result_of(output, house, counts, data, settings, method))
    return fits


def fit_house(
    house: House,
    settings: SpCoSettings | None = None,
    *,
    method: str = DEFAULT_METHOD,
    options: object | None = None,
    sweeps: int | str = 5000,
    seed: int = 0,
    init: str = "random",
    progress: bool | None = None,
    chains: int = 1,
    threads: int | str | None = AUTO,
) -> SpCoResult:
    """Fit SpCoMapping to a house.

    Args:
        settings: model hyperparameters and data preparation (default: :func:`preset`'s).
        method: the inference method's name in :mod:`spcopyro.registry` (``"gibbs"``).
        options: the method's options (``GibbsOptions`` for Gibbs; None for its defaults).
        sweeps: iterations (Gibbs sweeps), or ``"auto"`` for Gibbs: :func:`fit_house_converged`
            (``chains`` chains, at least 2; 4 if ``chains`` is 1) until split R-hat < 1.05;
            the diagnostics are logged at INFO level -- call :func:`fit_house_converged` to get
            them.
        init: ``"random"`` labels, ``"gaussian"`` (k-means Gaussians over the observed cells,
            eqs. 21-22) or ``"spcoa"`` (the paper's pre-learning: Gaussians of a SpCoA fit).
        chains: run that many chains (seeds ``seed``, ``seed + 1``, ...) and keep the one whose
            point estimate has the highest objective ("best of K chains", the remedy for the DP
            variant's instability measured in :mod:`spcopyro.experiments.robustness`).
        threads: torch intra-op threads during the fit (:mod:`spcopyro.threads`): ``"auto"`` (one
            thread unless the map is large), 0 or None (torch's own setting), or a count. The
            previous setting is restored afterwards; labels do not depend on it.
    """
    if not isinstance(chains, int) or chains < 1:
        raise ValueError(f"chains must be a positive integer, got {chains!r}")
    if sweeps == "auto":
        if method != "gibbs":
            raise ValueError(f"sweeps='auto' is Gibbs' convergence rule, not {method!r}'s")
        result, diagnostics = fit_house_converged(
            house, settings, options=options, chains=chains if chains > 1 else DEFAULT_CHAINS,
            seed=seed, init=init, progress=progress, threads=threads,
        )  # fmt: skip
        logger.info("--sweeps auto: %s", diagnostics.to_json())
        return result
    results = fit_house_chains(
        house, settings, method=method, options=options, sweeps=sweeps,
        seeds=[seed + k for k in range(chains)], init=init, progress=progress, threads=threads,
    )  # fmt: skip
    kept = best_chain(results)
    if chains > 1:
        logger.info(
            "best of %d chains: kept chain %d (seed %d); best objectives %s", chains, kept,
            seed + kept, [round(r.best_objective, 1) for r in results],
        )  # fmt: skip
    return results[kept]


def fit_house_converged(
    house: House,
    settings: SpCoSettings | None = None,
    *,
    options: GibbsOptions | None = None,
    chains: int = DEFAULT_CHAINS,
    block: int = DEFAULT_BLOCK,
    max_sweeps: int = DEFAULT_MAX_SWEEPS,
    threshold: float = DEFAULT_THRESHOLD,
    seed: int = 0,
    init: str = "random",
    progress: bool | None = None,
    threads: int | str | None = AUTO,
) -> tuple[SpCoResult, ConvergenceDiagnostics]:
    """Fit by Gibbs sampling with ``chains`` chains (seeds ``seed``, ``seed + 1``, ...) until
    split R-hat of the log joint and of the number of concepts are below ``threshold``, or
    ``max_sweeps`` sweeps (:func:`spcopyro.gibbs.convergence.run_until_converged`). Returns the
    chain of highest log joint as the result, and the diagnostics. Chain k starts from ``init``
    drawn with seed ``seed + k``; ``options.anneal_sweeps`` of gamma annealing come first.
    ``threads``: as for :func:`fit_house`.
    """
    settings = preset() if settings is None else settings
    options = GibbsOptions() if options is None else options
    count = resolve_threads(threads, house.grid.num_free)
    counts, data = prepare_model_data(house, settings)
    logger.info("threads: %s", describe_threads(threads, house.grid.num_free))
    with torch_threads(count):
        starts = []
        for k in range(chains):
            generator = torch.Generator().manual_seed(int(seed + k))
            starts.append(initial_labels(house, counts, settings, init, seed + k, generator))
        run, diagnostics = run_until_converged(
            data, settings.model, options=options, chains=chains, block=block,
            max_sweeps=max_sweeps, threshold=threshold, seed=seed, init_labels=starts,
            progress=progress,
        )  # fmt: skip
    record = {
        "sweeps": "auto", "chains": chains, "seed": seed, "init": init,
        **{k: v for k, v in vars(options).items()},
    }  # fmt: skip
    output = output_from_run(run, record)
    return result_of(output, house, counts, data, settings, "gibbs"), diagnostics
