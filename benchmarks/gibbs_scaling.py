"""``benchmarks/gibbs.py``'s scaling and quality sections: ms per sweep against the number of
free cells and against L (:func:`bench_scaling`), and the ARI of the default synthetic house
after some sweeps (:func:`bench_quality`).

Both run each map under the thread policy ``spcopyro fit`` uses (``threads="auto"``,
:func:`spcopyro._util.threads.resolve_threads`: one torch thread below
:data:`~spcopyro._util.threads.MIN_CELLS_FOR_MORE_THREADS` free cells, torch's own count above),
as the whole fits and the chains of ``gibbs.py`` do, or under ``gibbs.py --torch-threads``'s count
where it is given; each row records the count it ran with (``torch_threads``)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from bench_setup import HEADLINE_HOUSE, SEED, _try, make_problem, synthetic_house, time_backend
from gibbs_report import PRESET
from machine import progress

from spcopyro._util.threads import AUTO, resolve_threads, torch_threads
from spcopyro.config import SpCoSettings, preset
from spcopyro.data import House, load_house
from spcopyro.gibbs import GibbsOptions, GibbsState, run_gibbs
from spcopyro.synthetic import make_house

if TYPE_CHECKING:
    from gibbs import BenchSizes

__all__ = ["bench_quality", "bench_scaling"]


def bench_scaling(
    dataset: Path | None, backends: Sequence[str], sizes: BenchSizes, threads: int | str = AUTO
) -> dict[str, list[dict[str, Any]]]:
    """ms per sweep against the number of free cells (L = 120) and against L (~1e5 cells).

    A third series times the same L values on room2ldk4 (when the dataset is there): with its
    86 observed cells the O(M L (K + V)) part of a sweep is small, while the synthetic map of the
    L series has a few thousand observed cells.
    """
    series: dict[str, list[dict[str, Any]]] = {"cells": [], "num_concepts": []}
    points: list[tuple[str, str, Callable[[], House], SpCoSettings, float]] = [
        ("cells", f"{side}x{side}", lambda side=side: synthetic_house(side), preset(PRESET), 1.0)
        for side in sizes.scaling_sides
    ]
    side = sizes.scaling_l_side
    points += [
        (
            "num_concepts",
            f"{side}x{side}",
            lambda: synthetic_house(side),
            preset(PRESET, num_concepts=num_concepts),
            1.0,
        )
        for num_concepts in sizes.scaling_num_concepts
    ]
    if dataset is not None:
        # The same L values on room2ldk4, with Algorithm 1's full redraw of theta and w every
        # sweep, and redrawing the rows of concepts without observed cells in 10% of sweeps
        # (GibbsOptions.unobserved_refresh, still an exact sampler).
        for kind, refresh in (("num_concepts_house", 1.0), ("num_concepts_house_refresh", 0.1)):
            series[kind] = []
            points += [
                (
                    kind,
                    HEADLINE_HOUSE,
                    lambda: load_house(dataset / HEADLINE_HOUSE),
                    preset(PRESET, num_concepts=num_concepts),
                    refresh,
                )
                for num_concepts in sizes.scaling_num_concepts
            ]
    houses: dict[str, House] = {}
    for kind, map_name, load, settings, refresh in points:
        if map_name not in houses:
            houses = {map_name: load()}  # keep one map in memory at a time
        problem = make_problem(houses[map_name], settings, refresh)
        config = problem.config
        entry: dict[str, Any] = {
            "map": map_name,
            "free_cells": problem.data.num_free,
            "observed_cells": int(problem.data.obs_cells.shape[0]),
            "num_concepts": config.num_concepts,
            "backends": {},
        }
        with torch_threads(resolve_threads(threads, problem.data.num_free)) as used:
            entry["torch_threads"] = used
            for backend in backends:
                progress(
                    f"[scaling] {map_name}, {problem.data.num_free} cells, "
                    f"L={config.num_concepts}: {backend}, {used} torch thread(s)"
                )
                entry["backends"][backend] = _try(
                    f"scaling {map_name} L={config.num_concepts} {backend}",
                    lambda b=backend, p=problem: time_backend(
                        p, b, warmup=2, budget_s=sizes.scaling_budget_s
                    ),
                )
        series[kind].append(entry)
    return series


def bench_quality(
    backend: str, sizes: BenchSizes, threads: int | str = AUTO
) -> list[dict[str, Any]]:
    """ARI against the ground truth of the default synthetic house after some sweeps."""
    from sklearn.metrics import adjusted_rand_score

    house = make_house(seed=SEED)
    checkpoints = sorted(set(sizes.quality_checkpoints))
    results = []
    for gamma in sizes.quality_gammas:
        settings = preset(PRESET) if gamma is None else preset(PRESET, gamma=gamma)
        problem = make_problem(house, settings)
        config = problem.config
        truth = problem.truth  # [N]
        labelled = truth >= 0  # [N] bool
        saved: dict[int, np.ndarray] = {}

        def keep(sweep: int, state: GibbsState, saved: dict[int, np.ndarray] = saved) -> None:
            if sweep + 1 in checkpoints:
                saved[sweep + 1] = state.labels.numpy().copy()

        progress(f"[quality] gamma={config.gamma:g}: {checkpoints[-1]} sweeps, {backend}")
        with torch_threads(resolve_threads(threads, problem.data.num_free)) as used:
            run = run_gibbs(
                problem.data,
                config,
                checkpoints[-1],
                options=GibbsOptions(backend=backend),
                seed=SEED,
                progress=False,
                callback=keep,
            )
        points = [
            {
                "sweeps": sweeps,
                "seconds": float(run.seconds[sweeps - 1]),
                "ari": float(adjusted_rand_score(truth[labelled], saved[sweeps][labelled])),
                "concepts": int(run.num_concepts[sweeps - 1]),
            }
            for sweeps in checkpoints
        ]
        best = run.best_state.labels.numpy()
        results.append(
            {
                "gamma": config.gamma,
                "critical_gamma": config.critical_gamma,
                "num_concepts": config.num_concepts,
                "backend": backend,
                "torch_threads": used,
                "free_cells": problem.data.num_free,
                "labelled_cells": int(labelled.sum()),
                "true_categories": int(np.unique(truth[labelled]).size),
                "points": points,
                "best_sweep": run.best_sweep + 1,
                "best_ari": float(adjusted_rand_score(truth[labelled], best[labelled])),
            }
        )
    return results
