"""The experiment's robustness studies (``spcopyro experiment --robustness``) as shipped studies
(issue 26): stability (``stability.toml``) and sensitivity (``sensitivity.toml``).

:func:`robustness_studies` sets their budgets as the command does: the sweeps (and the anneal
settings' ramp, :data:`~spcopyro.experiments.robustness.ANNEAL_FRACTION` of them), the houses
and, for stability, the chains (chain k of house s runs with seed
s + :data:`~spcopyro.experiments.robustness.CHAIN_SEED_STRIDE` k: one source per house, its
cells the chains). :func:`write_robustness` runs both with the study engine into
``OUT/robustness/stability`` and ``OUT/robustness/sensitivity`` (cached and resumable, each
with its ``results.csv`` and ``report.md``) and writes ``robustness.md``, ``robustness.json``
and ``figures/stability.png`` from their tables and stored label maps alone: the best of K is
the chain of highest ``best_objective``, the chains' agreement their stored maps' pairwise ARI.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.outputs import replace_text
from spcopyro.config import preset
from spcopyro.experiments.robustness import (
    ANNEAL_FRACTION,
    CHAIN_SEED_STRIDE,
    SENSITIVITY_BASE,
    STABILITY_SETTINGS,
    check_runs,
    heldout_sensitivity_markdown,
    robustness_markdown,
    stability_summary,
)
from spcopyro.metrics import pairwise_chain_ari
from spcopyro.study import STUDIES
from spcopyro.study.maps import load_label_map
from spcopyro.study.report import with_warnings
from spcopyro.study.run import run_study
from spcopyro.study.spec import DataSource, Study, load_study
from spcopyro.study.table import TABLE, read_table
from spcopyro.synthetic import HouseSpec

__all__ = [
    "SENSITIVITY",
    "STABILITY",
    "robustness_studies",
    "sensitivity_of_rows",
    "stability_of_rows",
    "write_robustness",
]

STABILITY = STUDIES / "stability.toml"
"""Each setting's chains on each house: the spread of the ARI, one chain and best of K."""
SENSITIVITY = STUDIES / "sensitivity.toml"
"""One parameter at a time from ``original-code`` with gamma 3, synthetic and public houses."""


def _spec_options(spec: HouseSpec | None) -> tuple[tuple[str, object], ...]:
    from spcopyro.study.ablation import spec_options

    return () if spec is None else spec_options(spec)


def robustness_studies(
    *,
    sweeps: int,
    seeds: Sequence[int] = (0, 1, 2),
    chains: int = 3,
    public: bool = True,
    spec: HouseSpec | None = None,
    public_houses: Sequence[str] | None = None,
) -> tuple[Study, Study]:
    """The stability and sensitivity studies at these budgets (module docstring): houses of
    ``seeds`` (``spec``: their HouseSpec; None: the default house), ``chains`` chains per house
    and setting, ``sweeps`` a fit; ``public`` False: the sensitivity without the public
    houses; ``public_houses``: the public houses it scores (None: the file's five), each with the
    file's held-out folds, as ``spcopyro experiment --houses`` gives the table's."""
    check_runs(sweeps, tuple(seeds), chains)
    stability, sensitivity = load_study(STABILITY), load_study(SENSITIVITY)
    ramp = int(ANNEAL_FRACTION * sweeps)
    variants = tuple(
        dataclasses.replace(
            v, options=tuple((k, ramp if k == "anneal_sweeps" else x) for k, x in v.options)
        )
        for v in stability.variants
    )
    options = _spec_options(spec)
    chain_seeds = [tuple(s + CHAIN_SEED_STRIDE * k for k in range(chains)) for s in seeds]
    houses = tuple(
        DataSource(f"house{s}", "synthetic", "default", options, house_seed=s, seeds=mine)
        for s, mine in zip(seeds, chain_seeds, strict=True)
    )
    budget = (("*", int(sweeps)),)
    data = [dataclasses.replace(d, options=options) if d.kind == "synthetic" else d
            for d in sensitivity.data if d.kind != "public"]  # fmt: skip
    public_sources = [d for d in sensitivity.data if d.kind == "public"]
    if public_houses is not None:
        folds = public_sources[0].seeds if public_sources else (0, 1, 2)
        public_sources = [DataSource(h, "public", h, heldout=True, seeds=folds)
                          for h in public_houses]  # fmt: skip
    if public:
        data += public_sources
    return (
        dataclasses.replace(stability, variants=variants, data=houses, sweeps=budget),
        dataclasses.replace(sensitivity, data=tuple(data), seeds=tuple(seeds), sweeps=budget),
    )


def _ok(rows: Sequence[dict[str, object]], variant: str, data: str) -> list[dict[str, object]]:
    return [r for r in rows if (r["variant"], r["data"], r["status"]) == (variant, data, "ok")]


def stability_of_rows(
    rows: Sequence[dict[str, object]], study: Study, folder: str | os.PathLike[str]
) -> dict:
    """The stability study's result (as :func:`robustness_markdown` and
    :func:`~spcopyro.experiments.figures.plot_stability` read it) from its table's rows and the
    label maps stored in ``folder``: per setting and house, each chain's ARI and best
    objective, chain 0's ARI, the best chain's, and the chains' mean pairwise ARI."""
    sweeps = study.sweeps_for("gibbs")
    settings: dict[str, dict] = {}
    for variant in study.variants:
        known = STABILITY_SETTINGS.get(variant.name)
        options = dict(variant.options)
        row: dict = {
            "method": known.method if known else variant.name.split()[0],
            "init": str(dict(variant.fit).get("init", "random")),
            "anneal_sweeps": int(options.get("anneal_sweeps", 0)),
            "cluster_moves": float(options.get("cluster_moves", 0.0)),
            "single": [], "best_of_chains": [], "chain_ari": [], "chains": [],
        }  # fmt: skip
        for data in study.data:
            chains = _ok(rows, variant.name, data.name)
            if len(chains) < 2:
                continue  # a failed chain: the house is left out of this setting
            aris = [float(c["ari"]) for c in chains]  # type: ignore[arg-type]
            objectives = [float(c["best_objective"]) for c in chains]  # type: ignore[arg-type]
            maps = [load_label_map(folder, c) for c in chains]
            labels = [m.labels[m.grid.free] for m in maps if m is not None]
            pairs = pairwise_chain_ari(labels)  # [K, K]
            row["single"].append(aris[0])
            row["best_of_chains"].append(aris[int(np.argmax(objectives))])
            row["chain_ari"].append(float(pairs[np.triu_indices(len(labels), k=1)].mean()))
            row["chains"].append([{"ari": a, "best_log_joint": o}
                                  for a, o in zip(aris, objectives, strict=True)])  # fmt: skip
        settings[variant.name] = row
    seeds = [d.house_seed for d in study.data]
    chains = max((len(d.seeds or ()) for d in study.data), default=0)
    return stability_summary(settings, sweeps=sweeps, seeds=seeds, chains=chains)


def sensitivity_of_rows(rows: Sequence[dict[str, object]], study: Study) -> tuple[dict, dict]:
    """The sensitivity study's results (synthetic: ARI and concepts per seed; public: held-out
    word prediction and localisation, the mean over houses and folds) from its table's rows;
    a variant is named ``PARAMETER VALUE``."""
    base = preset(str(SENSITIVITY_BASE["preset"]), gamma=SENSITIVITY_BASE["gamma"])
    sweeps = study.sweeps_for("gibbs")
    synthetic = [d for d in study.data if d.kind == "synthetic"]
    public = [d for d in study.data if d.kind == "public"]
    parameters: dict[str, list[dict]] = {}
    heldout: dict[str, list[dict]] = {}
    for variant in study.variants:
        name, _, text = variant.name.partition(" ")
        mine = [r for d in synthetic for r in _ok(rows, variant.name, d.name)]
        aris = [float(r["ari"]) for r in mine]  # type: ignore[arg-type]
        concepts = [int(r["concepts"]) for r in mine]  # type: ignore[call-overload]
        parameters.setdefault(name, []).append({
            "value": float(text), "ari": aris, "concepts": concepts,
            "ari_mean": float(np.mean(aris)), "concepts_mean": float(np.mean(concepts)),
        })  # fmt: skip
        if public:
            folds = [r for d in public for r in _ok(rows, variant.name, d.name)]
            scores = {s: float(np.nanmean([float(r[s]) for r in folds]))  # type: ignore[arg-type]
                      for s in ("top1", "top3", "distance_m")}  # fmt: skip
            heldout.setdefault(name, []).append({"value": float(text), **scores})
    sensitivity = {
        "base": SENSITIVITY_BASE, "critical_gamma": base.model.critical_gamma, "sweeps": sweeps,
        "seeds": list(study.seeds), "parameters": parameters,
    }  # fmt: skip
    houses = [Path(d.target).name for d in public]
    held = {"base": SENSITIVITY_BASE, "sweeps": sweeps, "houses": houses, "parameters": heldout}
    return sensitivity, held


def write_robustness(
    out: str | os.PathLike[str],
    *,
    sweeps: int,
    seeds: Sequence[int] = (0, 1, 2),
    chains: int = 3,
    spec: HouseSpec | None = None,
    dataset_root: str | os.PathLike[str] | None = None,
    public_houses: Sequence[str] | None = None,
    workers: int = 1,
    rerun_stale: bool = False,
    report: Callable[[str], None] = lambda message: None,
) -> str:
    """Run both studies (:func:`robustness_studies`; the public houses under ``dataset_root``:
    ``public_houses`` or the file's five, none without it) into ``out/robustness/``; write
    ``robustness.md``, ``robustness.json`` and ``figures/stability.png`` into ``out`` from their
    tables; return the markdown."""
    out = Path(out)
    public = dataset_root is not None
    stability_study, sensitivity_study = robustness_studies(
        sweeps=sweeps, seeds=seeds, chains=chains, public=public, spec=spec,
        public_houses=public_houses,
    )  # fmt: skip
    tables = {}
    for study in (stability_study, sensitivity_study):
        folder = out / "robustness" / study.name
        run_study(study, folder, workers=workers, root=dataset_root, rerun_stale=rerun_stale,
                  report=report)  # fmt: skip
        tables[study.name] = read_table(folder / TABLE)
    stability = stability_of_rows(
        tables[stability_study.name], stability_study, out / "robustness" / stability_study.name
    )
    sensitivity, heldout = sensitivity_of_rows(tables[sensitivity_study.name], sensitivity_study)
    markdown = robustness_markdown(stability, sensitivity)
    payload = {"stability": stability, "sensitivity": sensitivity}
    if public:
        markdown += "\n" + heldout_sensitivity_markdown(heldout)
        payload["heldout_sensitivity"] = heldout
    out.mkdir(parents=True, exist_ok=True)
    from spcopyro.experiments.figures import plot_stability  # matplotlib only when writing

    plot_stability(stability, out / "figures" / "stability.png")
    markdown += "\n![stability](figures/stability.png)\n"
    for study in (stability_study, sensitivity_study):  # the cells' warnings, as report.md
        markdown = with_warnings(markdown, tables[study.name],
                                 f"robustness/{study.name}/{TABLE}",
                                 f"Cells with warnings: {study.name}")  # fmt: skip
    replace_text(out / "robustness.md", markdown)  # each whole or not at all
    replace_text(out / "robustness.json", json.dumps(payload, indent=1) + "\n")
    return markdown
