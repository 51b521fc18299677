"""The record an online update keeps of the fit it continued (``config.json``'s
``inference.update_of``, :func:`update_record`), where that fit is (:func:`fit_folder`), and
the fits before it (:func:`history`: a flat list, where records before 2026-12-05 nested each
update's whole record in the next).

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

__all__ = [
    "RELATIVE_TO",
    "RESULT_FOLDER",
    "UPDATE_INIT",
    "fit_folder",
    "history",
    "relative_record",
    "update_record",
]

UPDATE_INIT = "update of the fit in update_of"
"""An update's ``inference.init``: the saved fit's folder is named once, by ``update_of.fit``
(relative to the result's folder, :func:`relative_record`), not again as the path given, which
was relative to the working directory the update ran in."""
RELATIVE_TO = "fit_relative_to"
"""The key marking a record whose ``fit`` is relative to a folder (:data:`RESULT_FOLDER`)."""
RESULT_FOLDER = "result folder"
"""``fit`` is relative to the folder of the result whose ``config.json`` holds the record."""


def fit_folder(record: dict[str, object], result_dir: str | os.PathLike[str] | None) -> str:
    """The folder of the fit ``record`` (an ``update_of``) continued, for the result saved in
    ``result_dir``: ``fit`` joined onto ``result_dir`` where the record says it is relative to
    it, else ``fit`` as stored (absolute, or an older record's path relative to the working
    directory its update ran in)."""
    fit = str(record["fit"])
    if record.get(RELATIVE_TO) == RESULT_FOLDER and result_dir is not None:
        return os.path.normpath(os.path.join(os.fspath(result_dir), fit))
    return fit


def relative_record(
    record: dict[str, object], out_dir: str | os.PathLike[str]
) -> dict[str, object]:
    """``record`` with its ``fit`` relative to ``out_dir``, the folder its result is written to,
    and marked so (:data:`RELATIVE_TO`); unchanged where ``fit`` names no folder of this machine
    as an absolute path (a library caller's ``where`` such as ``"the saved fit"``)."""
    fit = str(record.get("fit"))
    earlier = record.get("earlier")
    if isinstance(earlier, list):  # each earlier fit's folder likewise
        record = {**record, "earlier": [relative_record(e, out_dir) for e in earlier]}
    if not os.path.isabs(fit):
        return record
    try:
        relative = os.path.relpath(fit, os.path.abspath(os.fspath(out_dir)))
    except ValueError:  # another drive (Windows): no relative path; keep it absolute
        return record
    return {**record, "fit": relative, RELATIVE_TO: RESULT_FOLDER}


def _absolute(folder: str) -> str:
    """``folder`` absolute where it is a folder here, else as it is (a fit no longer there)."""
    return os.path.abspath(folder) if os.path.isdir(folder) else folder


def _entry(record: dict[str, object], folder: str) -> dict[str, object]:
    """An earlier update's small record: the fit it continued (``folder``), that fit's method,
    iterations and data fingerprint, how many words and observations the update added."""
    new = record.get("new_words")
    entry = {
        "fit": _absolute(folder),
        "method": record.get("method"),
        "iterations": record.get("iterations"),
        "data_sha256": record.get("data_sha256"),
        "new_words": len(new) if isinstance(new, list) else new,  # a count in an entry
        "observations": record.get("observations"),
        "observations_before": record.get("observations_before"),
    }
    return {key: value for key, value in entry.items() if value is not None}


def history(record: object, result_dir: str | os.PathLike[str] | None) -> list[dict[str, object]]:
    """The earlier fits of the result saved in ``result_dir`` whose ``update_of`` is
    ``record``, newest first, each a small record (:func:`_entry`, ``fit`` absolute where it is
    a folder here): the fit the update continued, then the record's ``earlier`` list, or, in a
    record written before 2026-12-05, its nested ``update_of`` records (each ``fit`` there
    relative to the folder of the fit that held it). Empty for None (no update)."""
    entries: list[dict[str, object]] = []
    while isinstance(record, dict):
        folder = fit_folder(record, result_dir)
        entries.append(_entry(record, folder))
        earlier = record.get("earlier")
        if isinstance(earlier, list):  # flat: every entry's folder relative to result_dir
            entries += [
                _entry(e, fit_folder(e, result_dir)) for e in earlier if isinstance(e, dict)
            ]
            break
        record, result_dir = record.get("update_of"), folder  # nested: its own fit's folder
    return entries


def _placed(source: object) -> int | None:
    """The observations a fit's ``source`` record says its counts hold (None: not recorded, a
    fit saved before spcopyro recorded them)."""
    said = source.get("observations") if isinstance(source, dict) else None
    placed = said.get("placed") if isinstance(said, dict) else None
    return int(placed) if isinstance(placed, int) and not isinstance(placed, bool) else None


def update_record(
    saved: SpCoResult,
    words: tuple[Sequence[str], Sequence[str]],
    where: str,
    counts: CellCounts | None = None,
) -> dict[str, object]:
    """What ``config.json`` records of the fit an update continued (``inference.update_of``):
    ``fit``, the saved fit's folder ``where``, absolute where it is one (:func:`relative_record`
    makes it relative to the folder the result is written to);
    where that fit was itself an update, ``earlier``: the fits before it, newest first, back to
    the first fit, each a small record (:func:`history`; its folder, method, iterations, data
    fingerprint, how many words and observations its update added), a flat list that grows by
    one small entry an update. ``observations``: the observations the update's counts
    hold (``counts``, placed on free cells); ``observations_before``: the saved fit's (None
    where it did not record them). ``words``: the words the update added and the saved words
    its data lacks (:class:`~spcopyro.robot.online.VocabularyMerge`'s ``new_words``,
    ``unheard_words``)."""
    source = saved.provenance.get("source", {})
    # the saved fit's folder, absolute (where it is one here): the folder its own record's
    # relative paths are joined onto, so that an earlier fit no longer there is kept absolute
    # (relative_record can make it relative to OUT), not relative to this working directory
    folder = os.path.abspath(where) if os.path.isdir(where) else None
    record: dict[str, object] = {
        "fit": where if folder is None else folder,
        "method": saved.method,
        "iterations": len(saved.trace.objective),
        "data": source.get("data") if isinstance(source, dict) else None,
        "data_sha256": source.get("data_sha256") if isinstance(source, dict) else None,
        "new_words": list(words[0]),
        "unheard_words": list(words[1]),
        "observations": None if counts is None else counts.placement.num_placed,
        "observations_before": _placed(source),
    }
    earlier = history(saved.inference.get("update_of"), folder)
    if earlier:  # the saved fit was an update: the fits before it, flat (each entry small)
        record["earlier"] = earlier
    return record
