"""The line ``spcopyro`` prints when Ctrl-C (or SIGTERM) stops a command other than ``fit``
(which says more itself, :mod:`spcopyro.cli.fit_resume`): which command stopped and whether
anything it writes may be left half-written. Imports nothing of the package (``main`` is on the
``--help`` path, which must not import torch)."""

from __future__ import annotations

import argparse

__all__ = ["interrupted_line"]

WHOLE = frozenset({"export", "features", "features-head", "fit", "import-bag", "navigate"})
"""Commands whose ``--out`` appears whole or not at all: a folder written in a staging folder
and moved into place (:mod:`spcopyro._util.outputs`), or one file replaced whole."""
REMOVED = frozenset({"simulate-bag"})
"""Commands that remove what they had written when stopped."""
STUDIES = frozenset({"ablation", "compare-inference", "experiment", "study"})
"""Commands that run a study into ``--out``: every finished cell is kept there."""
IN_PLACE = frozenset({"show", "simulate", "where"})
"""Commands that write their ``--out`` in place: a file being written may be left half-written."""
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
        return f"{line}: nothing written" if command in WHOLE | IN_PLACE else line
    if command in WHOLE:
        return f"{line}: nothing written to {out} (it is written whole at the end, or not at all)"
    if command in REMOVED:
        return f"{line}: what it had written to {out} is removed"
    if command in STUDIES:
        return (f"{line}: {out} keeps the cells finished so far; run the same command again to "
                "continue")  # fmt: skip
    if command in IN_PLACE:
        again = " (with --overwrite)" if command == "simulate" else ""
        return (f"{line}: {out} may hold half-written files; run the same command again"
                f"{again} to write them whole")  # fmt: skip
    return line
