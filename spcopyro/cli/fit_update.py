"""``spcopyro fit --update``'s record of the saved fit relative to OUT (:func:`relative_records`;
the lines it prints: :func:`spcopyro.cli.fit_refine.report_update`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from spcopyro.results.result import SpCoResult

__all__ = ["relative_records"]


def relative_records(results: Sequence[SpCoResult], out: Path) -> None:
    """Each update result's ``inference.update_of`` with the saved fit's folder relative to
    ``out``, the folder the result is written to
    (:func:`spcopyro.robot.update_history.relative_record`)."""
    from spcopyro.robot.update_history import relative_record

    for result in results:
        result.inference["update_of"] = relative_record(result.inference["update_of"], out)
