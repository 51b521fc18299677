#!/usr/bin/env python
r"""Performance benchmark of the SpCoMapping Gibbs sampler (paper Algorithm 1).

One *iteration* is what :func:`spcopyro.gibbs.sweep.gibbs_sweep` does: every free cell's label
drawn from its full conditional (eq. 13),

.. math::

    p(C_i = l \mid \text{rest}) \propto \pi_l \, e^{\gamma n_l(i)}
        \prod_{t \in i} \theta_{l, f_t} \, w_{l, S_t},

then pi, theta and w from their conjugate Dirichlet conditionals (eqs. 14-17). The benchmark
measures, in one run:

1. **Per house** (the five public houses, ``paper-dp``, L = 120): milliseconds per iteration of
   each sweep backend ("torch", "numba" when installed) against
   :func:`reference_loop.per_cell_sweep`, a straightforward per-cell implementation of
   Algorithm 1 (a Python loop over the free cells in raster order, as the released code works;
   ``benchmarks/reference_loop.py``), timed in the same process.
2. **Headline run**: 5000 iterations of room2ldk4 through :func:`~spcopyro.gibbs.run.run_gibbs`
   with the fastest backend, in a fresh subprocess, reporting the real wall time and the process's
   resident-set high-water mark (``ru_maxrss``).
3. **Scaling**: synthetic maps (:meth:`~spcopyro.synthetic.HouseSpec.scaled`) from ~1e4 to ~1e6
   free cells at L = 120, and L in (10, 120, 500) at ~1e5 cells: ms per sweep and ns per cell.
4. **Quality against time**: adjusted Rand index of the label map against the ground truth of the
   default synthetic house after 10, 100, 1000, 5000 sweeps, with the cumulative seconds.

Usage::

    python benchmarks/gibbs.py                       # full run (several minutes)
    python benchmarks/gibbs.py --quick               # smoke test, well under a minute
    python benchmarks/gibbs.py --backends torch --skip-baseline --out /tmp/gibbs.json

It prints a plain-text table to stdout (progress goes to stderr) and writes every number, with
machine information, to a JSON file.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import resource
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from machine import (
    available_backends,
    busy_cpu_seconds,
    format_table,
    machine_info,
    own_cpu_seconds,
    progress,
    wait_until_idle,
)
from reference_loop import PerCellProblem, PerCellState, per_cell_sweep

from spcopyro.config import SpCoConfig, SpCoSettings, preset
from spcopyro.data import House, find_dataset_root, list_houses, load_house
from spcopyro.fit import prepare_model_data
from spcopyro.gibbs import GibbsOptions, GibbsState, init, run_gibbs
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.model import ModelData
from spcopyro.synthetic import HouseSpec, make_house

HEADLINE_HOUSE = "room2ldk4"
HEADLINE_SIDE = 180  # a synthetic stand-in of ~28k free cells when the dataset is absent
PRESET = "paper-dp"
SEED = 0
KNOWN_BACKENDS = ("torch", "numba")
SCRIPT_DIR = Path(__file__).resolve().parent

# The targets on a 2-core machine.
TARGET_SPEEDUP = 300.0  # x faster per iteration than the per-cell loop
TARGET_HEADLINE_SECONDS = 15.0  # 5000 iterations of room2ldk4
TARGET_PEAK_BYTES = 1 << 30  # 1 GiB resident-set high-water mark for the headline run

MEMORY_NOTE = (
    "peak_rss is the resident-set high-water mark (getrusage(RUSAGE_SELF).ru_maxrss) of a fresh "
    "Python process that imports spcopyro (torch, pyro), loads the house, builds the model data "
    "and runs run_gibbs for the whole headline run; it includes the interpreter and the torch "
    "runtime. rss_after_import and rss_before_run are the same high-water mark read after the "
    "imports and just before run_gibbs, so peak_rss - rss_before_run bounds what the run itself "
    "added; rss_now_* are the resident set (VmRSS) right before and after run_gibbs."
)


# ---------------------------------------------------------------------------------------------
# Sizes of a full and a quick run
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BenchSizes:
    """How much work each section does."""

    house_warmup: int  # sweeps before timing a backend on a house (includes any JIT compile)
    house_sweeps: int  # timed sweeps per backend and house
    baseline_sweeps: int  # timed sweeps of the per-cell loop per house
    headline_sweeps: int  # run_gibbs sweeps of the headline run
    scaling_sides: tuple[int, ...]  # synthetic map sides (cells) for the cell-count series
    scaling_num_concepts: tuple[int, ...]  # L values of the L series
    scaling_l_side: int  # map side of the L series
    scaling_budget_s: float  # seconds of timed sweeps per scaling point (at least 3 sweeps)
    quality_checkpoints: tuple[int, ...]  # sweeps after which the ARI is taken
    quality_gammas: tuple[float | None, ...]  # None: the preset's gamma


FULL = BenchSizes(
    house_warmup=10,
    house_sweeps=200,
    baseline_sweeps=3,
    headline_sweeps=5000,
    scaling_sides=(110, 185, 334, 580, 1050),  # ~1e4, 3e4, 1e5, 3e5, 1e6 free cells
    scaling_num_concepts=(10, 120, 500),
    scaling_l_side=334,
    scaling_budget_s=2.0,
    quality_checkpoints=(10, 100, 1000, 5000),
    quality_gammas=(None, 3.0, 2.1),
)
QUICK = BenchSizes(
    house_warmup=2,
    house_sweeps=5,
    baseline_sweeps=1,
    headline_sweeps=20,
    scaling_sides=(40, 80),
    scaling_num_concepts=(10, 120),
    scaling_l_side=60,
    scaling_budget_s=0.05,
    quality_checkpoints=(5, 20),
    quality_gammas=(None,),
)


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


# ---------------------------------------------------------------------------------------------
# Sections
# ---------------------------------------------------------------------------------------------


def bench_houses(
    dataset: Path | None, backends: Sequence[str], sizes: BenchSizes, skip_baseline: bool
) -> list[dict[str, Any]]:
    """Per-house ms per iteration of every backend, the per-cell baseline and the speed-ups."""
    if dataset is None:
        return []
    settings = preset(PRESET)
    results = []
    for name in list_houses(dataset):
        problem = make_problem(load_house(dataset / name), settings)
        entry: dict[str, Any] = {
            "house": name,
            "free_cells": problem.data.num_free,
            "observed_cells": int(problem.data.obs_cells.shape[0]),
            "backends": {},
        }
        for backend in backends:
            progress(f"[houses] {name}: {backend}, {sizes.house_sweeps} sweeps")
            entry["backends"][backend] = _try(
                f"{name} {backend}",
                lambda b=backend, p=problem: time_backend(
                    p, b, warmup=sizes.house_warmup, sweeps=sizes.house_sweeps
                ),
            )
        if not skip_baseline:
            progress(f"[houses] {name}: per-cell loop, {sizes.baseline_sweeps} sweeps")
            entry["per_cell"] = time_per_cell(problem, sizes.baseline_sweeps)
        timed = {b: r for b, r in entry["backends"].items() if "error" not in r}
        if timed:
            best = min(timed, key=lambda b: timed[b]["ms_per_iteration"])
            entry["fastest_backend"] = best
            entry["projected_5000_s"] = {
                b: 5000 * r["ms_per_iteration"] / 1e3 for b, r in timed.items()
            }
            if "per_cell" in entry:
                baseline_ms = 1e3 * entry["per_cell"]["seconds_per_iteration"]
                entry["speedup"] = {
                    b: baseline_ms / r["ms_per_iteration"] for b, r in timed.items()
                }
        results.append(entry)
    return results


def _max_rss_bytes() -> int:
    """This process's resident-set high-water mark (Linux reports KiB, macOS bytes)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss) if sys.platform == "darwin" else int(rss) * 1024


def _current_rss_bytes() -> int | None:
    """This process's resident set now (Linux /proc/self/status VmRSS), else None."""
    status = Path("/proc/self/status")
    if not status.is_file():
        return None
    for line in status.read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024  # kB
    return None


def child_run(dataset: Path | None, backend: str, sweeps: int) -> dict[str, Any]:
    """The headline run, meant for a fresh process: load, run_gibbs, time and peak memory."""
    rss_after_import = _max_rss_bytes()
    t0 = time.perf_counter()
    problem = make_problem(load_headline_house(dataset), preset(PRESET))
    setup_s = time.perf_counter() - t0
    rss_before_run, rss_now_before_run = _max_rss_bytes(), _current_rss_bytes()
    t0 = time.perf_counter()
    run = run_gibbs(
        problem.data,
        problem.config,
        sweeps,
        options=GibbsOptions(backend=backend),
        seed=SEED,
        progress=False,
    )
    wall_s = time.perf_counter() - t0
    rss_now_after_run = _current_rss_bytes()
    return {
        "house": problem.name,
        "free_cells": problem.data.num_free,
        "backend": backend,
        "sweeps": sweeps,
        "setup_s": setup_s,
        "wall_s": wall_s,
        "ms_per_iteration": 1e3 * wall_s / sweeps,
        "first_sweep_s": float(run.seconds[0]),
        "after_first_sweep_s": float(run.seconds[-1] - run.seconds[0]),
        "final_concepts": int(run.num_concepts[-1]),
        "final_log_joint": float(run.log_joint[-1]),
        "rss_after_import_bytes": rss_after_import,
        "rss_before_run_bytes": rss_before_run,
        "peak_rss_bytes": _max_rss_bytes(),
        "rss_now_before_run_bytes": rss_now_before_run,
        "rss_now_after_run_bytes": rss_now_after_run,
    }


def bench_headline(dataset: Path | None, backend: str, sweeps: int) -> dict[str, Any]:
    """Run :func:`child_run` in a fresh interpreter and collect its JSON line."""
    command = [sys.executable, str(Path(__file__).resolve()), "--child-run", backend]
    command += ["--child-sweeps", str(sweeps)]
    command += ["--torch-threads", str(torch.get_num_threads())]
    if dataset is None:
        command.append("--no-dataset")
    else:
        command += ["--dataset", str(dataset)]
    progress(f"[headline] {sweeps} sweeps, backend {backend}, in a subprocess")
    t0 = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    process_s = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(
            f"headline subprocess {' '.join(command)} exited with {done.returncode}:\n"
            f"{done.stderr[-3000:]}"
        )
    lines = done.stdout.strip().splitlines()
    if not lines:
        raise RuntimeError(f"headline subprocess printed nothing; stderr:\n{done.stderr[-3000:]}")
    result = json.loads(lines[-1])
    result["process_s"] = process_s  # interpreter start + imports + setup + run
    result["memory_note"] = MEMORY_NOTE
    result["synthetic_stand_in"] = dataset is None
    return result


def bench_scaling(
    dataset: Path | None, backends: Sequence[str], sizes: BenchSizes
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
        for backend in backends:
            progress(
                f"[scaling] {map_name}, {problem.data.num_free} cells, "
                f"L={config.num_concepts}: {backend}"
            )
            entry["backends"][backend] = _try(
                f"scaling {map_name} L={config.num_concepts} {backend}",
                lambda b=backend, p=problem: time_backend(
                    p, b, warmup=2, budget_s=sizes.scaling_budget_s
                ),
            )
        series[kind].append(entry)
    return series


def bench_quality(backend: str, sizes: BenchSizes) -> list[dict[str, Any]]:
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
                "free_cells": problem.data.num_free,
                "labelled_cells": int(labelled.sum()),
                "true_categories": int(np.unique(truth[labelled]).size),
                "points": points,
                "best_sweep": run.best_sweep + 1,
                "best_ari": float(adjusted_rand_score(truth[labelled], best[labelled])),
            }
        )
    return results


# ---------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------


@contextlib.contextmanager
def measure_contention(
    record: dict[str, dict[str, float | None]], name: str, wait_idle_s: float = 0.0
) -> Iterator[None]:
    """Record the wall time of a section and the CPU time OTHER processes used meanwhile
    (after waiting for an idle machine first, with ``--wait-idle``).

    other = (busy CPU time of the whole machine) - (this process + its children); a value well
    above 0 means the timings of that section competed with other work for the CPUs.
    """
    waited = wait_until_idle(wait_idle_s)
    busy0, own0, wall0 = busy_cpu_seconds(), own_cpu_seconds(), time.perf_counter()
    try:
        yield
    finally:
        busy1, own1 = busy_cpu_seconds(), own_cpu_seconds()
        other = None
        if busy0 is not None and busy1 is not None:
            other = max(0.0, (busy1 - busy0) - (own1 - own0))
        record[name] = {
            "wall_s": time.perf_counter() - wall0,
            "other_cpu_s": other,
            "waited_for_idle_s": waited,
        }


def _ms(result: dict[str, Any] | None, key: str = "ms_per_iteration", digits: int = 2) -> str:
    if result is None:
        return "-"
    if "error" in result:
        return "failed"
    return f"{result[key]:.{digits}f}"


def _mib(value: int | None) -> str:
    return "-" if value is None else f"{value / 2**20:.0f}"


def _verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def evaluate_targets(results: dict[str, Any]) -> list[dict[str, Any]]:
    """The issue's four targets against what was measured."""
    targets = []
    speedups = [
        max(h["speedup"].values()) for h in results["houses"] if h.get("speedup")
    ]  # best backend per house
    if speedups:
        worst = min(speedups)
        targets.append(
            {
                "target": f">= {TARGET_SPEEDUP:g}x faster per iteration than the per-cell loop",
                "measured": f"{worst:.0f}x (worst house, fastest backend)",
                "ok": worst >= TARGET_SPEEDUP,
            }
        )
    headline = results.get("headline")
    if headline and "error" not in headline:
        where = "synthetic stand-in" if headline["synthetic_stand_in"] else HEADLINE_HOUSE
        if headline["sweeps"] == 5000:
            targets.append(
                {
                    "target": f"5000 iterations of {HEADLINE_HOUSE} "
                    f"< {TARGET_HEADLINE_SECONDS:g} s",
                    "measured": f"{headline['wall_s']:.1f} s run_gibbs wall ({where}, "
                    f"{headline['backend']})",
                    "ok": headline["wall_s"] < TARGET_HEADLINE_SECONDS,
                }
            )
        targets.append(
            {
                "target": "peak memory of that run < 1 GiB",
                "measured": f"{headline['peak_rss_bytes'] / 2**20:.0f} MiB peak RSS",
                "ok": headline["peak_rss_bytes"] < TARGET_PEAK_BYTES,
            }
        )
    scaling = results.get("scaling", {})
    for backend in results["backends"]:
        cells = [
            e["backends"][backend]
            for e in scaling.get("cells", [])
            if "error" not in e["backends"].get(backend, {"error": ""})
        ]
        if len(cells) >= 2:
            ratio = cells[-1]["ns_per_cell"] / cells[0]["ns_per_cell"]
            targets.append(
                {
                    "target": f"time linear in cells ({backend}: ns/cell largest / smallest map)",
                    "measured": f"{ratio:.2f}",
                    "ok": 0.5 <= ratio <= 2.0,
                }
            )
        for kind in ("num_concepts", "num_concepts_house", "num_concepts_house_refresh"):
            by_l = [
                e
                for e in scaling.get(kind, [])
                if "error" not in e["backends"].get(backend, {"error": ""})
            ]
            if len(by_l) < 2:
                continue
            low, high = by_l[0], by_l[-1]
            ratio = (
                high["backends"][backend]["ms_per_iteration"]
                / low["backends"][backend]["ms_per_iteration"]
            )
            targets.append(
                {
                    "target": f"time nearly flat in L ({backend}, {low['map']}"
                    + (", refresh 0.1" if kind.endswith("refresh") else "")
                    + f": ms at L={high['num_concepts']} / L={low['num_concepts']})",
                    "measured": f"{ratio:.2f}",
                    "ok": ratio <= 2.0,
                }
            )
    return targets


def render(results: dict[str, Any]) -> str:
    """The plain-text report printed to stdout."""
    info = results["machine"]
    backends = results["backends"]
    out = [
        f"SpCoMapping Gibbs benchmark ({'quick' if results['quick'] else 'full'}), {info['date']}",
        f"{info['cpu_model']}, {info['cpus_usable']} usable CPUs; torch {info['torch']} "
        f"({info['torch_threads']} threads); numba {info['numba'] or 'not installed'}",
        "one iteration = all cell labels (eq. 13) + pi, theta, w draws (eqs. 14-17); "
        f"preset {PRESET}",
    ]
    out += [f"backend {name}: skipped: {note}" for name, note in results["backend_notes"].items()]
    contention = results.get("contention", {})
    if contention:
        parts = [
            f"{name} {c['other_cpu_s']:.0f} of {c['wall_s']:.0f} s"
            + (f" (after waiting {c['waited_for_idle_s']:.0f} s)" if c["waited_for_idle_s"] else "")
            for name, c in contention.items()
            if c.get("other_cpu_s") is not None
        ]
        out.append(
            "CPU time used by OTHER processes during each section (0 = machine to ourselves): "
            + ", ".join(parts)
        )
    out.append("")
    out.append("== Per house (L=120) ==")
    if results["dataset"] is None:
        out.append(
            "SKIPPED: no public dataset (not found, or --no-dataset; set SPCOPYRO_DATA): "
            "synthetic maps only"
        )
    else:
        headers = ["house", "free cells", "obs cells", "per-cell s/it"]
        headers += [f"{b} ms/it" for b in backends]
        headers += [f"{b} speed-up" for b in backends]
        headers += [f"{b} 5000 it s" for b in backends]
        rows = []
        for h in results["houses"]:
            row = [h["house"], str(h["free_cells"]), str(h["observed_cells"])]
            row.append(
                f"{h['per_cell']['seconds_per_iteration']:.3f}" if "per_cell" in h else "skipped"
            )
            row += [_ms(h["backends"].get(b)) for b in backends]
            row += [
                f"{h['speedup'][b]:.0f}x" if b in h.get("speedup", {}) else "-" for b in backends
            ]
            row += [
                f"{h['projected_5000_s'][b]:.1f}" if b in h.get("projected_5000_s", {}) else "-"
                for b in backends
            ]
            rows.append(row)
        out.append(format_table(headers, rows))
        out.append(
            "(ms/it, s/it: median of the timed sweeps of the sweep function after warm-up; "
            "5000 it s: 5000 times that)"
        )

    headline = results.get("headline")
    out.append("")
    out.append("== Headline: run_gibbs in a fresh process ==")
    if headline is None:
        out.append("not run")
    elif "error" in headline:
        out.append(f"FAILED: {headline['error']}")
    else:
        where = headline["house"]
        if headline["synthetic_stand_in"]:
            where += " (synthetic stand-in)"
        out.append(
            format_table(
                [
                    "house",
                    "free cells",
                    "backend",
                    "sweeps",
                    "wall s",
                    "ms/it",
                    "first sweep s",
                    "peak RSS MiB",
                    "RSS before / after run MiB",
                    "concepts",
                ],
                [
                    [
                        where,
                        str(headline["free_cells"]),
                        headline["backend"],
                        str(headline["sweeps"]),
                        f"{headline['wall_s']:.2f}",
                        f"{headline['ms_per_iteration']:.2f}",
                        f"{headline['first_sweep_s']:.2f}",
                        f"{headline['peak_rss_bytes'] / 2**20:.0f}",
                        f"{_mib(headline['rss_now_before_run_bytes'])} / "
                        f"{_mib(headline['rss_now_after_run_bytes'])}",
                        str(headline["final_concepts"]),
                    ]
                ],
            )
        )
        out.append(
            "(wall s: run_gibbs including its per-sweep log joint and trace; peak RSS: "
            "ru_maxrss of that process, interpreter and torch included)"
        )

    for kind, title in (
        ("cells", "Scaling in cells (L=120)"),
        ("num_concepts", "Scaling in L (synthetic, ~1e5 cells)"),
        ("num_concepts_house", f"Scaling in L ({HEADLINE_HOUSE})"),
        (
            "num_concepts_house_refresh",
            f"Scaling in L ({HEADLINE_HOUSE}, unobserved_refresh 0.1)",
        ),
    ):
        entries = results.get("scaling", {}).get(kind, [])
        if not entries:
            continue
        out.append("")
        out.append(f"== {title} ==")
        headers = ["map", "free cells", "obs cells", "L"]
        headers += [h for b in backends for h in (f"{b} ms/sweep", f"{b} ns/cell")]
        rows = []
        for e in entries:
            row = [e["map"], str(e["free_cells"]), str(e["observed_cells"])]
            row.append(str(e["num_concepts"]))
            for b in backends:
                r = e["backends"].get(b)
                row += [_ms(r), _ms(r, "ns_per_cell", 1)]
            rows.append(row)
        out.append(format_table(headers, rows))

    quality = results.get("quality", [])
    if quality:
        q0 = quality[0]
        out.append("")
        out.append(
            f"== Quality vs time: default synthetic house ({q0['free_cells']} cells, "
            f"{q0['true_categories']} categories), L={q0['num_concepts']}, {q0['backend']} =="
        )
        rows = []
        for q in quality:
            side = "above" if q["gamma"] > q["critical_gamma"] else "below"
            for p in q["points"]:
                rows.append(
                    [
                        f"{q['gamma']:g} ({side} {q['critical_gamma']:.2f})",
                        str(p["sweeps"]),
                        f"{p['seconds']:.2f}",
                        f"{p['ari']:.3f}",
                        str(p["concepts"]),
                    ]
                )
            best = [
                f"{q['gamma']:g} best visited",
                str(q["best_sweep"]),
                "",
                f"{q['best_ari']:.3f}",
            ]
            rows.append([*best, ""])
        out.append(format_table(["gamma (critical)", "sweeps", "seconds", "ARI", "concepts"], rows))

    targets = results.get("targets", [])
    if targets:
        out.append("")
        out.append("== Targets ==")
        out.append(
            format_table(
                ["target", "measured", ""],
                [[t["target"], t["measured"], _verdict(t["ok"])] for t in targets],
            )
        )
    out.append("")
    out.append(f"total {results['total_s']:.0f} s; JSON: {results['out']}")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description="Benchmark the SpCoMapping Gibbs sampler (see the module docstring)."
    )
    parser.add_argument("--quick", action="store_true", help="tiny sizes, a few sweeps (< 60 s)")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="JSON output (default benchmarks/gibbs_results.json, gibbs_quick.json with --quick)",
    )
    parser.add_argument(
        "--backends",
        default=",".join(KNOWN_BACKENDS),
        help="comma-separated sweep backends to time (default: torch,numba; missing ones are "
        "skipped with a note)",
    )
    parser.add_argument(
        "--skip-baseline", action="store_true", help="do not time the per-cell Python loop"
    )
    parser.add_argument(
        "--dataset", type=Path, default=None, help="dataset root (default: find_dataset_root())"
    )
    parser.add_argument("--no-dataset", action="store_true", help="synthetic maps only")
    parser.add_argument(
        "--torch-threads",
        type=int,
        default=None,
        help="torch.set_num_threads for this run and the headline subprocess (default: torch's)",
    )
    parser.add_argument(
        "--wait-idle",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="before each section wait up to this long for other processes to leave the CPUs "
        "(default 0: do not wait)",
    )
    parser.add_argument("--child-run", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--child-sweeps", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    names = [b.strip() for b in args.backends.split(",") if b.strip()]
    unknown = [b for b in names if b not in KNOWN_BACKENDS]
    if unknown or not names:
        parser.error(f"--backends {args.backends!r}: choose from {', '.join(KNOWN_BACKENDS)}")
    args.backend_list = list(dict.fromkeys(names))
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.torch_threads is not None:
        if args.torch_threads < 1:
            raise SystemExit(f"--torch-threads must be >= 1, got {args.torch_threads}")
        torch.set_num_threads(args.torch_threads)
    if args.no_dataset:
        dataset = None
    else:
        dataset = find_dataset_root(args.dataset)
    if args.child_run is not None:
        print(json.dumps(child_run(dataset, args.child_run, args.child_sweeps)))
        return 0

    started = time.perf_counter()
    sizes = QUICK if args.quick else FULL
    out_path = args.out or SCRIPT_DIR / ("gibbs_quick.json" if args.quick else "gibbs_results.json")
    backends, notes = available_backends(args.backend_list)
    for name, note in notes.items():
        progress(f"backend {name}: {note}")
    if not backends:
        raise SystemExit(f"none of the backends {args.backend_list} can be loaded: {notes}")
    if dataset is None:
        progress("public dataset not found: per-house timings skipped, synthetic maps only")

    results: dict[str, Any] = {
        "quick": args.quick,
        "preset": PRESET,
        "seed": SEED,
        "argv": sys.argv if argv is None else list(argv),
        "machine": machine_info(),
        "dataset": None if dataset is None else str(dataset),
        "backends": backends,
        "backend_notes": notes,
        "sizes": {k: v for k, v in vars(sizes).items()},
        "targets_definition": {
            "speedup": TARGET_SPEEDUP,
            "headline_seconds": TARGET_HEADLINE_SECONDS,
            "peak_bytes": TARGET_PEAK_BYTES,
        },
    }
    contention: dict[str, dict[str, float | None]] = {}
    results["contention"] = contention
    with measure_contention(contention, "houses", args.wait_idle):
        results["houses"] = bench_houses(dataset, backends, sizes, args.skip_baseline)

    # The fastest backend on the headline house (or on the first scaling map without data).
    headline_entry = next((h for h in results["houses"] if h["house"] == HEADLINE_HOUSE), None)
    if headline_entry is None or "fastest_backend" not in headline_entry:
        probe = make_problem(load_headline_house(None), preset(PRESET))
        timed = {
            b: _try(f"probe {b}", lambda b=b: time_backend(probe, b, warmup=2, sweeps=5))
            for b in backends
        }
        timed = {b: r for b, r in timed.items() if "error" not in r}
        fastest = min(timed, key=lambda b: timed[b]["ms_per_iteration"]) if timed else backends[0]
    else:
        fastest = headline_entry["fastest_backend"]
    results["fastest_backend"] = fastest

    with measure_contention(contention, "headline", args.wait_idle):
        results["headline"] = _try(
            "headline run", lambda: bench_headline(dataset, fastest, sizes.headline_sweeps)
        )
    with measure_contention(contention, "scaling", args.wait_idle):
        results["scaling"] = bench_scaling(dataset, backends, sizes)
    with measure_contention(contention, "quality", args.wait_idle):
        results["quality"] = bench_quality(fastest, sizes)
    results["targets"] = evaluate_targets(results)
    results["total_s"] = time.perf_counter() - started
    results["out"] = str(out_path)

    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(results, indent=2) + "\n")
    print(render(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
