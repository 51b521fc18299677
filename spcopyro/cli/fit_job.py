"""One ``spcopyro fit`` command in progress (:class:`FitJob`): what :mod:`spcopyro.cli.fit` sets
up and fits, and :mod:`spcopyro.cli.fit_finished` and :mod:`spcopyro.cli.fit_write` keep and
write. A module of its own so that all three import it (they annotated it as ``Any``: fit.py
imports the other two). Imports nothing at run time but the standard library.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import argparse

    from spcopyro._util.outputs import StagedOutput
    from spcopyro.config import SpCoSettings
    from spcopyro.data import House
    from spcopyro.fit.gibbs_chains import FitCheckpoint
    from spcopyro.results.result import SpCoResult

__all__ = ["FitJob"]


@dataclasses.dataclass
class FitJob:
    """One ``fit`` command in progress: its arguments, what they resolved to, where it writes."""

    args: argparse.Namespace
    house: House
    """The house on the model's grid (``--cell-size``)."""
    settings: SpCoSettings
    options: object | None
    """The method's options (None: its defaults)."""
    staged: StagedOutput
    keeper: FitCheckpoint | None
    """Keeps the Gibbs chains for a checkpoint beside OUT (None where none is kept)."""
    map_house: House | None = None
    """The house on its map's own cells, as loaded: ``--refine`` refits there, and sets
    ``refined`` and ``house = map_house`` when it does."""
    refined: bool = False
    sampled: bool = False
    """Set once the fit is done: a Ctrl-C while writing then keeps the finished chains."""
    finished: tuple[list[SpCoResult], int, list[str]] | None = None
    """Every fit's result, the one kept and the warnings said before the writing
    (:mod:`spcopyro.cli.fit_finished`)."""
    said: list[str] = dataclasses.field(default_factory=list)
    """The warnings the command gave so far, as printed (:mod:`spcopyro.cli.fit_warnings`):
    ``config.json``'s ``"warnings"``."""
