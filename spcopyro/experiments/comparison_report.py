"""The inference comparison's summary, findings, table (``comparison.md``) and figures; the fits
and their scoring are :mod:`spcopyro.experiments.inference_comparison`, the run is a study
(:func:`spcopyro.study.comparison.run_comparison`, behind ``spcopyro compare-inference``).

:func:`summarise` reduces the per-fit records (house type -> variant -> records, drawn from the
study's table) to means per variant and house type and states, from those numbers alone, where
mean field loses and where it wins (:func:`findings`); :func:`write_report` writes the JSON, the
markdown and one figure of quality against wall-clock time (log axis) per house type
(:mod:`spcopyro.experiments.comparison_figure`, whose
:func:`~spcopyro.experiments.comparison_figure.plot_curves` and
:data:`~spcopyro.experiments.comparison_figure.SCORE_NAMES` are importable from here too;
its :func:`~spcopyro.experiments.comparison_figure.curves_figure` only from there).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.messages import command_time, fixed, plural, seconds_text
from spcopyro._util.outputs import replace_text
from spcopyro.experiments.comparison_figure import FINAL_NOTE, SCORE_NAMES, plot_curves
from spcopyro.experiments.comparison_headline import (
    TIE,
    at_first_map,
    first_map_counts,
    load_text,
    mean_of,
    summary_lines,
    top1_words,
    within_one_word,
)
from spcopyro.experiments.comparison_stats import CONFIDENT
from spcopyro.experiments.inference_comparison import (
    HEARD_NOTHING,
    LOWER_IS_BETTER,
    PRIMARY,
    PUBLIC,
    SYNTHETIC,
    VARIANTS,
    ComparisonSettings,
    budget,
)
from spcopyro.experiments.table import json_default
from spcopyro.inference.protocol import options_for_start
from spcopyro.results.concept_words import NO_WORDS, WORDS_NOT_MODELLED_NOTE


def _mean_sd(values: list[float]) -> dict[str, float]:
    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=np.float64)
    if x.size == 0:
        return {"mean": math.nan, "sd": math.nan, "n": 0}
    return {"mean": float(x.mean()), "sd": float(x.std(ddof=1)) if x.size > 1 else 0.0,
            "n": int(x.size)}  # fmt: skip


def _summarise_variant(records: list[dict]) -> dict[str, object]:
    first = records[0]
    out: dict[str, object] = {
        "final": {s: _mean_sd([r["final"][s] for r in records]) for s in first["final"]},
        "final_given_labels": {
            s: _mean_sd([r["final_given_labels"][s] for r in records])
            for s in first["final_given_labels"]
        },
        "time_to_95": {
            s: _mean_sd([r["time_to_95"][s] for r in records]) for s in first["time_to_95"]
        },
        "fits": len(records),
        "t95_at_first_map": first_map_counts(records),  # score -> fits: no speed to read
        "seconds": _mean_sd([r["seconds"] for r in records]),
        "iterations": _mean_sd([r["iterations"] for r in records]),
        "concepts": _mean_sd([r["concepts"] for r in records]),
        "objective": first["objective"],
        "curve_kind": first["curve_kind"],
        "top_words_first_fit": first["top_words"],
    }
    if first.get("words_modelled", True) is False:  # use_words off: no concept lists words
        out["words_modelled_first_fit"] = False
    if all("start_iterations" in r for r in records):  # vi-gibbs: its CAVI start's iterations
        out["start_iterations"] = _mean_sd([r["start_iterations"] for r in records])
    if "ess_per_second" in first:
        out["ess_per_second"] = {
            k: _mean_sd([r["ess_per_second"][k] for r in records]) for k in first["ess_per_second"]
        }
    if "truth_categories" in first:
        out["truth_categories"] = _mean_sd([r["truth_categories"] for r in records])
    if all("overconfidence" in r for r in records):
        out["overconfidence"] = {
            k: _mean_sd([r["overconfidence"][k] for r in records]) for k in first["overconfidence"]
        }
    return out


def summarise(
    records: dict[str, dict[str, list[dict]]],
    settings: ComparisonSettings,
    notes: list[str],
    seconds: float,
    cached: int = 0,
) -> dict[str, object]:
    """The JSON of the comparison: settings, per house type and variant the means (and sd) of
    every score, and every fit's record with its curve. ``seconds``: this command's wall-clock
    time; ``cached``: the cells it found finished (their fits are not in ``seconds``)."""
    summary: dict[str, object] = {
        "command": settings.command,
        "settings": {  # what ran: a house type without fits records none of its settings
            "preset": settings.preset,
            "overrides": settings.overrides,
            "house_types": [t for t in (SYNTHETIC, PUBLIC) if t in records],
            "seeds": settings.seeds if SYNTHETIC in records else None,
            "synthetic_spec": None
            if settings.synthetic_spec is None or SYNTHETIC not in records
            else dataclasses.asdict(settings.synthetic_spec),
            "dataset_root": None
            if settings.dataset_root is None or PUBLIC not in records
            else str(settings.dataset_root),
            "public_houses": _trials(records.get(PUBLIC, {})) if PUBLIC in records else None,
            "folds": settings.folds if PUBLIC in records else None,  # None there: every trial
            "quick": settings.quick,
            "iterations": {
                key: budget(VARIANTS[key], settings)
                for by_variant in records.values()
                for key in by_variant
            },
            "options": {
                key: VARIANTS[key].options_for(settings.quick) for key in settings.variants
            },
        },  # fmt: skip
        "methods": {
            key: VARIANTS[key].label for by_variant in records.values() for key in by_variant
        },
        "summary": {
            house_type: {key: _summarise_variant(recs) for key, recs in by_variant.items() if recs}
            for house_type, by_variant in records.items()
        },
        "records": records,
        "seconds": seconds,
        "cells_finished_before": cached,
    }
    iterations = summary["settings"]["iterations"]  # type: ignore[index]
    shorter = unfinished_annealing(iterations, settings)
    summary["notes"] = [*notes, *shorter, *findings(summary["summary"])]  # type: ignore[arg-type]
    return summary


def unfinished_annealing(iterations: dict[str, int], settings: ComparisonSettings) -> list[str]:
    """A note per line whose budget (``--iterations``) ends before its gamma annealing does:
    its fits are of a weaker coupling than the others' (the method's warning went to the
    terminal only, and the line's label still read "gamma annealed over 20 it.")."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    notes = []
    for key, n in iterations.items():
        method = INFERENCE_METHODS.get(VARIANTS[key].method)
        defaults = None if method is None else method.default_options()
        if defaults is None or not dataclasses.is_dataclass(defaults):
            continue
        defaults = options_for_start(defaults, given_start=False)  # it fits from random starts
        options = VARIANTS[key].options_for(settings.quick)
        for name in ("anneal_iterations", "anneal_passes"):
            anneal = options.get(name, getattr(defaults, name, 0))
            if isinstance(anneal, int) and anneal > n:
                notes.append(f"{key}: {n} {iteration_unit(key)} end before its annealing ({name} = "
                             f"{anneal}): gamma reaches only {100 * n / anneal:.0f}% of the "
                             "model's, so its fits are of a weaker coupling")  # fmt: skip
    return notes


def _ratio(a: float, b: float) -> str:
    if not (math.isfinite(a) and math.isfinite(b)) or a <= 0 or b <= 0:
        return "n/a"
    return f"{b / a:.1f}x faster" if a < b else f"{a / b:.1f}x slower"


def _finding_seconds(value: float) -> str:
    """A time in a finding beside the ratio computed from it: two significant digits below 1 s
    (seconds_text's one decimal read "0.1 s vs 0.044 s (3.3x slower)" for 0.144 s)."""
    return seconds_text(value) if not value < 1 else f"{value:.2g}"


NO_WORDS_SHOWN = f"({NO_WORDS})"
"""How "Concepts found" shows a concept that heard no word (a record's
:data:`~spcopyro.experiments.inference_comparison.HEARD_NOTHING`): as the fit's listing,
``where`` and the figures show it (:func:`spcopyro.results.concept_words.format_concept_words`)."""

CHANCE_ARI = 0.05
"""A mean final ARI below this is at chance: the time to 95% of it (t95) means nothing (an SVI
quick run ended at ARI 0.006 and "reached 95% of its own final ARI" in 0.01 s)."""


def at_chance(entry: dict, score: str) -> bool:
    """Whether a line's mean final ``score`` is an ARI at chance (below :data:`CHANCE_ARI`)."""
    return score == "ari" and mean_of(entry, "final_given_labels", "ari") < CHANCE_ARI


def _time_to_95(s: dict, ref: dict, primary: str) -> str:
    """A finding's part on the time to 95% of the final ``primary`` of line ``s`` against
    gibbs's ``ref``; a line whose final ARI is at chance (:func:`at_chance`) gets no time."""
    name = SCORE_NAMES[primary]
    t, t_ref = mean_of(s, "time_to_95", primary), mean_of(ref, "time_to_95", primary)
    chance = f"at chance (ARI < {CHANCE_ARI:g}), so no time to 95% of it is given"
    first = "from its first map: that map already had 95% of its final {}, so no speed is read"
    if at_first_map(s, primary):  # gibbs-sw's first kept map read "28.5x faster" than gibbs
        return f"95% of its own final {name} after {_finding_seconds(t)} s, " + first.format(name)
    if at_chance(s, primary):
        text = f"its final {name} {fixed(mean_of(s, 'final_given_labels', primary))} is {chance}"
        if not at_chance(ref, primary):
            text += f" (gibbs reaches 95% of its own after {_finding_seconds(t_ref)} s)"
        return text
    text = f"95% of its own final {name} after {_finding_seconds(t)} s vs "
    if at_chance(ref, primary):
        final_ref = fixed(mean_of(ref, "final_given_labels", primary))
        return text + f"none for gibbs: its final {name} {final_ref} is {chance}"
    if at_first_map(ref, primary):
        return text + (f"{_finding_seconds(t_ref)} s for gibbs, from its first map (no speed "
                       "is read from it)")  # fmt: skip
    return text + f"{_finding_seconds(t_ref)} s ({_ratio(t, t_ref)})"


def findings(summary: dict[str, dict[str, dict]]) -> list[str]:
    """Plain statements, from the measured means only, of how each method compares with Gibbs
    (Algorithm 1): final quality, time to 95% of it, concepts, confidence on wrong cells, ESS."""
    notes = []
    for house_type, by_variant in summary.items():
        ref = by_variant.get("gibbs")
        if ref is None:
            continue
        primary = PRIMARY[house_type]
        better_low = primary in LOWER_IS_BETTER
        for key, s in by_variant.items():
            if key == "gibbs":
                continue
            q = mean_of(s, "final_given_labels", primary)
            q_ref = mean_of(ref, "final_given_labels", primary)
            diff = q - q_ref
            if abs(diff) < TIE:
                verdict = "equal"
            else:
                better = (diff < 0) == better_low
                verdict = f"{'better' if better else 'worse'} by {abs(diff):.3f}"
                if primary == "top1":  # 15 held-out words on room1dk5: one is 0.067
                    verdict += within_one_word(diff, s, ref)
            parts = [
                f"{house_type}, {key} against gibbs: final {SCORE_NAMES[primary]} (labels, means "
                f"given them) {fixed(q)} vs "
                f"{fixed(q_ref)} ({verdict})",
                _time_to_95(s, ref, primary),
                f"whole run {_finding_seconds(mean_of(s, 'seconds'))} s vs "
                f"{_finding_seconds(mean_of(ref, 'seconds'))} s",
                f"concepts {mean_of(s, 'concepts'):.1f} vs {mean_of(ref, 'concepts'):.1f}",
            ]
            if house_type == SYNTHETIC:
                k = mean_of(s, "truth_categories")
                parts[-1] += f" (truth: {k:.1f} categories)"
                if mean_of(s, "concepts") < k:
                    parts.append("fewer concepts than categories: it merges places")
            oc, oc_ref = s.get("overconfidence"), ref.get("overconfidence")
            if house_type == SYNTHETIC:
                own = mean_of(s, "final", "matching_rate")
                own_ref = mean_of(ref, "final", "matching_rate")
                means = mean_of(s, "final_given_labels", "matching_rate")
                means_ref = mean_of(ref, "final_given_labels", "matching_rate")
                parts.append(
                    f"matching rate of its own output {fixed(own)} vs gibbs {fixed(own_ref)}, "
                    f"with the means given the labels {fixed(means)} vs {fixed(means_ref)}"
                )
            else:
                own, own_ref = mean_of(s, "final", "top1"), mean_of(ref, "final", "top1")
                dist = mean_of(s, "final", "distance_m")
                dist_ref = mean_of(ref, "final", "distance_m")
                parts.append(
                    f"top-1 of its own output {fixed(own)} vs gibbs {fixed(own_ref)}; localisation "
                    f"distance {dist:.2f} m vs {dist_ref:.2f} m"
                )
            if oc and oc_ref:
                parts.append(
                    f"share of its wrong cells labelled with confidence >= {CONFIDENT}: "
                    f"{100 * mean_of(oc, 'confident_wrong_share'):.0f}% vs gibbs "
                    f"{100 * mean_of(oc_ref, 'confident_wrong_share'):.0f}% (mean confidence "
                    f"on wrong cells {mean_of(oc, 'confidence_wrong'):.3f} vs "
                    f"{mean_of(oc_ref, 'confidence_wrong'):.3f})"
                )
            if "ess_per_second" in s and "ess_per_second" in ref:
                parts.append(
                    f"ESS/s of the log joint {mean_of(s, 'ess_per_second', 'log_joint'):.2f} vs "
                    f"{mean_of(ref, 'ess_per_second', 'log_joint'):.2f}, of the agreement count "
                    f"{mean_of(s, 'ess_per_second', 'agreement'):.2f} vs "
                    f"{mean_of(ref, 'ess_per_second', 'agreement'):.2f}"
                )
            notes.append("; ".join(parts) + ".")
    return notes


SCORES_SHOWN = {SYNTHETIC: ("ari", "matching_rate"),
                PUBLIC: ("ari", "top1", "top3", "mean_rank", "distance_m")}  # fmt: skip
"""The scores of each house type's table that the summary names the best line of."""


def _fmt(entry: dict | None, digits: int = 3, sd: bool = True) -> str:
    if not entry or not math.isfinite(entry.get("mean", math.nan)):
        return "—"
    text = fixed(entry["mean"], digits)  # an SVI ARI of -1e-5 read "-0.000"
    if sd and entry.get("n", 0) > 1:
        text += f" ± {fixed(entry['sd'], digits)}"
    return text


def _percent(entry: dict | None, digits: int) -> str:
    """A share of cells (a mean over fits) in percent, as the project's tables give shares of
    cells (docs/variational.md's "1.4%"; comparison.md gave 0.007)."""
    if not entry or not math.isfinite(entry.get("mean", math.nan)):
        return "—"
    return f"{fixed(100 * entry['mean'], digits)}%"


BUDGETS = (
    "A budget is the sweeps of a sampler, run in full, and a ceiling for cavi, lbp, svi and "
    "stochastic-vi, which stop once their objective settles (column iterations run: a mean "
    "below the budget is a fit that converged first); vi-gibbs's budget counts its Gibbs sweeps, "
    "after a CAVI start of its own (column iterations run: + CAVI, its iterations), "
    "whose time its s per fit, t95 and curve include. An iteration is what each method's "
    "progress bar counts: a sweep of gibbs and vi-gibbs, an update of every cell of cavi and "
    "lbp, an optimiser step of svi, a pass over the tiles of stochastic-vi (memoized VI)."
)
"""What ``comparison.md``'s iteration budgets and its column *iterations run* count."""


ITERATION_UNITS = {"gibbs": "sweeps", "vi-gibbs": "sweeps", "cavi": "iterations",
                   "lbp": "iterations", "svi": "steps", "stochastic-vi": "passes"}  # fmt: skip
"""What one iteration of each method is, as its progress bar counts it: a Gibbs sweep, a CAVI or
LBP update of every cell, an SVI optimiser step, a memoized-VI pass over the tiles (the table
called them all "iterations")."""


def iteration_unit(key: str) -> str:
    """The unit of variant ``key``'s iterations (:data:`ITERATION_UNITS`)."""
    method = VARIANTS[key].method if key in VARIANTS else key
    return ITERATION_UNITS.get(method, "iterations")


def _iterations_run(summary: dict, key: str) -> str:
    """The mean iterations a line's fits ran, in the method's unit, with vi-gibbs's CAVI start:
    ``"60 sweeps (+ 43 CAVI iterations)"``."""
    text = _fmt(summary.get("iterations"), 1 if summary.get("iterations", {}).get("sd") else 0,
                False)  # fmt: skip
    if text != "—":
        text += f" {iteration_unit(key)}"
    start = summary.get("start_iterations")
    if start and math.isfinite(start.get("mean", math.nan)):
        text += f" (+ {_fmt(start, 1 if start.get('sd') else 0, False)} CAVI iterations)"
    return text


def _seconds(entry: dict | None) -> str:
    """A mean time in a table cell (:func:`~spcopyro._util.messages.seconds_text`)."""
    if not entry or not math.isfinite(entry.get("mean", math.nan)):
        return "—"
    return seconds_text(entry["mean"])


def _t95(entry: dict | None, runs: int, first: int = 0) -> str:
    """A t95 cell; ``first``: the fits that reached it at their first map (all: "first map")."""
    if not entry or entry.get("n", 0) == 0:
        return "never"
    text = seconds_text(entry["mean"])  # 0.0049 s read "0.00", beside "37.0x slower"
    text = text if entry["n"] == runs else f"{text} ({entry['n']}/{runs} reached)"
    return f"{text} (first map)" if first == runs else text


def _concurrent(workers: object) -> str:
    """What ``--workers N > 1`` does to the times (the table read as if each fit ran alone)."""
    if not isinstance(workers, int) or workers <= 1:
        return ""
    return (f" Run with --workers {workers}: fits may have run beside each other, so their "
            "times compare less well than with --workers 1.")  # fmt: skip


def _trials(records: dict[str, list[dict]]) -> dict[str, list[str]]:
    """The public houses the fits are of -> their held-out trials, in order."""
    trials: dict[str, set[str]] = {}
    for recs in records.values():
        for record in recs:
            house, _, trial = str(record["house"]).partition(" (held-out trial ")
            trials.setdefault(house, set()).add(trial.rstrip(")"))
    order = {house: sorted(held, key=lambda t: (len(t), t)) for house, held in trials.items()}
    return {house: [int(t) if t.isdigit() else t for t in held] for house, held in order.items()}


def _public_fits(records: dict[str, list[dict]]) -> str:
    """The public houses and held-out trials the table's fits are of, ``room1dk5 (trials 0, 1,
    2)``: comparison.md named none, so a --quick or --public-houses table read as all five."""
    parts = []
    for house, numbers in _trials(records).items():
        noun = "trial" if len(numbers) == 1 else "trials"
        parts.append(f"{house} (held-out {noun} {', '.join(map(str, numbers))})")
    return "; ".join(parts) or "none"


def found_words(entries: Sequence[str], modelled: bool = True) -> str:
    """A line of "Concepts found": a record's ``top_words`` entries (``"kitchen/sink"``, or
    :data:`~spcopyro.experiments.inference_comparison.HEARD_NOTHING`: :data:`NO_WORDS_SHOWN`);
    for a fit that did not model its words (``modelled`` False: the record's
    ``words_modelled``), whose concepts list none, "words not modelled (use_words off)" once for
    the whole fit, as ``fit`` says it
    (:data:`~spcopyro.results.concept_words.WORDS_NOT_MODELLED_NOTE`)."""
    if not modelled:
        return WORDS_NOT_MODELLED_NOTE
    return "; ".join(NO_WORDS_SHOWN if w == HEARD_NOTHING else w for w in entries)


def table_markdown(summary: dict[str, object]) -> str:
    """``comparison.md``: one table per house type, the settings and the findings."""
    settings: dict = summary["settings"]  # type: ignore[assignment]
    methods: dict = summary["methods"]  # type: ignore[assignment]
    by_type: dict = summary["summary"]  # type: ignore[assignment]
    lines = ["# Gibbs sampling against variational inference: quality against time", ""]
    if summary["command"]:
        lines += [f"Made by: `{summary['command']}`", ""]
    overrides = ", ".join(f"{k} {v}" for k, v in settings["overrides"].items())
    lines += [
        f"Preset `{settings['preset']}`" + (f" ({overrides})" if overrides else "")
        + ", random initial labels. Iteration budgets: "
        + ", ".join(f"{k} {v} {iteration_unit(k)}" for k, v in settings["iterations"].items())
        + f". {BUDGETS} {command_time(summary['seconds'], summary.get('cells_finished_before', 0))}"
        + _concurrent(summary.get("workers", 1)),
        "",
        "Scores: higher is better, but for those marked ↓ (lower is better); concepts, times "
        "and ESS/s describe a line, not its quality (a sampler's ESS/s: higher mixes faster).",
        "",
        "Times are wall-clock seconds of the inference alone, mean over fits. t95: time to reach "
        "95% of the method's own final quality along its run (\"at chance\": a mean final ARI "
        f"below {CHANCE_ARI:g}, whose t95 means nothing; \"first map\": every fit's first kept "
        "map or shortest re-run already had 95% of its final quality, so t95 is that map's "
        "time, not a speed). ESS/s: effective sample size per second over the second half of a "
        f"sampler's run, of the log joint and of the Potts agreement count.{load_text(summary)}",
        "",
        *summary_lines(summary, SCORES_SHOWN, SCORE_NAMES, LOWER_IS_BETTER),
    ]  # fmt: skip
    for house_type, by_variant in by_type.items():
        records = summary["records"][house_type]  # type: ignore[index]
        if house_type == SYNTHETIC:
            lines += [
                f"## Synthetic houses ({plural(settings['seeds'], 'seed')}, ground truth)",
                "",
                "Matching rate (means | labels): the same label map scored with pi and phi set "
                "to their posterior means given it, instead of the method's own estimates (a "
                "variational method's means under q; a sampler's result already holds the means "
                "given its labels, so its two agree). ARI and t95 read the labels only. "
                "Wrong cells: the share of cells whose concept's majority category is not "
                f"their own; sure: of them, those held with confidence >= {CONFIDENT} (a "
                "variational method's q(C_i = label), of the labels ARI scores; a sampler's "
                "share of its kept maps of the run's second half agreeing with its last state, "
                "whose wrong cells these are, not its reported point estimate's).",
                "",
                "| method | ARI | matching rate | matching rate (means \\| labels) "
                "| concepts (truth) | t95 ARI (s) | s per fit | iterations run "
                "| ESS/s log joint | ESS/s agreement | wrong cells ↓ | of them sure (>= 0.99) ↓ |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|",
            ]
        else:
            lines += [
                "## Public houses (held-out trials: one fit per trial, scored on it)",
                "",
                f"Fits: {_public_fits(records)}. Top-1 (means \\| labels): the same label map "
                "scored with pi and phi set to their posterior means given it. t95 is measured "
                "on that score along the run. Top-1 and top-3 are shares of the held-out words "
                "the model knows (top-1's words in brackets): one word more or less moves them "
                "by one over that count. A word whose probability ties with other words' counts "
                "the chance that a random tie-break ranks it first (top-3: in the first three), "
                "so a share need not be a whole number of words over the count.",
                "",
                "| method | ARI (region truth) | top-1 | top-1 (means \\| labels) | top-3 "
                "| mean rank ↓ | distance (m) ↓ | concepts | t95 top-1 (s) | s per fit "
                "| iterations run | ESS/s log joint | ESS/s agreement |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
            ]
        for key, s in by_variant.items():
            runs = len(records[key])
            first = s.get("t95_at_first_map", {})
            ess = s.get("ess_per_second", {})
            common_tail = (
                f"| {_seconds(s['seconds'])} | {_iterations_run(s, key)} "
                f"| {_fmt(ess.get('log_joint'), 1, False)} "
                f"| {_fmt(ess.get('agreement'), 1, False)} "
            )
            if house_type == SYNTHETIC:
                oc = s.get("overconfidence", {})
                t95 = _t95(s["time_to_95"].get("ari"), runs, first.get("ari", 0))
                t95 = "at chance" if at_chance(s, "ari") else t95
                lines.append(
                    f"| {methods[key]} | {_fmt(s['final']['ari'])} "
                    f"| {_fmt(s['final']['matching_rate'])} "
                    f"| {_fmt(s['final_given_labels']['matching_rate'])} "
                    f"| {_fmt(s['concepts'], 1, False)} ({_fmt(s['truth_categories'], 0, False)}) "
                    f"| {t95} {common_tail}"
                    f"| {_percent(oc.get('wrong_share'), 1)} "
                    f"| {_percent(oc.get('confident_wrong_share'), 0)} |"
                )
            else:
                f = s["final"]
                lines.append(
                    f"| {methods[key]} | {_fmt(f.get('ari'))} | {_fmt(f['top1'])}{top1_words(s)} "
                    f"| {_fmt(s['final_given_labels']['top1'])} | {_fmt(f['top3'])} "
                    f"| {_fmt(f['mean_rank'], 2)} | {_fmt(f['distance_m'], 2)} "
                    f"| {_fmt(s['concepts'], 1, False)} "
                    f"| {_t95(s['time_to_95'].get('top1'), runs, first.get('top1', 0))} "
                    f"{common_tail}|"
                )
        lines += ["", f"![quality against time](comparison_{house_type}.png)", "", FINAL_NOTE, ""]
    lines += [
        "## Concepts found (the first fit of each house type: top 2 words of the largest "
        f"8 concepts; {NO_WORDS_SHOWN}: none was said in the concept's region, whose words are "
        "only the prior's)",
        "",
    ]
    for house_type, by_variant in by_type.items():
        for key, s in by_variant.items():
            words = found_words(s["top_words_first_fit"], s.get("words_modelled_first_fit", True))
            lines.append(f"- {house_type}, {key}: {words}")
    lines += ["", "## Findings (from the numbers above)", ""]
    none = (  # the section was left empty
        "None: Gibbs (Algorithm 1) is the only method compared."
        if "gibbs" in methods
        else "None: the findings compare each method with Gibbs (Algorithm 1), which --methods "
        "left out."
    )
    lines += [f"- {note}" for note in summary["notes"]] or [none]  # type: ignore[union-attr]
    return "\n".join(lines) + "\n"


def write_report(
    out: Path, summary: dict[str, object], finish: Callable[[str], str] | None = None
) -> list[Path]:
    """Write ``comparison.json``, ``comparison.md`` and the figures; returns their paths.
    ``finish``: the markdown's last step before it is written, once (the study's
    :func:`spcopyro.study.report.with_warnings` of its cells), so a Ctrl-C never leaves this
    run's ``comparison.md`` without it."""
    figures = [
        plot_curves(summary, house_type, out / f"comparison_{house_type}.png")
        for house_type in (SYNTHETIC, PUBLIC)
        if house_type in summary["records"]  # type: ignore[operator]
    ]
    summary["figures"] = [p.name for p in figures]
    json_path = out / "comparison.json"
    text = json.dumps(_finite(summary), indent=1, default=json_default, allow_nan=False)
    replace_text(json_path, text + "\n")  # each whole or not at all
    md_path = out / "comparison.md"
    text = table_markdown(summary)
    replace_text(md_path, finish(text) if finish is not None else text)
    return [json_path, md_path, *figures]


def _finite(value: object) -> object:
    """``value`` with every NaN or infinite float replaced by None (strict JSON: null), e.g. a
    time-to-95% never reached."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (float, np.floating)) and not math.isfinite(value):
        return None
    return value
