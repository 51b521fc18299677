"""Occupancy grids in ROS map_server format: loading, geometry, neighbourhoods, semantic-map output.

Modules (the names below are re-exported here, so ``from spcopyro.maps import X`` works for
them; the rest of each module's public names are not, see the end):

* :mod:`~spcopyro.maps.grid`: :class:`OccupancyGrid` and the cell codes ``FREE``, ``OCCUPIED``,
  ``UNKNOWN``; the image-row-order conventions, world <-> cell (paper eq. 11), neighbour tables
  and pairs, colour classes.
* :mod:`~spcopyro.maps.map_server`: ROS map_server yaml + pgm files, :func:`load_map` (trinary
  mode) and :func:`save_map`, :class:`MapFormatError`; the only module that imports OpenCV and
  PyYAML.
* :mod:`~spcopyro.maps.render`: semantic-map output, :func:`label_colours`,
  :func:`render_labels`, :func:`save_label_png`, :func:`save_label_map_server` and
  :func:`load_label_map_server`.
* :mod:`~spcopyro.maps.filter_mask`: Nav2 costmap-filter masks (``mode: scale`` maps of values
  0..100), :func:`save_filter_mask` and :func:`load_filter_mask` (map_server's three modes).
* :mod:`~spcopyro.maps.free_space`: :func:`check_free_cells`, the refusal of a map with no
  free cell, naming the yaml's ``negate`` and threshold lines and the image's greys
  (:func:`no_free_cell_reason`).
* :mod:`~spcopyro.maps.palette`: colours a reader can tell apart (:func:`distinct_colours`,
  :func:`concept_colours`: touching concepts get the most different ones).
* :mod:`~spcopyro.maps.regions`: which labels touch (:func:`region_contacts`) and each label's
  connected regions (:func:`concept_regions`).

Not re-exported (import them from their module, ``from spcopyro.maps.grid import same_frame``):

* :mod:`~spcopyro.maps.coarse`: ``coarsen_grid``, ``coarsening_factor``,
  ``free_block_of_map_cells``, ``grow_labels``, ``is_coarsening``, ``labels_on_grid``,
  ``model_cell_of``, ``refine_labels``.
* :mod:`~spcopyro.maps.filter_mask`: ``MASK_FREE_THRESH``, ``MASK_OCCUPIED_THRESH``,
  ``mask_pixels``.
* :mod:`~spcopyro.maps.free_space`: ``negate_hint``, ``negate_line``,
  ``truth_negate_hint``.
* :mod:`~spcopyro.maps.grid`: ``MAP_TOLERANCE_CELLS``, ``cells_on_map``, ``describe_map``,
  ``frame_differences``, ``same_frame``, ``same_free_cells``, ``same_origin``,
  ``same_resolution``.
* :mod:`~spcopyro.maps.map_server`: ``MAX_MAP_COORDINATE``, ``read_occupancy_yaml``,
  ``trinary_pixels``.
* :mod:`~spcopyro.maps.map_yaml`: ``MAX_YAW_NOISE``, ``PLAUSIBLE_RESOLUTION``,
  ``read_map_yaml``.
* :mod:`~spcopyro.maps.palette`: ``concept_palette``, ``delta_e``, ``delta_e94``, ``srgb_to_lab``.
* :mod:`~spcopyro.maps.rooms`: ``AUTO_DOOR_WIDTHS``, ``DEFAULT_DOOR_WIDTH``,
  ``DEFAULT_MIN_ROOM_AREA``, ``auto_door_width``, ``counts_as_room``, ``free_cell_rooms``,
  ``room_count``, ``room_segments`` (room segmentation at a door width; also in
  :mod:`spcopyro.baselines.geometry`).
"""

from spcopyro.maps.filter_mask import FilterMask, load_filter_mask, save_filter_mask
from spcopyro.maps.free_space import check_free_cells, no_free_cell_reason
from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from spcopyro.maps.map_server import (
    PGM_FREE,
    PGM_OCCUPIED,
    PGM_UNKNOWN,
    SAVE_FREE_THRESH,
    SAVE_OCCUPIED_THRESH,
    MapFileNotFoundError,
    MapFormatError,
    load_map,
    save_map,
)
from spcopyro.maps.palette import concept_colours, distinct_colours, region_adjacency
from spcopyro.maps.regions import concept_regions, region_contacts
from spcopyro.maps.render import (
    RAW_CONCEPT_VALUES,
    RAW_FREE_UNLABELLED,
    RAW_OCCUPIED,
    RAW_UNKNOWN,
    RGB_BACKGROUND,
    RGB_OCCUPIED,
    RGB_UNKNOWN,
    label_colours,
    load_label_map_server,
    render_labels,
    save_label_map_server,
    save_label_png,
)

__all__ = [
    "FREE",
    "OCCUPIED",
    "PGM_FREE",
    "PGM_OCCUPIED",
    "PGM_UNKNOWN",
    "RAW_CONCEPT_VALUES",
    "RAW_FREE_UNLABELLED",
    "RAW_OCCUPIED",
    "RAW_UNKNOWN",
    "RGB_BACKGROUND",
    "RGB_OCCUPIED",
    "RGB_UNKNOWN",
    "SAVE_FREE_THRESH",
    "SAVE_OCCUPIED_THRESH",
    "UNKNOWN",
    "MapFileNotFoundError",
    "FilterMask",
    "MapFormatError",
    "OccupancyGrid",
    "check_free_cells",
    "concept_colours",
    "concept_regions",
    "distinct_colours",
    "label_colours",
    "load_filter_mask",
    "load_label_map_server",
    "load_map",
    "no_free_cell_reason",
    "region_adjacency",
    "region_contacts",
    "render_labels",
    "save_filter_mask",
    "save_label_map_server",
    "save_label_png",
    "save_map",
]
