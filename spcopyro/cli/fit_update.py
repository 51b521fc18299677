"""``spcopyro fit --update``'s own lines: its settings after a refined fit
(:func:`update_settings`), the lines it prints (:func:`report_update`), its record of the
saved fit relative to OUT (:func:`relative_records`), its refusal before anything is printed
(:func:`check_update`) and the hint that refusal of a fit saved before the reach share became
the default gets (:func:`reach_share_hint`)."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from spcopyro._util.messages import listed
from spcopyro.cli.fit_refine import prepares_data

if TYPE_CHECKING:
    import argparse

    from spcopyro.config import SpCoSettings
    from spcopyro.data import House
    from spcopyro.results.result import SpCoResult

__all__ = [
    "check_update", "reach_share_hint", "relative_records", "report_update", "update_settings"
]  # fmt: skip


def relative_records(results: Sequence[SpCoResult], out: Path) -> None:
    """Each update result's ``inference.update_of`` with the saved fit's folder relative to
    ``out``, the folder the result is written to
    (:func:`spcopyro.robot.update_history.relative_record`)."""
    from spcopyro.robot.update_history import relative_record

    for result in results:
        result.inference["update_of"] = relative_record(result.inference["update_of"], out)


def update_settings(
    args: argparse.Namespace, settings: SpCoSettings, map_cells: int
) -> SpCoSettings:
    """``--update OUT``'s settings: where OUT is a refined fit (its ``config.json`` records
    ``inference.refine.refine``), ``settings`` refined as that fit was
    (:func:`spcopyro.fit.refine.refined_settings`, alpha scaled from the coarse stage's free
    cells to the ``map_cells`` of this run's map), so that the update goes on on the map's cells
    with the refinement's preparation; else, or when this command line gives a data preparation
    of its own (:data:`~spcopyro.cli.fit_refine.REFINED_AWAY`), ``settings`` (the update checks
    them against OUT's). A word weighting ``auto`` becomes OUT's
    (:func:`~spcopyro.data.word_weighting.keeping_word_weighting`): an update keeps the
    weighting of the fit it updates, whatever its new utterances are; ValueError where OUT
    records none resolved."""
    from spcopyro.data.word_weighting import keeping_word_weighting
    from spcopyro.fit.refine import refined_settings

    config = Path(args.update) / "config.json"
    try:
        saved = json.loads(config.read_text())
        record = saved.get("inference", {}).get("refine") or {}
        kept = saved.get("data", {}).get("word_weighting")
    except (OSError, ValueError, AttributeError):  # the saved fit's own loading says what
        return settings
    settings = keeping_word_weighting(kept, settings, f"the fit in {args.update}")
    if not record.get("refine") or prepares_data(args):
        return settings
    return refined_settings(settings, int(record["coarse"]["free_cells"]), map_cells)


def reach_share_hint(args: argparse.Namespace, saved: SpCoResult, settings: SpCoSettings) -> str:
    """What to add to the refusal (:func:`spcopyro.robot.online.check_compatible`) of an update
    of ``saved``, a fit without the reach share (``footprint_reach_share`` 0, as preset
    ``coarse`` fitted before 2026-12-06), under ``settings`` whose share comes from the preset,
    ``--footprint-reach-share`` not given: that the flag at 0 updates it as it was fitted.
    Empty otherwise (the user chose the share, the saved fit has one, or this run has none)."""
    if args.footprint_reach_share is not None or saved.preparation.footprint_reach_share:
        return ""
    if not settings.data.footprint_reach_share:
        return ""
    return (
        f"; the fit in {args.update} has no reach share (footprint_reach_share 0, preset "
        f"coarse's default before 2026-12-06) and this run's is --preset {args.preset}'s: pass "
        "--footprint-reach-share 0 to update it as it was fitted"
    )


def check_update(
    args: argparse.Namespace, saved: SpCoResult, house: House, settings: SpCoSettings
) -> None:
    """:func:`spcopyro.robot.online.check_compatible`'s refusal of ``--update``: ``house`` and
    ``settings``, this run's, against ``saved``, the fit in ``args.update``, with
    :func:`reach_share_hint`'s flag where it mends the refusal. Run before fit prints the
    house's summary, so that a refused update prints none of it (the same check, on the same
    inputs, as the one :func:`~spcopyro.robot.online.fit_update` runs, which then passes)."""
    from spcopyro.robot.online import UpdateMismatchError, check_compatible

    try:
        check_compatible(saved, house, settings, str(args.update))
    except UpdateMismatchError as error:  # the flag mending it, where one does
        hint = reach_share_hint(args, saved, settings)
        if hint:
            raise UpdateMismatchError(f"{error}{hint}", error.problems) from error
        raise


def report_update(record: dict[str, object], where: str, data_sha256: object = None) -> None:
    """Print what ``--update`` changed (``record``: ``inference.update_of``): how many
    observations it added and how many the fit now holds (both placed on the map's free cells;
    where the saved fit in ``where`` did not record its own, saved by an older spcopyro, that
    the number added is not known), and in the vocabulary; note when this run's model data
    (``data_sha256``, this fit's ``source``) is the saved fit's, nothing added, and warn
    (stderr) when saved words are missing from DATA: an update fits DATA alone, so a folder
    holding only the new trial drops the old trials' observations (their words, without
    counts, are the visible sign; robot.md)."""
    now, before = record.get("observations"), record.get("observations_before")
    if isinstance(now, int) and isinstance(before, int):
        print(f"observations     {now - before:+d} added: {now} in the fit now, {before} "
              "before (those placed on the map's free cells)")  # fmt: skip
    elif isinstance(now, int):
        print(f"observations     {now} in the fit now (placed on the map's free cells); "
              f"the fit in {where} does not record how many it held (saved by an older "
              "spcopyro), so how many were added is not known")  # fmt: skip
    new, unheard = list(record["new_words"]), list(record["unheard_words"])
    print(f"new words        {len(new)}: {', '.join(new[:20]) or '-'}")
    if data_sha256 is not None and data_sha256 == record.get("data_sha256"):
        print(f"note: this data is the data the fit in {where} was fitted on (the same sha256 "
              "of the model data): no observation was added, the update only ran more "
              "iterations on it; add the new trial's files to DATA first")  # fmt: skip
    if unheard:
        print(f"warning: {len(unheard)} word(s) of the fit in {where} are not in this run's "
              f"data: {listed(unheard, 20)}; an update is fitted on DATA alone, so "
              "DATA must hold the old trials' observations as well as the new ones (their "
              "words keep their columns, without counts)", file=sys.stderr)  # fmt: skip
