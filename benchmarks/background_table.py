#!/usr/bin/env python
r"""The compiled sweep's background table through the footprint's factored counts (issue 25).

Under the default preset (``coarse``: a 0.75 m footprint on 0.25 m cells) a few dozen observation
spots reach hundreds of cells, and the per-sweep product loglik = x log(phi)^T [M, L] was the
largest piece of a sweep's arithmetic. :mod:`spcopyro.gibbs.numba_background` builds it as
``A (X log(phi)^T)`` from the footprints' factored counts
(:class:`~spcopyro.data.footprint.SpreadSources`). This benchmark times, in one run, for the
embedded house and each public house on the default preset's model grid:

* ``dense``: the table from the same counts without their factored form (the code before);
* ``factored``: the table as the sweep builds it now;

alternating in blocks of calls on one state drawn from the prior start, each the median ms of a
call over the blocks, with the largest relative difference of the two tables (rounding only).

Usage::

    python benchmarks/background_table.py            # ~20 s
    python benchmarks/background_table.py --quick --out /tmp/background_quick.json

It prints a table to stdout and writes every number, with machine information, to
``benchmarks/background_table.json`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import time
from pathlib import Path

import numpy as np
import torch
from bench_cli import dataset_root, results_path, run_main
from machine import format_table, machine_info, progress

from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.data import load_house
from spcopyro.data.model_grid import model_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs.numba_background import background_table
from spcopyro.gibbs.sampler import init
from spcopyro.synthetic import HouseSpec, make_house

SCRIPT_DIR = Path(__file__).resolve().parent
PUBLIC = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


def houses(quick: bool) -> list:
    """The embedded house, then the public houses where the dataset is found."""
    out = [make_house(seed=0, spec=HouseSpec.embedded())]
    root = dataset_root(without="embedded house only")
    if root is None:
        return out
    for name in PUBLIC[-1:] if quick else PUBLIC:
        out.append(load_house(root / name))
    return out


def time_calls(call, calls: int) -> float:
    """Seconds a call, over ``calls`` calls."""
    start = time.perf_counter()
    for _ in range(calls):
        call()
    return (time.perf_counter() - start) / calls


def measure(house, blocks: int, calls: int) -> dict[str, object]:
    """The two tables' ms a call on ``house`` under the default preset (module docstring)."""
    settings = preset(DEFAULT_PRESET)
    _, data = prepare_model_data(model_house(house, settings.data.cell_size), settings)
    dense = data
    for modality in data.modalities:
        dense = dense.with_counts(modality.name, modality.counts.clone())
    config = settings.model
    state = init(data, config, torch.Generator().manual_seed(0))
    factored_table = background_table(state, data, config)  # also compiles the kernel
    dense_table = background_table(state, dense, config)
    scale = np.maximum(np.abs(dense_table), 1e-300)
    times: dict[str, list[float]] = {"dense": [], "factored": []}
    for _ in range(blocks):
        times["dense"].append(time_calls(lambda: background_table(state, dense, config), calls))
        times["factored"].append(time_calls(lambda: background_table(state, data, config), calls))
    images = data.modality("images").factored()
    ms = {name: 1e3 * statistics.median(values) for name, values in times.items()}
    return {
        "house": house.name,
        "free_cells": data.num_free,
        "observed_cells": int(data.obs_cells.numel()),
        "image_footprints": None if images is None else int(images.sources.shape[0]),
        "image_weights": None if images is None else int(images.weights.size),
        "dense_ms": ms["dense"],
        "factored_ms": ms["factored"],
        "ratio": ms["factored"] / ms["dense"],
        "max_relative_difference": float(np.max(np.abs(factored_table - dense_table) / scale)),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke run: two houses, few calls")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="JSON output (default benchmarks/background_table.json, "
        "background_table_quick.json with --quick)",
    )
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "background_table", args.quick)
    logging.disable(logging.WARNING)  # the houses' placement notes are not this table's
    torch.set_num_threads(1)  # as `spcopyro fit` runs these maps (spcopyro._util.threads)
    blocks, calls = (3, 5) if args.quick else (9, 100)
    rows = []
    for house in houses(args.quick):
        progress(f"{house.name} ...")
        rows.append(measure(house, blocks, calls))
    print(f"== Background table, preset {DEFAULT_PRESET} (median of {blocks} blocks of "
          f"{calls} calls, alternated) ==")  # fmt: skip
    print(format_table(
        ["house", "free cells", "observed M", "footprints S", "nnz(A)", "dense ms", "factored ms",
         "factored / dense", "max rel. diff"],
        [[r["house"], str(r["free_cells"]), str(r["observed_cells"]),
          str(r["image_footprints"]), str(r["image_weights"]), f"{r['dense_ms']:.3f}",
          f"{r['factored_ms']:.3f}", f"{r['ratio']:.2f}", f"{r['max_relative_difference']:.1e}"]
         for r in rows],
    ))  # fmt: skip
    args.out.write_text(json.dumps({"machine": machine_info(), "houses": rows}, indent=1))
    progress(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
