"""The two-stage image weight against the default ``coarse`` (issue 21, an experiment; the
statistic and the rule in :mod:`spcopyro.fit.image_weight`, the numbers in docs/real_houses.md,
"What is still open").

    python benchmarks/two_stage.py [--sweeps 2000] [--seeds 3] [--fit-seeds 0 1 2]
        [--out benchmarks/two_stage.json] [--quick]

On every house of ``real_houses.py`` (the five public houses against the project's region
truth, fit seed 0; ``simulate --map`` on each public map against the simulation's truth, fit
seeds ``--fit-seeds``; the open-plan, sparse and dense synthetic houses, seeds 0..n-1), each
row the same house and seed:

* ``coarse``: the default, ``--sweeps`` sweeps (the benchmark's row);
* ``coarse 2x``: the default, twice as many sweeps (the two-stage fit's total budget);
* ``two-stage``: the default for ``--sweeps``, then the image weight from its concepts
  (:func:`~spcopyro.fit.image_weight.image_weight`) and ``--sweeps`` more with
  ``feature_scaling`` = that weight, started from the first fit's labels;
* ``two-stage auto``: where the rule gives the largest weight, preset ``auto`` (images as 100
  draws on the map's own cells, words once at their cell) fitted afresh for ``--sweeps``;
  elsewhere the ``two-stage`` row's map.

Also the first fit's ``explained`` share and the weight, held-out word top-1 on the public
houses (fold 0) for ``coarse`` and ``two-stage``, and (F) geometry at 2 m on the open-plan houses
(the margin the issue asks for). Prints markdown tables and writes the JSON.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np
from bench_cli import COUNT, INDEX, dataset_root, quick_or, results_path, run_main
from real_houses import on_map, scores  # a script beside this one (its folder is on sys.path)

from spcopyro.baselines.geometry import geometry_semantic_map
from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.data import load_house
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES, heldout_folds
from spcopyro.fit.house import fit_house, preset_fit_kwargs
from spcopyro.fit.image_weight import TOP, fit_two_stage
from spcopyro.metrics import heldout_word_prediction
from spcopyro.results.semantic_map import SpCoSemanticMap
from spcopyro.robot.map_simulation import MapTour, simulate_on_map
from spcopyro.synthetic import HouseSpec, make_house

SYNTHETIC = {"open-plan": HouseSpec.open_plan, "sparse": HouseSpec.public_like, "dense": HouseSpec}
ROWS = ("coarse", "coarse 2x", "two-stage", "two-stage auto")


def two_stage(house, sweeps: int, seed: int):
    kwargs = preset_fit_kwargs(DEFAULT_PRESET)
    return fit_two_stage(house, preset(DEFAULT_PRESET), first_sweeps=sweeps, second_sweeps=sweeps,
                         seed=seed, progress=False, **kwargs)  # fmt: skip


def fit_labels(house, name: str, sweeps: int, seed: int) -> np.ndarray:
    result = fit_house(house, preset(name), sweeps=sweeps, seed=seed, progress=False,
                       **preset_fit_kwargs(name))  # fmt: skip
    return on_map(result, house)


def compare(house, truth: np.ndarray, sweeps: int, seed: int) -> dict[str, dict]:
    """The four rows of the module docstring on one house and seed."""
    free = house.grid.free
    start = time.perf_counter()
    rows = {"coarse": scores(fit_labels(house, DEFAULT_PRESET, sweeps, seed), truth, free)}
    rows["coarse 2x"] = scores(fit_labels(house, DEFAULT_PRESET, 2 * sweeps, seed), truth, free)
    fit = two_stage(house, sweeps, seed)
    rows["two-stage"] = {
        **scores(on_map(fit.result, house), truth, free),
        "explained": fit.separation.explained,
        "kappa_within": fit.separation.kappa_within,
        "kappa_whole": fit.separation.kappa_whole,
        "weight": fit.weight,
    }
    if fit.weight >= TOP:
        rows["two-stage auto"] = scores(fit_labels(house, "auto", sweeps, seed), truth, free)
    else:
        rows["two-stage auto"] = dict(rows["two-stage"])
    aris = ", ".join(f"{k} {v['ari']:.3f}" for k, v in rows.items())
    print(f"  {house.name} seed {seed}: {aris}"
          f" (explained {fit.separation.explained:.2f}, weight {fit.weight:.3g}, "
          f"{time.perf_counter() - start:.0f} s)", file=sys.stderr, flush=True)  # fmt: skip
    return rows


def heldout(house, sweeps: int) -> dict[str, float]:
    """Held-out word top-1 (fold 0) of ``coarse`` and ``two-stage``."""
    _, _, train, test = next(iter(heldout_folds(house)))
    coarse = fit_house(train, preset(DEFAULT_PRESET), sweeps=sweeps, seed=0, progress=False,
                       **preset_fit_kwargs(DEFAULT_PRESET))  # fmt: skip
    staged = two_stage(train, sweeps, 0)
    return {
        "coarse": heldout_word_prediction(SpCoSemanticMap(coarse), test).top1,
        "two-stage": heldout_word_prediction(SpCoSemanticMap(staged.result), test).top1,
        "weight": staged.weight,
    }


def table(title: str, group: dict[str, dict[str, dict]]) -> str:
    """One markdown table: a column per house and seed, a row per fit, and the mean."""
    columns = list(group)
    lines = [f"### {title}", "", "| | " + " | ".join(columns) + " | mean |"]
    lines.append("|---" * (len(columns) + 2) + "|")
    for row in ROWS:
        aris = [group[c][row]["ari"] for c in columns]
        cells = [f"{group[c][row]['ari']:.3f} ({100 * group[c][row]['largest_share']:.0f}%)"
                 for c in columns]  # fmt: skip
        lines.append(f"| {row} | " + " | ".join(cells) + f" | {np.mean(aris):.3f} |")
    explained = [group[c]["two-stage"]["explained"] for c in columns]
    weights = [group[c]["two-stage"]["weight"] for c in columns]
    lines.append("| first fit's explained share | " + " | ".join(f"{e:.2f}" for e in explained)
                 + " | |")  # fmt: skip
    lines.append("| weight | " + " | ".join(f"{w:.3g}" for w in weights) + " | |")
    return "\n".join([*lines, "", "Cells: ARI (share of the largest concept).", ""])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=COUNT, help="default 2000 (--quick: 40)")
    parser.add_argument("--seeds", type=COUNT, help="synthetic seeds 0..n-1 (default 3; quick: 1)")
    parser.add_argument("--fit-seeds", type=INDEX, nargs="+",
                        help="fit seeds of the simulated public maps (default 0 1 2; --quick: "
                             "0)")  # fmt: skip
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/two_stage.json, two_stage_quick.json with --quick)",
    )
    parser.add_argument("--quick", action="store_true",
                        help="a smoke run: 40 sweeps, one house of each kind")  # fmt: skip
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "two_stage", args.quick)
    names = list(PUBLIC_CATEGORIES)[:1] if args.quick else list(PUBLIC_CATEGORIES)
    args.sweeps = quick_or(args.sweeps, args.quick, 40, 2000)
    args.seeds = quick_or(args.seeds, args.quick, 1, 3)
    args.fit_seeds = quick_or(args.fit_seeds, args.quick, [0], [0, 1, 2])
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    report: dict[str, object] = {"sweeps": args.sweeps}
    text = [f"# Two-stage image weight against {DEFAULT_PRESET!r} ({args.sweeps} sweeps a stage)"]
    root = dataset_root(without="the public houses are skipped")
    if root is None:
        text.append("public houses skipped: no dataset")
    else:
        houses = {name: load_house(Path(root) / name) for name in names}
        public = {n: compare(h, public_truth(h).labels, args.sweeps, 0) for n, h in houses.items()}
        report["public"] = public
        text.append(table("Public houses (fit seed 0), against the region truth", public))
        top1 = {n: heldout(h, args.sweeps) for n, h in houses.items()}
        report["heldout_top1"] = top1
        text += ["### Held-out word top-1 (fold 0)", "", "| | " + " | ".join(top1) + " | mean |",
                 "|---" * (len(top1) + 2) + "|"]  # fmt: skip
        for row in ("coarse", "two-stage"):
            values = [top1[n][row] for n in top1]
            text.append(f"| {row} | " + " | ".join(f"{v:.2f}" for v in values)
                        + f" | {np.mean(values):.3f} |")  # fmt: skip
        text.append("")
        simulated = {}
        for name, house in houses.items():
            sim = simulate_on_map(house.grid, seed=0, tour=MapTour(), name=name).house
            for seed in args.fit_seeds:
                simulated[f"{name} fit {seed}"] = compare(sim, sim.truth, args.sweeps, seed)
        report["simulated"] = simulated
        text.append(table("simulate --map on the public maps, against the simulation's truth",
                          simulated))  # fmt: skip
    for kind, spec in SYNTHETIC.items():
        group = {}
        for seed in range(args.seeds):
            house = make_house(seed=seed, spec=spec())
            group[f"seed {seed}"] = compare(house, house.truth, args.sweeps, seed)
            if kind == "open-plan":
                geometry = geometry_semantic_map(house.grid, house.observations, door_width=2.0)
                group[f"seed {seed}"]["F geometry 2 m"] = scores(
                    geometry.labels, house.truth, house.grid.free
                )
        report[kind] = group
        text.append(table(f"Synthetic {kind} houses (own truth)", group))
        if kind == "open-plan":
            f_mean = np.mean([group[s]["F geometry 2 m"]["ari"] for s in group])
            text.append(f"(F) geometry 2 m on these houses: mean ARI {f_mean:.3f}\n")
    print("\n".join(text))
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
