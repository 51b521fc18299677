"""The paper's comparison (Table 4 in form, Figs. 5-7) as a study (issue 26 item 1):
``spcopyro experiment`` runs the study engine on the shipped ``experiment.toml``
(``experiment_quick.toml`` with ``--quick``).

Its grid: the SpCoMapping rows of :mod:`spcopyro.experiments.methods` as variants (a variant is
named by its row's key: ``A-dp``, ``A-orig-g3``, ``B-dirichlet``) and the other rows as
baselines, on a synthetic house (seeds 0 .. n-1, house and fit) and the public houses (seed s
holds out trial s and fits on the other two), with the ARI against the truth kept every
``ari_every`` sweeps (Fig. 5). The command's options change that study
(:func:`experiment_study`); :func:`run_experiment` runs it -- cached and resumable in ``out``
(``cells/``, ``maps/``, ``traces/``, ``results.csv``, ``report.md``) -- and writes
``table.md``, ``table.json`` (:mod:`spcopyro.experiments.table`) and ``figures/`` from
``results.csv``, the stored traces and the stored label maps alone (:func:`summary_of_rows`,
:func:`write_figures`): nothing is refitted to draw them.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.messages import plural
from spcopyro._util.outputs import replace_figure, replace_text
from spcopyro.experiments.methods import METHOD_LABELS, SPCO_METHODS
from spcopyro.experiments.table import (
    PUBLIC_SCORES,
    SYNTHETIC_SCORES,
    findings,
    json_default,
    table_markdown,
)
from spcopyro.figures.fonts import any_script
from spcopyro.study import STUDIES
from spcopyro.study.maps import plot_label_maps, remove_stale, source_panels
from spcopyro.study.report import with_warnings
from spcopyro.study.run import run_study
from spcopyro.study.spec import DataSource, Study
from spcopyro.study.table import TABLE, read_table

__all__ = [
    "EXPERIMENT",
    "EXPERIMENT_QUICK",
    "experiment_study",
    "run_experiment",
    "summary_of_rows",
    "write_figures",
]

EXPERIMENT = STUDIES / "experiment.toml"
"""The comparison's default grid (``spcopyro experiment``)."""
EXPERIMENT_QUICK = STUDIES / "experiment_quick.toml"
"""Its smoke run (``spcopyro experiment --quick``)."""

SYNTHETIC_RECORD = (*SYNTHETIC_SCORES, "seconds", "concepts", "matching_rate_area")
"""A synthetic seed's record in ``table.json`` (``concepts`` and the area prior: SpCoMapping)."""
PUBLIC_RECORD = (*PUBLIC_SCORES, "inside_rate", "empty_regions", "scored_words",
                 "unknown_tokens", "seconds")  # fmt: skip
"""A public fold's record in ``table.json``."""


def experiment_study(
    study: Study,
    *,
    public: bool = True,
    houses: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    seeds: int | None = None,
    sweeps: int | None = None,
    spcoa_iterations: int | None = None,
    command: str = "",
) -> Study:
    """``study`` (the shipped file) changed as the command's options ask: ``public`` False
    drops the public houses; ``houses`` replaces them (each with the file's public seeds:
    one per held-out trial); ``methods`` keeps those rows (table order); ``seeds`` the
    synthetic seeds 0 .. seeds - 1; ``sweeps`` every fit's sweeps, the ARI then kept every
    ``max(1, sweeps // 100)``; ``spcoa_iterations`` SpCoA's."""
    changes: dict[str, object] = {"description": command or study.description}
    synthetic = [d for d in study.data if d.kind != "public"]
    public_sources = [d for d in study.data if d.kind == "public"]
    if seeds is not None:
        synthetic = [dataclasses.replace(d, seeds=tuple(range(seeds))) for d in synthetic]
    if houses is not None:
        fold_seeds = public_sources[0].seeds if public_sources else (0, 1, 2)
        public_sources = [DataSource(h, "public", h, heldout=True, seeds=fold_seeds)
                          for h in houses]  # fmt: skip
    changes["data"] = tuple(synthetic + (public_sources if public else []))
    if methods is not None:
        known = [v.name for v in study.variants] + list(study.baselines)
        unknown = sorted(set(methods) - set(known))
        if unknown:
            raise ValueError(f"unknown --methods {unknown}; choose from {known}")
        changes["variants"] = tuple(v for v in study.variants if v.name in methods)
        changes["baselines"] = tuple(b for b in study.baselines if b in methods)
    if sweeps is not None:
        changes.update(sweeps=(("*", int(sweeps)),), ari_every=max(1, int(sweeps) // 100))
    if spcoa_iterations is not None:
        changes["spcoa_iterations"] = int(spcoa_iterations)
    return dataclasses.replace(study, **changes)  # type: ignore[arg-type]


def _rows_of(rows: Sequence[dict[str, object]], public: bool) -> list[dict[str, object]]:
    return [r for r in rows if r["status"] == "ok" and (r["data_kind"] == "public") == public]


def _record(row: dict[str, object], names: Sequence[str], first: str) -> dict[str, object]:
    record = {first: row[first]}
    record.update({k: row[k] for k in names if row.get(k) is not None})
    return record


def _mean_sd(values: list[float]) -> dict[str, float]:
    array = np.asarray(values, dtype=np.float64)
    return {"mean": float(array.mean()), "sd": float(array.std(ddof=1)) if array.size > 1 else 0.0}


def summary_of_rows(
    rows: Sequence[dict[str, object]], study: Study, *, dataset_root: str | None = None
) -> dict[str, object]:
    """``table.json``'s content from the study's ``results.csv`` rows: per row (method), the
    synthetic scores' mean and sd over seeds and the per-seed records, the public houses'
    fold means and per-fold records (failed cells left out)."""
    methods = [v.name for v in study.variants] + list(study.baselines)
    synthetic_rows, public_rows = _rows_of(rows, False), _rows_of(rows, True)
    per_seed = {
        m: [_record(r, SYNTHETIC_RECORD, "seed") for r in synthetic_rows if r["variant"] == m]
        for m in methods
    }
    synthetic = {
        m: {
            score: _mean_sd([r[score] for r in records])  # type: ignore[misc]
            for score in (*SYNTHETIC_SCORES, "seconds", "matching_rate_area", "concepts")
            if records and all(score in r for r in records)
        }
        for m, records in per_seed.items()
    }
    houses = list(dict.fromkeys(str(r["data"]) for r in public_rows))
    per_fold = {
        h: {
            m: [_record(r, PUBLIC_RECORD, "held_out_trial") for r in public_rows
                if r["data"] == h and r["variant"] == m]
            for m in methods
        }
        for h in houses
    }  # fmt: skip
    means = (*PUBLIC_SCORES, "inside_rate", "seconds")
    public = {
        h: {
            m: {s: float(np.mean([r[s] for r in records])) for s in means}  # type: ignore[misc]
            for m, records in by.items() if records
        }
        for h, by in per_fold.items()
    }  # fmt: skip
    synthetic_data = [d for d in study.data if d.kind != "public"]
    seeds = synthetic_data[0].seeds if synthetic_data and synthetic_data[0].seeds else study.seeds
    return {
        "command": study.description,
        "settings": {
            "sweeps": study.sweeps_for("gibbs"), "spcoa_iterations": study.spcoa_iterations,
            "seeds": len(seeds), "ari_every": study.ari_every,
            "synthetic": [d.to_json() for d in synthetic_data],
            "dataset_root": dataset_root, "houses": houses,
        },
        "methods": {m: METHOD_LABELS.get(m, m) for m in methods},
        "synthetic": synthetic, "synthetic_per_seed": per_seed,
        "public": public, "public_per_fold": per_fold,
    }  # fmt: skip


def plot_traces(rows: Sequence[dict[str, object]], folder: Path, path: Path, title: str) -> Path:
    """ARI against the truth (kept every ``ari_every`` sweeps; Fig. 5) and concepts in use per
    sweep (Fig. 6) of each SpCoMapping row, from the stored traces of ``rows``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 6))
    top, bottom = fig.subplots(2, 1, sharex=True)
    for row in rows:
        if not row.get("trace"):
            continue
        with np.load(folder / str(row["trace"])) as trace:
            label = METHOD_LABELS.get(str(row["variant"]), str(row["variant"]))
            if "ari" in trace.files:
                top.plot(trace["ari_iterations"], trace["ari"], lw=1.0, label=label)
            concepts = trace["num_concepts"]
            bottom.plot(np.arange(1, len(concepts) + 1), concepts, lw=1.0, label=label)
    top.set_ylabel("ARI vs truth (Fig. 5)")
    bottom.set_ylabel("concepts in use (Fig. 6)")
    bottom.set_xlabel("sweep")
    for ax in (top, bottom):
        ax.set_xscale("log")
    top.legend(fontsize=7)
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    with any_script(fig):  # words of any script, not boxes
        replace_figure(fig, path, dpi=120, bbox_inches="tight")  # whole or not at all
    return path


def write_figures(out: str | os.PathLike[str], rows: Sequence[dict[str, object]]) -> list[Path]:
    """The comparison's figures into ``out/figures`` from the table's rows and the stored
    traces and label maps: per source, every row's map at its first seed beside the truth
    (Fig. 7: ``synthetic_maps.png`` for a synthetic house, ``HOUSE_maps.png`` for a public one,
    whose truth is the project's region truth), and the synthetic house's ARI and concepts
    per sweep (``synthetic_traces.png``; when it has SpCoMapping rows). Those figures of an
    earlier run that this one does not draw (a house no longer in the table) are deleted."""
    out = Path(out)
    folder = out / "figures"
    label = lambda row: METHOD_LABELS.get(str(row["variant"]), str(row["variant"]))  # noqa: E731
    paths = []
    for data in dict.fromkeys(str(r["data"]) for r in rows if r["status"] == "ok"):
        mine = [r for r in rows if r["data"] == data and r["status"] == "ok"]
        public = mine[0]["data_kind"] == "public"
        found = source_panels(mine, out, data, label=label)
        if found is None:
            continue
        grid, panels, seed = found
        if public:
            held = next((r["held_out_trial"] for r in mine if r["seed"] == seed), seed)
            name, what = f"{data}_maps.png", f"fold {seed} (held-out trial {held})"
        else:
            name, what = "synthetic_maps.png", f"seed {seed}"
        title = f"{data} {what}: every method's map"
        paths.append(plot_label_maps(grid, panels, folder / name, title))
        spco = [r for r in mine if r["seed"] == seed and r["variant"] in SPCO_METHODS]
        if not public and spco:  # baselines alone have no traces (an empty legend warned)
            title = f"{data} seed {seed}: ARI and concepts per sweep"
            paths.append(plot_traces(spco, out, folder / "synthetic_traces.png", title))
    if folder.is_dir():  # an earlier run's figures of sources the table no longer has
        remove_stale(folder, ["*_maps.png", "synthetic_traces.png"], paths)
    return paths


def run_experiment(
    out: str | os.PathLike[str],
    study: Study,
    *,
    root: str | os.PathLike[str] | None = None,
    workers: int = 1,
    retry_failed: bool = False,
    rerun_stale: bool = False,
    report: Callable[[str], None] = lambda message: None,
) -> dict[str, object]:
    """Run the cells of ``study`` (:func:`experiment_study`) that ``out`` does not hold yet,
    then write ``table.json``, ``table.md`` and ``figures/`` from ``out/results.csv`` and the
    stored traces and maps; returns the summary written to ``table.json`` (with ``failed``:
    the failed cells, left out of the tables). ``root``: the public dataset (None: the study
    must hold no public house). ``rerun_stale``: run again the finished cells another spcopyro
    source computed (else kept, and counted)."""
    out = Path(out)
    run = run_study(study, out, workers=workers, retry_failed=retry_failed, root=root,
                    rerun_stale=rerun_stale, report=report)  # fmt: skip
    rows = read_table(out / TABLE)
    summary = summary_of_rows(rows, study, dataset_root=None if root is None else str(root))
    notes: list[str] = []
    if not any(d.kind == "public" for d in study.data):
        notes.append("Public houses skipped: the dataset was not found (set $SPCOPYRO_DATA or "
                     "pass --data), or --no-public.")  # fmt: skip
    notes += findings(summary)
    ran = plural(run.ran, "cell")
    notes.append(f"Wall-clock time of this run: {run.seconds:.0f} s ({ran} run, "
                 f"{run.cached} finished before).")  # fmt: skip
    summary["notes"] = notes
    summary["figures"] = [str(p.relative_to(out)) for p in write_figures(out, rows)]
    summary["failed"] = sum(1 for r in rows if r.get("status") != "ok")
    replace_text(out / "table.json", json.dumps(summary, indent=1, default=json_default) + "\n")
    replace_text(out / "table.md", with_warnings(table_markdown(summary), rows))
    return summary
