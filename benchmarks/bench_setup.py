"""The problems ``benchmarks/gibbs.py`` times, and how it times a backend and the per-cell loop."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from machine import progress
from reference_loop import PerCellProblem, PerCellState, per_cell_sweep

from spcopyro.config import SpCoConfig, SpCoSettings
from spcopyro.data import House, load_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs import GibbsState, init
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.model import ModelData
from spcopyro.synthetic import HouseSpec, make_house

HEADLINE_HOUSE = "room2ldk4"
HEADLINE_SIDE = 180  # a synthetic stand-in of ~28k free cells when the dataset is absent
SEED = 0


# ---------------------------------------------------------------------------------------------
# Problems
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Problem:
    """A house turned into the model's tensors for one configuration (and the sweep's
    ``unobserved_refresh``, :class:`~spcopyro.gibbs.options.GibbsOptions`)."""

    name: str
    data: ModelData
    config: SpCoConfig
    truth: np.ndarray | None  # [N] int64 ground-truth category per free cell, -1 unlabelled
    unobserved_refresh: float = 1.0


def make_problem(house: House, settings: SpCoSettings, unobserved_refresh: float = 1.0) -> Problem:
    """Per-cell counts and model tensors of ``house`` under ``settings``."""
    _, data = prepare_model_data(house, settings)
    truth = None if house.truth is None else house.truth[house.grid.free]  # [N] raster order
    return Problem(house.name, data, settings.model, truth, unobserved_refresh)


def synthetic_house(side: int, seed: int = SEED) -> House:
    """A ``side x side`` synthetic house with rooms of the default size."""
    return make_house(seed=seed, spec=HouseSpec.scaled(side, side), name=f"synthetic{side}")


def load_headline_house(dataset: Path | None) -> House:
    """room2ldk4 from the dataset, or a synthetic stand-in of similar size when it is absent."""
    if dataset is not None:
        return load_house(dataset / HEADLINE_HOUSE)
    return synthetic_house(HEADLINE_SIDE)


def embedded_default_house(seed: int = 0) -> House:
    """The house ``spcopyro fit`` fits when given no house folder (``--seed`` 0): what a whole
    fit without the dataset is compared with, not the headline house's stand-in."""
    return make_house(seed=seed, spec=HouseSpec.embedded())


# ---------------------------------------------------------------------------------------------
# The per-cell baseline
# ---------------------------------------------------------------------------------------------


def time_per_cell(problem: Problem, sweeps: int, seed: int = SEED) -> dict[str, Any]:
    """Seconds per iteration (median) of :func:`per_cell_sweep`, from the backends' start state."""
    generator = torch.Generator().manual_seed(seed)
    start = init(problem.data, problem.config, generator)
    state = PerCellState(
        *(t.numpy().copy() for t in (start.labels, start.log_pi, start.log_theta, start.log_w))
    )
    arrays = PerCellProblem.from_model_data(problem.data)
    rng = np.random.default_rng(seed)
    times = []
    for _ in range(sweeps):
        t0 = time.perf_counter()
        state = per_cell_sweep(state, arrays, problem.config, rng)
        times.append(time.perf_counter() - t0)
    return {
        "sweeps": sweeps,
        "seconds_per_iteration": float(np.median(times)),
        "seconds_mean": float(np.mean(times)),
        "seconds_each": [float(t) for t in times],
    }


# ---------------------------------------------------------------------------------------------
# The library's backends
# ---------------------------------------------------------------------------------------------


def time_backend(
    problem: Problem,
    backend: str,
    *,
    warmup: int,
    sweeps: int | None = None,
    budget_s: float | None = None,
    seed: int = SEED,
) -> dict[str, Any]:
    """Milliseconds per iteration (label sweep + global draws) of one backend's sweep
    (:meth:`~spcopyro.gibbs.backends.SweepBackend.sweep`, with ``problem.unobserved_refresh``).

    ``warmup`` sweeps first (the first one, which includes any JIT compilation, is reported
    separately), then either ``sweeps`` timed sweeps or as many as fit in ``budget_s`` seconds
    (at least 3). ``ms_per_iteration`` is the median sweep (robust to other processes taking the
    CPU for a moment; the mean, min and max are kept too). Times the backend's sweep alone: no
    log joint, no trace (see the headline run for :func:`run_gibbs` as a user calls it).
    """
    if (sweeps is None) == (budget_s is None):
        raise ValueError("time_backend: give exactly one of sweeps and budget_s")
    sweep = get_backend(backend).sweep
    data, config, refresh = problem.data, problem.config, problem.unobserved_refresh
    generator = torch.Generator().manual_seed(seed)
    plan = make_sweep_plan(data)
    state: GibbsState = init(data, config, generator)
    first_sweep_s = math.nan
    for k in range(max(warmup, 1)):
        t0 = time.perf_counter()
        state = sweep(state, data, config, generator, plan, refresh)
        if k == 0:
            first_sweep_s = time.perf_counter() - t0
    times: list[float] = []
    started = time.perf_counter()
    while True:
        t0 = time.perf_counter()
        state = sweep(state, data, config, generator, plan, refresh)
        times.append(time.perf_counter() - t0)
        if sweeps is not None and len(times) >= sweeps:
            break
        if budget_s is not None and len(times) >= 3 and time.perf_counter() - started >= budget_s:
            break
    ms = 1e3 * np.asarray(times)
    median = float(np.median(ms))
    return {
        "sweeps": len(times),
        "ms_per_iteration": median,
        "ms_mean": float(ms.mean()),
        "ms_min": float(ms.min()),
        "ms_max": float(ms.max()),
        "first_sweep_ms": 1e3 * first_sweep_s,
        "ns_per_cell": median * 1e6 / data.num_free,
    }


def _try(what: str, action: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """Run one measurement; a failure is reported (stderr and the JSON), not raised."""
    try:
        return action()
    except Exception as error:  # noqa: BLE001 - one broken backend must not end the benchmark
        message = f"{type(error).__name__}: {error}"
        progress(f"  FAILED {what}: {message}")
        return {"error": message}
