r"""Baseline (F): room segmentation of the occupancy map alone, no words and no images.

A user's first question about SpCoMapping is whether words and images add anything over cutting
the map at its doors. This baseline answers it with the distance-transform segmentation surveyed
by R. Bormann, F. Jordan, W. Li, J. Hampp, M. Haegele: "Room segmentation: survey,
implementation, and analysis", ICRA 2016 (the ``ipa_room_segmentation`` package, its "distance"
method), in a hierarchical form that needs one physical parameter, the widest doorway.

Algorithm: :mod:`spcopyro.maps.rooms`, with the door width read from a map
(:func:`~spcopyro.maps.rooms.auto_door_width`); moved there so that the data layer may cut at
doors, every public name re-exported here.

Words. For the scores of :mod:`spcopyro.metrics` the segments are named afterwards with the
words heard in them (:func:`geometry_semantic_map`): the segmentation itself never sees them.
"""

from __future__ import annotations

from spcopyro.data import DEFAULT_SNAP_DISTANCE, Observations, cell_counts
from spcopyro.maps import OccupancyGrid
from spcopyro.maps.rooms import (
    AUTO_DOOR_WIDTHS,
    DEFAULT_DOOR_WIDTH,
    DEFAULT_MIN_ROOM_AREA,
    auto_door_width,
    counts_as_room,
    free_cell_rooms,
    room_count,
    room_segments,
)
from spcopyro.results.semantic_map import TabularSemanticMap

__all__ = [
    "AUTO_DOOR_WIDTHS",
    "DEFAULT_DOOR_WIDTH",
    "DEFAULT_MIN_ROOM_AREA",
    "auto_door_width",
    "counts_as_room",
    "free_cell_rooms",
    "geometry_semantic_map",
    "room_count",
    "room_segments",
]


def geometry_semantic_map(
    grid: OccupancyGrid,
    observations: Observations,
    *,
    door_width: float = DEFAULT_DOOR_WIDTH,
    min_room_area: float = DEFAULT_MIN_ROOM_AREA,
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    smoothing: float = 1e-3,
) -> TabularSemanticMap:
    """Baseline (F): :func:`room_segments`, each segment then named by the words heard in it.

    ``n_{s,v}`` counts word v in the utterances placed in segment s (as in fitting:
    :func:`spcopyro.data.cell_counts`); ``p(v | cell) = (n_{s,v} + eps) / (n_s + V eps)`` and
    ``region(v)`` is the segment where v was heard most often
    (:class:`~spcopyro.results.semantic_map.TabularSemanticMap`). Images are not used.
    """
    labels = room_segments(grid, door_width=door_width, min_room_area=min_room_area)
    vocabulary = None if observations.num_utterances else ()
    counts = cell_counts(grid, observations, snap_distance=snap_distance, vocabulary=vocabulary)
    segments = int(labels.max()) + 1
    return TabularSemanticMap.from_cell_counts(
        grid,
        labels,
        counts,
        num_labels=segments,
        smoothing=smoothing,
        name="geometry",
        notes=(f"{segments} room segments (door width {door_width:g} m)",),
    )
