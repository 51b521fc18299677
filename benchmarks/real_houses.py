"""Real houses and houses the default was not tuned on (issue 21): one run, one table.

    python benchmarks/real_houses.py [--sweeps 5000] [--seeds 3] [--open-plan-seeds 10]
        [--fit-seeds 0 1 2] [--heldout-seeds 0 1 2]
        [--out benchmarks/real_houses.json]

For each public house (``$SPCOPYRO_DATA`` or ``../shared/data/spcomapping``; skipped with the
reason when absent), scored against the project's region truth
(:mod:`spcopyro.experiments.public_truth`, its method and limits in docs/real_houses.md):

* the ARI of the reported map (a fit on a coarser model grid is refined back to the map's cells
  first, :func:`spcopyro.maps.coarse.refine_labels`),
* the share of the free cells in the largest concept,
* the concepts holding >= 1 % of the free cells, beside the paper's Table 2 counts,

for the default preset (with its inference settings: since 2026-12-03 its refinement on the
map's cells where the images separate its concepts, :mod:`spcopyro.fit.refine`; the row
``coarse, --refine never`` is the same chain stopped at the model grid), the previous default
``auto``,
``paper-dp`` (the paper's Algorithm 1: random start, the best visited state), and the baselines
(E) nearest utterance and (F) geometry at 1 m and 2 m door widths. Then the same for synthetic
houses (seeds 0..n-1, ``--seeds``; their own truth): ``open-plan`` (several categories in one
walled space; ``--open-plan-seeds``, 10 since 2026-12-03),
``sparse`` (``HouseSpec.public_like``) and ``dense`` (the embedded default house), each with
a reference row that is no method: the observations' own truth regions, every free cell taking
that of the nearest observation within its walls (``observation_oracle``): how much of the
truth the observations' places decide, where nothing observed lies between them.

Further sections (each from the same run): held-out word top-1 on the public houses (fit on two
trials, predict the third's words from where they were said; each trial held out in turn, the
folds' words pooled per house, and trial 1 alone as measured before 2026-12-03; every preset at
each fit seed of ``--heldout-seeds``, default 0 1 2 since 2026-12-06, seed 0 alone before: the
mean over the seeds, a row a seed, and the target line judged on that mean beside the per-seed
differences' range; each table's means over the houses and pooled over their words), every
inference method's default on the public houses (``--method-iterations`` iterations), a
simulated tour on each public map (``simulate --map`` with its default door width, read from the
map) scored against the simulation's own truth, one row per fit seed (``--fit-seeds``, default
0 1 2) and their mean, and the default fit run four times as long.

Every Gibbs fit runs ``--sweeps`` sweeps, by default the 5000 of ``spcopyro fit`` (the default
fit; 2000 until 2026-12-03), and the four-times-as-long section 4 x that.

Prints markdown tables and writes the JSON (per house and method, and the means).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections.abc import Callable, Hashable, Sequence
from pathlib import Path
from typing import TypeVar

import numpy as np
from bench_cli import COUNT, INDEX, dataset_root, quick_or, results_path, run_main

from spcopyro.baselines.geometry import geometry_semantic_map
from spcopyro.baselines.nearest import nearest_word_map
from spcopyro.config import DEFAULT_PRESET, SpCoSettings, preset
from spcopyro.data import load_house
from spcopyro.experiments.ablation import concepts_over, largest_share
from spcopyro.experiments.open_plan import observation_oracle
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES, heldout_folds
from spcopyro.fit.house import fit_house, preset_fit_kwargs
from spcopyro.maps.coarse import labels_on_grid
from spcopyro.metrics import (
    WordPredictionScores,
    adjusted_rand_index,
    heldout_word_prediction,
)
from spcopyro.results.semantic_map import SpCoSemanticMap
from spcopyro.robot.map_simulation import MapTour, simulate_on_map
from spcopyro.synthetic import HouseSpec, make_house

PRESETS = (DEFAULT_PRESET, "auto", "paper-dp")
UNREFINED = f"{DEFAULT_PRESET}, --refine never"
"""The default fit stopped at its model grid (its row: the same chain where it was not refined)."""
SYNTHETIC = {
    "open-plan": HouseSpec.open_plan,
    "sparse": HouseSpec.public_like,
    "dense": HouseSpec,
}


def synthetic_seeds(kind: str, open_plan_seeds: int, seeds: int) -> range:
    """The house seeds of synthetic ``kind`` (of :data:`SYNTHETIC`): 0..n-1, n
    ``open_plan_seeds`` for the open-plan houses, ``seeds`` for the others."""
    return range(open_plan_seeds if kind == "open-plan" else seeds)


def synthetic_house(kind: str, seed: int):
    """Synthetic house ``seed`` of ``kind`` (of :data:`SYNTHETIC`)."""
    return make_house(seed=seed, spec=SYNTHETIC[kind]())


ORACLE = "oracle: truth at the observations, Voronoi cut"
"""The synthetic houses' reference row (:func:`~spcopyro.experiments.open_plan.observation_oracle`):
every observation's own region, each border half-way between the places' observations."""
METHODS = ("cavi", "lbp", "svi", "stochastic-vi", "vi-gibbs")


def settings_of(name: str, **overrides: object) -> SpCoSettings:
    """The settings :func:`fit_result` fits preset ``name`` with (:data:`UNREFINED`: the default
    preset's; its ``refine="never"`` is :func:`fit_result`'s): ``preset(name, **overrides)``,
    and an override of None, which ``preset`` ignores, set over the preset's value."""
    unset = {k: v for k, v in overrides.items() if v is None}
    settings = preset(DEFAULT_PRESET if name == UNREFINED else name, **overrides)
    return settings.replace(**unset) if unset else settings


def fit_result(
    house, name: str, sweeps: int, seed: int, method: str = "gibbs", **overrides: object
):
    """The preset's default fit (its recommended inference settings for Gibbs; a variational
    method with its default options) and its seconds. :data:`UNREFINED`: the default preset's
    fit without its refinement on the map's cells (``--refine never``). ``overrides``: settings
    replacing the preset's (:func:`settings_of`: a variant of it)."""
    unrefined = name == UNREFINED
    name = DEFAULT_PRESET if unrefined else name
    kwargs = preset_fit_kwargs(name) if method == "gibbs" else {}  # else fit_house's defaults
    if unrefined:
        kwargs["refine"] = "never"
    start = time.perf_counter()
    result = fit_house(house, settings_of(name, **overrides), method=method, sweeps=sweeps,
                       seed=seed, progress=False, **kwargs)  # fmt: skip
    return result, time.perf_counter() - start


def on_map(result, house) -> np.ndarray:
    """``[H, W]`` the result's labels on the house's own map cells
    (:func:`~spcopyro.maps.coarse.labels_on_grid`: a fit refined on the map's cells is there
    already, a fit on a model grid is refined from the grid it ran on, ``result.grid``)."""
    return labels_on_grid(result.label_image(), house.grid, result.grid.resolution)


def fit_preset(
    house, name: str, sweeps: int, seed: int, **overrides: object
) -> tuple[np.ndarray, float]:
    """``[H, W]`` label image of the preset's default fit (:func:`fit_result`, with
    ``overrides``: a variant of it) on the house's map, and seconds."""
    result, seconds = fit_result(house, name, sweeps, seed, **overrides)
    return on_map(result, house), seconds


def scores(labels: np.ndarray, truth: np.ndarray, free: np.ndarray) -> dict[str, float]:
    on_free = labels[free]  # [N]
    return {
        "ari": adjusted_rand_index(labels, truth),
        "largest_share": largest_share(on_free),
        "concepts_1pct": concepts_over(on_free),
    }


def nearest_scores(house, truth: np.ndarray) -> dict[str, float]:
    """:func:`scores` of the baseline (E) nearest utterance on the house (it draws nothing: one
    map). Its mean ARI over the public houses is the bar of the target "public mean ARI above
    (E)'s" (0.510, docs/real_houses.md)."""
    return scores(nearest_word_map(house.grid, house.observations).labels, truth, house.grid.free)


def score_house(
    house, truth: np.ndarray, sweeps: int, seed: int, oracle: bool = False
) -> dict[str, dict]:
    free = house.grid.free
    rows: dict[str, dict] = {}
    for name in PRESETS:
        result, seconds = fit_result(house, name, sweeps, seed)
        rows[name] = {**scores(on_map(result, house), truth, free), "seconds": seconds}
        print(f"  {house.name} {name}: ARI {rows[name]['ari']:.3f}", file=sys.stderr, flush=True)
        if name == DEFAULT_PRESET:  # and the same chain without the refinement
            rows[UNREFINED] = rows[name]
            record = result.inference.get("refine", {})
            explained = (record.get("separation") or {}).get("explained")
            refined = bool(record.get("refine"))
            rows[name] = {**rows[name], "refined": refined, "explained": explained}
            if rows[name]["refined"]:
                result, seconds = fit_result(house, UNREFINED, sweeps, seed)
                labels = on_map(result, house)
                rows[UNREFINED] = {**scores(labels, truth, free), "seconds": seconds}
    return rows | baseline_scores(house, truth, oracle)


def baseline_scores(house, truth: np.ndarray, oracle: bool = False) -> dict[str, dict]:
    """:func:`scores` of the baselines (E) nearest utterance and (F) geometry at 1 m and 2 m
    door widths (they draw nothing), and with ``oracle`` the :data:`ORACLE` reference row."""
    obs, free = house.observations, house.grid.free
    rows = {"E nearest": nearest_scores(house, truth)}
    for door in (1.0, 2.0):
        labels = geometry_semantic_map(house.grid, obs, door_width=door).labels
        rows[f"F geometry {door:g} m"] = scores(labels, truth, free)
    if oracle:  # a reference, not a method: it reads the truth at the observations
        rows[ORACLE] = scores(observation_oracle(house.grid, obs, truth), truth, free)
    return rows


SCORES = ("all folds", "trial 1", "top 3", "mean rank")
"""A held-out row's scores: top-1 of every fold's words pooled, top-1 of fold 0 alone, top-3 and
the true word's mean rank (every fold)."""


def fold_summary(folds: Sequence[WordPredictionScores]) -> dict[str, float]:
    """Each fold's scores (fold 0 first) -> the :data:`SCORES` and the words: every fold's
    words pooled (:meth:`~spcopyro.metrics.heldout.WordPredictionScores.pooled`), and fold 0
    alone. A score of no scored words is NaN (none measured), its words 0."""
    every, first = WordPredictionScores.pooled(folds), folds[0]
    return {"all folds": every.top1, "trial 1": first.top1, "top 3": every.top3,
            "mean rank": every.mean_rank, "words": every.num_scored,
            "trial 1 words": first.num_scored}  # fmt: skip


Key = TypeVar("Key", bound=Hashable)


def heldout_fold_scores(
    house, models: dict[Key, Callable[..., object]]
) -> dict[Key, list[WordPredictionScores]]:
    """Every trial of the house held out in turn (:func:`heldout_folds`): each of ``models``
    (key -> a function of the house without the held-out trial giving a model that predicts
    words, e.g. a :class:`SpCoSemanticMap`) built on the other trials and scored on the held-out
    trial's words. Key -> each fold's scores, fold 0 first; within a fold the models are built
    in the order given."""
    folds: dict[Key, list[WordPredictionScores]] = {key: [] for key in models}
    for _, _, train, test in heldout_folds(house):
        for key, build in models.items():
            folds[key].append(heldout_word_prediction(build(train), test))
    return folds


def preset_model(
    name: str, sweeps: int, seed: int, **overrides: object
) -> Callable[..., SpCoSemanticMap]:
    """A function of a house: the semantic map of the preset's default fit on it
    (:func:`fit_result` with ``overrides``), for :func:`heldout_fold_scores`."""
    return lambda house: SpCoSemanticMap(fit_result(house, name, sweeps, seed, **overrides)[0])


def heldout_top1(
    house, sweeps: int, seeds: Sequence[int] = (0,), presets: Sequence[str] = PRESETS
) -> dict[str, dict]:
    """Held-out word scores of the presets and baselines, every trial held out in turn: per
    method ``"all folds"`` (top-1, the folds' scored words pooled), ``"trial 1"`` (top-1 of
    fold 0 alone, the table's measure until 2026-12-03), ``"top 3"`` and ``"mean rank"`` (of the
    true word, all folds), ``"words"`` and ``"trial 1 words"`` (how many words all folds and
    fold 0 score).

    Each preset is fitted on every fold with each fit seed of ``seeds``: its scores are the mean
    over the seeds, and ``"seeds"`` holds each seed's (``{"S": {score: value}}``). The
    baselines (E) and (F) draw nothing and are fitted once a fold (no ``"seeds"``). Before
    2026-12-06 every preset was fitted at seed 0 alone (the same numbers as ``seeds=[0]``)."""
    if len(set(seeds)) != len(seeds) or not seeds:
        raise ValueError(f"held-out fit seeds must be distinct and at least one, got {seeds}")
    models: dict[tuple[str, int | None], Callable[..., object]] = {  # (name, fit seed)
        (name, seed): preset_model(name, sweeps, seed) for name in presets for seed in seeds
    }
    models["E nearest", None] = lambda train: nearest_word_map(train.grid, train.observations)
    models["F geometry 2 m", None] = lambda train: geometry_semantic_map(
        train.grid, train.observations, door_width=2.0)  # fmt: skip
    folds = heldout_fold_scores(house, models)
    out: dict[str, dict] = {}
    for name in presets:
        per_seed = {str(s): fold_summary(folds[name, s]) for s in seeds}
        first = next(iter(per_seed.values()))
        out[name] = {key: float(np.mean([row[key] for row in per_seed.values()])) for key in SCORES}
        out[name] |= {"words": first["words"], "trial 1 words": first["trial 1 words"],
                      "seeds": per_seed}  # fmt: skip
    for name in ("E nearest", "F geometry 2 m"):
        out[name] = fold_summary(folds[name, None])
    return out


def score(row: dict, key: str, seed: str | None = None) -> float:
    """A held-out row's (:func:`heldout_top1`'s) ``key``: fit seed ``seed``'s (its
    ``"seeds"``), else the row's own (a preset's mean over the seeds; a baseline's)."""
    return row[key] if seed is None else row["seeds"][seed][key]


def mean_of_houses(
    per_house: dict[str, dict], name: str, key: str, seed: str | None = None
) -> float:
    """A held-out score of ``name`` (:func:`score`) averaged over the houses, each the same."""
    return float(np.mean([score(per_house[h][name], key, seed) for h in per_house]))


def pooled(per_house: dict[str, dict], name: str, key: str, seed: str | None = None) -> float:
    """A held-out score of ``name`` (:func:`score`) pooled over the houses' words (a house
    weighs by the words it scores: ``"trial 1 words"`` for ``"trial 1"``, ``"words"``
    otherwise; a house that scores none weighs nothing, NaN where none does)."""
    weight = "trial 1 words" if key == "trial 1" else "words"
    rows = [per_house[h][name] for h in per_house if per_house[h][name][weight] > 0]
    words = [row[weight] for row in rows]
    values = [score(row, key, seed) for row in rows]
    return float(np.dot(values, words) / sum(words)) if rows else float("nan")


def heldout_table(title: str, per_house: dict[str, dict], key: str, note: str) -> str:
    """A held-out score per house and both means: over the houses (each house weighs the same)
    and pooled over the houses' words. A preset fitted at several seeds gets its mean over the
    seeds and a row per seed (``"NAME, seed S"``)."""
    houses = list(per_house)
    lines = [
        f"### {title}",
        "",
        "| | " + " | ".join(houses) + " | mean of houses | pooled over words |",
    ]
    lines.append("|---" * (len(houses) + 3) + "|")
    for name in next(iter(per_house.values())):
        seeds = list(per_house[houses[0]][name].get("seeds", {}))
        label = f"{name} (mean of fit seeds {', '.join(seeds)})" if len(seeds) > 1 else name
        rows = [(label, None)] + (
            [(f"{name}, seed {s}", s) for s in seeds] if len(seeds) > 1 else []
        )
        for label, seed in rows:
            values = [score(per_house[h][name], key, seed) for h in houses]
            cells = " | ".join(f"{v:.2f}" for v in values)
            both = f"{np.mean(values):.3f} | "  # the mean of houses
            both += f"{pooled(per_house, name, key, seed):.3f}"
            lines.append(f"| {label} | {cells} | {both} |")
    return "\n".join([*lines, "", note, ""])


def heldout_target(
    per_house: dict[str, dict], ours: str = DEFAULT_PRESET, theirs: str = "paper-dp"
) -> str:
    """The issue's target line, "held-out word top-1 (every fold) not below ``theirs``'", judged
    on the mean over the fit seeds (of the houses' means), with the per-seed differences' range
    and the mean's standard error over the seeds beside it: "undecided at this spread" where the
    mean difference lies within two standard errors of 0 (one seed: its spread unmeasured)."""
    if not per_house:
        return ""
    first = next(iter(per_house.values()))
    if ours not in first or theirs not in first:
        return ""
    seeds = list(first[ours]["seeds"])
    mean = {name: mean_of_houses(per_house, name, "all folds") for name in (ours, theirs)}
    diffs = [
        mean_of_houses(per_house, ours, "all folds", s)
        - mean_of_houses(per_house, theirs, "all folds", s)
        for s in seeds
    ]
    words = {name: pooled(per_house, name, "all folds") for name in (ours, theirs)}
    gap = mean[ours] - mean[theirs]
    verdict = "met" if gap >= 0 else "not met"
    if len(diffs) == 1:
        spread = "one seed: its spread unmeasured"
        verdict += " at one seed"
    else:
        error = float(np.std(diffs, ddof=1) / np.sqrt(len(diffs)))  # of the mean over seeds
        spread = f"per seed {min(diffs):+.3f} to {max(diffs):+.3f}, standard error {error:.3f}"
        if abs(gap) < 2 * error:
            verdict += " on the mean; undecided at this spread (within 2 standard errors of 0)"
    return (
        f"Target: held-out word top-1 of {ours} not below {theirs}'s (every trial held out in "
        f"turn, mean over fit seeds {', '.join(seeds)} of the mean of houses): {mean[ours]:.3f} "
        f"against {mean[theirs]:.3f}, difference {gap:+.3f} ({spread}; pooled over words "
        f"{words[ours]:.3f} against {words[theirs]:.3f}): {verdict}"
    )


def methods_on(house, truth: np.ndarray, iterations: int) -> dict[str, dict]:
    """Every other inference method's default (options and preset) on a house."""
    out = {}
    for method in METHODS:
        result, seconds = fit_result(house, DEFAULT_PRESET, iterations, 0, method=method)
        labels = on_map(result, house)
        out[method] = {**scores(labels, truth, house.grid.free), "seconds": seconds}
        print(f"  {house.name} {method}: ARI {out[method]['ari']:.3f}", file=sys.stderr, flush=True)
    return out


def map_simulation(house):
    """``simulate --map`` on the house's map: its default (the door width read from the map;
    simulation seed 0, so the same simulation every time)."""
    return simulate_on_map(house.grid, seed=0, tour=MapTour(), name=house.name)


def simulated_on(
    house,
    sweeps: int,
    fit_seeds: list[int],
    name: str = DEFAULT_PRESET,
    *,
    simulation=None,
    **overrides: object,
) -> dict[str, dict[str, float]]:
    """``simulate --map`` on the house's map (:func:`map_simulation`; ``simulation``: that one
    built already), then the default fit of preset ``name`` (with ``overrides``: a variant of
    it; :func:`fit_preset`) with each of ``fit_seeds``, scored against the simulation's truth;
    the simulated rooms are never handed to the fit. One row a fit seed (``"fit seed S"``) and
    ``"mean"`` over them."""
    if simulation is None:
        simulation = map_simulation(house)
    simulated = simulation.house
    rooms = int(simulation.room_category.size)
    rows: dict[str, dict[str, float]] = {}
    for seed in fit_seeds:
        labels, seconds = fit_preset(simulated, name, sweeps, seed, **overrides)
        scored = scores(labels, simulated.truth, simulated.grid.free)
        rows[f"fit seed {seed}"] = {
            **scored, "door_width": simulation.door_width, "rooms": rooms, "seconds": seconds,
        }  # fmt: skip
        print(f"  simulated {house.name} fit seed {seed}: ARI {scored['ari']:.3f}",
              file=sys.stderr, flush=True)  # fmt: skip
    rows["mean"] = {key: float(np.mean([row[key] for row in rows.values()]))
                    for key in ("ari", "largest_share", "door_width", "rooms")}  # fmt: skip
    return rows


def simple_table(title: str, rows: dict[str, dict[str, float]], key: str | None, note: str) -> str:
    """A value per house (``rows[house][row][key]``) and their mean over the houses."""
    houses = list(rows)
    columns = list(next(iter(rows.values())))
    lines = [f"### {title}", "", "| | " + " | ".join(houses) + " | mean of houses |"]
    lines.append("|---" * (len(houses) + 2) + "|")
    for column in columns:
        values = [rows[h][column] if key is None else rows[h][column][key] for h in houses]
        cells = " | ".join(f"{v:.2f}" for v in values)
        lines.append(f"| {column} | {cells} | {np.mean(values):.3f} |")
    return "\n".join([*lines, "", note, ""])


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
        lines.append("| paper Table 2 categories | "
                     + " | ".join(str(expected.get(h, "")) for h in houses) + " | |")  # fmt: skip
    lines += [
        "",
        "Cells: ARI (share of the largest concept, concepts holding >= 1 % of the cells).",
        "",
    ]
    return "\n".join(lines)


def extras(root: Path, args: argparse.Namespace, report: dict, names: dict) -> list[str]:
    """Held-out words, the inference methods, simulate --map and the 4x chain (module
    docstring), as markdown sections; their numbers go into ``report``."""
    houses = {name: load_house(root / name) for name in names}
    truths = {name: public_truth(h).labels for name, h in houses.items()}
    text = []
    top1 = {n: heldout_top1(h, args.sweeps, args.heldout_seeds) for n, h in houses.items()}
    report["heldout_top1"] = top1
    report["heldout_seeds"] = args.heldout_seeds
    words = ", ".join(f"{n} {next(iter(row.values()))['words']}" for n, row in top1.items())
    seeds = ", ".join(map(str, args.heldout_seeds))
    text.append(heldout_table(
        "Held-out word top-1 (each trial held out in turn)", top1, "all folds",
        f"Share of the held-out trials' words ranked first (ties at their expected position), "
        f"the three folds' words pooled per house: {words}. The presets fitted at fit seeds "
        f"{seeds} (their mean, and a row a seed where more than one), (E) and (F) once. 'mean "
        f"of houses': each house weighs the same; 'pooled over words': each word does.",
    ))  # fmt: skip
    text.append(heldout_table(
        "Held-out word top-1 (trial 1 held out alone)", top1, "trial 1",
        "The measure until 2026-12-03: one fold, as few as 4 scored words on a house.",
    ))  # fmt: skip
    text.append(heldout_table(
        "Held-out words: mean rank of the true word (each trial held out in turn)", top1,
        "mean rank", "1 is first; ties at their expected position. Top-3 shares are in the JSON.",
    ))  # fmt: skip
    text.append(heldout_target(top1))
    text.append("")
    methods = {n: methods_on(h, truths[n], args.method_iterations) for n, h in houses.items()}
    report["methods"] = methods
    text.append(simple_table(
        f"Inference methods' defaults ({args.method_iterations} iterations): ARI", methods, "ari",
        "Their largest concept's share is the next table.",
    ))  # fmt: skip
    shares = {n: {m: v["largest_share"] for m, v in row.items()} for n, row in methods.items()}
    text.append(simple_table("Inference methods' defaults: largest concept's share", shares,
                             None, "A share of 1.00 is a one-concept map."))  # fmt: skip
    simulated = {n: simulated_on(h, args.sweeps, args.fit_seeds) for n, h in houses.items()}
    report["simulated"] = simulated
    widths = ", ".join(f"{n} {row['mean']['door_width']:g} m" for n, row in simulated.items())
    text.append(simple_table(
        "simulate --map on each public map (door width read from the map), then the default fit",
        simulated, "ari",
        f"ARI against the simulation's own truth, one row a fit seed (simulation seed 0); its "
        f"rooms are never handed to the fit. Door widths: {widths}.",
    ))  # fmt: skip
    longer = {}
    for name, house in houses.items():
        longer[name] = {}
        for factor in (1, 4):
            labels, _ = fit_preset(house, DEFAULT_PRESET, factor * args.sweeps, 0)
            row = f"{factor} x {args.sweeps} sweeps"
            longer[name][row] = scores(labels, truths[name], house.grid.free)
    report["longer_chain"] = longer
    text.append(simple_table("The default, four times as long: ARI", longer, "ari",
                             "The map is the posterior's if the two rows agree."))  # fmt: skip
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sweeps", type=COUNT,
        help="sweeps of every Gibbs fit (default: spcopyro fit's 5000; --quick: 60)",
    )  # fmt: skip
    parser.add_argument(
        "--seeds", type=COUNT, help="synthetic seeds 0..n-1 (default 3; --quick: 1)"
    )
    parser.add_argument(
        "--open-plan-seeds", type=COUNT,
        help="open-plan seeds 0..n-1 (their borders in unobserved space vary by about 0.1 ARI "
        "from house to house: three seeds judged chain luck; default 10, --quick: 1)",
    )  # fmt: skip
    parser.add_argument(
        "--out", default=None,
        help="JSON output (default benchmarks/real_houses.json, "
        "real_houses_quick.json with --quick)",
    )  # fmt: skip
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument(
        "--method-iterations", type=COUNT,
        help="iterations of each variational method (and vi-gibbs' sweeps; default 200, "
        "--quick: 5)",
    )  # fmt: skip
    parser.add_argument(
        "--fit-seeds", type=INDEX, nargs="+",
        help="fit seeds of the default fit on each simulated public map (a row each, and the "
        "mean; default 0 1 2, --quick: 0)",
    )  # fmt: skip
    parser.add_argument(
        "--heldout-seeds", type=INDEX, nargs="+",
        help="fit seeds of every preset on every held-out fold (their mean, and a row each): "
        "one seed is 45 fits, about 6 min on an idle core, 15-20 min on a busy 2-core machine; "
        "default 0 1 2, --quick: 0",
    )  # fmt: skip
    parser.add_argument(
        "--no-extras", action="store_true",
        help="only the ARI tables (no held-out words, methods, simulation, 4x)",
    )  # fmt: skip
    parser.add_argument(
        "--quick", action="store_true",
        help="a smoke run: 60 sweeps, one public house, one seed, 5 iterations",
    )  # fmt: skip
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "real_houses", args.quick)
    houses = dict(PUBLIC_CATEGORIES)
    args.sweeps = quick_or(args.sweeps, args.quick, 60, 5000)
    args.seeds = quick_or(args.seeds, args.quick, 1, 3)
    args.open_plan_seeds = quick_or(args.open_plan_seeds, args.quick, 1, 10)
    args.method_iterations = quick_or(args.method_iterations, args.quick, 5, 200)
    args.fit_seeds = quick_or(args.fit_seeds, args.quick, [0], [0, 1, 2])
    args.heldout_seeds = quick_or(args.heldout_seeds, args.quick, [0], [0, 1, 2])
    if len(set(args.heldout_seeds)) != len(args.heldout_seeds):
        parser.error(f"--heldout-seeds: each seed once, got {args.heldout_seeds}")
    if args.quick:
        houses = dict(list(houses.items())[:1])
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    report: dict[str, object] = {"default_preset": DEFAULT_PRESET, "sweeps": args.sweeps}
    seeds = ", ".join(map(str, args.heldout_seeds))
    text = [f"# Real houses (default preset {DEFAULT_PRESET!r}, {args.sweeps} sweeps, seed 0; "
            f"held-out words at fit seeds {seeds})", ""]  # fmt: skip
    root = dataset_root(without="the public houses are skipped")
    if root is None:
        text.append("public houses skipped: no dataset")
    else:
        public = {}
        for name in houses:
            house = load_house(Path(root) / name)
            public[name] = score_house(house, public_truth(house).labels, args.sweeps, 0)
        report["public"] = public
        text.append(table("Public houses, against the project's region truth", public, houses))
        if not args.no_extras:
            text += extras(Path(root), args, report, houses)
    if not args.no_synthetic:
        for kind in SYNTHETIC:
            per_seed = {}
            for seed in synthetic_seeds(kind, args.open_plan_seeds, args.seeds):
                house = synthetic_house(kind, seed)
                per_seed[f"seed {seed}"] = score_house(
                    house, house.truth, args.sweeps, seed, oracle=True
                )
            report[kind] = per_seed
            text.append(table(f"Synthetic {kind} houses (own truth)", per_seed, None))
    print("\n".join(text))
    Path(args.out).write_text(json.dumps(report, indent=1, default=float))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
