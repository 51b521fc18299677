"""The fit's refusal of a placement most of whose observations are left out on occupied cells.

:meth:`~spcopyro.data.placement.PlacementReport.free_space_inverted` says when: more than half of
the observations left out, more than half of those on occupied cells of the map.
:func:`check_placement` says why, giving those counts once: the yaml's ``negate`` line where
the other ``negate`` would free the cells the left-out observations lie on and keep those placed
near free space (:func:`~spcopyro.maps.free_space.negate_hint`); otherwise the causes on a map
that is right -- positions outside its frame, a floor plan drawn black where the tour went,
thick walls beside positions a little off -- and what to do about each.

A fit counts with ``warn=False`` and :func:`check_placement` says the counting's warnings
(:func:`~spcopyro.data.count_checks.say_placement_warnings`): a refusal that blames the map (no
observation on free space; the ``negate`` line) comes alone, not after the warnings listing the
observations left out and repeating its counts (a ``negate: 1`` map printed two long warnings,
then the refusal); the refusal on a map that may be right points to the lines those warnings
name, so they are said before it; a placement that passes says them once.
"""

from __future__ import annotations

import os

from spcopyro.data.counts import say_placement_warnings
from spcopyro.data.observations import Observations
from spcopyro.data.placement import PlacementReport, left_out_and_placed, on_map_text
from spcopyro.maps.grid import OccupancyGrid

__all__ = ["check_placement", "inverted_free_space_message"]


def _negate_hint(report: PlacementReport, obs: Observations, grid: OccupancyGrid) -> str:
    """:func:`~spcopyro.maps.free_space.negate_hint` for the observations left out and placed."""
    from spcopyro.maps.free_space import negate_hint  # reads the map image again

    left_out, placed = left_out_and_placed(report, obs)
    reach = report.snap_distance + grid.resolution  # placed: within snap distance of a cell
    return negate_hint(grid, left_out, placed, reach)


def inverted_free_space_message(report: PlacementReport, hint: str, where: str = "") -> str:
    """Why most observations are left out on occupied cells of the map (the fit's error when
    :meth:`~spcopyro.data.placement.PlacementReport.free_space_inverted`); ``hint``: the
    ``negate`` line's (:func:`~spcopyro.maps.free_space.negate_hint`, "" when the other
    ``negate`` would not place them); ``where`` names the map (``" on map PATH"``)."""
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
    source: str | os.PathLike[str] | None = None,
) -> None:
    """Raise ValueError when no observation lands on free space
    (:meth:`~spcopyro.data.placement.PlacementReport.check_on_free`) or when most are left out
    on occupied cells (:func:`inverted_free_space_message`): a fit would learn every concept from
    the prior alone, or from the few observations snapped onto the walls. The one place the
    second is refused (``check_on_free`` says only the first). The counting's warnings
    (:func:`~spcopyro.data.count_checks.say_placement_warnings` of ``report``, ``grid``, ``obs`` and
    the house folder ``source``: count with ``warn=False``) are said once: before the refusal
    on a map that may be right, which points to the lines the warnings name, or when the
    placement passes; not before the others, which blame the map. The messages name the map as
    the warnings do: ``" on map PATH"`` of ``grid``'s source
    (:func:`~spcopyro.data.placement.on_map_text`; nothing for a grid built in memory)."""
    where = on_map_text(grid)
    if report.num_observations and not report.num_on_free:  # the yaml's negate line named
        from spcopyro.maps.free_space import negate_line

        hint = _negate_hint(report, obs, grid)  # reads the yaml and image
        report.check_on_free(where, hint, "" if hint else negate_line(grid))  # the yaml again
    if report.free_space_inverted():
        hint = _negate_hint(report, obs, grid)
        if not hint:
            say_placement_warnings(report, grid, obs, source)
        raise ValueError(inverted_free_space_message(report, hint, where))
    say_placement_warnings(report, grid, obs, source)
