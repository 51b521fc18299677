"""``comparison.md``'s summary (which line did best on each score, and which lines' maps
collapsed to one concept) and the readings its other parts share: how many held-out words a
top-1 rests on, whether a time to 95% is only that of a line's first map, and the machine's
load beside the times. :mod:`spcopyro.experiments.comparison_report` writes them.

A QA run on room1dk5 (one held-out trial) read "gibbs-sw ... 95% of its own final held-out
top-1 after 0.014 s vs 0.41 s (28.5x faster)": its first kept map already had its final top-1,
so that time is when its first map was kept, not a speed. Its top-1 rested on 15 held-out words
(one word: 0.067), and the table said neither.
"""

from __future__ import annotations

import math

from spcopyro._util.messages import fixed, plural

WORD_SCORES = ("top1", "top3")
"""Scores that are a share of the held-out words (a word more or less moves them by one over
the words scored)."""

TIE = 5e-4
"""Means closer than this are equal (the findings' "equal")."""


def first_map_counts(records: list[dict]) -> dict[str, int]:
    """score -> how many of a line's fits reached 95% of their final score at their curve's
    first point (a kept map, or the shortest re-run): a time to 95% that is only the time of
    that point."""
    counts: dict[str, int] = {}
    for record in records:
        curve = record.get("curve") or []
        for score, t in record.get("time_to_95", {}).items():
            first = bool(curve) and t is not None and math.isfinite(t)
            counts[score] = counts.get(score, 0) + int(first and t <= curve[0]["seconds"])
    return counts


def at_first_map(line: dict, score: str) -> bool:
    """Whether every fit of ``line`` (a summary entry) reached 95% of its final ``score`` at its
    first map (:func:`first_map_counts`)."""
    fits = line.get("fits", 0)
    return fits > 0 and line.get("t95_at_first_map", {}).get(score, 0) == fits


def words_scored(line: dict) -> float:
    """The held-out words a line's top-1 rests on, all its fits together (nan if not known)."""
    entry = line.get("final", {}).get("scored_words", {})
    mean, n = entry.get("mean", math.nan), entry.get("n", 0)
    return mean * n if n and math.isfinite(mean) else math.nan


def one_word(*lines: dict) -> float:
    """What one held-out word moves a line's mean top-1 by (1 / the words scored, over all its
    fits), the largest of ``lines``'; nan when none says."""
    quanta = [1 / w for w in map(words_scored, lines) if math.isfinite(w) and w > 0]
    return max(quanta) if quanta else math.nan


def _words(w: float) -> str:
    return f"{w:.0f}" if abs(w - round(w)) < 1e-9 else f"{w:.1f}"


def within_one_word(diff: float, *lines: dict) -> str:
    """``", within one held-out word: 1/15 = 0.067"`` when ``diff`` of a top-1 or top-3 is at
    most one word's share (:func:`one_word`), else ``""``."""
    quantum = one_word(*lines)
    if not math.isfinite(quantum) or abs(diff) > quantum + 1e-12:
        return ""
    return f", within one held-out word: 1/{_words(1 / quantum)} = {quantum:.3f}"


def top1_words(line: dict) -> str:
    """A top-1 table cell's words: ``" (15 words)"``, per fit (``"15.5 words a fit"``)."""
    entry = line.get("final", {}).get("scored_words", {})
    mean = entry.get("mean", math.nan)
    if not math.isfinite(mean):
        return ""
    return f" ({_words(mean)} words{' a fit' if entry.get('n', 0) > 1 else ''})"


def load_text(summary: dict) -> str:
    """The machine's load when the comparison ended, for beside its times; ``""`` if not kept."""
    load = summary.get("load_average_at_end")
    if not load:
        return ""
    cpus = summary.get("cpus")
    on = f" on {plural(cpus, 'CPU')}" if isinstance(cpus, int) else ""
    numbers = ", ".join(f"{x:.2f}" for x in load)
    earlier = " (the fits of cells finished before it ran under their own)" if summary.get(
        "cells_finished_before") else ""  # fmt: skip
    return (f" Load average as this command ended (1, 5, 15 min): {numbers}{on}{earlier}; "
            "the times grow with it.")  # fmt: skip


def mean_of(entry: dict, *keys: str) -> float:
    """The ``"mean"`` of ``entry[keys[0]][keys[1]]...`` (a line's ``"final"`` score, say); nan
    where a key or the mean is missing."""
    for key in keys:
        entry = entry.get(key, {}) if isinstance(entry, dict) else {}
    return entry.get("mean", math.nan) if isinstance(entry, dict) else math.nan


def best_lines(by_variant: dict[str, dict], scores: tuple[str, ...], names: dict[str, str],
               lower: tuple[str, ...]) -> list[str]:  # fmt: skip
    """Per score the line(s) with the best mean of their own output, with the value; for a
    share of held-out words, the other lines within one word of it."""
    parts = []
    for score in scores:
        means = {k: mean_of(s, "final", score) for k, s in by_variant.items()}
        means = {k: v for k, v in means.items() if math.isfinite(v)}
        if not means:
            continue
        sign = -1 if score in lower else 1
        best = max(sign * v for v in means.values()) * sign
        top = [k for k, v in means.items() if abs(v - best) < TIE]
        digits = 2 if score in ("mean_rank", "distance_m") else 3
        text = f"{names.get(score, score)}: {', '.join(top)} {fixed(best, digits)}"
        if score in WORD_SCORES:
            near = [f"{k} {fixed(v, digits)}" for k, v in means.items() if k not in top
                    and within_one_word(v - best, by_variant[k], by_variant[top[0]])]  # fmt: skip
            quantum = one_word(*(by_variant[k] for k in means))
            if math.isfinite(quantum):
                text += f" (one held-out word: {quantum:.3f}; within one word of it: "
                text += f"{', '.join(near) or 'none'})"
        parts.append(text)
    return parts


def summary_lines(summary: dict, scores: dict[str, tuple[str, ...]], names: dict[str, str],
                  lower: tuple[str, ...]) -> list[str]:  # fmt: skip
    """``comparison.md``'s "## Summary": per house type the best line on each score of
    ``scores[house_type]`` (the table's own-output columns) and the lines whose cells warned of
    a one-concept map (``summary["one_concept_maps"]``: house type -> line -> cells)."""
    lines = ["## Summary (best mean of each score, the method's own output)", ""]
    collapsed: dict = summary.get("one_concept_maps", {})
    for house_type, by_variant in summary["summary"].items():
        best = best_lines(by_variant, scores[house_type], names, lower)
        lines.append(f"- {house_type}, best: " + "; ".join(best) + ".")
        warned = collapsed.get(house_type, {})
        runs = {k: len(v) for k, v in summary["records"][house_type].items()}
        if warned:
            said = ", ".join(f"{k} ({n} of {plural(runs.get(k, n), 'fit')})"
                             for k, n in warned.items())  # fmt: skip
            lines.append(f"- {house_type}, warned of a one-concept map (Cells with warnings): "
                         f"{said}.")  # fmt: skip
        elif "one_concept_maps" in summary:
            lines.append(f"- {house_type}: no cell warned of a one-concept map.")
    return lines + [""]
