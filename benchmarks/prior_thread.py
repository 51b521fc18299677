#!/usr/bin/env python
r"""The compiled sweep's prior draw on a worker thread (issue 25 item 4), with and without a
busy neighbour.

The numba sweep draws the Gamma(b) variates of its globals whose shape does not depend on the
labels ahead, on a worker thread while the label loop runs where a CPU is spare
(:mod:`spcopyro.gibbs.numba_globals`). This benchmark times, in one run, the bare sweep
(``gibbs_sweep_numba`` in a loop, paper-dp, L = 120) on room2ldk4 (a synthetic stand-in without
the dataset) in three settings:

* ``one-pass``: the default draw (labels, then every variate on the calling thread);
* ``worker off``: the two-part draw on the calling thread (what ``auto`` does when no CPU is
  spare: many chains in threads, or one usable CPU);
* ``worker on``: the two-part draw with the worker thread (``auto`` for one chain on >= 2 CPUs);

first on the machine as it is ("as is": the CPUs other processes kept busy meanwhile are
reported), then next to ``--busy-cores`` spinning processes (``threads.busy_neighbour``), so
that the worker competes for the other core. The settings alternate in blocks of sweeps inside a
condition; each entry is the median ms a sweep over the blocks, and the ratios to ``one-pass``
are taken in the same condition. ``worker on`` and ``worker off`` draw the same numbers (checked
at the end of each condition on the final states).

Usage::

    python benchmarks/prior_thread.py                  # ~1 min on an idle 2-core machine
    python benchmarks/prior_thread.py --quick --out /tmp/prior_thread_quick.json

It prints a table to stdout (progress to stderr) and writes every number, with machine
information, to ``benchmarks/prior_thread.json`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any

import torch
from bench_cli import COUNT, dataset_root, run_main
from bench_setup import load_headline_house, make_problem
from machine import format_table, machine_info, progress
from threads import busy_neighbour, other_load

from spcopyro.config import preset
from spcopyro.gibbs import GibbsOptions, GibbsState
from spcopyro.gibbs.numba_globals import prior_thread
from spcopyro.gibbs.numba_sweep import gibbs_sweep_numba
from spcopyro.gibbs.run import advance, start_chain
from spcopyro.gibbs.state import make_sweep_plan

SCRIPT_DIR = Path(__file__).resolve().parent
SETTINGS = ("one-pass", "worker off", "worker on")
MODES = {"one-pass": "one-pass", "worker off": "off", "worker on": "on"}
"""The :func:`~spcopyro.gibbs.numba_globals.prior_thread` mode of each setting."""


def time_condition(problem, start: GibbsState, blocks: int, block: int) -> dict[str, Any]:
    """Median ms a sweep of each setting, alternating blocks of ``block`` sweeps, after one
    untimed sweep of each (the warm-up chain runs the default setting only: the first timed
    block of the others loaded their kernels, 765 ms a sweep against 9 in a --quick run)."""
    data, config = problem.data, problem.config
    plan = make_sweep_plan(data)
    states = dict.fromkeys(SETTINGS, start)
    generators = {name: torch.Generator().manual_seed(1) for name in SETTINGS}
    per_block: dict[str, list[float]] = {name: [] for name in SETTINGS}
    before = prior_thread()
    for name in SETTINGS:  # untimed: each setting's kernels loaded (or compiled), its worker up
        prior_thread(MODES[name])
        gibbs_sweep_numba(start, data, config, torch.Generator().manual_seed(0), plan)
    for _ in range(blocks):
        for name in SETTINGS:
            prior_thread(MODES[name])
            state, generator = states[name], generators[name]
            began = time.perf_counter()
            for _ in range(block):
                state = gibbs_sweep_numba(state, data, config, generator, plan)
            per_block[name].append(1e3 * (time.perf_counter() - began) / block)
            states[name] = state
    prior_thread(before)
    on, off = states["worker on"], states["worker off"]
    same = torch.equal(on.labels, off.labels) and all(
        torch.equal(a, b) for a, b in zip(on.log_emissions, off.log_emissions, strict=True)
    )
    ms = {name: statistics.median(values) for name, values in per_block.items()}
    return {
        "ms_per_sweep": ms,
        "ns_per_cell": {name: 1e6 * value / data.num_free for name, value in ms.items()},
        "over_one_pass": {name: value / ms["one-pass"] for name, value in ms.items()},
        "blocks": per_block,
        "same_draws_on_and_off": bool(same),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test")
    parser.add_argument("--busy-cores", type=COUNT, default=1, help="spinning neighbours (>= 1)")
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default benchmarks/prior_thread.json, "
                             "prior_thread_quick.json with --quick)")  # fmt: skip
    args = parser.parse_args(argv)
    blocks, block = (2, 3) if args.quick else (15, 40)
    torch.set_num_threads(1)
    dataset = dataset_root(without="a synthetic stand-in for room2ldk4 is used")
    house = load_headline_house(dataset)
    problem = make_problem(house, preset("paper-dp"))
    chain = start_chain(problem.data, problem.config, options=GibbsOptions(backend="numba"),
                        seed=0)  # fmt: skip
    advance(chain, 5 if args.quick else 200, progress=False)  # regions formed, kernels loaded
    results: dict[str, Any] = {
        "machine": machine_info(),
        "house": house.name if dataset is not None else f"{house.name} (no dataset)",
        "free_cells": problem.data.num_free,
        "preset": "paper-dp",
        "busy_cores": args.busy_cores,
        "conditions": {},
    }
    for condition in ("as is", "busy neighbour"):
        progress(f"{condition}: {blocks} blocks of {block} sweeps per setting")
        record: dict[str, Any] = {}
        if condition == "as is":
            with other_load(record):
                record.update(time_condition(problem, chain.state, blocks, block))
        else:
            with busy_neighbour(args.busy_cores, 600.0), other_load(record):
                record.update(time_condition(problem, chain.state, blocks, block))
        results["conditions"][condition] = record
    rows = []
    for condition, record in results["conditions"].items():
        for name in SETTINGS:
            rows.append([
                condition, name, f"{record['ms_per_sweep'][name]:.3f}",
                f"{record['ns_per_cell'][name]:.1f}", f"{record['over_one_pass'][name]:.2f}",
                f"{record['other_cores']:.2f}" if record.get("other_cores") is not None else "-",
            ])  # fmt: skip
    print(f"The bare compiled sweep on {results['house']} ({results['free_cells']} free cells, "
          "paper-dp, L = 120): median of alternating blocks")  # fmt: skip
    print(format_table(
        ["condition", "setting", "ms/sweep", "ns/cell", "/ one-pass", "other CPUs busy"], rows
    ))  # fmt: skip
    same = all(r["same_draws_on_and_off"] for r in results["conditions"].values())
    print(f"worker on and off drew the same chain: {same}")
    name = "prior_thread_quick.json" if args.quick else "prior_thread.json"
    out = args.out or SCRIPT_DIR / name
    out.write_text(json.dumps(results, indent=2))
    progress(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
