"""The fit's refusal of a placement most of whose observations are left out on occupied cells.

:meth:`~spcopyro.data.placement.PlacementReport.free_space_inverted` says when: more than half of
the observations left out, more than half of those on occupied cells of the map.
:func:`check_placement` says why, once (the placement warnings before it gave the counts of
snapped and left-out observations): the yaml's ``negate`` line where the other ``negate`` would
free the cells the left-out observations lie on and keep those placed near free space
(:func:`~spcopyro.maps.free_space.negate_hint`); otherwise the causes on a map that is
right -- positions outside its frame, a floor plan drawn black where the tour went, thick walls
beside positions a little off -- and what to do about each.

:func:`placement_warnings_held` holds the counting's warnings back until :func:`check_placement`
has passed: a refusal that blames the map (no observation on free space; the ``negate`` line)
comes alone, not after the warnings listing the observations left out and repeating its counts
(a ``negate: 1`` map printed two long warnings, then the refusal); the refusal on a map that may
be right points to the lines those warnings name, so they are said before it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from spcopyro.data.observations import Observations
from spcopyro.data.placement import PlacementReport, left_out_and_placed
from spcopyro.maps.grid import OccupancyGrid

__all__ = ["check_placement", "inverted_free_space_message", "placement_warnings_held"]


class _Held(logging.Filter):
    """A logger's records held back (filtered out) until :meth:`say` hands them to its handlers."""

    def __init__(self, logger: logging.Logger) -> None:
        super().__init__()
        self.logger, self.records = logger, list[logging.LogRecord]()

    def filter(self, record: logging.LogRecord) -> bool:
        self.records.append(record)
        return False

    def say(self) -> None:
        """Hand the records held to the logger's handlers, once, in their order."""
        records, self.records = self.records, []
        for record in records:
            self.logger.handle(record)


@contextmanager
def placement_warnings_held(name: str = "spcopyro") -> Iterator[Callable[[], None]]:
    """Hold what logger ``name`` logs in the block (cell_counts' warnings of observations left
    out or off free space) and give the function that says it: call it once
    :func:`check_placement` has passed, and pass it to :func:`check_placement`, which calls it
    only before the refusal that points to those warnings. A refusal that blames the map drops
    them. An error inside the block says them first."""
    logger = logging.getLogger(name)
    held = _Held(logger)
    logger.addFilter(held)
    try:
        yield held.say
    except BaseException:
        logger.removeFilter(held)
        held.say()
        raise
    logger.removeFilter(held)


def _negate_hint(report: PlacementReport, obs: Observations, grid: OccupancyGrid) -> str:
    """:func:`~spcopyro.maps.free_space.negate_hint` for the observations left out and placed."""
    from spcopyro.maps.free_space import negate_hint  # reads the map image again

    left_out, placed = left_out_and_placed(report, obs)
    reach = report.snap_distance + grid.resolution  # placed: within snap distance of a cell
    return negate_hint(grid, left_out, placed, reach)


def inverted_free_space_message(
    report: PlacementReport,
    obs: Observations,
    grid: OccupancyGrid,
    where: str = "",
    hint: str | None = None,
) -> str:
    """Why most observations are left out on occupied cells of ``grid`` (the fit's error when
    :meth:`~spcopyro.data.placement.PlacementReport.free_space_inverted`); ``where`` names the
    map (``" on map PATH"``); ``hint``: the ``negate`` line's (None: read here)."""
    hint = _negate_hint(report, obs, grid) if hint is None else hint
    counts = (
        f"{report.num_unplaced} of {report.num_observations} observations are left out, "
        f"{report.unplaced_on_occupied} of them on occupied cells{where}"
    )
    if hint:
        return f"{counts}: the map's free space reads as occupied: {hint}"
    return (
        f"{counts}: the map draws occupied where most of the tour went. If the map is right: "
        "the positions are not in its frame (check the yaml's origin and resolution, and that "
        "the positions are metres in the map's frame), or the tour went where the map draws "
        "walls -- a floor plan's outside or unmapped wings drawn black (draw them map_saver's "
        "unknown grey 205: observations on unknown cells are left out with a warning, not "
        "refused), or thick walls beside positions a little off (align the frame, or a larger "
        f"snap distance, --snap-distance, now {report.snap_distance:g} m, places them on the "
        "free space nearby). Otherwise its free_thresh / occupied_thresh leave its free space "
        "occupied. To fit without those observations, remove them from the data (the warning "
        "above names their lines)"
    )


def check_placement(
    report: PlacementReport,
    obs: Observations,
    grid: OccupancyGrid,
    where: str = "",
    say_warnings: Callable[[], None] = lambda: None,
) -> None:
    """Raise ValueError when no observation lands on free space
    (:meth:`~spcopyro.data.placement.PlacementReport.check_on_free`) or when most are left out
    on occupied cells (:func:`inverted_free_space_message`): a fit would learn every concept from
    the prior alone, or from the few observations snapped onto the walls. The one place the
    second is refused (``check_on_free`` says only the first). ``say_warnings``
    (:func:`placement_warnings_held`'s) is called before the refusal on a map that may be right,
    which points to the lines the warnings name; not before the others, which blame the map."""
    report.check_on_free(where)  # none on free space: said without weighing the map's negate
    if report.free_space_inverted():
        hint = _negate_hint(report, obs, grid)
        if not hint:
            say_warnings()
        raise ValueError(inverted_free_space_message(report, obs, grid, where, hint))
