"""The line ``spcopyro`` prints when Ctrl-C (or SIGTERM) stops a command: which command stopped
and what became of what it writes. ``fit`` says more itself (:mod:`spcopyro.cli.fit_resume`,
from the moment its parser's handler runs); it is listed in :data:`WHOLE` for a Ctrl-C in the
instant before that handler is in place, when this line is the one printed. Imports nothing of
the package (``main`` is on the ``--help`` path, which must not import torch) but
:mod:`spcopyro.cli.out_names` and, once stopped, :mod:`spcopyro._util.outputs` (which import
nothing of it either)."""

from __future__ import annotations

import argparse
import os
from pathlib import PurePath

from spcopyro.cli.out_names import graph_json, probability_figure

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
(:func:`spcopyro._util.outputs.commit_folder`)."""
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
        aside = _set_aside(out) if overwrite else []
        if aside and not os.path.isdir(out):  # stopped between the two renames
            line = f"{line}: nothing new written; the old {out} is in {', '.join(aside)}"
        elif aside:  # stopped while the old OUT's files were carried into the new one
            line = (f"{line}: {out} is the new one, written whole; what of the old one was not "
                    f"yet carried into it is in {', '.join(aside)}")  # fmt: skip
        else:
            line = (
                f"{line}: nothing written to {out} (it is written whole at the end, or not at all)"
            )
        if command == "import-bag" and overwrite:
            path = PurePath(out)  # the house's map, as the import names it (rosbag.importer)
            new = "the new" if aside and os.path.isdir(out) else "still the old"
            line += (f"; {path.parent / 'map' / path.name}.yaml and .pgm are {new} map's (moved "
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
    """What became of ``simulate``'s house ``OUT/NAME`` (NAME: ``--name``, else the ``--map``
    file's name or ``synthetic``, as ``simulate`` names it) and its map."""
    map_file = getattr(args, "map", None)
    name = getattr(args, "name", None) or (PurePath(map_file).stem if map_file else "synthetic")
    room = PurePath(out) / name
    house = f"{room} and its map {PurePath(out) / 'map' / name}.yaml"
    aside = _set_aside(str(room))
    if aside and os.path.isdir(room):  # stopped while the old house's own files were carried
        return (f"{house} are the new ones, written whole; what of the old {room} was not yet "
                f"carried into it is in {', '.join(aside)}")  # fmt: skip
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


def _set_aside(out: str) -> list[str]:
    """The folders an ``--overwrite`` of ``out`` in this process set the old one aside in and
    kept, the block carrying its files over having been stopped (``OUT.replaced-XXXXXXXX``,
    hidden for ``import-bag``: :func:`spcopyro._util.outputs.swapped_in` records them), as the
    user named OUT, sorted. A leftover of an earlier run beside OUT is none of them: it said
    OUT was the new one when this run had not swapped it yet."""
    from spcopyro._util.outputs import set_aside  # on Ctrl-C only: nothing on the --help path

    shown = PurePath(out).parent
    return sorted(str(shown / folder.name) for folder in set_aside(out))
