"""The ablation's outputs: per-seed records -> mean +- sd per row and house -> ``ablation.md``,
``ablation.json`` and ``ablation.png`` (:func:`write_report`; the runs are in
:mod:`spcopyro.experiments.ablation`).

``ablation.json`` holds ``settings``, ``statistics`` (the houses' sparsity, public and
synthetic), ``summary`` (row -> house -> score -> {mean, sd, n}), ``top_words`` (row -> house ->
the top words of the largest concepts holding an utterance, seed 0), ``targets`` (the issue's
targets, checked), ``records`` (one per job), ``seconds`` (this command's wall-clock time) and
``cells_finished_before`` (the cells it found finished, whose fits are not in ``seconds``) and
``failed_cells`` (a line per failed cell, left out of the tables).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from spcopyro._util.messages import command_time, fixed, plural, seconds_text
from spcopyro._util.outputs import replace_figure, replace_text
from spcopyro.experiments.table import PUBLIC_CATEGORIES, json_default
from spcopyro.figures.fonts import any_script
from spcopyro.synthetic.statistics import public_and_synthetic_statistics, statistics_table

__all__ = ["SCORES", "TABLE2_CATEGORIES", "settings_json", "summarise", "targets", "write_report"]

TABLE2_CATEGORIES: dict[str, int] = dict(PUBLIC_CATEGORIES)
"""Ground-truth categories per public house: the paper's Table 2 (6, 5, 7, 7, 7)."""

AblationSettings = Any
"""An :class:`spcopyro.experiments.ablation.AblationSettings` (not imported: that module
imports this one)."""

SCORES = (
    "ari", "ari_off", "ari_on_off", "matching_rate", "matching_rate_area", "concepts",
    "concepts_1pct", "concepts_1pct_off", "place_top_share", "top1", "top3", "mean_rank",
    "distance_m", "inside_rate", "seconds", "seconds_off", "cpu_seconds", "cpu_seconds_off",
)  # fmt: skip
"""Every score a record may hold (a record holds those that apply to its row and house)."""

JSON_KEYS = ("settings", "statistics", "summary", "top_words", "targets", "records", "seconds",
             "cells_finished_before", "failed_cells")  # fmt: skip


def _spread(values: list[float]) -> dict[str, float]:
    array = np.asarray([v for v in values if v is not None], dtype=np.float64)
    finite = array[np.isfinite(array)]
    if finite.size == 0:
        return {"mean": math.nan, "sd": math.nan, "n": 0}
    sd = float(finite.std(ddof=1)) if finite.size > 1 else 0.0
    return {"mean": float(finite.mean()), "sd": sd, "n": int(finite.size)}


def summarise(records: list[dict[str, object]]) -> dict[str, dict[str, dict[str, dict]]]:
    """row -> house -> score -> {mean, sd (sample), n} over the seeds (non-finite left out)."""
    summary: dict[str, dict[str, dict[str, dict]]] = {}
    for record in records:
        by_house = summary.setdefault(str(record["row"]), {})
        by_house.setdefault(str(record["house"]), {})
    for row, by_house in summary.items():
        for house in by_house:
            mine = [r for r in records if r["row"] == row and r["house"] == house]
            by_house[house] = {
                score: _spread([r[score] for r in mine])  # type: ignore[misc]
                for score in SCORES
                if any(score in r for r in mine)
            }
    return summary


def targets(summary: dict, settings: AblationSettings) -> list[str]:
    """The issue's targets, checked per variant: on each synthetic house the variant's ARI
    beats (C) and (F) with a seed-to-seed sd no larger than theirs; on each public house its
    concept count (>= 1 % of the cells) is within 2 of Table 2's."""
    lines = []
    baselines = [b for b in settings.baselines if b in summary]
    for variant in settings.variants:
        row = summary.get(variant.name, {})
        for house in settings.synthetic:
            if house not in row or "ari" not in row[house]:
                continue
            mine = row[house]["ari"]
            verdicts = []
            for base in baselines:
                theirs = summary[base].get(house, {}).get("ari")
                if theirs is None:
                    continue
                beats = mine["mean"] > theirs["mean"]
                verdict = (f"{'beats' if beats else 'does NOT beat'} {base} "
                           f"({mine['mean']:.3f} vs {theirs['mean']:.3f}), ")  # fmt: skip
                if min(mine.get("n", 2), theirs.get("n", 2)) < 2:  # one seed: no sd (it read
                    verdict += "sd not compared (one seed)"  # "sd <= theirs (0.000 vs 0.000)")
                else:
                    steady = mine["sd"] <= theirs["sd"]
                    verdict += (f"sd {'<=' if steady else '>'} theirs ({mine['sd']:.3f} vs "
                                f"{theirs['sd']:.3f})")  # fmt: skip
                verdicts.append(verdict)
            if verdicts:
                lines.append(f"{variant.name} on {house}: ARI " + "; ".join(verdicts))
        for house, count in TABLE2_CATEGORIES.items():
            if house in row and "concepts_1pct" in row[house]:
                mean = row[house]["concepts_1pct"]["mean"]
                within = abs(mean - count) <= 2
                lines.append(
                    f"{variant.name} on {house}: {mean:.1f} concepts >= 1% vs Table 2's {count}: "
                    + ("within 2" if within else "NOT within 2")
                )
    return lines


def _fmt(spread: dict | None, digits: int = 3) -> str:
    if spread is None or not math.isfinite(spread["mean"]):
        return "—"
    if spread.get("n", 2) < 2:  # one value: no sample sd to show (its JSON keeps 0)
        return fixed(spread["mean"], digits)
    return f"{fixed(spread['mean'], digits)} ± {spread['sd']:.{digits}f}"


def _cell(text: object) -> str:
    """A row's name as one cell of a markdown table: a '|' in it (``--variant 'x|y:...'``)
    split the row into one column more than the header's, as the study report escapes it."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _variant_line(variant: Any) -> str:
    """A variant's line under "Variants:": its text, and its preset where the text leaves it
    out (the default preset; ``--variant x:gamma=3`` read "`x:settings.gamma=3.0`", its preset
    unsaid)."""
    from spcopyro.config import DEFAULT_PRESET

    line = f"- `{variant.describe()}`"
    if variant.preset == DEFAULT_PRESET:
        line += f" (preset `{DEFAULT_PRESET}`, the default)"
    return line


def _synthetic_houses(settings: AblationSettings) -> list[str]:
    """The synthetic houses the run fits: none with ``--seeds 0`` (their tables and the figure's
    panel were drawn empty)."""
    return list(settings.synthetic) if settings.seeds > 0 else []


def _seconds(scores: dict) -> str:
    wall, cpu = scores.get("seconds"), scores.get("cpu_seconds")
    if wall is None:
        return "—"
    return seconds_text(wall["mean"]) + ("" if cpu is None else f" / {seconds_text(cpu['mean'])}")


def _top_words(records: list[dict[str, object]]) -> dict[str, dict[str, list]]:
    """row -> house -> the top words of seed 0 (the lowest seed run)."""
    found: dict[str, dict[str, tuple[int, list]]] = {}
    for r in records:
        if "top_words" not in r:
            continue
        by_house = found.setdefault(str(r["row"]), {})
        seed = int(r["seed"])  # type: ignore[call-overload]
        if str(r["house"]) not in by_house or seed < by_house[str(r["house"])][0]:
            by_house[str(r["house"])] = (seed, r["top_words"])  # type: ignore[assignment]
    return {row: {h: words for h, (_, words) in v.items()} for row, v in found.items()}


def _words_text(words: list) -> str:
    """Each concept's words and probabilities; "—" where none lists any (a fit that did not
    model its words lists none: :func:`spcopyro.experiments.ablation.top_words`)."""
    if not any(words):
        return "—"
    return "; ".join(", ".join(f"{w} {p:.2f}" for w, p in concept) for concept in words)


def markdown(report: dict, settings: AblationSettings) -> str:
    """``ablation.md``: settings, statistics, one table per synthetic house, the public tables,
    the top words and the targets."""
    summary: dict = report["summary"]
    rows = [v.name for v in settings.variants] + list(settings.baselines)
    lines = ["# Ablation (issue #14)", ""]
    if settings.command:
        lines += [f"Made by: `{settings.command}`", ""]
    spcoa = "C-spcoa" in settings.baselines
    # a variant of another method ran as many of its iterations (this said "Gibbs sweeps")
    others = ", ".join(f"{v.name}: {v.method}" for v in settings.variants if v.method != "gibbs")
    budget = f"{settings.sweeps} Gibbs sweeps per fit"
    if others:
        budget = f"{settings.sweeps} iterations per fit (Gibbs sweeps; {others})"
    parts = [budget + (f" (SpCoA: {settings.spcoa_iterations} iterations)" if spcoa else "")]
    synthetic = _synthetic_houses(settings)
    if synthetic:  # --seeds 0 read "synthetic seeds 0--1"
        seeds = "0" if settings.seeds == 1 else f"0-{settings.seeds - 1}"
        parts.append(f"synthetic seeds {seeds} (house and fit)")
    if settings.dataset_root is not None and settings.public_seeds > 0:  # not with --no-public
        parts.append(f"public houses: {plural(settings.public_seeds, 'seed')}, seed s holding "
                     "out trial s mod 3")  # fmt: skip
    lines += [
        "; ".join(parts)
        + ". Mean ± sd over seeds (the mean alone for one seed). "
        + f"Workers: {settings.workers}. "
        + command_time(report["seconds"], report.get("cells_finished_before", 0)),
        "",
        "Variants:",
        "",
    ]
    lines += [_variant_line(v) for v in settings.variants]
    lines += ["", "## The houses", "", report["statistics_md"], ""]
    for house in synthetic:
        spec = settings.houses[house]
        lines += [
            f"## Synthetic: {house} ({spec.height} x {spec.width} cells at {spec.resolution} m, "
            f"{spec.num_regions} regions)",
            "",
            "| row | ARI | ARI, observations off | ARI(with, without) | matching rate | "
            "matching rate (area prior) | concepts ≥ 1% | top word a place | s per fit "
            "(wall / CPU) |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for row in rows:
            s = summary.get(row, {}).get(house)
            if s is None:
                continue
            lines.append(
                f"| {_cell(row)} | {_fmt(s.get('ari'))} | {_fmt(s.get('ari_off'))} "
                f"| {_fmt(s.get('ari_on_off'))} | {_fmt(s.get('matching_rate'))} "
                f"| {_fmt(s.get('matching_rate_area'))} | {_fmt(s.get('concepts_1pct'), 1)} "
                f"| {_fmt(s.get('place_top_share'), 2)} | {_seconds(s)} |"
            )
        lines.append("")
    public = _public_houses(report["records"])
    if public:
        lines += [
            "## Public houses: concepts holding ≥ 1% of the free cells",
            "",
            "Fitted on two of the three trials. Table 2: the paper's ground-truth categories.",
            "",
            "| row | " + " | ".join(public) + " |",
            "|---|" + "---|" * len(public),
            "| Table 2 | " + " | ".join(str(TABLE2_CATEGORIES.get(h, "?")) for h in public) + " |",
        ]
        for row in rows:
            cells = [_fmt(summary.get(row, {}).get(h, {}).get("concepts_1pct"), 1) for h in public]
            lines.append(f"| {_cell(row)} | " + " | ".join(cells) + " |")
        lines += [
            "",
            "## Public houses: held-out trial",
            "",
            "Each cell: word prediction top-1, mean distance (m) from where a held-out word was "
            "said to the region it names, ARI between the maps fitted with and without the "
            "observations (1: the data did not move the map).",
            "",
            "| row | " + " | ".join(public) + " |",
            "|---|" + "---|" * len(public),
        ]
        for row in rows:
            cells = []
            for h in public:
                s = summary.get(row, {}).get(h, {})
                cells.append(
                    f"{_fmt(s.get('top1'), 2)} / {_fmt(s.get('distance_m'), 2)} m / "
                    f"{_fmt(s.get('ari_on_off'), 2)}"
                )
            lines.append(f"| {_cell(row)} | " + " | ".join(cells) + " |")
        lines += [
            "",
            "## Public houses: top words of the largest concepts that hold an utterance (seed 0)",
            "",
            "| row | house | top words (per concept; probability) | top word a place |",
            "|---|---|---|---|",
        ]
        for row in rows:
            for h in public:
                words = report["top_words"].get(row, {}).get(h)
                if words is None:
                    continue
                share = summary[row][h].get("place_top_share")
                lines.append(f"| {_cell(row)} | {_cell(h)} | {_words_text(words)} "
                             f"| {_fmt(share, 2)} |")  # fmt: skip
        lines.append("")
    checked = [f"- {t}" for t in report["targets"]] or [  # the section was left empty
        "None checked: no synthetic house with a baseline row (C-spcoa, F-geometry) and no "
        "public house of the paper's Table 2."
    ]
    if report.get("failed_cells"):  # ablation.md named no failed cell
        lines += ["## Failed cells", "", *(f"- {line}" for line in report["failed_cells"]), ""]
    lines += ["## Targets", "", *checked]
    lines += ["", "Figure: `ablation.png`.", ""]
    return "\n".join(lines)


def _public_houses(records: list[dict[str, object]]) -> list[str]:
    return list(dict.fromkeys(str(r["house"]) for r in records if r["public"]))


def figure(report: dict, settings: AblationSettings, path: Path) -> Path:
    """Write :func:`ablation_figure` to ``path`` (``ablation.png``)."""
    fig = ablation_figure(report, settings)
    with any_script(fig):  # words of any script, not boxes
        replace_figure(fig, path, dpi=110, bbox_inches="tight")  # whole or not at all
    return path


def ablation_figure(report: dict, settings: AblationSettings) -> Figure:
    """ARI per synthetic house (bars: with observations, mean ± sd; open circles: observations
    off) and concepts >= 1% per public house against Table 2 (black lines). One legend below
    the panels names the rows, the circles and Table 2's line (inside a panel, loc="best", it
    covered bars and left Table 2 out). A :class:`~matplotlib.figure.Figure`, no pyplot: the
    caller's matplotlib backend is left alone (``matplotlib.use("Agg")`` switched a notebook's)."""
    from matplotlib import colormaps

    summary: dict = report["summary"]
    rows = [v.name for v in settings.variants] + list(settings.baselines)
    public = _public_houses(report["records"])
    synthetic = _synthetic_houses(settings)
    panels = int(bool(synthetic)) + int(bool(public)) or 1
    fig = Figure(figsize=(6 + 5 * panels, 4.5))
    axes = fig.subplots(1, panels, squeeze=False)
    width = 0.8 / max(len(rows), 1)
    colours = colormaps["tab10"]
    handles: list[Artist] = [Patch(color=colours(k % 10), label=row) for k, row in enumerate(rows)]

    def bars(ax, houses: list[str], score: str, off: str | None) -> bool:
        x = np.arange(len(houses))
        drawn = False
        for k, row in enumerate(rows):
            stats = [summary.get(row, {}).get(h, {}).get(score) for h in houses]
            mean = [s["mean"] if s else np.nan for s in stats]
            # one seed: no sd, no error bar (its JSON keeps 0; a bar of 0 said "no spread")
            sd = [s["sd"] if s and s.get("n", 2) > 1 else np.nan for s in stats]
            pos = x - 0.4 + width * (k + 0.5)
            ax.bar(pos, mean, width, yerr=sd, color=colours(k % 10), capsize=2)
            if off:
                offs = [summary.get(row, {}).get(h, {}).get(off) for h in houses]
                means = [s["mean"] if s else np.nan for s in offs]
                ax.plot(pos, means, "o", mfc="none", mec="black", ms=5)
                drawn = drawn or bool(np.isfinite(means).any())
        ax.set_xticks(x, houses)
        return drawn

    if synthetic:  # --seeds 0: no synthetic panel (it was drawn empty)
        ax = axes[0, 0]
        if bars(ax, synthetic, "ari", "ari_off"):
            handles.append(Line2D([], [], ls="", marker="o", mfc="none", mec="black", ms=5,
                                  label="observations off (mean ARI)"))  # fmt: skip
        ax.set_ylabel("ARI against the truth (circles: observations off)")
        ax.set_title("synthetic houses")
    if public:
        ax = axes[0, panels - 1]
        bars(ax, public, "concepts_1pct", None)
        counts = [TABLE2_CATEGORIES.get(h, np.nan) for h in public]
        x = np.arange(len(public))
        ax.hlines(counts, x - 0.45, x + 0.45, colors="black", linewidth=2)
        handles.append(Line2D([], [], color="black", lw=2,
                              label="Table 2: the paper's categories of the house"))  # fmt: skip
        ax.set_ylabel("concepts holding >= 1% of the free cells")
        ax.set_title("public houses (black: Table 2)")
    fig.tight_layout()
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), fontsize=8,
               ncol=min(4, len(handles)) or 1, frameon=False)  # fmt: skip
    return fig


def write_report(
    out: Path, settings: AblationSettings, records: list[dict[str, object]], seconds: float,
    cached: int = 0, failed: tuple[str, ...] | list[str] = (),
    finish: Callable[[str], str] | None = None,
) -> dict[str, object]:  # fmt: skip
    """Write ``ablation.md``, ``ablation.json`` and ``ablation.png`` into ``out``. ``seconds``:
    this command's wall-clock time; ``cached``: the cells it found finished (not in it);
    ``failed``: a line per failed cell (left out of the tables, listed under "Failed cells");
    ``finish``: the markdown's last step before it is written, once (the study's
    :func:`spcopyro.study.report.with_warnings` of its cells), so a Ctrl-C never leaves this
    run's ``ablation.md`` without it."""
    from spcopyro.data import load_house

    out.mkdir(parents=True, exist_ok=True)
    public_names = _public_houses(records)
    public = []
    if settings.dataset_root is not None:
        public = [load_house(Path(settings.dataset_root) / name) for name in public_names]
    synthetic = {name: settings.houses[name] for name in settings.synthetic}
    if settings.seeds < 1:  # public houses only (--seeds 0): no synthetic house to describe
        synthetic = {}
    stats = public_and_synthetic_statistics(public, synthetic, seeds=range(min(settings.seeds, 5)))
    summary = summarise(records)
    report: dict[str, object] = {
        "settings": settings_json(settings),
        "statistics": [s.to_json() for s in stats],
        "summary": summary,
        "top_words": _top_words(records),
        "targets": targets(summary, settings),
        "records": records,
        "seconds": seconds,
        "cells_finished_before": cached,
        "failed_cells": list(failed),
    }
    report["statistics_md"] = statistics_table(stats)
    text = markdown(report, settings)
    del report["statistics_md"]
    if finish is not None:
        text = finish(text)
    replace_text(out / "ablation.md", text)  # each whole or not at all
    replace_text(out / "ablation.json", json.dumps(report, indent=1, default=json_default) + "\n")
    figure(report, settings, out / "ablation.png")
    return report


def settings_json(settings: AblationSettings) -> dict[str, object]:
    """The run's settings as JSON values."""
    return {
        "variants": [v.to_json() for v in settings.variants],
        "variant_texts": [v.describe() for v in settings.variants],
        "baselines": list(settings.baselines),
        "synthetic": {
            name: dataclasses.asdict(settings.houses[name]) for name in settings.synthetic
        },
        "seeds": settings.seeds,
        "public_seeds": settings.public_seeds,
        "dataset_root": None if settings.dataset_root is None else str(settings.dataset_root),
        "public_houses": None if settings.public_houses is None else list(settings.public_houses),
        "sweeps": settings.sweeps,
        "spcoa_iterations": settings.spcoa_iterations,
        "observations_off": settings.observations_off,
        "workers": settings.workers,
        "command": settings.command,
    }
