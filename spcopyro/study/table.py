"""A study's results on disk: the cell cache and the tidy table (issue 26 items 2 and 3).

Layout of ``OUT``::

    study.json        the study as run (resolved paths)
    cells/KEY.json    one finished cell: its status, error and scores (the cache)
    traces/KEY.npz    its trace: objective, num_concepts, seconds per iteration (and the ARI
                      per kept iteration with the study's ari_every)
    maps/KEY.npz      its label map on the map's cells (int16) with the map and the truth
                      (spcopyro.study.maps.label_map_arrays): figures need no refit
    results.csv       the tidy table: one row per (variant, data, method, seed) of the study
    results.parquet   the same table as Parquet, when pyarrow is installed (the parquet extra)
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

from spcopyro._util.npz import write_npz
from spcopyro.study.cells import Cell
from spcopyro.study.evaluate import SCORES, STATUS_COLUMNS, WARNINGS

__all__ = [
    "COLUMNS", "INPUT_COLUMNS", "PARQUET", "CellStore", "read_parquet", "read_table", "table_rows",
    "write_parquet", "write_table",
]  # fmt: skip

INPUT_COLUMNS = (
    "variant", "data", "method", "seed", "data_kind", "data_source", "house_seed", "heldout",
    "sweeps", "observations_off", "scoring", "preset", "overrides", "version", "key",
)  # fmt: skip
"""What made a row (:meth:`Cell.inputs`)."""
COLUMNS = (*INPUT_COLUMNS, "source_digest", *STATUS_COLUMNS, WARNINGS, *SCORES, "trace",
           "label_map")  # fmt: skip
"""Every column of ``results.csv``, in order (``source_digest``: of the code that ran the cell,
:func:`spcopyro.study.cells.source_digest`; ``warnings``: the cell's warnings as JSON text,
empty when none and for a cell stored before records had them,
:mod:`spcopyro.study.cell_warnings`)."""
TABLE = "results.csv"
PARQUET = "results.parquet"
"""The table as Parquet, written beside ``results.csv`` when pyarrow can be imported."""


class CellStore:
    """The finished cells of a study folder, by key."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.out = Path(out)
        self.cells = self.out / "cells"
        self.traces = self.out / "traces"
        self.maps = self.out / "maps"

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

    def put(
        self,
        record: dict[str, object],
        trace: dict[str, np.ndarray] | None,
        label_map: dict[str, np.ndarray] | None = None,
    ) -> None:
        """Store one finished cell (its trace and its label map first) under its key."""
        key = str(record["key"])
        self.cells.mkdir(parents=True, exist_ok=True)
        for column, folder, arrays in (("trace", self.traces, trace),
                                       ("label_map", self.maps, label_map)):  # fmt: skip
            if arrays is not None:
                folder.mkdir(parents=True, exist_ok=True)
                staging = folder / f".{key}.npz"
                write_npz(staging, arrays)  # savez_compressed's file, faster when large
                os.replace(staging, folder / f"{key}.npz")
                record = {**record, column: f"{folder.name}/{key}.npz"}
        staging = self.cells / f".{key}.json"
        staging.write_text(json.dumps(record, default=_json_value, indent=1))
        os.replace(staging, self.cells / f"{key}.json")


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
    """Write ``rows`` as CSV with the :data:`COLUMNS` header (atomically), and the same table
    as :data:`PARQUET` beside it when pyarrow is installed (:func:`write_parquet`)."""
    path = Path(path)
    staging = path.with_name(f".{path.name}")
    with open(staging, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell_text(v) for k, v in row.items()})
    os.replace(staging, path)
    write_parquet(path.with_name(PARQUET), read_table(path))
    return path


def write_parquet(path: str | os.PathLike[str], rows: list[dict[str, object]]) -> Path | None:
    """Write ``rows`` (as :func:`read_table` gives them) as Parquet, one column per
    :data:`COLUMNS` entry: text columns as strings, the others as int64, float64 or bool where
    every value is one (None: null), else as text. Returns None (writes nothing) without
    pyarrow (``pip install 'spcopyro[parquet]'``)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ModuleNotFoundError:
        return None
    columns = {}
    for name in COLUMNS:
        values = [row.get(name) for row in rows]
        columns[name] = pa.array(values, type=_arrow_type(name, values, pa))
    path = Path(path)
    staging = path.with_name(f".{path.name}")
    pq.write_table(pa.table(columns), staging)
    os.replace(staging, path)
    return path


def _arrow_type(name: str, values: list[object], pa):
    present = [v for v in values if v is not None]
    if name in TEXT_COLUMNS:
        return pa.string()
    for kind, arrow in ((bool, pa.bool_()), (int, pa.int64())):
        if present and all(type(v) is kind for v in present):
            return arrow
    if present and all(isinstance(v, int | float) and not isinstance(v, bool) for v in present):
        return pa.float64()
    return pa.string() if present else pa.null()


def read_parquet(path: str | os.PathLike[str]) -> list[dict[str, object]]:
    """The rows of a ``results.parquet`` as :func:`read_table` gives those of the CSV (needs
    pyarrow)."""
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


def _cell_text(value: object) -> object:
    if isinstance(value, float) and math.isfinite(value):
        return repr(value)  # every digit: a redrawn report equals the first
    return value


TEXT_COLUMNS = frozenset(
    ("variant", "data", "method", "data_kind", "data_source", "preset", "overrides", "version",
     "key", "source_digest", "status", "error_type", "error", "trace", "top_words", "details",
     "scoring", "label_map", "concept_words", "hyperparameters", "warnings")
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
