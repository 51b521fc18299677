"""Stability and sensitivity of SpCoMapping on synthetic houses (issue 4, the paper's open problem).

* :func:`stability_study`: the spread (mean, sd, min) over seeds of the ARI against the truth for
  the DP variants (``paper-dp``; ``original-code`` values with gamma 3) and the Dirichlet one
  (``paper-dirichlet``, L = the number of categories), from random labels and -- for the DP
  variants -- from the SpCoA pre-learning (paper Section 5, eqs. 21-22) and from random labels with
  gamma annealed over the first fifth of the sweeps (:mod:`spcopyro.gibbs.anneal`) or with
  Swendsen-Wang cluster moves in a tenth of the sweeps (:mod:`spcopyro.gibbs.cluster`); each with
  one chain and with the best of K chains (the chain whose MAP-visited state has the highest log
  joint, :func:`spcopyro.fit.house.best_chain`), and the ARI between the K chains' maps
  (:func:`spcopyro.metrics.chain_ari`).
  It reports which DP settings are at least as stable (sd of ARI over seeds no larger) as the
  Dirichlet prior with one chain from random labels (the paper's row B).
* :func:`sensitivity_study`: one-at-a-time sweeps of gamma (around the Potts critical coupling
  ln(1 + sqrt(L)) = 2.48 for L = 120), beta, chi and alpha from
  ``preset("original-code", gamma=3.0)``: mean ARI and concepts in use over seeds.

The sd is the sample standard deviation (ddof 1); it is NaN with a single seed.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from spcopyro.config import SpCoSettings, preset
from spcopyro.fit.house import best_chain, fit_house, fit_house_chains
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.metrics import adjusted_rand_index, pairwise_chain_ari
from spcopyro.synthetic import HouseSpec, make_house

ANNEAL_FRACTION = 0.2
"""Share of a run's sweeps spent annealing gamma (:mod:`spcopyro.gibbs.anneal`), when annealed."""
CLUSTER_MOVES = 0.1
"""Share of sweeps that start with a Swendsen-Wang move (:mod:`spcopyro.gibbs.cluster`), when
the setting uses them."""


class StabilitySetting(NamedTuple):
    """One row of the stability study."""

    method: str
    """SpCoMapping row of :mod:`spcopyro.experiments.methods` (its configuration)."""
    init: str = "random"
    """``init`` of :func:`~spcopyro.fit.house.fit_house`."""
    anneal: bool = False
    """Anneal gamma over the first :data:`ANNEAL_FRACTION` of the sweeps."""
    cluster_moves: float = 0.0
    """``GibbsOptions.cluster_moves``: the share of sweeps that start with a Swendsen-Wang move."""


STABILITY_SETTINGS: dict[str, StabilitySetting] = {
    "A-dp random": StabilitySetting("A-dp"),
    "A-orig-g3 random": StabilitySetting("A-orig-g3"),
    "B-dirichlet random": StabilitySetting("B-dirichlet"),
    "A-dp spcoa": StabilitySetting("A-dp", "spcoa"),
    "A-orig-g3 spcoa": StabilitySetting("A-orig-g3", "spcoa"),
    "A-dp random anneal": StabilitySetting("A-dp", anneal=True),
    "A-orig-g3 random anneal": StabilitySetting("A-orig-g3", anneal=True),
    "A-dp random cluster": StabilitySetting("A-dp", cluster_moves=CLUSTER_MOVES),
    "A-orig-g3 random cluster": StabilitySetting("A-orig-g3", cluster_moves=CLUSTER_MOVES),
}
"""Setting name -> :class:`StabilitySetting`."""

REFERENCE_SETTING = "B-dirichlet random"
"""The setting the DP variants are compared with, with one chain (the paper's row B)."""
CHAIN_SEED_STRIDE = 1000
"""Chain k of house seed s runs with seed ``s + CHAIN_SEED_STRIDE * k`` (chain 0: seed s)."""

SENSITIVITY_BASE = dict(preset="original-code", gamma=3.0)
"""The configuration every one-at-a-time sweep of :func:`sensitivity_study` starts from."""
SENSITIVITY_GRID: dict[str, tuple[float, ...]] = {
    "gamma": (2.0, 2.48, 3.0, 4.0),
    "beta": (0.1, 10.0, 500.0),
    "chi": (1.0, 100.0, 1e4),
    "alpha": (1e2, 1e5, 1e7),
}


def method_settings(method: str, num_categories: int) -> SpCoSettings:
    """The settings of an SpCoMapping row (as :func:`~.methods.spco_settings`)."""
    from spcopyro.experiments.methods import spco_settings

    return spco_settings(method, num_categories)


def spread(values: Sequence[float]) -> dict[str, float]:
    """``{"mean", "sd", "min"}`` of ``values`` (sample sd, ddof 1; NaN for fewer than 2)."""
    array = np.asarray(values, dtype=np.float64)  # [n]
    if array.size == 0:
        raise ValueError("spread of no values")
    sd = float(array.std(ddof=1)) if array.size > 1 else math.nan
    return {"mean": float(array.mean()), "sd": sd, "min": float(array.min())}


def _check_runs(sweeps: int, seeds: tuple[int, ...], chains: int | None = None) -> None:
    if not isinstance(sweeps, int) or sweeps < 1:
        raise ValueError(f"sweeps must be a positive integer, got {sweeps!r}")
    if len(seeds) == 0:
        raise ValueError("seeds must name at least one synthetic house")
    if chains is not None and (not isinstance(chains, int) or chains < 2):
        raise ValueError(f"chains must be an integer >= 2 (best of K, chain ARI), got {chains!r}")


def stability_study(
    *,
    sweeps: int,
    seeds: tuple[int, ...] = (0, 1, 2),
    chains: int = 3,
    spec: HouseSpec | None = None,
) -> dict:
    """Spread of the ARI over synthetic houses for every setting of :data:`STABILITY_SETTINGS`.

    For house seed s and setting, K = ``chains`` chains run with seeds s + 1000 k. Per setting:
    ``single`` (chain 0's ARI per seed), ``best_of_chains`` (ARI of the chain of highest best log
    joint, :func:`best_chain`), ``chain_ari`` (mean ARI between the K chains' maps, per seed),
    ``chains`` (per seed, per chain: ARI and best log joint), and their ``summary`` spreads.
    ``at_least_as_stable``: the DP settings and modes (single / best of K) whose sd of ARI is at
    most that of :data:`REFERENCE_SETTING` with one chain.
    """
    _check_runs(sweeps, seeds, chains)
    settings: dict[str, dict] = {
        name: {"method": setting.method, "init": setting.init,
               "anneal_sweeps": int(ANNEAL_FRACTION * sweeps) if setting.anneal else 0,
               "cluster_moves": setting.cluster_moves,
               "single": [], "best_of_chains": [], "chain_ari": [], "chains": []}
        for name, setting in STABILITY_SETTINGS.items()
    }  # fmt: skip
    for seed in seeds:
        house = make_house(seed=seed, spec=spec)
        num_categories = len(house.category_names)
        for row in settings.values():
            options = GibbsOptions(
                cluster_moves=row["cluster_moves"], anneal_sweeps=row["anneal_sweeps"]
            )
            results = fit_house_chains(
                house, method_settings(row["method"], num_categories), options=options,
                sweeps=sweeps, seeds=[seed + CHAIN_SEED_STRIDE * k for k in range(chains)],
                init=row["init"], progress=False,
            )  # fmt: skip
            aris = [adjusted_rand_index(r.label_image(), house.truth) for r in results]  # [K]
            pairs = pairwise_chain_ari([r.labels for r in results])  # [K, K]
            row["single"].append(aris[0])
            row["best_of_chains"].append(aris[best_chain(results)])
            row["chain_ari"].append(float(pairs[np.triu_indices(chains, k=1)].mean()))
            row["chains"].append(
                [{"ari": a, "best_log_joint": r.best_objective}
                 for a, r in zip(aris, results, strict=True)]
            )  # fmt: skip
    for row in settings.values():
        row["summary"] = {
            mode: spread(row[mode]) for mode in ("single", "best_of_chains", "chain_ari")
        }
    reference_sd = settings[REFERENCE_SETTING]["summary"]["single"]["sd"]
    stable = [
        f"{name} / {mode}"
        for name, row in settings.items()
        if row["method"] != "B-dirichlet"
        for mode in ("single", "best_of_chains")
        if row["summary"][mode]["sd"] <= reference_sd
    ]
    return {
        "sweeps": sweeps, "seeds": list(seeds), "chains": chains, "settings": settings,
        "reference": f"{REFERENCE_SETTING} / single", "reference_sd": reference_sd,
        "at_least_as_stable": stable,
    }  # fmt: skip


def sensitivity_study(
    *,
    sweeps: int,
    seeds: tuple[int, ...] = (0, 1, 2),
    grid: dict[str, tuple[float, ...]] | None = None,
    spec: HouseSpec | None = None,
) -> dict:
    """One-at-a-time sweeps from :data:`SENSITIVITY_BASE` over :data:`SENSITIVITY_GRID` (or
    ``grid``): per parameter and value, the ARI and the number of concepts in use per seed
    (one chain of seed s from random labels on the house of seed s) and their means. A value
    equal to the base's is fitted once and shared between the parameters."""
    _check_runs(sweeps, seeds)
    grid = SENSITIVITY_GRID if grid is None else grid
    base = preset(str(SENSITIVITY_BASE["preset"]), gamma=SENSITIVITY_BASE["gamma"])
    for name in grid:
        if name not in ("gamma", "alpha", "beta", "chi"):
            raise ValueError(f"sensitivity grid parameter must be gamma/alpha/beta/chi: {name!r}")
    houses = [make_house(seed=seed, spec=spec) for seed in seeds]
    cache: dict[SpCoSettings, tuple[list[float], list[int]]] = {}

    def scores(config: SpCoSettings) -> tuple[list[float], list[int]]:
        if config not in cache:
            aris, concepts = [], []
            for seed, house in zip(seeds, houses, strict=True):
                result = fit_house(house, config, sweeps=sweeps, seed=seed, progress=False)
                aris.append(adjusted_rand_index(result.label_image(), house.truth))
                concepts.append(len(result.concepts_in_use()))
            cache[config] = (aris, concepts)
        return cache[config]

    parameters: dict[str, list[dict]] = {}
    for name, values in grid.items():
        rows = []
        for value in values:
            aris, concepts = scores(base.replace(**{name: float(value)}))
            rows.append({
                "value": float(value), "ari": aris, "concepts": concepts,
                "ari_mean": float(np.mean(aris)), "concepts_mean": float(np.mean(concepts)),
            })  # fmt: skip
        parameters[name] = rows
    return {
        "base": SENSITIVITY_BASE, "critical_gamma": base.model.critical_gamma, "sweeps": sweeps,
        "seeds": list(seeds), "parameters": parameters,
    }  # fmt: skip


def _fmt(value: float) -> str:
    return "nan" if math.isnan(value) else f"{value:.3f}"


def robustness_markdown(stability: dict, sensitivity: dict) -> str:
    """The markdown report of both studies."""
    seeds, chains = stability["seeds"], stability["chains"]
    lines = [
        "# Stability and sensitivity",
        "",
        f"Synthetic houses of seeds {seeds}, {stability['sweeps']} sweeps per chain.",
        "",
        f"## Stability: ARI against the truth over seeds ({chains} chains per house)",
        "",
        "One chain: chain 0. Best of K: the chain of highest best log joint. Chain ARI: mean ARI "
        "between the K chains' maps (1 = the chains agree). anneal: gamma ramped up over the "
        f"first {int(ANNEAL_FRACTION * stability['sweeps'])} sweeps (burn-in). cluster: a "
        f"Swendsen-Wang move starts {CLUSTER_MOVES:.0%} of the sweeps.",
        "",
        "| setting | one chain: mean | sd | min | best of K: mean | sd | min "
        "| chain ARI: mean | min |",
        "|---|" + "---|" * 8,
    ]
    for name, row in stability["settings"].items():
        one, best, pair = (row["summary"][m] for m in ("single", "best_of_chains", "chain_ari"))
        cells = [one["mean"], one["sd"], one["min"], best["mean"], best["sd"], best["min"],
                 pair["mean"], pair["min"]]  # fmt: skip
        lines.append(f"| {name} | " + " | ".join(_fmt(v) for v in cells) + " |")
    stable = stability["at_least_as_stable"]
    lines += [
        "",
        f"DP settings at least as stable (sd of ARI over seeds <= {_fmt(stability['reference_sd'])}"
        f", that of {stability['reference']}): " + (", ".join(stable) if stable else "none") + ".",
        "",
        f"## Sensitivity: one at a time from `{sensitivity['base']['preset']}` with gamma "
        f"{sensitivity['base']['gamma']}",
        "",
        f"Potts critical coupling ln(1 + sqrt(L)) = {sensitivity['critical_gamma']:.2f}.",
        "",
        "| parameter | value | "
        + " | ".join(f"ARI seed {s}" for s in sensitivity["seeds"])
        + " | mean ARI | mean concepts in use |",
        "|---|---|" + "---|" * (len(sensitivity["seeds"]) + 2),
    ]
    for name, rows in sensitivity["parameters"].items():
        for row in rows:
            aris = " | ".join(f"{v:.3f}" for v in row["ari"])
            lines.append(
                f"| {name} | {row['value']:g} | {aris} | {row['ari_mean']:.3f} "
                f"| {row['concepts_mean']:.1f} |"
            )
    return "\n".join(lines) + "\n"


def write_robustness(
    out: str | Path,
    *,
    sweeps: int,
    seeds: tuple[int, ...] = (0, 1, 2),
    chains: int = 3,
    spec: HouseSpec | None = None,
    dataset_root: str | Path | None = None,
) -> str:
    """Run both studies (and, given the public dataset, :func:`heldout_sensitivity` on all its
    houses); write ``robustness.md``, ``robustness.json`` and ``figures/stability.png``
    (:func:`~spcopyro.experiments.figures.plot_stability`) into ``out``; return the markdown."""
    stability = stability_study(sweeps=sweeps, seeds=seeds, chains=chains, spec=spec)
    sensitivity = sensitivity_study(sweeps=sweeps, seeds=seeds, spec=spec)
    markdown = robustness_markdown(stability, sensitivity)
    payload = {"stability": stability, "sensitivity": sensitivity}
    if dataset_root is not None:
        heldout = heldout_sensitivity(dataset_root, sweeps=sweeps)
        markdown += "\n" + heldout_sensitivity_markdown(heldout)
        payload["heldout_sensitivity"] = heldout
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    from spcopyro.experiments.figures import plot_stability  # matplotlib only when writing

    plot_stability(stability, out / "figures" / "stability.png")
    markdown += "\n![stability](figures/stability.png)\n"
    (out / "robustness.md").write_text(markdown)
    (out / "robustness.json").write_text(json.dumps(payload, indent=1) + "\n")
    return markdown


def heldout_sensitivity(
    root: str | Path,
    *,
    sweeps: int,
    houses: Sequence[str] | None = None,
    grid: dict[str, tuple[float, ...]] | None = None,
) -> dict:
    """The held-out-trial scores of the public houses across the one-at-a-time grid.

    Per parameter and value (from :data:`SENSITIVITY_BASE`): fit on two trials of each house,
    predict the held-out trial's words from their positions (top-1, top-3 of p(word | cell)) and
    localise them (distance to the region eq. (19) names, pi prior), averaged over the folds and
    houses. A value equal to the base's is fitted once.
    """
    from spcopyro.data import list_houses, load_house
    from spcopyro.experiments.table import heldout_folds
    from spcopyro.metrics import heldout_localisation, heldout_word_prediction
    from spcopyro.results.semantic_map import SpCoSemanticMap

    _check_runs(sweeps, (0,))
    grid = SENSITIVITY_GRID if grid is None else grid
    base = preset(str(SENSITIVITY_BASE["preset"]), gamma=SENSITIVITY_BASE["gamma"])
    names = tuple(houses) if houses is not None else tuple(list_houses(root))
    loaded = [load_house(Path(root) / name) for name in names]
    cache: dict[SpCoSettings, dict[str, float]] = {}

    def scores(config: SpCoSettings) -> dict[str, float]:
        if config not in cache:
            top1, top3, distance = [], [], []
            for house in loaded:
                for fold, _, train_house, test in heldout_folds(house):
                    fitted = fit_house(train_house, config, sweeps=sweeps, seed=fold,
                                       progress=False)  # fmt: skip
                    model = SpCoSemanticMap(fitted)
                    words = heldout_word_prediction(model, test)
                    top1.append(words.top1)
                    top3.append(words.top3)
                    distance.append(heldout_localisation(model, test).mean_distance)
            cache[config] = {
                "top1": float(np.nanmean(top1)), "top3": float(np.nanmean(top3)),
                "distance_m": float(np.nanmean(distance)),
            }  # fmt: skip
        return cache[config]

    parameters = {
        name: [{"value": float(v), **scores(base.replace(**{name: float(v)}))} for v in values]
        for name, values in grid.items()
    }
    return {"base": SENSITIVITY_BASE, "sweeps": sweeps, "houses": list(names),
            "parameters": parameters}  # fmt: skip


def heldout_sensitivity_markdown(heldout: dict) -> str:
    """The table of :func:`heldout_sensitivity`."""
    lines = [
        "## Sensitivity on the public houses (held-out trials)",
        "",
        f"Fit on two trials, score the third, mean over the folds of {', '.join(heldout['houses'])}"
        f"; {heldout['sweeps']} sweeps; one parameter at a time from `original-code` with gamma 3.",
        "",
        "| parameter | value | word top-1 | word top-3 | distance to the named region (m) |",
        "|---|---|---|---|---|",
    ]
    for name, rows in heldout["parameters"].items():
        for row in rows:
            lines.append(f"| {name} | {row['value']:g} | {row['top1']:.3f} | "
                         f"{row['top3']:.3f} | {row['distance_m']:.2f} |")  # fmt: skip
    return "\n".join(lines) + "\n"
