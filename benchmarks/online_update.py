#!/usr/bin/env python
r"""Online updates against refits: a fit of trials 1-2 continued with trial 3 (``--update``).

For every house (the five public houses, found by ``find_dataset_root()`` and skipped with a note
when absent, and the default synthetic house, whose ground truth gives ARI and matching rate) and
every seed:

1. **old**: ``fit_house`` on the first two trials (trial ids 0 and 1: "trials 1-2"),
   S sweeps (default 5000, ``spcopyro fit``'s);
2. **scratch**: ``fit_house`` on all three trials, S sweeps from random labels (the refit);
3. **update**: :func:`spcopyro.robot.online.start_update_chain` from the old fit with all three
trials (the saved labels and globals at sweep 0, new words under the prior), then Gibbs sweeps,
   read after N = 0, 25, 50, 100, 200, 300, 500, 1000 sweeps of one chain.

Quality (all on the same model and data, so comparable): the **log joint** of the best state
visited (the MAP-visited state a fit keeps), **concepts** in use, **ARI against the scratch fit**
of the same seed (agreement; for scale, ``scratch_vs_scratch`` is the ARI between the scratch
fits of two seeds), and on the synthetic house the **ARI against the ground truth** and the
**matching rate** (precision, area prior, eq. 18) of its category words. The public houses have
no drawn ground truth. Time: seconds of sampling (the chain's clock) and wall seconds with the
data preparation; an update's time is its setup (counts over the merged vocabulary, the start
state) plus its sweeps; the old fit's time is reported but not charged to the update (it exists
already when the new trial arrives).

``reached``: the first N at which the update's best log joint is at least the scratch fit's (same
seed), None if not within the largest N.

Usage::

    python benchmarks/online_update.py                       # full run
    python benchmarks/online_update.py --quick --out /tmp/online_quick.json   # smoke test
    python benchmarks/online_update.py --preset original-code --gamma 3 --houses synthetic

It prints a table to stdout (progress to stderr) and writes every number with machine
information to a JSON file (``benchmarks/online_update_results.json``,
``online_update_results_quick.json`` with ``--quick``, unless ``--out``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from bench_cli import (
    COUNT,
    GAMMA,
    check_houses,
    dataset_root,
    preset_name,
    quick_or,
    results_path,
    run_main,
)
from machine import format_table, machine_info, progress

from spcopyro.config import preset
from spcopyro.data import House, load_house
from spcopyro.fit.house import fit_house, result_of
from spcopyro.gibbs.method import output_from_run
from spcopyro.gibbs.run import advance
from spcopyro.gibbs.sampler import trace_point
from spcopyro.metrics import adjusted_rand_index, matching_rate
from spcopyro.results.semantic_map import SpCoSemanticMap
from spcopyro.robot.online import start_update_chain
from spcopyro.synthetic import make_house

PUBLIC = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")
CHECKPOINTS = (0, 25, 50, 100, 200, 300, 500, 1000)
WINDOW = 100
"""The typical log joint of a run: the mean over its last WINDOW sweeps (fewer if it has fewer):
the level the chain sits at, unlike the best visited state, an extreme value that grows with
the number of sweeps drawn."""
OLD_TRIALS = (0, 1)


def houses(names: list[str], root: Path | None) -> list[House]:
    found = []
    for name in names:
        if name == "synthetic":
            found.append(make_house(0))
        elif root is None:
            progress(f"skipping {name}: the public dataset is not found (set SPCOPYRO_DATA)")
        else:
            found.append(load_house(root / name))
    return found


def truth_scores(result, house: House) -> dict[str, float]:
    """ARI against the ground truth and the matching rate (area prior), where there is a truth."""
    if house.truth is None or house.category_names is None:
        return {}
    area = SpCoSemanticMap(result, prior="area")
    return {
        "ari_truth": adjusted_rand_index(result.label_image(), house.truth),
        "matching_rate": matching_rate(area, house.truth, house.category_names).value,
    }


def run_house(house: House, settings, sweeps: int, seeds: list[int], checkpoints) -> dict:
    old_house = dataclasses.replace(
        house, observations=house.observations.select_trials(OLD_TRIALS)
    )
    runs: list[dict[str, Any]] = []
    scratch_labels = []
    for seed in seeds:
        progress(f"{house.name}, seed {seed}: old fit (trials 1-2), {sweeps} sweeps")
        start = time.perf_counter()
        old = fit_house(old_house, settings, sweeps=sweeps, seed=seed, progress=False)
        old_wall = time.perf_counter() - start
        progress(f"{house.name}, seed {seed}: scratch fit (trials 1-3), {sweeps} sweeps")
        start = time.perf_counter()
        scratch = fit_house(house, settings, sweeps=sweeps, seed=seed, progress=False)
        scratch_wall = time.perf_counter() - start
        scratch_labels.append(scratch.label_image())
        progress(f"{house.name}, seed {seed}: update with trial 3, up to {checkpoints[-1]} sweeps")
        start = time.perf_counter()
        chain, begun = start_update_chain(old, house, settings, seed=seed)
        setup = time.perf_counter() - start
        points = []
        for n in checkpoints:
            if n > chain.sweeps_done:
                advance(chain, n - chain.sweeps_done, progress=False)
            if n == 0:
                value, _ = trace_point(
                    chain.state, chain.data, chain.config, chain.constant, chain.backend
                )
                labels = chain.state.labels.numpy().astype(np.int64)
                result = dataclasses.replace(old, labels=labels)  # the saved map, for scoring
                seconds = 0.0
                typical = float(value)
            else:
                value = chain.best_value
                typical = float(np.mean(chain.log_joint[-min(WINDOW, n) :]))
                output = output_from_run(chain.to_run())
                result = result_of(output, house, begun.counts, begun.data, settings, "gibbs")
                seconds = float(chain.seconds[-1])
            points.append({
                "sweeps": n,
                "best_log_joint": float(value),
                "typical_log_joint": typical,
                "concepts": int(len(result.concepts_in_use())),
                "ari_vs_scratch": adjusted_rand_index(result.label_image(), scratch_labels[-1]),
                "sample_seconds": seconds,
                "seconds": setup + seconds,
                **truth_scores(result, house),
            })  # fmt: skip
        target = scratch.best_objective
        reached = next((p["sweeps"] for p in points if p["best_log_joint"] >= target), None)
        level = float(np.mean(scratch.trace.objective[-WINDOW:]))
        reached_typical = next(
            (p["sweeps"] for p in points if p["typical_log_joint"] >= level), None
        )
        runs.append({
            "seed": seed,
            "old": {"wall_seconds": old_wall, "best_log_joint_on_old_trials": old.best_objective,
                    "concepts": int(len(old.concepts_in_use()))},
            "scratch": {"wall_seconds": scratch_wall,
                        "sample_seconds": float(scratch.trace.seconds[-1]),
                        "best_log_joint": target,
                        "typical_log_joint": level,
                        "concepts": int(len(scratch.concepts_in_use())),
                        **truth_scores(scratch, house)},
            "update": {"setup_seconds": setup, "new_words": list(begun.merge.new_words),
                       "points": points},
            "reached": reached,
            "reached_typical": reached_typical,
        })  # fmt: skip
    agreement = [
        adjusted_rand_index(scratch_labels[k], scratch_labels[k + 1])
        for k in range(len(scratch_labels) - 1)
    ]
    return {
        "house": house.name,
        "free_cells": int(house.grid.num_free),
        "trials": list(house.observations.trials),
        "runs": runs,
        "scratch_vs_scratch_ari": agreement,
    }


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def table(records: list[dict], sweeps: int) -> str:
    """One row per house and update length: medians over the seeds."""
    headers = ["house", "fit", "sweeps", "best LJ - scratch", "typical LJ - scratch",
               "ARI vs scratch", "ARI truth",
               "match", "concepts", "seconds", "x scratch time"]  # fmt: skip
    rows = []
    for record in records:
        runs = record["runs"]
        scratch_seconds = _median([r["scratch"]["wall_seconds"] for r in runs])
        has_truth = "ari_truth" in runs[0]["scratch"]

        def truth(items, key, has_truth=has_truth):
            return f"{_median([i[key] for i in items]):.3f}" if has_truth else "-"

        scratch = [r["scratch"] for r in runs]
        agree = record["scratch_vs_scratch_ari"]
        rows.append([record["house"], "scratch", str(sweeps), "0", "0",
                     f"{_median(agree):.3f}*" if agree else "-", truth(scratch, "ari_truth"),
                     truth(scratch, "matching_rate"),
                     f"{_median([s['concepts'] for s in scratch]):.0f}",
                     f"{scratch_seconds:.1f}", "1"])  # fmt: skip
        for k, n in enumerate(p["sweeps"] for p in runs[0]["update"]["points"]):
            points = [r["update"]["points"][k] for r in runs]
            gap = _median([p["best_log_joint"] - r["scratch"]["best_log_joint"]
                           for p, r in zip(points, runs, strict=True)])  # fmt: skip
            typical = _median([p["typical_log_joint"] - r["scratch"]["typical_log_joint"]
                               for p, r in zip(points, runs, strict=True)])  # fmt: skip
            seconds = _median([p["seconds"] for p in points])
            rows.append(["", "update", str(n), f"{gap:+.0f}", f"{typical:+.0f}",
                         f"{_median([p['ari_vs_scratch'] for p in points]):.3f}",
                         truth(points, "ari_truth"), truth(points, "matching_rate"),
                         f"{_median([p['concepts'] for p in points]):.0f}",
                         f"{seconds:.2f}", f"{seconds / scratch_seconds:.3f}"])  # fmt: skip
        for key, lj in (("reached", "best"), ("reached_typical", "typical")):
            shown = "/".join("-" if r[key] is None else str(r[key]) for r in runs)
            rows.append(["", f"first sweeps: {lj} LJ >= scratch", shown, *[""] * 8])
    return format_table(headers, rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test: synthetic, few sweeps")
    parser.add_argument(
        "--out",
        type=Path,
        help="JSON file to write (default benchmarks/online_update_results.json, "
        "online_update_results_quick.json with --quick)",
    )
    parser.add_argument("--houses", help="comma-separated public houses and 'synthetic' (default: "
                        "the five and synthetic; --quick: synthetic)")  # fmt: skip
    parser.add_argument("--seeds", type=COUNT, help="seeds 0..n-1 (default 3; --quick: 2)")
    parser.add_argument("--sweeps", type=COUNT,
                        help="sweeps of old and scratch fits (default 5000; --quick: "
                             "40)")  # fmt: skip
    parser.add_argument("--preset", type=preset_name, default="paper-dp")
    parser.add_argument("--gamma", type=GAMMA)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    os.environ.setdefault("CI", "1")  # no progress bars
    checkpoints = (0, 5, 10) if args.quick else CHECKPOINTS
    every = ",".join((*PUBLIC, "synthetic"))
    names = [n.strip() for n in quick_or(args.houses, args.quick, "synthetic", every).split(",")]
    args.seeds = quick_or(args.seeds, args.quick, 2, 3)
    args.sweeps = quick_or(args.sweeps, args.quick, 40, 5000)
    named = args.houses is not None and set(names) != {"synthetic"}  # there, or an error
    root = dataset_root(
        without=None if named else "the public houses are skipped",
        needed_by=f"--houses {','.join(names)}",
    )
    if named:
        check_houses(root, names, synthetic=("synthetic",))
    settings = preset(args.preset, gamma=args.gamma)
    records = []
    for house in houses(names, root):
        records.append(run_house(house, settings, args.sweeps, list(range(args.seeds)),
                                 checkpoints))  # fmt: skip
    text = table(records, args.sweeps)
    print(
        f"Online update (trials 1-2 fitted, then trial 3 added) against a refit on trials 1-3; "
        f"preset {args.preset}, gamma {settings.model.gamma:g}; medians over {args.seeds} seeds"
    )
    print(text)
    print(
        f"LJ: log joint; best: of the best state visited; typical: mean over the last {WINDOW} "
        "sweeps (at N = 0: the start state's, whose globals are the saved fit's posterior means "
        "where it kept them, not draws: not comparable). * scratch row: ARI between the scratch "
        "fits of consecutive seeds (refit agreement). 'first sweeps: best (typical) LJ >= "
        "scratch': per seed, the first update length whose best (typical) log joint is at "
        "least the scratch fit's ('-': not within the last)."
    )
    out = results_path(args.out, "online_update_results", args.quick)
    record = {"machine": machine_info(), "preset": args.preset,
              "settings": settings.model.to_json(), "sweeps": args.sweeps, "seeds": args.seeds,
              "checkpoints": list(checkpoints), "houses": records}  # fmt: skip
    out.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    run_main(main)
