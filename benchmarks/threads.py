#!/usr/bin/env python
r"""Threads that do not fight: torch's default intra-op threads against
:mod:`spcopyro._util.threads`.

A Gibbs sweep is hundreds of small torch operations; with T > 1 intra-op threads each of them
forks and joins an OpenMP team, and on a machine that is doing anything else every join waits for
the thread the scheduler set aside. This benchmark measures, in one run:

1. **Under load.** ``run_gibbs`` for S sweeps (the loop a fit runs: sweep, log joint, trace) on
   room1dk5 (public dataset; skipped with a note when absent) and the default synthetic house,
   both backends, under torch's default thread count and under the policy
   (:func:`spcopyro._util.threads.resolve_threads` with ``"auto"``), first as the machine is
   ("idle":
   the CPU time other processes used meanwhile is reported) and then next to a busy neighbour:
   ``--busy-cores`` processes started by the benchmark that spin, each bounded in time and killed
   when the condition ends, also on error or Ctrl-C. The settings alternate within a condition
   (R repeats each) and the ratio of the medians, default / policy, is measured in the same run.
   The final labels of both settings are compared: the thread count must not change them.
2. **Threshold.** Synthetic maps of ~1e4 to ~1e6 free cells (``HouseSpec.scaled``), both
   backends, one thread against the default, on the machine as it is: where more threads start to
   pay. :data:`spcopyro._util.threads.MIN_CELLS_FOR_MORE_THREADS` is read off this table.

Usage::

    python benchmarks/threads.py                 # full run (~10 min on a 2-core machine)
    python benchmarks/threads.py --quick         # smoke test
    python benchmarks/threads.py --busy-cores 2 --repeats 5 --out /tmp/threads.json

It prints plain-text tables to stdout (progress goes to stderr) and writes every number, with
machine information, to a JSON file (``benchmarks/threads_results.json`` unless ``--out``).
Timings on a shared machine are noisy: each entry is a median over the repeats.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from bench_cli import COUNT, WAIT, dataset_root, run_main
from machine import (
    available_backends,
    busy_cpu_seconds,
    format_table,
    machine_info,
    own_cpu_seconds,
    progress,
    wait_until_idle,
)

from spcopyro._util.threads import MIN_CELLS_FOR_MORE_THREADS, resolve_threads, torch_threads
from spcopyro.config import preset
from spcopyro.data import House, load_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs import GibbsOptions, run_gibbs
from spcopyro.model import ModelData
from spcopyro.synthetic import HouseSpec, make_house

PUBLIC_HOUSE = "room1dk5"
PRESET = "paper-dp"
SEED = 0
SCRIPT_DIR = Path(__file__).resolve().parent
GAIN = 1.2
"""More threads "pay" on a map when one thread is at least this much slower (threshold table)."""

SPIN = r"""
import os, sys, time
end, parent = time.monotonic() + float(sys.argv[1]), int(sys.argv[2])
x = 0
while time.monotonic() < end and os.getppid() == parent:
    for _ in range(200000):
        x += 1
"""
"""A busy neighbour: spins one core until its deadline, or until its parent has gone."""


@dataclass(frozen=True)
class Sizes:
    """How much work a run does."""

    sweeps: int  # run_gibbs sweeps per timed run (section 1)
    repeats: int  # timed runs per setting and condition
    public: bool  # include room1dk5 when the dataset is there
    synthetic_spec: HouseSpec | None  # the synthetic house (None: make_house's default)
    threshold_sides: tuple[int, ...]  # synthetic map sides of the threshold table
    threshold_cell_sweeps: float  # free cells x sweeps per timed threshold run (>= 2 sweeps)
    busy_max_s: float  # a neighbour's own deadline (it is killed sooner, at the condition's end)


FULL = Sizes(100, 3, True, None, (110, 180, 240, 334, 580, 1050), 2e6, 1800.0)
QUICK = Sizes(3, 1, False, HouseSpec(height=30, width=40, num_rooms=2, num_trials=1), (60,),
              1e4, 120.0)  # fmt: skip


# ---------------------------------------------------------------------------------------------
# The busy neighbour and the machine's other load
# ---------------------------------------------------------------------------------------------


def _terminate_on_sigterm() -> None:
    """Turn SIGTERM into SystemExit, so that ``finally`` blocks (killing the neighbour) run."""

    def handler(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, handler)


@contextlib.contextmanager
def busy_neighbour(cores: int, max_seconds: float) -> Iterator[list[subprocess.Popen]]:
    """``cores`` processes spinning one core each for the duration of the block (each also stops
    by itself after ``max_seconds`` or when this process dies); always killed at the end."""
    procs: list[subprocess.Popen] = []
    try:
        for _ in range(cores):
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-c", SPIN, str(max_seconds), str(os.getpid())],
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.DEVNULL,
                )  # fmt: skip
            )
        time.sleep(0.2)  # let them start spinning
        yield procs
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
        for proc in procs:
            proc.wait(timeout=10)


@contextlib.contextmanager
def other_load(record: dict[str, Any]) -> Iterator[None]:
    """Record the block's wall time and the CPUs that OTHER processes kept busy meanwhile
    (``other_cores``: their CPU seconds / wall seconds; the busy neighbour counts as other)."""
    busy0, own0, wall0 = busy_cpu_seconds(), own_cpu_seconds(), time.perf_counter()
    try:
        yield
    finally:
        wall = time.perf_counter() - wall0
        busy1, own1 = busy_cpu_seconds(), own_cpu_seconds()
        other = None
        if busy0 is not None and busy1 is not None:
            other = max(0.0, (busy1 - busy0) - (own1 - own0))
        record.update(wall_s=wall, other_cpu_s=other,
                      other_cores=None if other is None else other / max(wall, 1e-9))  # fmt: skip


# ---------------------------------------------------------------------------------------------
# Timing
# ---------------------------------------------------------------------------------------------


def timed_run(data: ModelData, backend: str, sweeps: int, threads: int | None) -> tuple[float, Any]:
    """(ms per sweep, final labels [N]) of ``run_gibbs`` from seed 0 with ``threads``."""
    config = preset(PRESET).model
    with torch_threads(threads):
        start = time.perf_counter()
        run = run_gibbs(data, config, sweeps, options=GibbsOptions(backend=backend), seed=SEED,
                        progress=False)  # fmt: skip
        seconds = time.perf_counter() - start
    return 1e3 * seconds / sweeps, run.final_state.labels


def compare(
    data: ModelData, backend: str, sweeps: int, repeats: int, settings: dict[str, int | None]
) -> dict[str, Any]:
    """Median ms per sweep of each setting (alternating, ``repeats`` runs each) and whether the
    settings' final labels agree."""
    times: dict[str, list[float]] = {name: [] for name in settings}
    labels: dict[str, Any] = {}
    for _ in range(repeats):
        for name, threads in settings.items():
            ms, labels[name] = timed_run(data, backend, sweeps, threads)
            times[name].append(ms)
    first = next(iter(labels.values()))
    return {
        "ms_per_sweep": {name: statistics.median(v) for name, v in times.items()},
        "ms_per_sweep_runs": times,
        "labels_identical": all(bool((v == first).all()) for v in labels.values()),
    }


def warm_up(data: ModelData, backends: Sequence[str]) -> None:
    """A few sweeps of each backend (numba's compile, torch's first calls)."""
    for backend in backends:
        timed_run(data, backend, 3, None)


# ---------------------------------------------------------------------------------------------
# The sections
# ---------------------------------------------------------------------------------------------


def load_houses(sizes: Sizes, dataset: Path | None, notes: list[str]) -> list[House]:
    houses = []
    if sizes.public and dataset is not None and (dataset / PUBLIC_HOUSE).is_dir():
        houses.append(load_house(dataset / PUBLIC_HOUSE))
    elif sizes.public:
        notes.append(f"{PUBLIC_HOUSE} not measured: the public dataset was not found "
                     "($SPCOPYRO_DATA, ../shared/data/spcomapping, --dataset); the synthetic "
                     "house stands in for it")  # fmt: skip
    houses.append(make_house(seed=SEED, spec=sizes.synthetic_spec))
    return houses


def bench_load(
    houses: Sequence[House],
    backends: Sequence[str],
    sizes: Sizes,
    default_threads: int,
    busy_cores: int,
    wait_idle_s: float = 0.0,
) -> list[dict[str, Any]]:
    """Section 1: default threads against the policy, idle and next to a busy neighbour."""
    problems = []
    for house in houses:
        _, data = prepare_model_data(house, preset(PRESET))
        warm_up(data, backends)
        problems.append((house, data))
    rows = []
    for condition in ("idle", "busy"):
        record: dict[str, Any] = {}
        if condition == "idle":
            record["waited_for_idle_s"] = wait_until_idle(wait_idle_s)
        context = (
            busy_neighbour(busy_cores, sizes.busy_max_s)
            if condition == "busy"
            else contextlib.nullcontext()
        )
        with context, other_load(record):
            for house, data in problems:
                policy = resolve_threads("auto", data.num_free)
                settings = {"default": default_threads, "policy": policy}
                for backend in backends:
                    progress(f"  {condition}: {house.name} ({data.num_free} cells), {backend}")
                    result = compare(data, backend, sizes.sweeps, sizes.repeats, settings)
                    ms = result["ms_per_sweep"]
                    rows.append({
                        "condition": condition, "house": house.name, "free_cells": data.num_free,
                        "backend": backend, "default_threads": default_threads,
                        "policy_threads": torch.get_num_threads() if policy is None else policy,
                        "busy_cores": busy_cores if condition == "busy" else 0,
                        "sweeps": sizes.sweeps, "repeats": sizes.repeats, **result,
                        "ratio_default_over_policy": ms["default"] / ms["policy"],
                    })  # fmt: skip
        for row in rows:
            if row["condition"] == condition:
                row["machine_load"] = dict(record)
    return rows


def bench_threshold(
    sizes: Sizes, backends: Sequence[str], default_threads: int, wait_idle_s: float = 0.0
) -> list[dict[str, Any]]:
    """Section 2: one thread against the default on maps of growing size."""
    rows = []
    for side in sizes.threshold_sides:
        progress(f"  threshold: building a {side} x {side} synthetic map")
        house = make_house(seed=SEED, spec=HouseSpec.scaled(side, side), name=f"synthetic{side}")
        _, data = prepare_model_data(house, preset(PRESET))
        warm_up(data, backends)
        sweeps = max(2, int(sizes.threshold_cell_sweeps // data.num_free))
        for backend in backends:
            progress(f"  threshold: {data.num_free} cells, {backend}, {sweeps} sweeps a run")
            record: dict[str, Any] = {"waited_for_idle_s": wait_until_idle(wait_idle_s)}
            with other_load(record):
                result = compare(data, backend, sweeps, sizes.repeats,
                                 {"one": 1, "default": default_threads})  # fmt: skip
            ms = result["ms_per_sweep"]
            rows.append({
                "map": house.name, "free_cells": data.num_free,
                "observed_cells": int(data.obs_cells.shape[0]), "backend": backend,
                "default_threads": default_threads, "sweeps": sweeps, **result,
                "ratio_one_over_default": ms["one"] / ms["default"], "machine_load": record,
            })  # fmt: skip
    return rows


def measured_threshold(rows: Sequence[dict[str, Any]]) -> int | None:
    """The smallest map size from which more threads are at least :data:`GAIN` times faster on
    every backend and every larger map of the table; None if no such size."""
    sizes = sorted({row["free_cells"] for row in rows})
    pays = {n: all(r["ratio_one_over_default"] >= GAIN for r in rows if r["free_cells"] == n)
            for n in sizes}  # fmt: skip
    found = None
    for n in reversed(sizes):
        if not pays[n]:
            break
        found = n
    return found


# ---------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------


def _load(row: dict[str, Any]) -> str:
    cores = row["machine_load"].get("other_cores")
    return "?" if cores is None else f"{cores:.2f}"


def render(results: dict[str, Any]) -> str:
    info = results["machine"]
    parts = [
        f"machine: {info['cpu_model']}, {info['cpus_usable']} usable CPUs; torch {info['torch']} "
        f"(default {results['default_threads']} intra-op threads); numba {info['numba']}",
    ]
    parts += [f"note: {note}" for note in results["notes"]]
    rows = [
        [r["house"], str(r["free_cells"]), r["backend"], r["condition"], _load(r),
         f"{r['default_threads']}", f"{r['ms_per_sweep']['default']:.2f}",
         f"{r['policy_threads']}", f"{r['ms_per_sweep']['policy']:.2f}",
         f"{r['ratio_default_over_policy']:.1f}x", "yes" if r["labels_identical"] else "NO"]
        for r in results["load"]
    ]  # fmt: skip
    parts += [
        "",
        "== Default threads against the policy (run_gibbs, preset paper-dp) ==",
        format_table(
            [
                "house",
                "free cells",
                "backend",
                "condition",
                "other CPUs",
                "default T",
                "default ms/sweep",
                "policy T",
                "policy ms/sweep",
                "default / policy",
                "same labels",
            ],
            rows,
        ),  # fmt: skip
        "(ms/sweep: median over the repeats of run_gibbs wall time / sweeps; other CPUs: CPU "
        "seconds other processes used per second meanwhile, the busy neighbour included)",
    ]
    if results["threshold"]:
        rows = [
            [r["map"], str(r["free_cells"]), str(r["observed_cells"]), r["backend"], _load(r),
             f"{r['ms_per_sweep']['one']:.2f}", f"{r['ms_per_sweep']['default']:.2f}",
             f"{r['ratio_one_over_default']:.2f}"]
            for r in results["threshold"]
        ]  # fmt: skip
        found = results["measured_threshold"]
        parts += [
            "",
            "== Threshold: one thread against the default, by map size ==",
            format_table(
                [
                    "map",
                    "free cells",
                    "obs cells",
                    "backend",
                    "other CPUs",
                    "1 thread ms/sweep",
                    f"{results['default_threads']} threads ms/sweep",
                    "1 / default",
                ],
                rows,
            ),  # fmt: skip
            f"more threads pay (>= {GAIN}x on every backend, from this size up): "
            + (f"from {found} free cells" if found else "on no map of this table")
            + f"; the policy's threshold: {MIN_CELLS_FOR_MORE_THREADS} free cells",
        ]
    return "\n".join(parts)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test: tiny sizes")
    parser.add_argument("--out", type=Path, help="JSON file to write (default benchmarks/"
                        "threads_results.json, threads_quick.json with --quick)")  # fmt: skip
    parser.add_argument("--backends", default="torch,numba", help="comma-separated")
    parser.add_argument("--sweeps", type=COUNT, help="run_gibbs sweeps per timed run (default "
                        f"{FULL.sweeps}; --quick: {QUICK.sweeps})")  # fmt: skip
    parser.add_argument("--repeats", type=COUNT, help="timed runs per setting, the median kept "
                        f"(default {FULL.repeats}; --quick: {QUICK.repeats})")  # fmt: skip
    parser.add_argument(
        "--busy-cores",
        type=COUNT,
        default=1,
        help="spinning neighbour processes in the busy condition (default 1)",
    )
    parser.add_argument("--sides", type=COUNT, nargs="+", help="threshold map sides (cells; "
                        f"default {' '.join(map(str, FULL.threshold_sides))}; --quick: "
                        f"{' '.join(map(str, QUICK.threshold_sides))})")  # fmt: skip
    parser.add_argument("--skip-threshold", action="store_true")
    parser.add_argument(
        "--wait-idle",
        type=WAIT,
        default=0.0,
        help="before the idle condition and each threshold point, wait up to this many seconds "
        "for the other processes to leave the CPUs (default 0: measure at once)",
    )
    parser.add_argument("--dataset", help="public dataset root (default: found automatically)")
    parser.add_argument("--no-dataset", action="store_true", help="synthetic houses only")
    args = parser.parse_args(argv)
    names = [b.strip() for b in args.backends.split(",") if b.strip()]
    if not names or any(b not in ("torch", "numba") for b in names):  # a typo: not a note
        parser.error(f"--backends {args.backends!r}: choose from torch, numba")
    args.backend_list = list(dict.fromkeys(names))
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    _terminate_on_sigterm()
    sizes = QUICK if args.quick else FULL
    changes = {k: v for k, v in (("sweeps", args.sweeps), ("repeats", args.repeats)) if v}
    if args.sides:
        changes["threshold_sides"] = tuple(args.sides)
    if args.skip_threshold:
        changes["threshold_sides"] = ()
    sizes = Sizes(**{**sizes.__dict__, **changes})
    notes: list[str] = []
    default_threads = torch.get_num_threads()
    if default_threads == 1:
        default_threads = 2
        notes.append("torch's default is 1 thread here (one CPU, or OMP_NUM_THREADS=1): the "
                     "'default' setting uses 2 threads instead")  # fmt: skip
    backends, skipped = available_backends(args.backend_list)
    notes += [f"backend {name} skipped: {why}" for name, why in skipped.items()]
    if not backends:
        raise SystemExit(f"no backend to measure: {skipped}")
    without = f"{PUBLIC_HOUSE} is not measured"
    dataset = None if args.no_dataset else dataset_root(args.dataset, without=without)
    results: dict[str, Any] = {
        "machine": machine_info(), "sizes": {**sizes.__dict__, "synthetic_spec": None
                                             if sizes.synthetic_spec is None else "quick"},
        "default_threads": default_threads, "policy_min_cells": MIN_CELLS_FOR_MORE_THREADS,
        "notes": notes,
    }  # fmt: skip
    houses = load_houses(sizes, dataset, notes)
    progress("== default threads against the policy ==")
    results["load"] = bench_load(
        houses, backends, sizes, default_threads, args.busy_cores, args.wait_idle
    )
    progress("== threshold ==")
    results["threshold"] = bench_threshold(sizes, backends, default_threads, args.wait_idle)
    results["measured_threshold"] = measured_threshold(results["threshold"])
    out = args.out or SCRIPT_DIR / ("threads_quick.json" if args.quick else "threads_results.json")
    out.write_text(json.dumps(results, indent=1, default=str) + "\n")
    print(render(results))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
