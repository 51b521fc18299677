"""Whether a fit was refined on its map's cells, read from its record (``inference["refine"]``).

:func:`spcopyro.fit.refine.refine_chains` records its decision either way (``with_decision``
records a fit that stayed on its model grid, ``refine: false``), so "the record is there" does
not mean "refined": :func:`coarse_stage` is the one test, for the summary and the figures.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def coarse_stage(inference: Mapping[str, Any]) -> dict[str, Any] | None:
    """The coarse stage's record (``sweeps``, ``cell_size``, ...) of a fit refined on its map's
    cells, from its ``inference`` (``SpCoResult.inference``, config.json's); None for a fit that
    was not refined, whether or not it recorded a decision."""
    record = inference.get("refine")
    if isinstance(record, dict) and record.get("refine") and isinstance(record.get("coarse"), dict):
        return record["coarse"]
    return None
