"""Real houses and houses the default was not tuned on (issue 21): one run, one table.

    python benchmarks/real_houses.py [--sweeps 2000] [--seeds 3] [--out benchmarks/real_houses.json]

For each public house (``$SPCOPYRO_DATA`` or ``../shared/data/spcomapping``; skipped with the
reason when absent), scored against the project's region truth
(:mod:`spcopyro.experiments.public_truth`, its method and limits in docs/real_houses.md):

* the ARI of the reported map (a fit on a coarser model grid is refined back to the map's cells
  first, :func:`spcopyro.maps.coarse.refine_labels`),
* the share of the free cells in the largest concept,
* the concepts holding >= 1 % of the free cells, beside the paper's Table 2 counts,

for the default preset (with its inference settings), the previous default ``auto``,
``paper-dp`` (the paper's Algorithm 1: random start, the best visited state), and the baselines
(E) nearest utterance and (F) geometry at 1 m and 2 m door widths. Then the same for synthetic
houses (seeds 0..n-1; their own truth): ``open-plan`` (several categories in one walled space),
``sparse`` (``HouseSpec.public_like``) and ``dense`` (the embedded default house).

Prints markdown tables and writes the JSON (per house and method, and the means).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

from spcopyro.baselines.geometry import geometry_semantic_map
from spcopyro.baselines.nearest import nearest_word_map
from spcopyro.config import DEFAULT_PRESET, preset, preset_inference
from spcopyro.data import find_dataset_root, load_house
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES
from spcopyro.fit import fit_house
from spcopyro.gibbs import GibbsOptions
from spcopyro.maps.coarse import coarsening_factor, refine_labels
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import HouseSpec, make_house

PRESETS = (DEFAULT_PRESET, "auto", "paper-dp")
SYNTHETIC = {
    "open-plan": HouseSpec.open_plan,
    "sparse": HouseSpec.public_like,
    "dense": HouseSpec,
}


def fit_preset(house, name: str, sweeps: int, seed: int) -> tuple[np.ndarray, float]:
    """``[H, W]`` label image of the preset's default fit on the house's map, and seconds."""
    settings = preset(name)
    recommended = preset_inference(name)
    start = time.perf_counter()
    result = fit_house(
        house,
        settings,
        options=GibbsOptions(merge_moves=float(recommended.get("merge_moves", 0.0))),
        sweeps=sweeps,
        seed=seed,
        init=str(recommended.get("init", "random")),
        progress=False,
        marginal_samples=50
        if recommended.get("point_estimate", "map-visited") != "map-visited"
        else 0,
        point_estimate=str(recommended.get("point_estimate", "map-visited")),
    )
    seconds = time.perf_counter() - start
    factor = coarsening_factor(house.grid.resolution, settings.data.cell_size)
    return refine_labels(result.label_image(), house.grid, factor), seconds


def scores(labels: np.ndarray, truth: np.ndarray, free: np.ndarray) -> dict[str, float]:
    on_free = labels[free]
    sizes = np.bincount(on_free[on_free >= 0])
    sizes = sizes[sizes > 0]
    return {
        "ari": adjusted_rand_index(labels, truth),
        "largest_share": float(sizes.max() / sizes.sum()),
        "concepts_1pct": int((sizes >= 0.01 * sizes.sum()).sum()),
    }


def score_house(house, truth: np.ndarray, sweeps: int, seed: int) -> dict[str, dict]:
    free = house.grid.free
    rows: dict[str, dict] = {}
    for name in PRESETS:
        labels, seconds = fit_preset(house, name, sweeps, seed)
        rows[name] = {**scores(labels, truth, free), "seconds": seconds}
        print(f"  {house.name} {name}: ARI {rows[name]['ari']:.3f}", file=sys.stderr, flush=True)
    obs = house.observations
    rows["E nearest"] = scores(nearest_word_map(house.grid, obs).labels, truth, free)
    for door in (1.0, 2.0):
        labels = geometry_semantic_map(house.grid, obs, door_width=door).labels
        rows[f"F geometry {door:g} m"] = scores(labels, truth, free)
    return rows


def table(title: str, per_house: dict[str, dict[str, dict]], expected: dict | None) -> str:
    houses = list(per_house)
    methods = list(next(iter(per_house.values())))
    lines = [f"### {title}", "", "| method | " + " | ".join(houses) + " | mean |"]
    lines.append("|---" * (len(houses) + 2) + "|")
    for method in methods:
        cells = []
        for h in houses:
            s = per_house[h][method]
            cells.append(f"{s['ari']:.2f} ({100 * s['largest_share']:.0f}%, {s['concepts_1pct']})")
        mean = np.mean([per_house[h][method]["ari"] for h in houses])
        lines.append(f"| {method} | " + " | ".join(cells) + f" | {mean:.3f} |")
    if expected:
        lines.append(
            "| paper Table 2 categories | "
            + " | ".join(str(expected.get(h, "")) for h in houses)
            + " | |"
        )
    lines += [
        "",
        "Cells: ARI (share of the largest concept, concepts holding >= 1 % of the cells).",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=2000)
    parser.add_argument("--seeds", type=int, default=3, help="synthetic seeds 0..n-1")
    parser.add_argument("--out", default="benchmarks/real_houses.json")
    parser.add_argument("--no-synthetic", action="store_true")
    args = parser.parse_args(argv)
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    report: dict[str, object] = {"default_preset": DEFAULT_PRESET, "sweeps": args.sweeps}
    text = [f"# Real houses (default preset {DEFAULT_PRESET!r}, {args.sweeps} sweeps, seed 0)", ""]
    root = find_dataset_root()
    if root is None:
        text.append(
            "public houses skipped: no dataset at $SPCOPYRO_DATA or ../shared/data/spcomapping"
        )
    else:
        public = {}
        for name in PUBLIC_CATEGORIES:
            house = load_house(Path(root) / name)
            public[name] = score_house(house, public_truth(house).labels, args.sweeps, 0)
        report["public"] = public
        text.append(
            table("Public houses, against the project's region truth", public, PUBLIC_CATEGORIES)
        )
    if not args.no_synthetic:
        for kind, spec in SYNTHETIC.items():
            per_seed = {}
            for seed in range(args.seeds):
                house = make_house(seed=seed, spec=spec())
                per_seed[f"seed {seed}"] = score_house(house, house.truth, args.sweeps, seed)
            report[kind] = per_seed
            text.append(table(f"Synthetic {kind} houses (own truth)", per_seed, None))
    print("\n".join(text))
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
