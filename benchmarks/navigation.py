"""Does ``navigate`` drive to the right place? Held-out place words on the public and synthetic
houses (issue 27 item 4).

    python benchmarks/navigation.py [--sweeps 2000] [--seeds 3] [--radius 0.2]
                                    [--out benchmarks/navigation.json] [--quick]

Per public house (``$SPCOPYRO_DATA`` or ``../shared/data/spcomapping``): the first trial is held
out (fold 0 of :func:`spcopyro.experiments.table.heldout_folds`), the default preset is fitted on
the others (its recommended inference settings, seed 0, ``--sweeps``), and the robot starts
where the held-out trial's first image was taken. For every held-out utterance of a place word
(:data:`~spcopyro.experiments.public_truth.PLACE_CATEGORIES`) that the fit knows, ``navigate``
plans to the word on the house's own map (``--map``: 0.05 m cells, ``--radius``); **success**:
the goal lies in the truth region of the word's category
(:func:`~spcopyro.experiments.public_truth.public_truth`, built from every trial's words). The
**baseline** drives to the training utterance of the same word nearest to the start by path
(snapped to the nearest cell the robot fits on); success the same way. Also the path's length
over the shortest path from the start into the truth region (``navigate`` successes only).

The truth is a geodesic Voronoi partition of the place words' positions, training ones
included, so a training utterance lies in its own word's region unless it is a stray: the
baseline is favoured by construction (docs/real_houses.md says the same of baseline E).

Synthetic houses (``HouseSpec()``, seeds 0..n-1): the same, scored against their own truth,
with a place word being a category name; their doorways are 0.2-0.3 m wide, so the robot there
has a radius of 0.05 m.

Prints a markdown table and writes the JSON.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.data import find_dataset_root, load_house, place_observations
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES, heldout_folds
from spcopyro.fit.house import fit_house, preset_fit_kwargs
from spcopyro.robot.navigation import NavigationError, navigate, planning_grid
from spcopyro.robot.navigation.graph import shortest_paths
from spcopyro.synthetic import HouseSpec, make_house

SYNTHETIC_RADIUS = 0.05


def fit_default(house, sweeps: int, seed: int):
    return fit_house(house, preset(DEFAULT_PRESET), sweeps=sweeps, seed=seed, progress=False,
                     **preset_fit_kwargs(DEFAULT_PRESET))  # fmt: skip


def nearest_allowed(planning, xy: np.ndarray) -> int:
    """The allowed cell nearest to a point (Euclidean)."""
    centres = planning.grid.cell_to_world(planning.allowed.free_cells)  # [M, 2]
    return int(np.argmin(np.hypot(*(centres - xy).T)))


def score_house(house, truth: np.ndarray, category_of, sweeps: int, seed: int, radius: float):
    """Success rates of navigate and of the nearest-training-utterance baseline on fold 0."""
    _, _, train, test = next(iter(heldout_folds(house)))
    start_time = time.perf_counter()
    result = fit_default(train, sweeps, seed)
    fit_seconds = time.perf_counter() - start_time
    planning = planning_grid(house.grid, radius)
    start = nearest_allowed(planning, test.image_xy[0])
    start_xy = tuple(house.grid.cell_to_world(planning.cells(np.array([start]))[0]))
    distance, _ = shortest_paths(planning, start)  # [M]
    allowed_truth = truth[planning.allowed.free_cells[:, 0], planning.allowed.free_cells[:, 1]]
    train_words = [u[-1].lower() for u in train.observations.utterances]
    train_cells = [nearest_allowed(planning, xy) for xy in train.observations.word_xy]
    _, _, unplaced = place_observations(house.grid, test.word_xy, 0.25)
    rows, cache = [], {}
    for word_tokens, off in zip(test.utterances, unplaced, strict=True):
        word = word_tokens[-1].lower()
        category = category_of(word)
        if category is None or off or word not in result.vocabulary:
            continue
        if word not in cache:
            try:
                plan = navigate(result, word, start_xy, radius=radius, grid=house.grid,
                                planning=planning)  # fmt: skip
                row, col = house.grid.world_to_cell(np.array(plan.goal.xy))
                ok = bool(truth[row, col] == category)
                length = plan.length
            except NavigationError:
                ok, length = False, float("nan")
            region = allowed_truth == category
            shortest = float(distance[region].min()) if region.any() else float("nan")
            same = [c for w, c in zip(train_words, train_cells, strict=True) if w == word]
            if same:
                target = min(same, key=lambda c: distance[c])
                baseline = bool(np.isfinite(distance[target]) and allowed_truth[target] == category)
            else:
                baseline = False
            ratio = length / shortest if ok and shortest > 0 else (1.0 if ok else float("nan"))
            cache[word] = {"navigate": ok, "baseline": baseline, "length_ratio": ratio}
        rows.append({"word": word, **cache[word]})
    n = len(rows)
    ratios = [r["length_ratio"] for r in rows if r["navigate"] and np.isfinite(r["length_ratio"])]
    return {
        "utterances": n,
        "navigate": float(np.mean([r["navigate"] for r in rows])) if n else float("nan"),
        "baseline": float(np.mean([r["baseline"] for r in rows])) if n else float("nan"),
        "length_ratio": float(np.median(ratios)) if ratios else float("nan"),
        "per_word": {w: v for w, v in cache.items()},
        "fit_seconds": fit_seconds,
    }


def table(title: str, rows: dict[str, dict]) -> str:
    lines = [f"### {title}", "", "| house | utterances | navigate | nearest training utterance "
             "| median path / shortest |", "|---|---|---|---|---|"]  # fmt: skip
    for name, r in rows.items():
        lines.append(f"| {name} | {r['utterances']} | {r['navigate']:.2f} | {r['baseline']:.2f} "
                     f"| {r['length_ratio']:.2f} |")  # fmt: skip
    nav = np.mean([r["navigate"] for r in rows.values()])
    base = np.mean([r["baseline"] for r in rows.values()])
    lines += [f"| mean | | {nav:.3f} | {base:.3f} | |", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=2000)
    parser.add_argument("--seeds", type=int, default=3, help="synthetic seeds 0..n-1")
    parser.add_argument("--radius", type=float, default=0.2, help="metres (public houses)")
    parser.add_argument("--out", default="benchmarks/navigation.json")
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument("--quick", action="store_true",
                        help="a smoke run: 30 sweeps, one public house, one seed")  # fmt: skip
    args = parser.parse_args(argv)
    houses = list(PUBLIC_CATEGORIES)
    if args.quick:
        args.sweeps, args.seeds, houses = 30, 1, houses[:1]
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    report: dict[str, object] = {"default_preset": DEFAULT_PRESET, "sweeps": args.sweeps,
                                 "radius": args.radius}  # fmt: skip
    text = [f"# navigate on held-out place words (preset {DEFAULT_PRESET!r}, {args.sweeps} "
            "sweeps, fold 0)", ""]  # fmt: skip
    root = find_dataset_root()
    if root is None:
        text.append("public houses skipped: no dataset at $SPCOPYRO_DATA")
    else:
        public = {}
        for name in houses:
            house = load_house(Path(root) / name)
            truth = public_truth(house)
            public[name] = score_house(house, truth.labels, truth.category_of_word, args.sweeps,
                                       0, args.radius)  # fmt: skip
            print(f"  {name}: navigate {public[name]['navigate']:.2f}, baseline "
                  f"{public[name]['baseline']:.2f}", file=sys.stderr, flush=True)  # fmt: skip
        report["public"] = public
        text.append(table(f"Public houses (radius {args.radius:g} m)", public))
    if not args.no_synthetic:
        synthetic = {}
        for seed in range(args.seeds):
            house = make_house(seed=seed, spec=HouseSpec())
            names = house.category_names or ()

            def category_of(word: str, names=names) -> int | None:
                return names.index(word) if word in names else None

            synthetic[f"seed {seed}"] = score_house(house, house.truth, category_of, args.sweeps,
                                                    seed, SYNTHETIC_RADIUS)  # fmt: skip
        report["synthetic"] = synthetic
        text.append(table(f"Synthetic houses (radius {SYNTHETIC_RADIUS:g} m)", synthetic))
    print("\n".join(text))
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
