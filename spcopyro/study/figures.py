"""A study's quality-against-time figure, drawn from its table only (issue 26 item 2).

One panel per data source; in it, one colour per (variant, method): every finished seed as a
faint point at (wall seconds of its fit, its score), and the group's mean score with its sample
standard deviation over the seeds at the geometric mean of its times; a held-out source's
held-out top-1 word accuracy (``top1``) the same way in a second panel beside it. The time axis is
logarithmic, since methods differ by orders of magnitude (a CAVI run in seconds, 5000 Gibbs
sweeps in minutes). What is plotted is what ``results.csv`` holds: a report redrawn from the
table (``spcopyro study STUDY --out OUT --report-only``) redraws this figure too.
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from spcopyro._util.number_checks import is_finite_number
from spcopyro._util.outputs import replace_figure
from spcopyro.figures.fonts import any_script, quiet_glyph_warnings
from spcopyro.study.maps import row_names

__all__ = ["QUALITY_TIME_FILE", "WORD_SCORE", "quality_time_figure", "write_quality_time"]

QUALITY_TIME_FILE = "quality_time.png"
"""The figure's file name, beside ``report.md``."""
TIME_WORDS = {"seconds": "wall-clock seconds", "cpu_seconds": "CPU seconds"}
"""A time column of ``results.csv`` in words (the title and axis said "seconds")."""


def _score_words(score: str, kinds: set[object]) -> str:
    """What ``score`` (a ``results.csv`` column) is, in words: an ARI against which truth (a
    public house's is this project's region truth, a synthetic house's or simulated map's the
    ground truth it was drawn from; ``kinds``: the plotted rows' ``data_kind``); other columns
    by their name. The title read "ari against seconds", two column names."""
    if score != "ari":
        return score
    if kinds == {"public"}:
        return "ARI against the region truth"
    if "public" in kinds:
        return "ARI against the truth (a public house's: the region truth)"
    return "ARI against the ground truth"


WORD_SCORE = "top1"
"""The held-out word score a row of a held-out source carries (:mod:`spcopyro.study.evaluate`):
the share of the held-out trial's words whose top-ranked concept is right, drawn beside the
map's score so that the word side of the trade-off shows."""


def _timed(rows, score: str, time: str) -> list[dict[str, object]]:
    """The rows that finished with a number of ``score`` and a positive ``time`` (a time of 0
    left out: the log axis has no place for it)."""
    placed = []
    for row in rows:
        seconds, value = row.get(time), row.get(score)
        if (
            row.get("status") == "ok"
            and is_finite_number(seconds)
            and seconds > 0
            and is_finite_number(value)
        ):
            placed.append(row)
    return placed


def _points(rows, score: str, time: str) -> list[tuple[str, str, str, float, float]]:
    """``(data, variant, method, seconds, score)`` of each of :func:`_timed`'s ``rows``."""
    return [(str(row["data"]), str(row["variant"]), str(row["method"]),
             float(row[time]), float(row[score]))  # type: ignore[arg-type]
            for row in rows]  # fmt: skip


def _draw_panel(ax, points, source, groups, colour) -> None:
    """``source``'s seeds (faint) and each group's mean +- sd at the geometric mean time."""
    for group in groups:
        mine = [(s, v) for d, *g, s, v in points if d == source and tuple(g) == group]
        if not mine:
            continue
        seconds, values = np.asarray(mine).T  # [n], [n]
        ax.scatter(seconds, values, s=14, color=colour[group], alpha=0.35, linewidths=0)
        spread = float(values.std(ddof=1)) if len(values) > 1 else 0.0
        ax.errorbar(
            float(np.exp(np.log(seconds).mean())),
            float(values.mean()),
            yerr=spread or None,
            fmt="o",
            ms=6,
            capsize=3,
            color=colour[group],
        )  # fmt: skip  (no zero-height bar: one seed)


def quality_time_figure(
    rows: Sequence[dict[str, object]], score: str = "ari", time: str = "seconds"
) -> Figure | None:
    """The figure of ``score`` against ``time`` (module docstring) for the rows that finished
    with both numbers (a time of 0 is left out: the log axis has no place for it); None when no
    row has them (a study that scores no ``score``, or none finished). A source whose rows hold
    a held-out word score (:data:`WORD_SCORE`, a held-out source's) gets a second panel beside
    its first, that score against the same time: the map's quality alone hid the words'."""
    placed = _timed(rows, score, time)
    if not placed:
        return None
    points = _points(placed, score, time)
    kinds = {row.get("data_kind") for row in placed}
    words = _points(_timed(rows, WORD_SCORE, time), WORD_SCORE, time) if score != WORD_SCORE else []
    sources = list(dict.fromkeys(p[0] for p in points))
    worded = {p[0] for p in words}
    panels = [(source, kind) for source in sources
              for kind in ("score", "words") if kind == "score" or source in worded]  # fmt: skip
    groups = list(dict.fromkeys((p[1], p[2]) for p in points + words))
    palette = colormaps["tab10" if len(groups) <= 10 else "tab20"]
    colour = {group: palette(i % palette.N) for i, group in enumerate(groups)}
    if len(panels) > len(sources):  # a line per source: its panels side by side, the cells
        columns, lines = 2, len(sources)  # right of a source without words left empty
        slots = [sources.index(source) * columns + (kind == "words") for source, kind in panels]
    else:  # one panel per source: three a line
        columns = min(len(panels), 3)
        lines = math.ceil(len(panels) / columns)
        slots = list(range(len(panels)))
    legend_rows = math.ceil(len(groups) / 4)
    fig = Figure(figsize=(4.3 * columns, 3.5 * lines + 0.5 + 0.25 * legend_rows))
    for slot, (source, kind) in zip(slots, panels, strict=True):
        ax = fig.add_subplot(lines, columns, slot + 1)
        shown = points if kind == "score" else words
        _draw_panel(ax, shown, source, groups, colour)
        times = [s for d, _, _, s, _ in shown if d == source]
        ax.set_xlim(min(times) / 1.5, max(times) * 1.5)  # a panel of equal times is not singular
        ax.set_xscale("log")  # after the limits: one seed's autoscaled ones are singular
        _label_time_axis(ax, max(times) / min(times) * 2.25)
        ax.set_title(source if kind == "score" else f"{source}: held-out words", fontsize=10)
        ax.set_xlabel(f"{TIME_WORDS.get(time, time)} per fit (log scale)")
        if kind == "words":
            ax.set_ylabel("held-out top-1 word accuracy")
        else:
            ax.set_ylabel("ARI" if score == "ari" else score)
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], marker="o", ls="", color=colour[g]) for g in groups]
    named = row_names(rows)  # as the maps' titles: distinct where two rows share a name
    legend = fig.legend(handles, [named[g] for g in groups], loc="lower center",
                        ncol=min(len(groups), 4), frameon=False, fontsize=8)  # fmt: skip
    # one panel is 4.3 in wide: four columns of "stochastic-vi / stochastic-vi" ran past both
    # edges of the image, cut off; the figure widens to hold its legend
    wide = legend.get_window_extent(FigureCanvasAgg(fig).get_renderer()).width / fig.dpi
    fig.set_figwidth(max(fig.get_figwidth(), wide + 0.2))
    both = " and held-out top-1 word accuracy" if words else ""
    title = (f"{_score_words(score, kinds)}{both}, against {TIME_WORDS.get(time, time)} per "
             "fit: seeds (faint), mean ± sd (marked)")  # fmt: skip
    # wrapped to the figure's width (about 12 characters an inch at 10 pt); tight_layout
    # leaves the suptitle its room
    fig.suptitle(textwrap.fill(title, int(fig.get_figwidth() * 12)), fontsize=10)
    fig.tight_layout(rect=(0, min(0.3, 0.06 * legend_rows + 0.03), 1, 1))
    return fig


def _label_time_axis(ax, span: float) -> None:
    """Label the log time axis at 1, 2, 5 x 10^k when it spans under ~2.5 decades (``span``: its
    upper over its lower limit), else at the powers of ten, as plain numbers, and leave the minor
    ticks unlabelled: matplotlib's default labelled every minor tick of a panel spanning under a
    decade, ``4x10^-2 6x10^-2 ...``, printed over each other."""
    subs = (1.0, 2.0, 5.0) if math.log10(span) <= 2.5 else (1.0,)
    ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=subs))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def write_quality_time(
    rows: Sequence[dict[str, object]], path: str | os.PathLike[str], score: str = "ari"
) -> Path | None:
    """Write :func:`quality_time_figure` as a PNG at ``path`` (None, and nothing written, when
    no row has both numbers)."""
    with quiet_glyph_warnings():  # its layout measures the texts: any_script tells them below
        fig = quality_time_figure(rows, score)
    if fig is None:
        return None
    path = Path(path)
    with any_script(fig):  # words of any script, not boxes
        replace_figure(fig, path, dpi=110)  # whole or not at all
    return path
