"""A study's results on disk: the cell cache and the tidy table (issue 26 items 2 and 3).

Layout of ``OUT``::

    study.json        the study as run (resolved paths)
    cells/KEY.json    one finished cell: its status, error and scores (the cache)
    traces/KEY.npz    its trace: objective, num_concepts, seconds per iteration
    results.csv       the tidy table: one row per (variant, data, method, seed) of the study
    report.md         mean +- sd tables drawn from results.csv (spcopyro.study.report)

A cell is written (atomically) the moment it finishes, so an interrupted study keeps every
finished cell. The table is rebuilt from the cache for the study's current cells: its inputs
(:meth:`spcopyro.study.cells.Cell.inputs`: the names come from the study, not the cache), the
status and every score (:data:`COLUMNS`; a score that does not apply is empty).
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from spcopyro.study.cells import Cell
from spcopyro.study.evaluate import SCORES, STATUS_COLUMNS

__all__ = [
    "COLUMNS", "INPUT_COLUMNS", "CellStore", "is_number", "read_table", "table_rows", "write_table",
]  # fmt: skip

INPUT_COLUMNS = (
    "variant", "data", "method", "seed", "data_kind", "data_source", "house_seed", "heldout",
    "sweeps", "observations_off", "scoring", "preset", "overrides", "version", "key",
)  # fmt: skip
"""What made a row (:meth:`Cell.inputs`)."""
COLUMNS = (*INPUT_COLUMNS, *STATUS_COLUMNS, *SCORES, "trace")
"""Every column of ``results.csv``, in order."""
TABLE = "results.csv"


class CellStore:
    """The finished cells of a study folder, by key."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.out = Path(out)
        self.cells = self.out / "cells"
        self.traces = self.out / "traces"

    def finished(self) -> dict[str, dict[str, object]]:
        """Every stored record, by key (a half-written file is never there: writes are atomic)."""
        if not self.cells.is_dir():
            return {}
        records = {}
        for path in self.cells.glob("*.json"):
            try:
                records[path.stem] = json.loads(path.read_text())
            except (OSError, ValueError):  # unreadable: the cell runs again
                continue
        return records

    def put(self, record: dict[str, object], trace: dict[str, np.ndarray] | None) -> None:
        """Store one finished cell (and its trace) under its key."""
        key = str(record["key"])
        self.cells.mkdir(parents=True, exist_ok=True)
        if trace is not None:
            self.traces.mkdir(parents=True, exist_ok=True)
            staging = self.traces / f".{key}.npz"
            np.savez_compressed(staging, **trace)
            os.replace(staging, self.traces / f"{key}.npz")
            record = {**record, "trace": f"traces/{key}.npz"}
        staging = self.cells / f".{key}.json"
        staging.write_text(json.dumps(record, default=_json_value, indent=1))
        os.replace(staging, self.cells / f"{key}.json")


def is_number(value: object) -> bool:
    """Whether a table value is a finite number (a score that applied; not a bool, None or
    text)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _json_value(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON")


def table_rows(cells: Iterable[Cell], records: dict[str, dict[str, object]]) -> list[dict]:
    """One row per cell that has a record: its inputs, status and scores (:data:`COLUMNS`)."""
    rows = []
    for cell in cells:
        record = records.get(cell.key)
        if record is None:
            continue
        row = dict.fromkeys(COLUMNS, "")
        row.update({k: v for k, v in record.items() if k in row})
        row.update(cell.inputs())
        rows.append(row)
    return rows


def write_table(path: str | os.PathLike[str], rows: list[dict]) -> Path:
    """Write ``rows`` as CSV with the :data:`COLUMNS` header (atomically)."""
    path = Path(path)
    staging = path.with_name(f".{path.name}")
    with open(staging, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell_text(v) for k, v in row.items()})
    os.replace(staging, path)
    return path


def _cell_text(value: object) -> object:
    if isinstance(value, float) and math.isfinite(value):
        return repr(value)  # every digit: a redrawn report equals the first
    return value


TEXT_COLUMNS = frozenset(
    ("variant", "data", "method", "data_kind", "data_source", "preset", "overrides", "version",
     "key", "status", "error_type", "error", "trace", "top_words", "details",
     "scoring")
)  # fmt: skip
"""Columns read back as text, even when they look like a number."""


def _parse(text: str) -> object:
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_table(path: str | os.PathLike[str]) -> list[dict[str, object]]:
    """The rows of a ``results.csv``, numbers as numbers and empty cells as None."""
    with open(path, newline="") as file:
        return [
            {k: v if k in TEXT_COLUMNS else _parse(v) for k, v in row.items()}
            for row in csv.DictReader(file)
        ]
