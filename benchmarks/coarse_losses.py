"""Where the default (preset ``coarse``) loses on the synthetic houses and the simulated maps
(issue 21; the numbers are in docs/real_houses.md, "Where coarse still loses").

    python benchmarks/coarse_losses.py [--sweeps 2000] [--seeds 3] [--fit-seeds 0]
        [--out benchmarks/coarse_losses.json] [--quick] [--two-stage]

For the dense (:class:`HouseSpec`) and sparse (:meth:`HouseSpec.public_like`) synthetic houses,
seeds 0..n-1, and ``simulate --map`` on room1dk6 and room1ldk5 (the dataset's maps, its default
door width, simulation seed 0; fit seeds ``--fit-seeds``), against each house's own truth:

* **ceiling**: the ARI of the truth itself taken to the model grid (each free model cell the
  majority category of its map cells) and back (:func:`~spcopyro.maps.coarse.refine_labels`):
  what a perfect fit on that grid scores;
* the default fit's **ARI**, and its errors: **region-level** ARI (each truth region labelled
  with the concept holding most of it: below 1 when two regions share a concept, i.e. merged),
  regions **split** (a second concept holding > 10 % of a region), **specks** (concepts under
  1 % of the cells), **wrong** cells (not in their region's majority concept) and how many of
  them lie within 0.3 / 0.6 / 1 m of a truth border;
* **model or sampler**: the log joint of the fitted map minus that of the region-level map on
  the model grid (pi, theta, w integrated out, term by term as in ``collapse_terms.py``);
  positive: the model prefers the fit's errors.

``--two-stage``: the same for the two-stage fit (:func:`spcopyro.fit.image_weight.fit_two_stage`,
``--sweeps`` a stage), its log joint under the refit's image weight.

Prints a markdown table and writes the rows as JSON. ``--quick``: 60 sweeps, seed 0, room1dk6
only (a smoke run).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
from pathlib import Path

import numpy as np
from bench_cli import COUNT, INDEX, dataset_root, quick_or, results_path, run_main
from collapse_terms import terms  # a script beside this one (its folder is on sys.path)
from scipy import ndimage

from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.data import load_house
from spcopyro.data.model_grid import model_house
from spcopyro.fit.house import fit_house, prepare_model_data, preset_fit_kwargs
from spcopyro.fit.image_weight import fit_two_stage
from spcopyro.maps.coarse import (
    coarsen_grid,
    coarsening_factor,
    model_cell_of,
    refine_labels,
)
from spcopyro.metrics import adjusted_rand_index
from spcopyro.robot.map_simulation import MapTour, simulate_on_map
from spcopyro.synthetic import HouseSpec, make_house


def ceiling(house, truth: np.ndarray, cell_size: float | None) -> float:
    """ARI of the truth taken to the model grid by majority and refined back to the map."""
    grid = house.grid
    factor = coarsening_factor(grid.resolution, cell_size)
    if factor == 1:
        return 1.0
    coarse_free = np.asarray(coarsen_grid(grid, factor).free)  # [h, w]
    rows, cols = model_cell_of(grid, factor)
    labelled = np.asarray(grid.free) & (truth >= 0)  # [H, W]
    rr, cc = np.nonzero(labelled)
    votes = np.zeros((*coarse_free.shape, int(truth.max()) + 1), dtype=np.int64)  # [h, w, K]
    np.add.at(votes, (rows[rr], cols[cc], truth[rr, cc]), 1)
    labels = np.where(coarse_free & votes.any(-1), votes.argmax(-1), -1)  # [h, w]
    return adjusted_rand_index(refine_labels(labels, grid, factor), truth)


def border_distance(truth: np.ndarray, labelled: np.ndarray) -> np.ndarray:
    """``[H, W]`` cells to the nearest cell beside a border between two truth regions."""
    t = np.where(labelled, truth, -1)
    border = np.zeros(t.shape, dtype=bool)
    for dr, dc in ((0, 1), (1, 0)):
        a, b = t[: t.shape[0] - dr, : t.shape[1] - dc], t[dr:, dc:]
        edge = (a >= 0) & (b >= 0) & (a != b)
        border[: t.shape[0] - dr, : t.shape[1] - dc] |= edge
        border[dr:, dc:] |= edge
    return ndimage.distance_transform_edt(~border)


def errors(labels: np.ndarray, truth: np.ndarray, house) -> dict[str, object]:
    """Region-level ARI, split regions, specks, wrong cells and their distance to a border."""
    ok = np.asarray(house.grid.free) & (truth >= 0) & (labels >= 0)  # [H, W]
    table = np.zeros((int(truth.max()) + 1, int(labels.max()) + 1), dtype=np.int64)
    np.add.at(table, (truth[ok], labels[ok]), 1)
    majority = table.argmax(1)  # [T] concept holding most of each region
    region_level = np.where(ok, majority[np.clip(truth, 0, None)], -1)
    sizes = table.sum(1)
    second = np.sort(table, axis=1)[:, -2] if table.shape[1] > 1 else np.zeros_like(sizes)
    split = {int(r): round(float(second[r] / sizes[r]), 2)
             for r in np.flatnonzero(sizes) if second[r] > 0.1 * sizes[r]}  # fmt: skip
    concept_sizes = np.bincount(labels[ok])
    wrong = ok & (labels != region_level)
    metres = border_distance(truth, ok) * house.grid.resolution
    return {
        "region_level_ari": round(adjusted_rand_index(region_level, np.where(ok, truth, -1)), 3),
        "split": split,
        "specks": int(((concept_sizes > 0) & (concept_sizes < 0.01 * ok.sum())).sum()),
        "wrong": int(wrong.sum()),
        "free": int(ok.sum()),
        "wrong_within_0.3_0.6_1m": [int((wrong & (metres <= d)).sum()) for d in (0.3, 0.6, 1.0)],
    }


def model_or_sampler(house, truth: np.ndarray, result, settings) -> dict[str, float]:
    """Log joint of the fit minus that of the region-level map on the model grid, by term."""
    model = model_house(dataclasses.replace(house, truth=truth), settings.data.cell_size)
    _, data = prepare_model_data(model, settings)
    free = np.asarray(model.grid.free)
    fit = np.asarray(result.label_image())[free].astype(np.int64)  # [N]
    regions = np.asarray(model.truth)[free]  # [N]
    labelled = regions >= 0
    table = np.zeros((int(regions.max()) + 1, int(fit.max()) + 1), dtype=np.int64)
    np.add.at(table, (regions[labelled], fit[labelled]), 1)
    region_level = np.where(labelled, table.argmax(1)[np.clip(regions, 0, None)], fit)
    a, b = terms(fit, data, settings.model), terms(region_level, data, settings.model)
    out = {k: round(a[k] - b[k], 1) for k in a}
    out["total"] = round(sum(out.values()), 1)
    return out


HEADERS = (
    "house", "ARI", "ceiling", "region-level ARI", "regions split (share)", "specks",
    "wrong cells", "of them within 0.3 / 0.6 / 1 m of a border",
    "fit minus region-level map: total (labels, Potts, images, words) nats",
)  # fmt: skip


def table_row(
    name: str, ari: float, top: float, e: dict[str, object], joint: dict[str, float]
) -> list[str]:
    """One row of the printed table (the JSON keeps the numbers as they are): the split regions,
    the wrong cells by distance and the log joint's terms as text, not Python's dict and list
    reprs ("{1: 0.47}", "[7, 7, 7]", "{'labels': 0.0, ...}") the table printed before."""
    split = ", ".join(f"{r}: {100 * share:.0f} %" for r, share in e["split"].items()) or "-"
    within = " / ".join(str(n) for n in e["wrong_within_0.3_0.6_1m"])
    terms_ = ", ".join(f"{joint[k]:+.1f}" for k in ("labels", "potts", "images", "words"))
    return [
        name, f"{ari:.3f}", f"{top:.3f}", f"{e['region_level_ari']:.3f}", split,
        str(e["specks"]), f"{e['wrong']} of {e['free']}", within,
        f"{joint['total']:+.1f} ({terms_})",
    ]  # fmt: skip


def houses(seeds: int, fit_seeds: list[int], maps: tuple[str, ...]):
    for kind, spec in (("dense", HouseSpec), ("sparse", HouseSpec.public_like)):
        for seed in range(seeds):
            house = make_house(seed=seed, spec=spec())
            yield f"{kind} {seed}", house, house.truth, seed
    root = dataset_root(without="the simulated maps are skipped")
    if root is None:
        return
    for name in maps:
        grid = load_house(Path(root) / name).grid
        simulated = simulate_on_map(grid, seed=0, tour=MapTour(), name=name).house
        for fit_seed in fit_seeds:
            yield f"sim {name} (fit seed {fit_seed})", simulated, simulated.truth, fit_seed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=COUNT, help="default 2000 (--quick: 60)")
    parser.add_argument("--seeds", type=COUNT, help="synthetic seeds 0..n-1 (default 3; quick: 1)")
    parser.add_argument("--fit-seeds", type=INDEX, nargs="+", default=[0], help="simulated maps")
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/coarse_losses.json, "
        "coarse_losses_quick.json with --quick)",
    )
    parser.add_argument("--quick", action="store_true", help="60 sweeps, seed 0, room1dk6 only")
    parser.add_argument("--two-stage", action="store_true",
                        help="take apart the two-stage fit (spcopyro.fit.image_weight: --sweeps "
                        "a stage) instead of the default's")  # fmt: skip
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "coarse_losses", args.quick)
    maps = ("room1dk6",) if args.quick else ("room1dk6", "room1ldk5")
    args.sweeps = quick_or(args.sweeps, args.quick, 60, 2000)
    args.seeds = quick_or(args.seeds, args.quick, 1, 3)
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    settings = preset(DEFAULT_PRESET)
    # the coarse fit itself, on its model grid: what the refinement starts from
    kwargs = {**preset_fit_kwargs(DEFAULT_PRESET), "refine": "never"}
    print("| " + " | ".join(HEADERS) + " |")
    print("|" + "---|" * len(HEADERS))
    rows = {}
    for name, house, truth, seed in houses(args.seeds, args.fit_seeds, maps):
        fitted = settings
        if args.two_stage:
            staged = fit_two_stage(house, settings, first_sweeps=args.sweeps,
                                   second_sweeps=args.sweeps, seed=seed, progress=False,
                                   **kwargs)  # fmt: skip
            result, fitted = staged.result, settings.replace(feature_scaling=staged.weight)
        else:
            result = fit_house(house, settings, sweeps=args.sweeps, seed=seed, progress=False,
                               **kwargs)  # fmt: skip
        factor = coarsening_factor(house.grid.resolution, settings.data.cell_size)
        labels = refine_labels(result.label_image(), house.grid, factor)
        e = errors(labels, truth, house)
        joint = model_or_sampler(house, truth, result, fitted)  # the refit's model if two-stage
        ari = adjusted_rand_index(labels, truth)
        top = ceiling(house, truth, settings.data.cell_size)
        rows[name] = {"ari": ari, "ceiling": top, **e, "fit_minus_region_level": joint}
        print("| " + " | ".join(table_row(name, ari, top, e, joint)) + " |", flush=True)
    Path(args.out).write_text(json.dumps({"sweeps": args.sweeps, "houses": rows}, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
