#!/usr/bin/env python
"""Hyperparameters inferred inside the Gibbs chain: what they converge to, and what a sweep costs.

For the default synthetic house (ground truth known) and the public house room1dk5 (skipped with
a note when the dataset is absent), from the ``paper-dp`` preset's values, one chain per variant
of ``GibbsOptions.hyper`` (:mod:`spcopyro.gibbs.hyperparameters`):

``fixed`` (the baseline, measured in the same run), ``concentrations``, ``alpha``, ``gamma-pl``
(pseudo-likelihood), ``gamma-exchange``, ``all`` (alpha, concentrations, gamma by exchange).

It reports the milliseconds per sweep (and the ratio to ``fixed``), the posterior mean and sd of
every sampled hyperparameter over the second half of the sweeps, the concepts in use at the end,
and, on the synthetic house, the adjusted Rand index of the best visited state.

Usage::

    python benchmarks/hyperparameters.py                # full run
    python benchmarks/hyperparameters.py --quick        # smoke test
    python benchmarks/hyperparameters.py --sweeps 2000 --out /tmp/hyper.json

Prints a table to stdout (progress to stderr) and writes every number, with machine
information, to a JSON file (``benchmarks/hyperparameters_results.json`` unless ``--out``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import torch
from bench_cli import COUNT, INDEX, dataset_root, quick_or, results_path, run_main
from machine import available_backends, format_table, machine_info, progress

from spcopyro.config import preset
from spcopyro.data import load_house
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs import GibbsOptions, run_gibbs
from spcopyro.gibbs.hyper_options import HyperparameterOptions
from spcopyro.gibbs.hyperparameters import hyperparameter_summary
from spcopyro.synthetic import make_house

PUBLIC_HOUSE = "room1dk5"
PRESET = "paper-dp"
SEED = 0
SCRIPT_DIR = Path(__file__).resolve().parent
VARIANTS: dict[str, HyperparameterOptions] = {
    "fixed": HyperparameterOptions(),
    "concentrations": HyperparameterOptions(concentrations=True),
    "alpha": HyperparameterOptions(alpha=True),
    "gamma-pl": HyperparameterOptions(gamma="pseudolikelihood"),
    "gamma-exchange": HyperparameterOptions(gamma="exchange"),
    "all": HyperparameterOptions(alpha=True, concentrations=True, gamma="exchange"),
}


def run_variant(house, name: str, hyper: HyperparameterOptions, sweeps: int, backend: str):
    settings = preset(PRESET)
    _, data = prepare_model_data(house, settings)
    options = GibbsOptions(backend=backend, hyper=hyper)
    torch.set_num_threads(1)
    run = run_gibbs(data, settings.model, sweeps, options=options, seed=SEED, progress=False)
    row: dict[str, Any] = {
        "variant": name,
        "sweeps": sweeps,
        "ms_per_sweep": 1e3 * float(run.seconds[-1]) / sweeps,
        "concepts_final": int(run.num_concepts[-1]),
        "hyperparameters": (
            hyperparameter_summary(run.hyperparameters, settings.model, hyper)
            if run.hyperparameters is not None
            else {}
        ),
    }
    if house.truth is not None:
        from spcopyro.metrics import adjusted_rand_index

        image = np.full(house.grid.shape, -1, dtype=np.int64)
        image[house.grid.free] = run.best_state.labels.numpy()
        row["ari"] = float(adjusted_rand_index(image, house.truth))
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=COUNT, help="default 1000 (--quick: 12)")
    parser.add_argument("--public-sweeps", type=INDEX,
                        help=f"sweeps on {PUBLIC_HOUSE}, 0 for none (default 500; --quick: "
                             "0)")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="smoke test: few sweeps")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="JSON output (default benchmarks/hyperparameters_results.json, "
        "hyperparameters_results_quick.json with --quick)",
    )
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "hyperparameters_results", args.quick)
    sweeps = quick_or(args.sweeps, args.quick, 12, 1000)
    public_sweeps = quick_or(args.public_sweeps, args.quick, 0, 500)
    backend = "numba" if "numba" in available_backends(["numba"])[0] else "torch"
    houses = [("synthetic", make_house(), sweeps)]
    if public_sweeps:
        root = dataset_root(without=f"{PUBLIC_HOUSE} is left out")
        if root is not None and (root / PUBLIC_HOUSE).is_dir():
            houses.append((PUBLIC_HOUSE, load_house(root / PUBLIC_HOUSE), public_sweeps))
        elif root is not None:  # no dataset: dataset_root's one note line said so
            progress(f"note: no {PUBLIC_HOUSE} in the dataset at {root}: it is left out")
    run_variant(houses[0][1], "warm-up", VARIANTS["all"], 3, backend)  # compile numba first
    rows = []
    for house_name, house, count in houses:
        for name, hyper in VARIANTS.items():
            progress(f"{house_name}: {name}, {count} sweeps ({backend})")
            row = run_variant(house, name, hyper, count, backend)
            rows.append({"house": house_name, "backend": backend, **row})
    baseline = {r["house"]: r["ms_per_sweep"] for r in rows if r["variant"] == "fixed"}
    table = []
    for r in rows:
        values = "; ".join(
            f"{k} {v['posterior_mean']:.3g} +- {v['posterior_sd']:.2g}"
            for k, v in r["hyperparameters"].items()
        )
        r["cost_ratio"] = r["ms_per_sweep"] / baseline[r["house"]]
        table.append([r["house"], r["variant"], f"{r['ms_per_sweep']:.1f}",
                      f"{r['cost_ratio']:.1f}x", str(r["concepts_final"]),
                      f"{r['ari']:.3f}" if "ari" in r else "-", values or "(preset)"])  # fmt: skip
    print("Hyperparameters inferred (paper-dp start; posterior mean +- sd, second half)")
    header = ["house", "variant", "ms/sweep", "vs fixed", "concepts", "ARI", "values"]
    print(format_table(header, table))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    report = {"machine": machine_info(), "preset": PRESET, "seed": SEED, "rows": rows}
    args.out.write_text(json.dumps(report, indent=1, default=float) + "\n")
    progress(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    run_main(main)
