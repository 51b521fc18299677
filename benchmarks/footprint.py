"""Does the observation footprint let words and images shape the map? (issue 14, item 4)

For each house and seed, SpCoMapping is fitted by Gibbs sampling (random start, the same seed)

* with the observations switched off (``use_images = use_words = False``: the MRF alone), and
* with them, at every footprint radius R (``DataPreparation.footprint_radius``; 0 = the paper),

and each fit reports: the ARI against the ground-truth rooms (synthetic houses), the ARI
against the same seed's fit without observations (1 = the data did not move the map; lower =
they did), the number of concepts holding at least 1% of the free cells, the number of cells the
data reach (M) and the seconds of the fit.

Houses: ``synthetic`` (the embedded default, 5% of its cells observed), ``synthetic-sparse``
(the same floor plans with one image and one utterance per room and trial, about as sparse as
the public houses), and the public houses (``room1dk5`` ...) where the dataset is found.

Run ``python benchmarks/footprint.py`` (``--quick`` for a smoke run); it prints a table and
writes ``benchmarks/footprint_results.json`` (``footprint_quick.json`` with --quick), or --out.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch
from bench_cli import COUNT, INDEX, METRES, WRITTEN, check_houses, dataset_root, quick_or, run_main
from machine import format_table, machine_info, progress

from spcopyro.config import preset
from spcopyro.data import load_house
from spcopyro.experiments.methods import fit_spco
from spcopyro.fit.house import prepare_model_data
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import HouseSpec, make_house

SCRIPT_DIR = Path(__file__).resolve().parent
SYNTHETIC = ("synthetic", "synthetic-sparse")
PUBLIC = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")
SPARSE_SPEC = dict(images_per_room_per_trial=1, utterances_per_room_per_trial=1)
WARMUP_SWEEPS = 2
"""Sweeps of the untimed fits (without and with observations) before the first timed one."""
PRESETS = {
    "paper-dp": dict(),
    "original-code-g3": dict(gamma=3.0),
}


def _house(name: str, seed: int, root: Path | None):
    if name == "synthetic":
        return make_house(seed=seed)
    if name == "synthetic-sparse":
        return make_house(seed=seed, spec=HouseSpec(**SPARSE_SPEC), name="synthetic-sparse")
    if root is None:
        return None
    return load_house(root / name)


def _settings(preset_name: str, **changes: object):
    base = "original-code" if preset_name.startswith("original-code") else preset_name
    return preset(base, **PRESETS[preset_name], **changes)


def partial_path(out: Path) -> Path:
    """Where the rows done so far are kept while ``out`` is being computed (removed when
    ``out`` is written)."""
    return out.with_suffix(".partial.json")


def run(args: argparse.Namespace) -> dict[str, object]:
    torch.set_num_threads(1)
    root = dataset_root(without="synthetic houses only")
    rows = []
    warmed = False
    for preset_name in args.presets:
        for house_name in args.houses:
            for seed in args.seeds:
                # a synthetic house of each seed; a public house is the same for every seed
                house = _house(house_name, seed, root)
                if house is None:
                    continue
                free = house.grid.num_free
                off = _settings(preset_name, use_images=False, use_words=False)
                if not warmed:  # the first timed fit paid numba's load: 1.5 s against 0.1
                    for settings in (off, _settings(preset_name)):
                        fit_spco(house, settings, sweeps=WARMUP_SWEEPS, seed=seed)
                    warmed = True
                start = time.perf_counter()
                plain, _ = fit_spco(house, off, sweeps=args.sweeps, seed=seed)
                seconds = time.perf_counter() - start
                plain_image = plain.label_image()
                fits = [("no observations", None, plain, seconds, 0)]
                for radius in args.radii:
                    settings = _settings(preset_name, footprint_radius=radius)
                    counts, _ = prepare_model_data(house, settings)
                    start = time.perf_counter()
                    result, _ = fit_spco(house, settings, sweeps=args.sweeps, seed=seed)
                    seconds = time.perf_counter() - start
                    fits.append((f"R = {radius:g} m", radius, result, seconds, len(counts.cells)))
                for label, radius, result, seconds, reached in fits:
                    image = result.label_image()
                    sizes = np.bincount(result.labels, minlength=result.config.num_concepts)
                    row = {
                        "preset": preset_name, "house": house_name, "seed": seed,
                        "fit": label, "radius": radius, "free_cells": free,
                        "cells_reached": reached,
                        "ari_truth": None if house.truth is None
                        else adjusted_rand_index(image, house.truth),
                        "ari_vs_no_observations": adjusted_rand_index(image, plain_image),
                        "concepts_1pct": int((sizes >= 0.01 * free).sum()),
                        "seconds": seconds,
                    }  # fmt: skip
                    row["_image"] = image
                    rows.append(row)
                    if args.out is not None:  # partial results survive an interrupted run
                        partial = [{k: v for k, v in r.items() if k != "_image"} for r in rows]
                        partial_path(args.out).write_text(json.dumps(partial))
                        if partial_path(args.out) not in WRITTEN:
                            WRITTEN.append(partial_path(args.out))  # named if interrupted
                    progress(
                        f"{preset_name} {house_name} seed {seed} {label}: ARI truth "
                        f"{row['ari_truth']}, vs no obs {row['ari_vs_no_observations']:.3f}, "
                        f"{row['concepts_1pct']} concepts >= 1%, {seconds:.1f} s"
                    )
    _seed_agreement(rows)
    return {
        "machine": machine_info(),
        "sweeps": args.sweeps,
        "seeds": list(args.seeds),
        "radii": list(args.radii),
        "rows": rows,
    }


def _seed_agreement(rows: list[dict]) -> None:
    """Each public-house row gets ``ari_between_seeds``: its map's mean ARI with the maps of the
    other seeds' fits of the same setting (how much the data pin the map down); synthetic
    houses differ per seed (None). Drops the rows' label images."""
    for row in rows:
        others = [
            r["_image"] for r in rows
            if (r["preset"], r["house"], r["fit"]) == (row["preset"], row["house"], row["fit"])
            and r["seed"] != row["seed"]
        ]  # fmt: skip
        public = not row["house"].startswith("synthetic")
        row["ari_between_seeds"] = (
            float(np.mean([adjusted_rand_index(row["_image"], o) for o in others]))
            if public and others
            else None
        )
    for row in rows:
        del row["_image"]


def _mean_sd(values: list[float]) -> str:
    if not values:
        return "-"
    if len(values) == 1:
        return f"{values[0]:.3f}"
    return f"{np.mean(values):.3f} +- {np.std(values, ddof=1):.3f}"


def summary_table(results: dict[str, object]) -> str:
    rows = results["rows"]
    keys = list(dict.fromkeys((r["preset"], r["house"], r["fit"]) for r in rows))
    table = []
    for preset_name, house, fit in keys:
        group = [
            r for r in rows if (r["preset"], r["house"], r["fit"]) == (preset_name, house, fit)
        ]
        truth = [r["ari_truth"] for r in group if r["ari_truth"] is not None]
        seeds = [r["ari_between_seeds"] for r in group if r["ari_between_seeds"] is not None]
        table.append([
            f"{preset_name} {house}", fit, _mean_sd(truth),
            _mean_sd([r["ari_vs_no_observations"] for r in group]), _mean_sd(seeds),
            f"{np.mean([r['concepts_1pct'] for r in group]):.1f}",
            f"{np.mean([r['cells_reached'] / r['free_cells'] for r in group]):.3f}",
            f"{np.mean([r['seconds'] for r in group]):.1f}",
        ])  # fmt: skip
    headers = ["preset house", "fit", "ARI truth", "ARI vs no obs", "ARI seeds", "concepts>=1%",
               "share of cells reached", "s / fit"]  # fmt: skip
    return format_table(headers, table)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run (seconds)")
    parser.add_argument("--sweeps", type=COUNT, help="default 1000 (--quick: 20)")
    parser.add_argument("--seeds", type=INDEX, nargs="+", help="default 0 1 2 (--quick: 0)")
    parser.add_argument("--radii", type=METRES, nargs="+",
                        help="footprint radii, metres (default 0 0.5 1 2; --quick: "
                             "0 0.5)")  # fmt: skip
    parser.add_argument("--houses", nargs="+",
                        help=f"{', '.join(SYNTHETIC)} and public houses (default: all; --quick: "
                             "synthetic-sparse)")  # fmt: skip
    parser.add_argument("--presets", nargs="+", choices=list(PRESETS),
                        help="default: all (--quick: original-code-g3)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default benchmarks/footprint_results.json, "
                             "footprint_quick.json with --quick; OUT.partial.json while it "
                             "runs)")  # fmt: skip
    args = parser.parse_args(argv)
    named = args.houses is not None
    args.sweeps = quick_or(args.sweeps, args.quick, 20, 1000)
    args.seeds = quick_or(args.seeds, args.quick, [0], [0, 1, 2])
    args.radii = quick_or(args.radii, args.quick, [0.0, 0.5], [0.0, 0.5, 1.0, 2.0])
    args.houses = quick_or(args.houses, args.quick, ["synthetic-sparse"], [*SYNTHETIC, *PUBLIC])
    args.presets = quick_or(args.presets, args.quick, ["original-code-g3"], list(PRESETS))
    if named and set(args.houses) - set(SYNTHETIC):  # asked for by name: there, or an error
        root = dataset_root(needed_by=f"--houses {' '.join(args.houses)}")
        check_houses(root, args.houses, synthetic=SYNTHETIC)
    out = args.out or SCRIPT_DIR / (
        "footprint_quick.json" if args.quick else "footprint_results.json"
    )
    results = run(args)
    print(f"Footprint: {args.sweeps} sweeps, seeds {args.seeds}")
    print(summary_table(results))
    out.write_text(json.dumps(results, indent=1))
    partial_path(out).unlink(missing_ok=True)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
