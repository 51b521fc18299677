#!/usr/bin/env python
r"""The batched sweep of B chains (:mod:`spcopyro.gibbs.batched`, issue 25 item 5) in cells a
second, on the CPU and, when ``torch.cuda.is_available()``, on the GPU, against the compiled
numba kernel measured in the same run.

For each house (the embedded synthetic house ``make_house(seed=0)``, and room2ldk4 when the
public dataset is found; a note otherwise), preset ``paper-dp`` (L = 120), one table:

* ``numba x1``: the compiled kernel, one chain (``backend.sweep`` in a loop, nothing recorded);
* ``numba x4 chains``: :func:`~spcopyro.gibbs.chains.advance_chains` of 4 chains, one thread per
  usable CPU (its run loop included: the per-sweep trace);
* ``torch x1``: the torch reference sweep, one chain (for context);
* ``batched xB``: :func:`~spcopyro.gibbs.batched.gibbs_sweep_batched` for B in (1, 4, 16, 64)
  on the CPU in float64, and on the GPU in float64 and float32 for B in (1, 4, 16, 64, 256).

Cells a second = B x free cells / seconds per sweep (median of single timed sweeps after two
warm-up sweeps, each point timed for about ``--seconds``; on the GPU every timed sweep ends with
``torch.cuda.synchronize()``); each row also gives its ratio to ``numba x1`` and to
``numba x4 chains`` of the same run, the peak GPU memory for GPU rows, and the load average
before and after the run. The numba and torch one-chain rows run with the fit's thread policy
for the house (:func:`spcopyro._util.threads.resolve_threads` ``"auto"``: one intra-op thread
below 50 000 cells; torch's default of one a core makes even the compiled sweep 50x slower on a
busy machine), the batched CPU rows with ``--torch-threads`` (default the same policy for
B x free cells).

Usage::

    python benchmarks/batched_gpu.py                 # ~2 min on a 2-core machine without a GPU
    python benchmarks/batched_gpu.py --quick --out /tmp/batched_quick.json   # smoke test

It prints plain-text tables to stdout (progress to stderr) and writes every number with machine
information to ``benchmarks/batched_gpu.json`` (git-ignored) unless ``--out`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import torch
from bench_cli import COUNT, SECONDS, dataset_root, quick_or, run_main
from machine import busy_cpu_seconds, format_table, machine_info, own_cpu_seconds, progress

from spcopyro._util.threads import resolve_threads, torch_threads
from spcopyro.config import SpCoConfig, preset
from spcopyro.data import load_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs import GibbsOptions, start_chain
from spcopyro.gibbs.batched import gibbs_sweep_batched, init_batched, make_batched_plan
from spcopyro.gibbs.chains import advance_chains, resolve_workers
from spcopyro.gibbs.sampler import init
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.gibbs.sweep import gibbs_sweep
from spcopyro.model import ModelData
from spcopyro.synthetic import make_house

HERE = Path(__file__).resolve().parent
PRESET = "paper-dp"
CPU_CHAINS = (1, 4, 16, 64)
GPU_CHAINS = (1, 4, 16, 64, 256)
NUMBA_CHAINS = 4


def time_sweeps(sweep: Callable[[], None], seconds: float, sync: Callable[[], None]) -> float:
    """Median seconds of one ``sweep()`` (two warm-up sweeps, then at least 3, for ~``seconds``)."""
    for _ in range(2):
        sweep()
    sync()
    times: list[float] = []
    started = time.perf_counter()
    while len(times) < 3 or time.perf_counter() - started < seconds:
        start = time.perf_counter()
        sweep()
        sync()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def no_sync() -> None:
    """Nothing to wait for on the CPU."""


def numba_one_chain(data: ModelData, config: SpCoConfig, seconds: float) -> float | None:
    """Seconds a sweep of the compiled kernel, one chain (None without numba)."""
    try:
        from spcopyro.gibbs.numba_sweep import gibbs_sweep_numba
    except ImportError:
        return None
    generator = torch.Generator().manual_seed(0)
    state = [init(data, config, generator)]
    plan = make_sweep_plan(data)

    def sweep() -> None:
        state[0] = gibbs_sweep_numba(state[0], data, config, generator, plan, 1.0)

    return time_sweeps(sweep, seconds, no_sync)


def numba_chains(data: ModelData, config: SpCoConfig, seconds_per_sweep: float,
                 seconds: float) -> dict[str, Any] | None:  # fmt: skip
    """Wall seconds of :data:`NUMBA_CHAINS` chains advanced together by ``advance_chains``,
    sized to take about ``seconds``; None without numba."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return None
    options = GibbsOptions(backend="numba")
    sweeps = max(10, int(seconds / seconds_per_sweep / NUMBA_CHAINS * resolve_workers("auto", 4)))
    warm = [start_chain(data, config, options=options, seed=99)]
    advance_chains([(warm[0], 2)], progress=False)  # kernels loaded
    chains = [start_chain(data, config, options=options, seed=k) for k in range(NUMBA_CHAINS)]
    start = time.perf_counter()
    advance_chains([(chain, sweeps) for chain in chains], workers="auto", progress=False)
    wall = time.perf_counter() - start
    return {"chains": NUMBA_CHAINS, "sweeps": sweeps, "wall_s": wall,
            "workers": resolve_workers("auto", NUMBA_CHAINS)}  # fmt: skip


def torch_one_chain(data: ModelData, config: SpCoConfig, seconds: float) -> float:
    """Seconds a sweep of the torch reference, one chain."""
    generator = torch.Generator().manual_seed(0)
    state = [init(data, config, generator)]
    plan = make_sweep_plan(data)

    def sweep() -> None:
        state[0] = gibbs_sweep(state[0], data, config, generator, plan)

    return time_sweeps(sweep, seconds, no_sync)


def batched(data: ModelData, config: SpCoConfig, chains: int, device: str, dtype: torch.dtype,
            seconds: float, threads: int | str) -> dict[str, Any]:  # fmt: skip
    """Seconds a batched sweep of ``chains`` chains on ``device`` in ``dtype`` (and the peak
    GPU memory on a GPU)."""
    cuda = device.startswith("cuda")
    if cuda:
        torch.cuda.empty_cache()
        torch.cuda.reset_peak_memory_stats()
    plan = make_batched_plan(data, config, device, dtype)
    generator = torch.Generator(device=device).manual_seed(0)
    state = [init_batched(data, config, plan, generator, chains)]

    def sweep() -> None:
        state[0] = gibbs_sweep_batched(state[0], plan, config, generator)

    count = None if cuda else resolve_threads(threads, chains * data.num_free)
    with torch_threads(count):
        seconds_per_sweep = time_sweeps(sweep, seconds, torch.cuda.synchronize if cuda else no_sync)
    peak = torch.cuda.max_memory_allocated() / 2**20 if cuda else None
    return {"seconds_per_sweep": seconds_per_sweep, "peak_gpu_mib": peak}


def problems(args: argparse.Namespace) -> tuple[list[tuple[str, ModelData, SpCoConfig]], list]:
    """(name, data, config) of the embedded house and room2ldk4 (when the dataset is found)."""
    settings = preset(PRESET)
    logging.disable(logging.WARNING)  # the Potts critical-coupling note
    out, notes = [], []
    _, data = prepare_model_data(make_house(seed=0), settings)
    out.append(("embedded", data, settings.model))
    if args.quick or args.no_dataset:
        notes.append("room2ldk4 not measured (--quick / --no-dataset)")
    else:
        root = dataset_root(args.dataset, without="room2ldk4 is not measured")
        if root is None:
            notes.append("room2ldk4 not measured: public dataset not found (set SPCOPYRO_DATA)")
        else:
            _, data = prepare_model_data(load_house(root / "room2ldk4"), settings)
            out.append(("room2ldk4", data, settings.model))
    logging.disable(logging.NOTSET)
    return out, notes


def measure(name: str, data: ModelData, config: SpCoConfig, args) -> list[dict[str, Any]]:
    """Every row of one house's table."""
    N = data.num_free
    rows: list[dict[str, Any]] = []

    def add(engine: str, device: str, dtype: str, chains: int, seconds_per_sweep: float,
            **extra: Any) -> None:  # fmt: skip
        rows.append({"house": name, "free_cells": N, "engine": engine, "device": device,
                     "dtype": dtype, "chains": chains, "ms_per_sweep": 1e3 * seconds_per_sweep,
                     "cells_per_s": chains * N / seconds_per_sweep, **extra})  # fmt: skip

    with torch_threads(resolve_threads("auto", N)):  # what a fit of this house runs with
        progress(f"{name}: numba, one chain")
        one = numba_one_chain(data, config, args.seconds)
        if one is not None:
            add("numba x1", "cpu", "float64", 1, one)
            progress(f"{name}: numba, {NUMBA_CHAINS} chains (advance_chains)")
            many = numba_chains(data, config, one, args.seconds)
            add(f"numba x{NUMBA_CHAINS} chains", "cpu", "float64", NUMBA_CHAINS,
                many["wall_s"] / many["sweeps"], workers=many["workers"])  # fmt: skip
        progress(f"{name}: torch reference, one chain")
        add("torch x1", "cpu", "float64", 1, torch_one_chain(data, config, args.seconds))
    targets = [("cpu", torch.float64, args.cpu_chains)]
    if torch.cuda.is_available():
        targets += [("cuda", torch.float64, args.gpu_chains),
                    ("cuda", torch.float32, args.gpu_chains)]  # fmt: skip
    for device, dtype, chain_counts in targets:
        for chains in chain_counts:
            progress(f"{name}: batched, {chains} chains on {device} ({dtype})")
            result = batched(data, config, chains, device, dtype, args.seconds,
                             args.torch_threads)  # fmt: skip
            add(f"batched x{chains}", device, str(dtype).removeprefix("torch."), chains,
                result["seconds_per_sweep"], peak_gpu_mib=result["peak_gpu_mib"])  # fmt: skip
    baselines = {r["engine"]: r["cells_per_s"] for r in rows if r["engine"].startswith("numba")}
    for row in rows:
        for engine, value in baselines.items():
            row[f"over {engine}"] = row["cells_per_s"] / value
    return rows


def render(rows: Sequence[dict[str, Any]]) -> str:
    baselines = [k for k in rows[0] if k.startswith("over ")]
    headers = ["engine", "device", "dtype", "ms/sweep", "Mcells/s", *baselines, "peak GPU MiB"]
    body = [
        [r["engine"], r["device"], r["dtype"], f"{r['ms_per_sweep']:.2f}",
         f"{r['cells_per_s'] / 1e6:.2f}", *(f"{r[k]:.2f}x" for k in baselines),
         "" if r.get("peak_gpu_mib") is None else f"{r['peak_gpu_mib']:.0f}"]
        for r in rows
    ]  # fmt: skip
    return format_table(headers, body)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test: embedded house, B 1, 4")
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default benchmarks/batched_gpu.json, "
                             "batched_gpu_quick.json with --quick)")  # fmt: skip
    parser.add_argument("--seconds", type=SECONDS, default=None,
                        help="timing budget per point (default 2; --quick: 0.2)")  # fmt: skip
    parser.add_argument("--dataset", type=Path, default=None,
                        help="dataset root (default: find_dataset_root())")  # fmt: skip
    parser.add_argument("--no-dataset", action="store_true", help="the embedded house only")
    parser.add_argument("--torch-threads", default="auto",
                        help="intra-op threads of the batched CPU rows: 'auto' (the fit's "
                        "policy for B x free cells) or a count")  # fmt: skip
    args = parser.parse_args(argv)
    if args.torch_threads != "auto":
        try:
            args.torch_threads = COUNT(args.torch_threads)
        except argparse.ArgumentTypeError as error:
            parser.error(f"argument --torch-threads: 'auto' or a count: {error}")
    args.seconds = quick_or(args.seconds, args.quick, 0.2, 2.0)
    args.cpu_chains, args.gpu_chains = CPU_CHAINS, GPU_CHAINS
    if args.quick:
        args.cpu_chains, args.gpu_chains = (1, 4), (1, 4)
    if args.out is None:
        args.out = HERE / ("batched_gpu_quick.json" if args.quick else "batched_gpu.json")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    load_before = list(os.getloadavg())
    busy0, own0 = busy_cpu_seconds(), own_cpu_seconds()
    houses, notes = problems(args)
    gpu = torch.cuda.get_device_name() if torch.cuda.is_available() else None
    if gpu is None:
        notes.append("no CUDA device on this machine: the batched sweep measured on the CPU only")
    tables = {}
    for name, data, config in houses:
        tables[name] = measure(name, data, config, args)
    other = None if busy0 is None else (busy_cpu_seconds() - busy0) - (own_cpu_seconds() - own0)
    load_after = list(os.getloadavg())
    for name, rows in tables.items():
        print(f"\n== Batched sweep of {name} ({rows[0]['free_cells']} free cells, {PRESET}, "
              f"L = {houses[0][2].num_concepts}) ==")  # fmt: skip
        print(render(rows))
    print()
    for note in notes:
        print(f"note: {note}")
    print(
        f"load average (1, 5, 15 min) before {load_before}, after {load_after}; other "
        f"processes' CPU seconds meanwhile: {other if other is None else round(other, 1)}"
    )
    rows = [row for house_rows in tables.values() for row in house_rows]
    results = {"machine": machine_info(), "gpu": gpu, "preset": PRESET, "notes": notes,
               "load_before": load_before, "load_after": load_after,
               "other_cpu_seconds": other, "rows": rows}  # fmt: skip
    args.out.write_text(json.dumps(results, indent=2))
    progress(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
