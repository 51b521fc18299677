r"""Table 4 of the paper in form: every method on synthetic houses and on the public houses.

The grid runs as the shipped study ``experiment`` (:mod:`spcopyro.study.experiment`, issue 26);
this module holds what its tables are made of. Two tables, written to ``table.md`` and
``table.json`` from the study's ``results.csv``:

* **Synthetic houses** (ground truth known; :func:`spcopyro.synthetic.make_house` with seeds
  0..n-1, method seed = house seed): adjusted Rand index of the label map against the truth
  (:func:`~spcopyro.metrics.adjusted_rand_index`) and the matching rate of place estimation from
  the category names (eq. 18, places by eq. 19: :func:`~spcopyro.metrics.matching_rate`,
  ``kind="precision"``), as mean +- sample standard deviation over the seeds.
* **Public houses** (no drawn ground truth): for each of the three trials, fit on the other two
  and score the held-out trial (:func:`heldout_folds`): top-1 / top-3 accuracy and mean rank of
  each heard word under p(word | cell) (:func:`~spcopyro.metrics.heldout_word_prediction`) and
  the mean distance in metres from where it was said to the region "where is it?" names
  (:func:`~spcopyro.metrics.heldout_localisation`, over non-empty regions; 0 = inside). Each
  score is the mean of the three folds' scores.

The paper's own Table 4 numbers are quoted in a section of their own
(:mod:`spcopyro.experiments.paper_table4`), not as a column beside ours: the public-house scores
here are a different measurement (held-out trials, not the paper's hand-drawn ground truth).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from spcopyro._util.messages import fixed, seconds_text
from spcopyro.data import House, Observations
from spcopyro.experiments.methods import SPCO_METHODS
from spcopyro.experiments.paper_table4 import PAPER_ITERATIONS, paper_numbers_markdown

PUBLIC_CATEGORIES = {
    "room1dk5": 6,
    "room1dk6": 5,
    "room1ldk4": 7,
    "room1ldk5": 7,
    "room2ldk4": 7,
}
"""Ground-truth categories per public house (the dataset's README.md); L of ``B-dirichlet``."""
PUBLIC_SCORES = ("top1", "top3", "mean_rank", "distance_m")
SYNTHETIC_SCORES = ("ari", "matching_rate")


def report_nothing(message: str) -> None:
    """The experiments' default ``report``: say nothing."""
    del message


def heldout_folds(house: House) -> Iterator[tuple[int, int, House, Observations]]:
    """(fold, held-out trial, the house with the other trials, the held-out observations) for
    every trial of the house."""
    trials = house.observations.trials
    if len(trials) < 2:
        where = house.source if house.source is not None else f"house {house.name!r}"
        raise ValueError(f"{where}: held-out folds need >= 2 trials, got {trials}")
    for fold, held in enumerate(trials):
        train = house.observations.select_trials([t for t in trials if t != held])
        test = house.observations.select_trials([held])
        # no source: the folder's files hold every trial, so its lines no longer name these
        # observations (cell_counts' messages), nor is the folder this fit's data (provenance)
        yield fold, held, dataclasses.replace(house, observations=train, source=None), test


def _fmt(value: float, digits: int = 3) -> str:
    return "n/a" if not math.isfinite(value) else fixed(value, digits)


def table_markdown(summary: dict[str, object]) -> str:
    """``table.md``: the synthetic table, the public table, the settings and the notes."""
    methods: dict[str, str] = summary["methods"]  # type: ignore[assignment]
    settings: dict[str, object] = summary["settings"]  # type: ignore[assignment]
    synthetic: dict = summary["synthetic"]  # type: ignore[assignment]
    public: dict = summary["public"]  # type: ignore[assignment]
    lines = ["# SpCoMapping and the comparison methods (paper Table 4, in form)", ""]
    if summary["command"]:
        lines += [f"Made by: `{summary['command']}`", ""]
    ran = [f"SpCoMapping: {settings['sweeps']} Gibbs sweeps from random labels, the MAP-visited "
           "state"] if any(m in methods for m in SPCO_METHODS) else []  # fmt: skip
    if "C-spcoa" in methods:  # named only where a row ran it
        ran.append(f"SpCoA: {settings['spcoa_iterations']} iterations")
    lines += [
        *([f"{'; '.join(ran)}.", ""] if ran else []),
        f"## Synthetic houses ({settings['seeds']} seeds, ground truth known)",
        "",
        "ARI of the label map against the truth; matching rate (eq. 18, precision) of the "
        "place named by each category word. Mean ± sd over seeds (the mean alone for one).",
        "",
        "Matching rate (area prior): SpCoMapping's place for a word by eq. (19) with p(C) the "
        "share of cells labelled C instead of pi (the presets' huge alpha makes pi nearly "
        "uniform, so eq. (19) can point at a speck); concepts: concepts in use.",
        "",
        "| method | ARI | matching rate | matching rate (area prior) | concepts | s per fit |",
        "|---|---|---|---|---|---|",
    ]

    per_seed: dict = summary.get("synthetic_per_seed") or {}  # type: ignore[assignment]

    def mean_sd(s: dict, score: str, digits: int = 3) -> str:
        if score not in s:
            return "—"
        if seeds < 2:  # one value: no sample sd to show (its JSON keeps 0)
            return _fmt(s[score]["mean"], digits)
        return f"{_fmt(s[score]['mean'], digits)} ± {_fmt(s[score]['sd'], digits)}"

    for method, label in methods.items():
        s = synthetic.get(method, {})
        seeds = len(per_seed[method]) if method in per_seed else int(settings["seeds"])
        seconds = seconds_text(s["seconds"]["mean"]) if "seconds" in s else "—"
        lines.append(
            f"| {label} | {mean_sd(s, 'ari')} | {mean_sd(s, 'matching_rate')} "
            f"| {mean_sd(s, 'matching_rate_area')} | {mean_sd(s, 'concepts', 1)} | {seconds} |"
        )
    lines.append("")
    if public:
        houses = list(public)
        lines += [
            "## Public houses (held-out trials: mean over the folds, one per trial)",
            "",
            "Each cell: word prediction top-1 / top-3 / mean rank, then the mean distance (m) "
            "from where a held-out word was said to the region its word names.",
            "",
            "| method | " + " | ".join(houses) + " | mean top-1 |",
            "|---|" + "---|" * (len(houses) + 1),
        ]
        for method, label in methods.items():
            cells = []
            for house in houses:
                p = public[house].get(method)
                cells.append(
                    "—"
                    if p is None
                    else f"{_fmt(p['top1'], 2)} / {_fmt(p['top3'], 2)} / "
                    f"{_fmt(p['mean_rank'], 1)} / {_fmt(p['distance_m'], 2)} m"
                )
            top1 = [public[h][method]["top1"] for h in houses if method in public[h]]
            mean_top1 = _fmt(float(np.mean(top1))) if top1 else "—"
            lines.append(f"| {label} | " + " | ".join(cells) + f" | {mean_top1} |")
        lines.append("")
    lines += paper_numbers_markdown(settings.get("sweeps"))  # type: ignore[arg-type]
    lines += ["## Notes", ""] + smoke_run_caveat(settings.get("sweeps"))  # type: ignore[arg-type]
    lines += [f"- {note}" for note in summary["notes"]]  # type: ignore[operator]
    return "\n".join(lines) + "\n"


SMOKE_SWEEPS = 1000
"""Below this many sweeps a fit (the paper's 5000) the notes' verdicts come with a caveat."""


def smoke_run_caveat(sweeps: int | None) -> list[str]:
    """The line said before the notes' verdicts when the fits ran fewer than
    :data:`SMOKE_SWEEPS` sweeps (``--quick``: 20): SpCoMapping's maps are then still specks, so
    "does NOT beat the best baseline" says nothing of the method."""
    if sweeps is None or sweeps >= SMOKE_SWEEPS:
        return []
    return [f"- **{sweeps} sweeps a fit** (the paper ran {PAPER_ITERATIONS}): a smoke run, whose "
            "SpCoMapping maps are far from converged; the verdicts below say nothing of the "
            "methods at that budget"]  # fmt: skip


def findings(summary: dict[str, object]) -> list[str]:
    """Which method wins each column, and whether SpCoMapping beats every baseline."""
    notes = []
    synthetic: dict = summary["synthetic"]  # type: ignore[assignment]
    for score in SYNTHETIC_SCORES:
        scored = [m for m in synthetic if score in synthetic[m]]
        if not scored:
            continue
        baselines = [m for m in scored if m not in SPCO_METHODS]
        spco = [m for m in scored if m in SPCO_METHODS]
        best = max(scored, key=lambda m: synthetic[m][score]["mean"])
        notes.append(f"synthetic {score}: best is {best}")
        if spco and baselines:
            top_spco = max(spco, key=lambda m: synthetic[m][score]["mean"])
            top_base = max(baselines, key=lambda m: synthetic[m][score]["mean"])
            verdict = (
                "beats"
                if synthetic[top_spco][score]["mean"] > synthetic[top_base][score]["mean"]
                else "does NOT beat"
            )
            notes.append(
                f"synthetic {score}: the best SpCoMapping row ({top_spco}) {verdict} "
                f"the best baseline ({top_base})"
            )
    public: dict = summary["public"]  # type: ignore[assignment]
    for house, by_method in public.items():
        best = max(by_method, key=lambda m: by_method[m]["top1"])
        notes.append(f"{house} held-out top-1: best is {best}")
    return notes


def failed_cells(rows: list[dict[str, object]]) -> list[str]:
    """One line per failed cell of a study's table rows: which row, house and seed, and its
    error, for the tables that leave it out (comparison.md, ablation.md named none)."""
    lines = []
    for row in rows:
        if row.get("status") == "ok":
            continue
        error = f"{row.get('error_type') or 'error'}: {row.get('error') or '?'}"
        lines.append(f"{row.get('variant')} on {row.get('data')}, seed {row.get('seed')}, "
                     f"failed ({error}); left out of the tables (--retry-failed runs it "
                     "again)")  # fmt: skip
    return lines


def json_default(value: object) -> object:
    """``json.dumps``' ``default``: numpy scalars as Python numbers, tuples and paths as text."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, Path)):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
