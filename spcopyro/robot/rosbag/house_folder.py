"""The house folder ``import-bag`` writes, and what its ``--overwrite`` may replace.

An existing non-empty OUT is replaced only when it holds an earlier import: a readable
:data:`MARKER` (``bag_import.json``) that names the trials it wrote. Of that folder only the
entries the earlier import wrote (:func:`written_by`: the fixed files and, for *its* trials,
``img_K/``, ``pose_K.csv``, ``word_K.csv``) are replaced; everything else (``Ft.csv`` of
``spcopyro features``, notes, a trial folder added by hand) is carried into the new OUT and named.
An entry the earlier import did not write but the new one would (a hand-made ``img_2`` and a
third bag) is refused before anything is read, so nothing of the user's is replaced unsaid.

The map at ``OUT/../map/NAME.yaml`` belongs to the house named NAME: a different map there is
replaced (with ``overwrite``) only when OUT holds an earlier import, whose map it is; a map beside
no import (another tool's, a house folder removed by hand) is refused even with ``overwrite``.
"""

from __future__ import annotations

import filecmp
import json
import os
import re
from collections.abc import Iterable
from pathlib import Path

from spcopyro._util.outputs import check_folder_path, check_not_holding_cwd
from spcopyro.maps.grid import OccupancyGrid
from spcopyro.maps.map_server import MapFormatError, load_map

__all__ = [
    "IMPORT_FILES",
    "MARKER",
    "check_map",
    "check_out",
    "same_images",
    "written_by",
]

MARKER = "bag_import.json"
"""Marks a folder written by ``import_bags`` (``overwrite`` replaces only those)."""

IMPORT_FILES = frozenset(
    ["Xtx.csv", "Xty.csv", "St.csv", "StXtx.csv", "StXty.csv", "skipped.csv", MARKER]
)
"""The files every import writes (with ``img_K/``, ``pose_K.csv`` and ``word_K.csv``)."""


def written_by(trials: Iterable[int]) -> frozenset[str]:
    """The entries an import of these trial ids writes into its folder."""
    names = set(IMPORT_FILES)
    for k in trials:
        names.update((f"img_{k}", f"pose_{k}.csv", f"word_{k}.csv"))
    return frozenset(names)


def _earlier_trials(out: Path) -> list[int]:
    """The trial ids the import in ``out`` wrote, from its :data:`MARKER`; a FileExistsError
    when there is none or it is not an import's record."""
    marker = out / MARKER
    if not marker.is_file():
        raise FileExistsError(
            f"{out} was not written by import-bag (no {MARKER}); not replacing it: choose "
            "another --out"
        )
    try:
        record = json.loads(marker.read_text(encoding="utf-8"))
        trials = [t["trial"] for t in record["trials"]]
        if not trials or not all(type(k) is int and k >= 0 for k in trials):
            raise ValueError("its trials are not integers >= 0")
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as error:
        raise FileExistsError(
            f"{marker} is not a record import-bag wrote ({type(error).__name__}: {error}); "
            f"not replacing {out}: choose another --out"
        ) from None
    return trials


def check_out(out: Path, overwrite: bool, trials: Iterable[int]) -> frozenset[str] | None:
    """Check the house folder ``out`` before an import of ``trials`` into it: the entries of the
    earlier import there that ``overwrite`` replaces, or None when ``out`` is missing or empty.

    Raises:
        ValueError: ``out``'s name cannot name a house.
        FileExistsError: ``out`` (or a parent) is a file, or ``out`` a symbolic link; a
            non-empty ``out`` without ``overwrite``, or not an earlier import's, or holding the
            current directory; an entry the earlier import did not write that this one would.
    """
    name = out.name
    if not name or name in (".", "..", "map") or re.search(r"[/\\,]", name):
        raise ValueError(f"{out}: its folder name {name!r} cannot name a house")
    if out.is_symlink():  # renaming it would move the link, not the folder
        raise FileExistsError(
            f"{out} is a symbolic link (to {os.readlink(out)}); give a folder as --out"
        )
    check_folder_path(out, f"--out {out}")  # a parent that is a file said "[Errno 17] ..."
    check_not_holding_cwd(out, f"--out {out}")  # as fit and export refuse it
    if not out.is_dir() or not any(out.iterdir()):
        return None
    if not overwrite:
        raise FileExistsError(f"{out} already exists and is not empty; pass --overwrite")
    earlier = written_by(_earlier_trials(out))
    clash = sorted(
        entry.name
        for entry in out.iterdir()
        if entry.name in written_by(trials) and entry.name not in earlier
    )
    if clash:
        raise FileExistsError(
            f"{out} holds {', '.join(clash)}, which the import there did not write (its "
            f"{MARKER} names other trials) and this one would: move them away first, or "
            "choose other trial ids with --first-trial"
        )
    return earlier


def check_map(
    target: Path, grid: OccupancyGrid, source: str | os.PathLike[str], overwrite: bool, out: Path,
    earlier: frozenset[str] | None,
) -> bool:  # fmt: skip
    """Whether the import replaces a different map at ``target`` (the map of house ``out``);
    a FileExistsError when it may not (no ``overwrite``, or no earlier import in ``out`` whose
    map it would be)."""
    if not target.exists():
        return False
    try:
        if load_map(target) == grid:
            return False
        differs = f"differs from {source}"
    except MapFormatError as error:  # an unreadable map there blocked every later import
        differs = f"cannot be read as a map ({' '.join(str(error).split())})"  # one line
    if not overwrite:
        raise FileExistsError(f"{target} exists and {differs}; pass --overwrite to replace it")
    if earlier is None:
        raise FileExistsError(
            f"{target} exists and {differs}, and {out} holds no earlier import (no {MARKER}) "
            "whose map it would be: not replacing it, even with --overwrite; move it away, or "
            "choose another --out name"
        )
    return True


def _image_files(folder: Path) -> dict[str, Path]:
    """The images of a house folder by their path in it (``img_0/00000.jpg``, ...)."""
    return {
        f"{trial.name}/{image.name}": image
        for trial in folder.glob("img_*")
        if trial.is_dir()
        for image in trial.iterdir()
    }


def same_images(old: Path, new: Path) -> bool:
    """Whether the house folders ``old`` and ``new`` hold the same image files, byte for byte
    (then what ``spcopyro features`` made of the old ones, ``Ft.csv``, describes the new)."""
    before, after = _image_files(old), _image_files(new)
    return before.keys() == after.keys() and all(
        filecmp.cmp(before[name], after[name], shallow=False) for name in before
    )
