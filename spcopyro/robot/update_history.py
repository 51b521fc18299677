"""The record an online update keeps of the fit it continued (``config.json``'s
``inference.update_of``, :func:`update_record`), and where that fit is (:func:`fit_folder`).

``update_of.fit`` names the saved fit's folder. ``spcopyro fit --update`` writes it relative to
the folder of the result that holds the record (:func:`relative_record`, marked
``"fit_relative_to": "result folder"``), so that the two folders can move together or be read
from another working directory. Records written before 2026-12-05 hold the path as given on the
command line, relative to the working directory the update ran in, and are read as such.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from spcopyro.data import CellCounts
    from spcopyro.results.result import SpCoResult

__all__ = ["RELATIVE_TO", "RESULT_FOLDER", "fit_folder", "relative_record", "update_record"]

RELATIVE_TO = "fit_relative_to"
"""The key marking a record whose ``fit`` is relative to a folder (:data:`RESULT_FOLDER`)."""
RESULT_FOLDER = "result folder"
"""``fit`` is relative to the folder of the result whose ``config.json`` holds the record."""


def fit_folder(record: dict[str, object], result_dir: str | os.PathLike[str]) -> str:
    """The folder of the fit ``record`` (an ``update_of``) continued, for the result saved in
    ``result_dir``: ``fit`` joined onto ``result_dir`` where the record says it is relative to
    it, else ``fit`` as stored (absolute, or an older record's path relative to the working
    directory its update ran in)."""
    fit = str(record["fit"])
    if record.get(RELATIVE_TO) == RESULT_FOLDER:
        return os.path.normpath(os.path.join(os.fspath(result_dir), fit))
    return fit


def relative_record(
    record: dict[str, object], out_dir: str | os.PathLike[str]
) -> dict[str, object]:
    """``record`` with its ``fit`` relative to ``out_dir``, the folder its result is written to,
    and marked so (:data:`RELATIVE_TO`); unchanged where ``fit`` names no folder of this machine
    as an absolute path (a library caller's ``where`` such as ``"the saved fit"``)."""
    fit = str(record.get("fit"))
    if not os.path.isabs(fit):
        return record
    try:
        relative = os.path.relpath(fit, os.path.abspath(os.fspath(out_dir)))
    except ValueError:  # another drive (Windows): no relative path; keep it absolute
        return record
    return {**record, "fit": relative, RELATIVE_TO: RESULT_FOLDER}


def _placed(source: object) -> int | None:
    """The observations a fit's ``source`` record says its counts hold (None: not recorded, a
    fit saved before spcopyro recorded them)."""
    said = source.get("observations") if isinstance(source, dict) else None
    placed = said.get("placed") if isinstance(said, dict) else None
    return int(placed) if isinstance(placed, int) and not isinstance(placed, bool) else None


def _num_placed(counts: CellCounts) -> int:
    """The observations ``counts`` hold: placed on free cells, snapped ones included."""
    return counts.placement.num_on_free + counts.placement.num_snapped


def update_record(
    saved: SpCoResult,
    words: tuple[Sequence[str], Sequence[str]],
    where: str,
    counts: CellCounts | None = None,
) -> dict[str, object]:
    """What ``config.json`` records of the fit an update continued (``inference.update_of``):
    ``fit``, the saved fit's folder ``where``, absolute where it is one (:func:`relative_record`
    makes it relative to the folder the result is written to);
    where that fit was itself an update, its own record nested as ``update_of``, so the
    history goes back to the first fit. ``observations``: the observations the update's counts
    hold (``counts``, placed on free cells); ``observations_before``: the saved fit's (None
    where it did not record them). ``words``: the words the update added and the saved words
    its data lacks (:class:`~spcopyro.robot.online.VocabularyMerge`'s ``new_words``,
    ``unheard_words``)."""
    source = saved.provenance.get("source", {})
    record: dict[str, object] = {
        "fit": os.path.abspath(where) if os.path.isdir(where) else where,
        "method": saved.method,
        "iterations": len(saved.trace.objective),
        "data": source.get("data") if isinstance(source, dict) else None,
        "data_sha256": source.get("data_sha256") if isinstance(source, dict) else None,
        "new_words": list(words[0]),
        "unheard_words": list(words[1]),
        "observations": None if counts is None else _num_placed(counts),
        "observations_before": _placed(source),
    }
    if isinstance(earlier := saved.inference.get("update_of"), dict):
        record["update_of"] = earlier  # the saved fit's own update: the earlier history
    return record
