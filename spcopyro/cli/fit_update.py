"""``spcopyro fit --update``'s own lines and records: how many observations an update added
(:func:`report_observations`), and its record of the saved fit relative to OUT
(:func:`relative_records`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from spcopyro.results.result import SpCoResult

__all__ = ["relative_records", "report_observations"]


def relative_records(results: Sequence[SpCoResult], out: Path) -> None:
    """Each update result's ``inference.update_of`` with the saved fit's folder relative to
    ``out``, the folder the result is written to
    (:func:`spcopyro.robot.update_history.relative_record`)."""
    from spcopyro.robot.update_history import relative_record

    for result in results:
        result.inference["update_of"] = relative_record(result.inference["update_of"], out)


def report_observations(record: dict[str, object], where: str) -> None:
    """Print how many observations ``--update`` added and how many the fit now holds
    (``record``: ``inference.update_of``; both placed on the map's free cells), or, where the
    saved fit in ``where`` did not record its own (saved by an older spcopyro), that the number
    added is not known."""
    now, before = record.get("observations"), record.get("observations_before")
    if not isinstance(now, int):
        return
    if isinstance(before, int):
        print(f"observations     {now - before:+d} added: {now} in the fit now, {before} "
              "before (those placed on the map's free cells)")  # fmt: skip
    else:
        print(f"observations     {now} in the fit now (placed on the map's free cells); "
              f"the fit in {where} does not record how many it held (saved by an older "
              "spcopyro), so how many were added is not known")  # fmt: skip
