"""The files of further modalities of a house folder: ``ROOM/modality_<name>.csv``.

A header ``trial,x,y,<item>,...`` (:data:`MODALITY_COLUMNS`, then the modality's items, each
named once), then one observation per line: its trial id, its position in metres and a
non-negative count of every item (read as :class:`~spcopyro.data.observations.ModalityObservations`
by :func:`read_modalities`, written by :func:`modality_lines`). A malformed file raises
:class:`~spcopyro.data.observations.DataFormatError` naming the file, the 1-based line and
column and the offending value, as the other files of the layout
(:mod:`~spcopyro.data.dataset_files`) do.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from spcopyro.data.dataset_files import _format_float, _parse_number, _read_lines
from spcopyro.data.observations import (
    DataFormatError,
    ModalityObservations,
    _modality_name_problem,
)

__all__ = ["MODALITY_COLUMNS", "MODALITY_FILE", "modality_lines", "read_modalities"]

MODALITY_FILE = re.compile(r"modality_(.*)\.csv")  # ROOM/modality_<name>.csv, group 1: name
MODALITY_COLUMNS = ("trial", "x", "y")  # the columns before a modality file's items


def _read_modality(path: Path, name: str) -> ModalityObservations:
    """A further modality's file: header ``trial,x,y,<item>,...``, one observation per line."""
    lines = _read_lines(path)
    if not lines or not lines[0].strip():
        raise DataFormatError(
            path, f"no header line (expected {','.join(MODALITY_COLUMNS)},<item>,...)", line=1
        )
    header = [text.strip() for text in lines[0].split(",")]
    for column, want in enumerate(MODALITY_COLUMNS, start=1):
        got = header[column - 1] if column <= len(header) else ""
        if got != want:
            raise DataFormatError(
                path, f"header column {column} must be {want!r}", line=1, column=column, value=got
            )
    if len(header) <= len(MODALITY_COLUMNS):
        raise DataFormatError(
            path, "the header names no item after trial,x,y", line=1, value=lines[0]
        )
    items = header[len(MODALITY_COLUMNS) :]
    first_column: dict[str, int] = {}
    for column, item in enumerate(items, start=len(MODALITY_COLUMNS) + 1):
        if not item:
            raise DataFormatError(path, "empty item name", line=1, column=column, value=item)
        if item in first_column:
            raise DataFormatError(
                path,
                f"item named twice in the header (also column {first_column[item]})",
                line=1,
                column=column,
                value=item,
            )
        first_column[item] = column
    width = len(header)
    trials: list[int] = []
    rows: list[list[float]] = []  # x, y, counts
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            raise DataFormatError(path, "empty line", line=number, value=line)
        fields = line.split(",")
        if len(fields) != width:
            raise DataFormatError(
                path,
                f"row has {len(fields)} values, expected {width} (as the header)",
                line=number,
                value=line,
            )
        trial = fields[0].strip()
        if re.fullmatch(r"[0-9]+", trial) is None or int(trial) >= 2**63:
            raise DataFormatError(
                path, "trial id is not a non-negative integer", line=number, column=1, value=trial
            )
        trials.append(int(trial))
        row = [_parse_number(path, text, number, c) for c, text in enumerate(fields[1:], 2)]
        for c, value in enumerate(row[2:], start=len(MODALITY_COLUMNS) + 1):
            if value < 0:
                raise DataFormatError(
                    path,
                    f"negative count of item {items[c - 4]!r}",
                    line=number,
                    column=c,
                    value=fields[c - 1].strip(),
                )
        rows.append(row)
    table = np.array(rows, dtype=np.float64).reshape(len(rows), width - 1)  # [T, 2 + K]
    try:
        return ModalityObservations(
            name=name,
            items=tuple(items),
            positions=table[:, :2],
            trials=np.array(trials, dtype=np.int64),
            counts=table[:, 2:],
        )
    except ValueError as error:  # an item name that is not a valid column name
        raise DataFormatError(path, str(error), line=1) from None


def read_modalities(room: Path) -> tuple[ModalityObservations, ...]:
    """Every ``ROOM/modality_<name>.csv``, sorted by name."""
    files: dict[str, Path] = {}
    for entry in room.iterdir():
        match = MODALITY_FILE.fullmatch(entry.name)
        if match and entry.is_file():
            problem = _modality_name_problem(match.group(1))
            if problem is not None:
                raise DataFormatError(entry, problem, value=match.group(1))
            files[match.group(1)] = entry
    return tuple(_read_modality(files[name], name) for name in sorted(files))


def modality_lines(modality: ModalityObservations) -> Iterator[str]:
    """The lines of ``modality_<name>.csv``: the header, then one observation per line."""
    yield ",".join((*MODALITY_COLUMNS, *modality.items))
    for trial, xy, counts in zip(
        modality.trials.tolist(),
        modality.positions.tolist(),
        modality.counts.tolist(),
        strict=True,
    ):
        yield ",".join((str(trial), *map(_format_float, xy), *map(_format_float, counts)))
