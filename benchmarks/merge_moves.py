#!/usr/bin/env python
r"""Split-merge moves and posterior point estimates: concepts, ARI and cost, with and without.

For each house (the default synthetic house ``make_house(seed=0)``, and a public house when the
dataset is found; skipped with a note otherwise) and each share of sweeps with a split-merge move
(:mod:`spcopyro.gibbs.merge`; 0 is the baseline, run in the same process), one Gibbs chain of S
sweeps (preset ``paper-dp`` unless ``--preset``), the step of :func:`spcopyro.gibbs.sampler.step`
with the merge move timed separately. Reported per run:

* concepts holding at least 1% of the free cells, in the last state and in the reported map
  (the highest-log-joint state visited, and the VI / Binder point estimates of
  :mod:`spcopyro.results.point_estimate` over ~50 label maps of the second half, their speck
  concepts joined to others as ``spcopyro fit``'s ``vi`` and ``binder`` join them: told by the
  words heard at each cell, :func:`spcopyro.results.posterior_means.words_per_cell`; the cells
  and specks joined are reported too);
* the adjusted Rand index of each of those maps against the ground truth (where the house has
  one);
* seconds per sweep (whole step), seconds per split-merge move, and the moves proposed and
  accepted by kind.

Usage::

    python benchmarks/merge_moves.py                     # full run
    python benchmarks/merge_moves.py --quick --out /tmp/merge_quick.json   # smoke test

It prints a table to stdout (progress to stderr) and writes every number with machine
information to ``benchmarks/merge_moves_results.json`` unless ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch
from bench_cli import (
    COUNT,
    GAMMA,
    INDEX,
    dataset_root,
    fraction,
    house_folder,
    preset_name,
    quick_or,
    run_main,
)
from machine import format_table, machine_info

from spcopyro.config import preset
from spcopyro.data import House, load_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs import GibbsOptions
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.merge import merge_move
from spcopyro.gibbs.sampler import init, step, trace_point
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.likelihood import log_joint_constant
from spcopyro.metrics import adjusted_rand_index
from spcopyro.results.point_estimate import point_estimate
from spcopyro.results.posterior_means import words_per_cell
from spcopyro.synthetic import make_house

SCRIPT_DIR = Path(__file__).resolve().parent
PUBLIC_HOUSE = "room1dk5"


def _big_concepts(labels: np.ndarray) -> int:
    sizes = np.bincount(labels)
    return int((sizes >= 0.01 * labels.shape[0]).sum())


def _ari(house: House, labels: np.ndarray) -> float | None:
    if house.truth is None:
        return None
    image = np.full(house.grid.shape, -1)
    image[house.grid.free] = labels
    return adjusted_rand_index(image, house.truth)


def run_chain(
    house: House,
    preset_name: str,
    merge_share: float,
    sweeps: int,
    seed: int,
    samples: int,
    gamma: float | None = None,
    quiet: bool = False,
) -> dict[str, object]:
    settings = preset(preset_name) if gamma is None else preset(preset_name, gamma=gamma)
    _, data = prepare_model_data(house, settings)
    config = settings.model
    generator = torch.Generator().manual_seed(seed)
    options = GibbsOptions()
    backend = get_backend(options.backend)
    plan = make_sweep_plan(data)
    constant = float(log_joint_constant(data, config))
    state = init(data, config, generator)
    thin = max(1, sweeps // (2 * samples))
    kept, best, best_labels = [], -np.inf, state.labels.numpy().copy()
    moves = {"merge": [0, 0], "split": [0, 0]}
    merge_seconds, start = 0.0, time.perf_counter()
    for sweep in range(sweeps):
        if merge_share > 0 and float(torch.rand((), generator=generator)) < merge_share:
            tick = time.perf_counter()
            state, info = merge_move(state, data, config, generator)
            merge_seconds += time.perf_counter() - tick
            moves[info.kind][0] += 1
            moves[info.kind][1] += int(info.accepted)
        state, _ = step(state, data, config, generator, sweep=sweep, options=options,
                        backend=backend, plan=plan)  # fmt: skip
        value, _ = trace_point(state, data, config, constant, backend)
        if value > best:
            best, best_labels = value, state.labels.numpy().copy()
        if sweep >= sweeps // 2 and (sweep + 1) % thin == 0:
            kept.append(state.labels.numpy().astype(np.int64))
        if not quiet and sweep % max(1, sweeps // 10) == 0:
            print(f"  sweep {sweep}: log joint {value:.1f}", file=sys.stderr)
    seconds = time.perf_counter() - start
    samples_array = np.stack(kept)
    maps = {"last": state.labels.numpy(), "map-visited": best_labels}
    cell_words = words_per_cell(data, settings.data.word_scaling)  # [N] as fit's vi, binder
    joined = {}
    for loss in ("vi", "binder"):
        tick = time.perf_counter()
        found = point_estimate(samples_array, loss, max_clusters=config.num_concepts,
                               cell_words=cell_words,
                               cell_area=house.grid.cell_area)  # fmt: skip
        maps[loss] = found.labels
        maps[f"{loss}_seconds"] = time.perf_counter() - tick
        joined[loss] = {"cells": found.speck_cells, "specks": found.specks}
    proposed = sum(v[0] for v in moves.values())
    return {
        "house": house.name,
        "preset": preset_name,
        "gamma": config.gamma,
        "merge_moves": merge_share,
        "sweeps": sweeps,
        "seed": seed,
        "free_cells": int(data.num_free),
        "samples": len(kept),
        "concepts_1pct": {k: _big_concepts(v) for k, v in maps.items() if "seconds" not in k},
        "ari": {k: _ari(house, v) for k, v in maps.items() if "seconds" not in k},
        "estimate_seconds": {k: maps[f"{k}_seconds"] for k in ("vi", "binder")},
        "specks_joined": joined,
        "seconds_per_sweep": seconds / sweeps,
        "seconds_per_merge_move": merge_seconds / proposed if proposed else None,
        "moves": {k: {"proposed": v[0], "accepted": v[1]} for k, v in moves.items()},
    }


WARMUP_SWEEPS = 3


def warm_up(house: House, preset_name: str, merge_share: float, gamma: float | None) -> None:
    """A short untimed chain of each setting (with moves: a move every sweep), so that the
    first timed chain -- the baseline -- is not charged numba's compilation or cache load."""
    print(f"{house.name}: warm-up, {WARMUP_SWEEPS} sweeps of each setting", file=sys.stderr)
    for share in (0.0, 1.0) if merge_share > 0 else (0.0,):
        run_chain(house, preset_name, share, WARMUP_SWEEPS, 0, 1, gamma, quiet=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test: a few sweeps")
    parser.add_argument("--sweeps", type=COUNT, help="default 1000 (--quick: 12)")
    parser.add_argument("--merge-moves", type=fraction, default=0.2,
                        help="share with moves, in [0, 1] (default 0.2)")  # fmt: skip
    parser.add_argument("--preset", type=preset_name, default="paper-dp")
    parser.add_argument("--gamma", type=GAMMA, help="override the preset's gamma")
    parser.add_argument("--seeds", type=INDEX, nargs="+", default=[0])
    parser.add_argument("--public", help=f"public house ('' for none; default {PUBLIC_HOUSE}, "
                        "skipped with a note without the dataset; --quick: none)")  # fmt: skip
    parser.add_argument("--out", type=Path,
                        help="JSON output (default benchmarks/merge_moves_results.json, "
                             "merge_moves_quick.json with --quick)")  # fmt: skip
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    sweeps = quick_or(args.sweeps, args.quick, 12, 1000)
    public = quick_or(args.public, args.quick, "", PUBLIC_HOUSE)
    houses = [make_house(seed=0)]
    notes = []
    if public and args.public is not None:  # asked for by name: there, or an error
        root = dataset_root(needed_by=f"--public {public}")
        houses.append(load_house(house_folder(root, public, "--public")))
    elif public:
        root = dataset_root(without="the public house is skipped")
        if root is not None:
            houses.append(load_house(house_folder(root, public, "--public")))
        else:
            notes.append("public dataset not found: the public house is skipped")
    rows = []
    for house in houses:
        warm_up(house, args.preset, args.merge_moves, args.gamma)
        for seed in args.seeds:
            for share in dict.fromkeys((0.0, args.merge_moves)):  # 0: the baseline once
                print(f"{house.name} merge_moves={share} seed={seed}", file=sys.stderr)
                rows.append(run_chain(house, args.preset, share, sweeps, seed, 50, args.gamma))
                print(json.dumps(rows[-1]), file=sys.stderr)  # each row as soon as it is done
    table = [
        [
            r["house"], r["merge_moves"], r["seed"],
            f"{r['concepts_1pct']['last']}/{r['concepts_1pct']['map-visited']}/"
            f"{r['concepts_1pct']['vi']}/{r['concepts_1pct']['binder']}",
            "-" if r["ari"]["map-visited"] is None else
            f"{r['ari']['map-visited']:.3f}/{r['ari']['vi']:.3f}/{r['ari']['binder']:.3f}",
            f"{1e3 * r['seconds_per_sweep']:.1f}",
            "-" if r["seconds_per_merge_move"] is None
            else f"{1e3 * r['seconds_per_merge_move']:.1f}",
            f"{r['moves']['merge']['accepted']}/{r['moves']['merge']['proposed']}",
            f"{r['moves']['split']['accepted']}/{r['moves']['split']['proposed']}",
        ]
        for r in rows
    ]  # fmt: skip
    header = ["house", "merge", "seed", "concepts>=1% last/MAP/VI/Binder",
              "ARI MAP/VI/Binder", "ms/sweep", "ms/move", "merges acc", "splits acc"]  # fmt: skip
    print(format_table(header, table))
    for note in notes:
        print(f"note: {note}")
    out = args.out or SCRIPT_DIR / ("merge_moves_quick.json" if args.quick else
                                    "merge_moves_results.json")  # fmt: skip
    out.write_text(json.dumps({"machine": machine_info(), "rows": rows, "notes": notes},
                              indent=1) + "\n")  # fmt: skip
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    run_main(main)
