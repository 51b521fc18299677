"""The line ``spcopyro`` prints when Ctrl-C (or SIGTERM) stops a command: which command stopped
and what became of what it writes. ``fit`` says more itself (:mod:`spcopyro.cli.fit_resume`,
from the moment its parser's handler runs); it is listed in :data:`WHOLE` for a Ctrl-C in the
instant before that handler is in place, when this line is the one printed. Imports nothing of
the package (``main`` is on the ``--help`` path, which must not import torch) but
:mod:`spcopyro.cli.out_names` and, once stopped, :mod:`spcopyro._util.folder_commit` (which
import nothing of it either)."""

from __future__ import annotations

import argparse
import sys
from pathlib import PurePath
from types import ModuleType

from spcopyro.cli.out_names import graph_json, house_name, probability_figure

__all__ = ["interrupted_line"]

WHOLE = frozenset({"export", "features", "features-head", "fit", "import-bag", "navigate"})
"""Commands whose ``--out`` appears whole or not at all: a folder written in a staging folder
and moved into place (:mod:`spcopyro._util.outputs`), or one file replaced whole."""
EACH_WHOLE = frozenset({"show", "where"})
"""Commands that write one or two files (a figure; ``where``'s ``_probability`` figure beside
it, ``show --graph``'s JSON), each replaced whole (:func:`spcopyro._util.outputs.replace_file`):
the file there before stays until its new one is complete."""
REMOVED = frozenset({"simulate-bag"})
"""Commands that remove what they had written when stopped."""
STUDIES = frozenset({"ablation", "compare-inference", "experiment", "study"})
"""Commands that run a study into ``--out``: every finished cell is kept there (and each report
the command writes is replaced whole: ``spcopyro.study.commands`` names those left an earlier
run's)."""
HOUSES = frozenset({"simulate"})
"""Commands that write a house under ``--out`` (``OUT/NAME/`` and its map ``OUT/map/NAME.yaml``
and ``.pgm``) whole, folder and map together, or not at all
(:func:`spcopyro._util.folder_commit.commit_folder`)."""
OUT_OPTION = {"export": "nav2"}
"""The attribute of a command's output where it is not ``out`` (``export --nav2 DIR``)."""


def interrupted_line(args: argparse.Namespace) -> str:
    """``"interrupted spcopyro CMD: ..."``: what stopped and what became of its ``--out``
    (``--nav2`` of ``export``)."""
    command = getattr(args, "command", None)
    if command is None:  # no command parsed (a caller's own parser)
        return "interrupted"
    out = getattr(args, OUT_OPTION.get(command, "out"), None)
    line = f"interrupted spcopyro {command}"
    if out is None:  # where, navigate without --out: they write nothing
        return f"{line}: nothing written" if command in WHOLE | EACH_WHOLE else line
    if command in WHOLE:
        overwrite = getattr(args, "overwrite", False)
        new = _completed(out)
        if new:  # a Ctrl-C held through the commit, or one after it
            line = f"{line}: {out} was written whole{_old_kept(out)}"
        else:
            line = (
                f"{line}: nothing written to {out} (it is written whole at the end, or not at all)"
            )
        if command == "import-bag" and overwrite:
            path = PurePath(out)  # the house's map, as the import names it (rosbag.importer)
            which = "the new" if new else "still the old"
            line += (f"; {path.parent / 'map' / path.name}.yaml and .pgm are {which} map's (moved "
                     "in with OUT)")  # fmt: skip
        return line
    if command in EACH_WHOLE:
        files = _figures(args, out)
        each = f"{files[0]} is" if len(files) == 1 else f"{' and '.join(files)} are each"
        return (f"{line}: {each} written whole or not at all (a file there before stays until "
                "it is replaced)")  # fmt: skip
    if command in REMOVED:
        return f"{line}: what it had written to {out} is removed"
    if command in STUDIES:
        return (f"{line}: {out} keeps the cells finished so far; run the same command again to "
                "continue")  # fmt: skip
    if command in HOUSES:
        return f"{line}: {_house_line(args, out)}"
    return line


def _house_line(args: argparse.Namespace, out: str) -> str:
    """What became of ``simulate``'s house ``OUT/NAME`` (:func:`house_name`) and its map."""
    name = house_name(getattr(args, "name", None), getattr(args, "map", None))
    room = PurePath(out) / name
    house = f"{room} and its map {PurePath(out) / 'map' / name}.yaml"
    if _completed(str(room)):  # a Ctrl-C held through the commit, or one after it
        return f"{house} were written whole{_old_kept(str(room))}"
    return f"nothing written to {house} (they are written whole at the end, or not at all)"


def _figures(args: argparse.Namespace, out: str) -> list[str]:
    """The files ``show`` or ``where`` writes for ``--out OUT``, as the user named OUT: the
    figure (``.png`` added where OUT has no suffix, as ``cli.common.figure_file`` adds it), and
    ``where``'s ``NAME_probability.EXT`` or ``show --graph``'s ``NAME.json``
    (:mod:`spcopyro.cli.out_names`)."""
    figure = PurePath(out if PurePath(out).suffix else f"{out}.png")
    if args.command == "where":
        return [str(figure), str(probability_figure(figure))]
    if getattr(args, "graph", False):
        return [str(figure), str(graph_json(figure))]
    return [str(figure)]


def _commits() -> ModuleType | None:
    """:mod:`spcopyro._util.folder_commit` where something imported it (as
    :mod:`spcopyro._util.outputs` does), else None (then no folder was moved in); the Ctrl-C line
    imports nothing to say so."""
    return sys.modules.get("spcopyro._util.folder_commit")


def _completed(out: str) -> bool:
    """Whether this process's latest write into ``out`` is in place, whole
    (:func:`spcopyro._util.folder_commit.completed`); not when nothing imported that module."""
    commits = _commits()
    return commits is not None and commits.completed(out)


def _old_kept(out: str) -> str:
    """``"; the old one, not yet removed, is in OUT.replaced-XXXXXXXX"``, where a Ctrl-C came
    as the replaced folder was being removed (after the commit, which carried the files its
    writer did not write into the new one: what is left is the earlier run's own), as the user
    named OUT; else ``""``. A leftover of an earlier process is not named
    (:func:`spcopyro._util.folder_commit.set_aside`)."""
    commits = _commits()
    folders = [] if commits is None else commits.set_aside(out)
    shown = PurePath(out).parent
    aside = sorted(str(shown / folder.name) for folder in folders)
    return f"; the old one, not yet removed, is in {', '.join(aside)}" if aside else ""
