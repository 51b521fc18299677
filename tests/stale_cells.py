"""Cells a study command finds stored by another spcopyro source: kept and counted, then run
again with ``--rerun-stale`` -- the study engine's rule, which ``compare-inference``,
``ablation`` and ``experiment`` each expose (their tests share these steps)."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

STALE_DIGEST = "0123456789abcdef"


def mark_stale(out: Path) -> Path:
    """The one cell stored under ``out/cells``, its ``source_digest`` made another source's."""
    (stored,) = (out / "cells").glob("*.json")
    record = json.loads(stored.read_text())
    record["source_digest"] = STALE_DIGEST
    stored.write_text(json.dumps(record))
    return stored


def check_stale_kept_then_rerun(
    main: Callable[[list[str]], int],
    command: Sequence[str],
    out: Path,
    report: str,
    capsys,
    counted: str = "1 of 1 cells to run (0 finished before)",
) -> None:
    """Mark ``out``'s cell stale; the command run again keeps it (its ``report``.md/.json say
    the cell was finished before this command), and with ``--rerun-stale`` runs it again,
    saying ``counted`` (the study engine's count, or the command's own)."""
    stored = mark_stale(out)
    assert main(list(command)) == 0
    printed = capsys.readouterr().out
    assert "nothing to run" in printed and "--rerun-stale runs them again" in printed
    text = (out / f"{report}.md").read_text()
    assert "Whole command" not in text
    assert "This command: " in text and "1 cell of the table was finished before it" in text
    assert json.loads((out / f"{report}.json").read_text())["cells_finished_before"] == 1
    assert main([*command, "--rerun-stale"]) == 0
    assert counted in capsys.readouterr().out
    assert json.loads(stored.read_text())["source_digest"] != STALE_DIGEST
