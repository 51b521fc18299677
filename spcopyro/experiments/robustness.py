"""Stability and sensitivity of SpCoMapping on synthetic houses (issue 4, the paper's open problem).

Both run as shipped studies (:mod:`spcopyro.study.robustness`: ``stability.toml`` and
``sensitivity.toml``); this module holds their settings, their summary and their report.

* stability: the spread (mean, sd, min) over seeds of the ARI against the truth for
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
* sensitivity: one-at-a-time sweeps of gamma (around the Potts critical coupling
  ln(1 + sqrt(L)) = 2.48 for L = 120), beta, chi and alpha from
  ``preset("original-code", gamma=3.0)``: mean ARI and concepts in use over seeds.

The sd is the sample standard deviation (ddof 1); it is NaN with a single seed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from spcopyro._util.number_checks import is_int

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
"""The configuration every one-at-a-time sweep of the sensitivity study starts from."""
SENSITIVITY_GRID: dict[str, tuple[float, ...]] = {
    "gamma": (2.0, 2.48, 3.0, 4.0),
    "beta": (0.1, 10.0, 500.0),
    "chi": (1.0, 100.0, 1e4),
    "alpha": (1e2, 1e5, 1e7),
}


def spread(values: Sequence[float]) -> dict[str, float]:
    """``{"mean", "sd", "min"}`` of ``values`` (sample sd, ddof 1; NaN for fewer than 2)."""
    array = np.asarray(values, dtype=np.float64)  # [n]
    if array.size == 0:
        raise ValueError("spread of no values")
    sd = float(array.std(ddof=1)) if array.size > 1 else math.nan
    return {"mean": float(array.mean()), "sd": sd, "min": float(array.min())}


def check_runs(sweeps: int, seeds: tuple[int, ...], chains: int | None = None) -> None:
    if not is_int(sweeps) or sweeps < 1:
        raise ValueError(f"sweeps must be a positive integer, got {sweeps!r}")
    if len(seeds) == 0:
        raise ValueError("seeds must name at least one synthetic house")
    if chains is not None and (not is_int(chains) or chains < 2):
        raise ValueError(f"chains must be an integer >= 2 (best of K, chain ARI), got {chains!r}")


def stability_summary(
    settings: dict[str, dict], *, sweeps: int, seeds: Sequence[int], chains: int
) -> dict:
    """The stability study's result from its per-setting rows (``single``: chain 0's ARI per
    house; ``best_of_chains``: the ARI of the chain of highest best log joint; ``chain_ari``:
    the mean ARI between the K chains' maps; ``chains``: per house, per chain, its ARI and best
    log joint): each row's ``summary`` spreads, and ``at_least_as_stable``: the DP settings and
    modes (single / best of K) whose sd of ARI is at most that of :data:`REFERENCE_SETTING`
    with one chain. The rows are filled by :func:`spcopyro.study.robustness.stability_of_rows`
    from the study ``stability``."""
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


def _fmt(value: float) -> str:
    return "—" if math.isnan(value) else f"{value:.3f}"  # nan: a sd of one seed


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
    if math.isnan(stability["reference_sd"]):  # "none" said no setting was, of an sd of nan
        verdict = "not judged: one house has no sd of ARI over seeds; run 2 or more seeds"
    else:
        verdict = ", ".join(stable) if stable else "none"
    lines += [
        "",
        f"DP settings at least as stable (sd of ARI over seeds <= {_fmt(stability['reference_sd'])}"
        f", that of {stability['reference']}): {verdict}.",
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


def heldout_sensitivity_markdown(heldout: dict) -> str:
    """The table of the sensitivity study on the public houses
    (:func:`spcopyro.study.robustness.sensitivity_of_rows`)."""
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
