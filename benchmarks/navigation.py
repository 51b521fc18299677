"""Does ``navigate`` drive to the right place? Held-out place words on the public and synthetic
houses (issue 27 item 4), on the default preset's map and on the paper's (``paper-dp``).

    python benchmarks/navigation.py [--sweeps 2000] [--seeds 3] [--radius 0.2]
                                    [--planner hierarchical|grid] [--houses H ...]
                                    [--out benchmarks/navigation.json] [--quick]

Per public house (``$SPCOPYRO_DATA`` or ``../shared/data/spcomapping``): the first trial is held
out (fold 0 of :func:`spcopyro.experiments.table.heldout_folds`), each preset of :data:`PRESETS`
(the default, ``coarse``, and ``paper-dp``) is fitted on the others with its recommended
inference settings (:func:`spcopyro.fit.house.preset_fit_kwargs`, seed 0, ``--sweeps``), and the
robot starts where the held-out trial's first image was taken. For every held-out utterance of a
place word (:data:`~spcopyro.experiments.public_truth.PLACE_CATEGORIES`) that the fit knows,
``navigate`` plans to the word on the house's own map (0.05 m cells, ``--radius``, the
hierarchical planner unless ``--planner grid``); **success**: the goal lies in the truth region
of the word's category (:func:`~spcopyro.experiments.public_truth.public_truth`, built from
every trial's words). The **baseline** drives to the training utterance of the same word
nearest to the start by path (snapped to the nearest cell the robot fits on); success the same
way. **path / shortest**: the path's length over the shortest path from the start into the
truth region (the median over the successes of that method): 1 is the shortest possible way
into the right region; the goal is a region's middle, so a success is longer. Also per preset:
the share of plans that kept every leg to its route over the place graph (no fallback to the
grid path) and the median **detour**, the path over the shortest grid path to the same goal.

The truth is a geodesic Voronoi partition of the place words' positions, training ones
included, so a training utterance lies in its own word's region unless it is a stray: the
baseline is favoured by construction (docs/real_houses.md says the same of baseline E).

Synthetic houses (``HouseSpec.embedded()``, the commands' default house, seeds 0..n-1): the
same, scored against their own truth, with a place word being a category name, the robot of the
same ``--radius`` (their doorways are 0.7-0.9 m wide; before 2026-12-03 the benchmark drew
``HouseSpec()``, whose 0.2-0.4 m doorways needed a radius of 0.05 m).

Prints markdown tables and writes the JSON (per house, per method, per word).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np
from bench_cli import (
    COUNT,
    METRES,
    check_houses,
    dataset_root,
    quick_or,
    results_path,
    run_main,
)

from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.data import load_house, place_observations
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES, heldout_folds
from spcopyro.fit.house import fit_house, preset_fit_kwargs
from spcopyro.robot.navigation import NavigationError, navigate, planning_grid
from spcopyro.robot.navigation.graph import shortest_paths
from spcopyro.robot.navigation.places import place_graph
from spcopyro.synthetic import HouseSpec, make_house

PRESETS = (DEFAULT_PRESET, "paper-dp")
"""The maps whose goals are scored: the default preset's and the paper's (DP prior)."""


def fit_preset(house, name: str, sweeps: int, seed: int):
    """``name``'s recommended Gibbs fit (as ``spcopyro fit --preset name`` runs it)."""
    return fit_house(house, preset(name), sweeps=sweeps, seed=seed, progress=False,
                     **preset_fit_kwargs(name))  # fmt: skip


def nearest_allowed(planning, xy: np.ndarray) -> int:
    """The allowed cell nearest to a point (Euclidean)."""
    centres = planning.grid.cell_to_world(planning.allowed.free_cells)  # [M, 2]
    return int(np.argmin(np.hypot(*(centres - xy).T)))


def _median(values) -> float:
    values = [v for v in values if np.isfinite(v)]
    return float(np.median(values)) if values else float("nan")


def score_plans(result, words, house, planning, start_xy, truth_at, shortest, planner):
    """Per word: does ``navigate`` on ``result`` reach the word's truth region, its path length
    over the shortest one into the region, and how the path was planned."""
    places = place_graph(result)
    out = {}
    for word, category in words.items():
        try:
            plan = navigate(result, word, start_xy, radius=planning.radius, grid=house.grid,
                            planning=planning, places=places, planner=planner)  # fmt: skip
        except (NavigationError, ValueError) as error:  # unreachable, or an unknown word
            out[word] = {"success": False, "length_ratio": float("nan"), "planned": None,
                         "detour": float("nan"), "error": str(error)}  # fmt: skip
            continue
        row, col = house.grid.world_to_cell(np.array(plan.goal.xy))
        ok = bool(truth_at[row, col] == category)
        best = shortest[category]
        ratio = plan.length / best if ok and best > 0 else (1.0 if ok else float("nan"))
        out[word] = {"success": ok, "length_ratio": ratio, "planned": plan.planned,
                     "detour": plan.length / plan.grid_length if plan.grid_length > 0 else 1.0,
                     "places": len(places.places)}  # fmt: skip
    return out


def score_house(house, truth: np.ndarray, category_of, sweeps: int, seed: int, radius: float,
                planner: str = "hierarchical", presets=PRESETS):  # fmt: skip
    """Success rates and path lengths of navigate on every preset's map and of the
    nearest-training-utterance baseline, fold 0 (module docstring)."""
    _, _, train, test = next(iter(heldout_folds(house)))
    planning = planning_grid(house.grid, radius)
    start = nearest_allowed(planning, test.image_xy[0])
    start_xy = tuple(house.grid.cell_to_world(planning.cells(np.array([start]))[0]))
    distance, _ = shortest_paths(planning, start)  # [M]
    allowed_truth = truth[planning.allowed.free_cells[:, 0], planning.allowed.free_cells[:, 1]]
    train_words = [u[-1].lower() for u in train.observations.utterances]
    train_cells = [nearest_allowed(planning, xy) for xy in train.observations.word_xy]
    results, methods = {}, {}
    for name in presets:
        start_time = time.perf_counter()
        results[name] = fit_preset(train, name, sweeps, seed)
        methods[name] = {"fit_seconds": time.perf_counter() - start_time}
    known = set(results[presets[0]].vocabulary)  # the same training words for every preset
    _, _, unplaced = place_observations(house.grid, test.word_xy, 0.25)
    held = []  # the held-out place words the fit knows, one per utterance
    for word_tokens, off in zip(test.utterances, unplaced, strict=True):
        word = word_tokens[-1].lower()
        if category_of(word) is not None and not off and word in known:
            held.append(word)
    words = {w: category_of(w) for w in dict.fromkeys(held)}
    shortest = {}
    for category in set(words.values()):
        region = allowed_truth == category
        shortest[category] = float(distance[region].min()) if region.any() else float("nan")
    per_word = {w: {} for w in words}
    for word, category in words.items():  # the baseline: the nearest training utterance
        same = [c for w, c in zip(train_words, train_cells, strict=True) if w == word]
        target = min(same, key=lambda c: distance[c]) if same else None
        ok = bool(target is not None and np.isfinite(distance[target])
                  and allowed_truth[target] == category)  # fmt: skip
        best = shortest[category]
        ratio = float(distance[target]) / best if ok and best > 0 else (1.0 if ok else np.nan)
        per_word[word]["baseline"] = {"success": ok, "length_ratio": ratio}
    for name, result in results.items():
        scored = score_plans(result, words, house, planning, start_xy, truth, shortest, planner)
        for word in words:
            per_word[word][name] = scored[word]
    summary = {}
    for method in (*presets, "baseline"):
        rows = [per_word[w][method] for w in held]
        summary[method] = {
            "success": float(np.mean([r["success"] for r in rows])) if rows else float("nan"),
            "length_ratio": _median(r["length_ratio"] for r in rows if r["success"]),
            **methods.get(method, {}),
        }
        if method != "baseline":
            summary[method]["hierarchical"] = (
                float(np.mean([r["planned"] == "hierarchical" for r in rows])) if rows
                else float("nan"))  # fmt: skip
            summary[method]["detour"] = _median(r["detour"] for r in rows)
    return {"utterances": len(held), **summary, "per_word": per_word}


def table(title: str, rows: dict[str, dict], presets=PRESETS) -> str:
    methods = (*presets, "baseline")
    head = " | ".join(f"{m} success | {m} path/shortest" for m in methods)
    lines = [f"### {title}", "", f"| house | utterances | {head} |",
             "|---|---|" + "---|---|" * len(methods)]  # fmt: skip
    for name, r in rows.items():
        cells = " | ".join(f"{r[m]['success']:.2f} | {r[m]['length_ratio']:.2f}" for m in methods)
        lines.append(f"| {name} | {r['utterances']} | {cells} |")
    means = " | ".join(f"{np.mean([r[m]['success'] for r in rows.values()]):.3f} | "
                       for m in methods)  # fmt: skip
    lines += [f"| mean | | {means} |", ""]
    lines += ["How the paths were planned (share of utterances whose plan kept every leg to its "
              "route's places; median path length over the shortest grid path to the same goal):",
              "", "| house | " + " | ".join(f"{m} hierarchical | {m} detour" for m in presets)
              + " |", "|---|" + "---|---|" * len(presets)]  # fmt: skip
    for name, r in rows.items():
        cells = " | ".join(f"{r[m]['hierarchical']:.2f} | {r[m]['detour']:.2f}" for m in presets)
        lines.append(f"| {name} | {cells} |")
    return "\n".join(lines + [""])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=COUNT, help="default 2000 (--quick: 30)")
    parser.add_argument("--seeds", type=COUNT, help="synthetic seeds 0..n-1 (default 3; quick: 1)")
    parser.add_argument("--radius", type=METRES, default=0.2, help="the robot's, metres")
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/navigation.json, navigation_quick.json with --quick)",
    )
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument("--no-public", action="store_true")
    parser.add_argument("--planner", choices=("hierarchical", "grid"), default="hierarchical")
    parser.add_argument("--houses", nargs="+",
                        help="public houses (default: all five; --quick: the first)")  # fmt: skip
    parser.add_argument("--quick", action="store_true",
                        help="a smoke run: 30 sweeps, one public house, one seed")  # fmt: skip
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "navigation", args.quick)
    houses = quick_or(args.houses, args.quick, list(PUBLIC_CATEGORIES)[:1], list(PUBLIC_CATEGORIES))
    args.sweeps = quick_or(args.sweeps, args.quick, 30, 2000)
    args.seeds = quick_or(args.seeds, args.quick, 1, 3)
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    report: dict[str, object] = {"presets": list(PRESETS), "sweeps": args.sweeps,
                                 "radius": args.radius, "planner": args.planner}  # fmt: skip
    text = [f"# navigate on held-out place words (maps of {', '.join(PRESETS)}; {args.sweeps} "
            f"sweeps, fold 0; {args.planner} planner)", ""]  # fmt: skip
    named = args.houses is not None and not args.no_public  # there, or an error
    root = dataset_root(
        without=None if named else "the public houses are skipped",
        needed_by=f"--houses {' '.join(houses)}",
    )
    if named:
        check_houses(root, houses)
    if root is None:
        text.append("public houses skipped: no dataset")
    elif not args.no_public:
        public = {}
        for name in houses:
            house = load_house(Path(root) / name)
            truth = public_truth(house)
            public[name] = score_house(house, truth.labels, truth.category_of_word, args.sweeps,
                                       0, args.radius, args.planner)  # fmt: skip
            print(f"  {name}: " + ", ".join(f"{m} {public[name][m]['success']:.2f}"
                                            for m in (*PRESETS, "baseline")),
                  file=sys.stderr, flush=True)  # fmt: skip
        report["public"] = public
        text.append(table(f"Public houses (radius {args.radius:g} m)", public))
    if not args.no_synthetic:
        synthetic = {}
        for seed in range(args.seeds):
            house = make_house(seed=seed, spec=HouseSpec.embedded())
            names = house.category_names or ()

            def category_of(word: str, names=names) -> int | None:
                return names.index(word) if word in names else None

            synthetic[f"seed {seed}"] = score_house(
                house, house.truth, category_of, args.sweeps, seed, args.radius, args.planner
            )
        report["synthetic"] = synthetic
        text.append(table(f"Synthetic houses (radius {args.radius:g} m)", synthetic))
    print("\n".join(text))
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
