"""The names of the files ``where`` and ``show --graph`` write beside their figure, and of the
house ``simulate`` writes: defined once for the commands that write them
(:mod:`spcopyro.cli.main`, :mod:`spcopyro.cli.navigate`) and the Ctrl-C line that names them
(:mod:`spcopyro.cli.interrupted`, on the ``--help`` path). Imports nothing but :mod:`pathlib`."""

from __future__ import annotations

from pathlib import PurePath
from typing import TypeVar

__all__ = ["graph_json", "house_name", "probability_figure"]

P = TypeVar("P", bound=PurePath)


def probability_figure(out: P) -> P:
    """``where --out NAME.EXT``'s second figure, the per-cell probability of the word's place:
    ``NAME_probability.EXT`` (the same format; ``.png`` without a suffix)."""
    return out.with_name(f"{out.stem}_probability{out.suffix or '.png'}")


def graph_json(figure: P) -> P:
    """The JSON of ``show --graph``'s place graph, beside its ``figure`` and named after it
    (``X.png`` -> ``X.json``: two graphs in one folder keep both)."""
    return figure.with_suffix(".json")


def house_name(name: str | None, map_file: str | None) -> str:
    """The folder ``simulate`` writes its house in, ``OUT/NAME``: ``--name``, else the ``--map``
    file's name without its suffix (what :func:`spcopyro.robot.map_simulation.write_simulated_map`
    defaults to), else ``synthetic``."""
    return name or (PurePath(map_file).stem if map_file else "synthetic")
