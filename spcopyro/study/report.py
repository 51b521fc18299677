"""A study's report, drawn from its table only (issue 26 item 2): nothing is refitted, so a
report can be redrawn or re-cut from ``results.csv`` alone (``spcopyro study STUDY --out OUT
--report-only``).

:func:`summary_rows` groups the table's rows by (variant, data, method) and gives each score's
mean and sample standard deviation over the seeds that finished; :func:`report_markdown` writes
one markdown table per data source (the scores that apply to it) and lists the failed cells
and the cells whose fit gave warnings.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.messages import fixed, plural
from spcopyro._util.number_checks import is_finite_number
from spcopyro._util.outputs import replace_text
from spcopyro.study.cell_warnings import read_warnings
from spcopyro.study.evaluate import SCORES, WARNINGS

__all__ = [
    "REPORT_SCORES", "report_markdown", "summary_rows", "table_cell", "warnings_section",
    "with_warnings", "write_report",
]  # fmt: skip

REPORT_SCORES = (
    "ari", "matching_rate", "top1", "top3", "mean_rank", "distance_m", "concepts",
    "concepts_1pct", "largest_share", "seconds",
)  # fmt: skip
"""The scores a report shows by default (every score is in the table)."""
GROUP = ("variant", "data", "method")


def summary_rows(
    rows: Sequence[dict[str, object]], scores: Sequence[str] = SCORES
) -> list[dict[str, object]]:
    """Per (variant, data, method), in the table's order: ``n`` (finished seeds), ``failed``,
    and ``SCORE`` -> (mean, sd, count) over the rows where it is a number."""
    groups: dict[tuple, list[dict[str, object]]] = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in GROUP), []).append(row)
    summary = []
    for group, members in groups.items():
        ok = [r for r in members if r.get("status") == "ok"]
        entry: dict[str, object] = dict(zip(GROUP, group, strict=True))
        entry.update(n=len(ok), failed=len(members) - len(ok))
        for score in scores:
            values = [float(r[score]) for r in ok if is_finite_number(r.get(score))]  # type: ignore[arg-type]
            if values:
                array = np.asarray(values)
                sd = float(array.std(ddof=1)) if array.size > 1 else math.nan
                entry[score] = (float(array.mean()), sd, len(values))
        summary.append(entry)
    return summary


COUNT_SCORES = ("concepts", "concepts_1pct")
"""Scores that count things: their means get one decimal in every row ("90.0 +- 1.4"); a
mean chosen per value read "90.000 +- 1.414" above "117.5 +- 2.1" in one column."""


def _mean_sd(value: object, score: str) -> str:
    if not isinstance(value, tuple):
        return ""
    mean, sd, _ = value
    digits = 1 if score in COUNT_SCORES or abs(mean) >= 100 else 3
    shown = fixed(mean, digits)
    return shown if math.isnan(sd) else f"{shown} +- {sd:.{digits}f}"


def table_cell(text: object) -> str:
    """``text`` as one cell of a markdown table: a ``|`` in a variant's or source's name
    (``[variants."a|b"]``) split its row into one column more than the header's."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def report_markdown(
    rows: Sequence[dict[str, object]],
    title: str = "study",
    scores: Sequence[str] = REPORT_SCORES,
    expected: int | None = None,
) -> str:
    """Markdown: per data source, a table of mean +- sd over seeds per (variant, method);
    then the failed cells with their errors and the cells that gave warnings
    (:func:`warnings_section`). A table whose cells other spcopyro source computed
    (more than one ``source_digest``) says so first, and one with fewer rows than the study's
    ``expected`` cells (an interrupted run) says how many are not run yet."""
    summary = summary_rows(rows, scores)
    count = f"{plural(len(rows), 'cell')} in the table"
    if expected is not None and len(rows) < expected:  # an interrupted run read as whole
        count += (f" of the study's {expected}: {expected - len(rows)} not run yet (an "
                  "interrupted run: run the same command again)")  # fmt: skip
    lines = [f"# {title}", "", f"{count}; mean +- sample sd over seeds.", ""]
    digests = Counter(str(r.get("source_digest") or "none") for r in rows)
    if len(digests) > 1:
        counts = ", ".join(f"`{d}` {n}" for d, n in digests.most_common())
        lines += [f"**Cells of {len(digests)} versions of spcopyro's source** (column "
                  f"`source_digest`: {counts}); `--rerun-stale` runs again those that other "
                  "source than the running spcopyro's computed.", ""]  # fmt: skip
    for data in dict.fromkeys(str(e["data"]) for e in summary):
        entries = [e for e in summary if e["data"] == data]
        shown = [s for s in scores if any(s in e for e in entries)]
        lines += [f"## {data}", ""]
        lines.append("| variant | method | seeds |" + "".join(f" {s} |" for s in shown))
        lines.append("|---|---|---|" + "---|" * len(shown))  # no score (all failed): 3 columns
        for e in entries:
            seeds = f"{e['n']}" + (f" ({e['failed']} failed)" if e["failed"] else "")
            cells = "".join(f" {_mean_sd(e.get(s), s)} |" for s in shown)
            lines.append(f"| {table_cell(e['variant'])} | {table_cell(e['method'])} | "
                         f"{seeds} |{cells}")  # fmt: skip
        lines.append("")
    failed = [r for r in rows if r.get("status") != "ok"]
    if failed:
        lines += ["## Failed cells", ""]
        for r in failed:
            lines.append(f"- {r['variant']} / {r['data']} / {r['method']} / seed {r['seed']}: "
                         f"{r['error_type']}: {r['error']}")  # fmt: skip
        lines.append("")
    lines += warnings_section(rows)
    return "\n".join(lines)


def warnings_section(
    rows: Sequence[dict[str, object]],
    table: str = "results.csv",
    title: str = "Cells with warnings",
) -> list[str]:
    """The report's lines on the cells whose fit gave warnings (column ``warnings``,
    :mod:`spcopyro.study.cell_warnings`): each distinct message once and whole (on one line),
    followed by the cells that gave it, per (variant, data, method) with their seeds; none
    without such cells. Messages were cut at 300 characters before, which lost e.g. SVI's
    flat-q warning's advice. ``table``: the table that holds each cell's messages, as the text
    names it; ``title``: the section's heading."""
    said: dict[str, dict[tuple, list[object]]] = {}  # message -> (variant, data, method) -> seeds
    cells = 0
    for r in rows:
        messages = dict.fromkeys(" ".join(m.split()) for m in read_warnings(r.get(WARNINGS)))
        cells += bool(messages)
        for message in messages:
            said.setdefault(message, {}).setdefault(tuple(r[k] for k in GROUP), []).append(
                r["seed"]
            )
    if not said:
        return []
    lines = [f"## {title}", "",
             f"{plural(cells, 'cell')} of {len(rows)} gave warnings while fitted (column "
             f"`warnings` of {table} holds each cell's): each warning once, whole, with the "
             "cells that gave it.", ""]  # fmt: skip
    for message, groups in said.items():
        lines.append(f"- {message}")
        where = "; ".join(
            f"{variant} / {data} / {method} / seed{'s' if len(seeds) > 1 else ''} "
            + ", ".join(str(s) for s in seeds)
            for (variant, data, method), seeds in groups.items()
        )
        lines.append(f"  - cells: {where}")
    lines.append("")
    return lines


def with_warnings(text: str, rows: Sequence[dict[str, object]], table: str = "results.csv",
                  title: str = "Cells with warnings") -> str:  # fmt: skip
    """``text`` (a command's own report: ``ablation.md``, ``comparison.md``, ...) followed by
    :func:`warnings_section` of ``rows``; ``text`` as it is when no cell gave warnings."""
    lines = warnings_section(rows, table, title)
    if not lines:
        return text
    return text.rstrip("\n") + "\n\n" + "\n".join(lines)


def write_report(
    table: str | os.PathLike[str],
    out: str | os.PathLike[str],
    title: str = "study",
    expected: int | None = None,
) -> Path:
    """Read ``results.csv`` and write its report to ``out``, with the quality-against-time figure
    (:mod:`spcopyro.study.figures`) beside it when rows have an ARI and a time, and each data
    source's maps (:mod:`spcopyro.study.maps`, from the stored label maps beside the table).
    ``expected``: the study's number of cells (:func:`report_markdown`)."""
    from spcopyro.study.figures import QUALITY_TIME_FILE, write_quality_time
    from spcopyro.study.maps import remove_stale, write_house_maps
    from spcopyro.study.table import read_table

    path = Path(out)
    rows = read_table(table)
    text = report_markdown(rows, title, expected=expected)
    if write_quality_time(rows, path.parent / QUALITY_TIME_FILE) is not None:
        text += f"\n![ARI against wall time per fit]({QUALITY_TIME_FILE})\n"
    else:  # an earlier run's figure would stand beside a report without it
        remove_stale(path.parent, [QUALITY_TIME_FILE], [])
    maps = write_house_maps(rows, Path(table).parent)
    if maps:
        text += "\n## Maps (each source's first seed)\n\n"
        text += "".join(f"![{p.stem}]({os.path.relpath(p, path.parent)})\n" for p in maps)
    replace_text(path, text)  # whole or not at all: Ctrl-C leaves the old report
    return path
