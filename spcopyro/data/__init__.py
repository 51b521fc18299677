"""Observations of a house, their placement on the occupancy grid, and the dataset files.

A robot takes images (each turned into a K-class place histogram by a CNN) and hears utterances,
each at a world position. This package

* holds them in :class:`Observations` (world coordinates, free vocabulary: nothing pre-listed),
  together with any number of further modalities (:class:`ModalityObservations`: named count
  vectors at world positions),
* puts each observation on a free cell of an :class:`~spcopyro.maps.OccupancyGrid`
  (:func:`place_observations`: paper eq. 11, ``convert(x) = floor((x - origin) / resolution)``,
  with snapping of positions that land just off free space),
* sums them per cell into the sparse sufficient statistics the model reads (:func:`cell_counts`),
  with the image-feature scaling and word weighting (counts or tf-idf, paper eq. 20) as options,
* reads and writes the public SpCoMapping dataset layout (:func:`load_house`, :func:`save_house`;
  see the dataset's README.md).

Nothing is dropped silently: observations that cannot be placed are logged (``logging``, logger
``"spcopyro"``) and listed in a :class:`PlacementReport`; malformed files raise
:class:`DataFormatError` naming the file, the 1-based line and the offending value.

Modules (everything public is re-exported here, so ``from spcopyro.data import X`` works):

* :mod:`~spcopyro.data.observations`: :class:`Observations`, :class:`ModalityObservations` and
  their validation, :class:`DataFormatError`.
* :mod:`~spcopyro.data.text`: :func:`tokenize`, :func:`word_matrix`, :func:`tfidf_weights`
  (eq. 20).
* :mod:`~spcopyro.data.placement`: :func:`place_observations` (eq. 11, snapping),
  :class:`PlacementReport`, :class:`ModalityPlacement`.
* :mod:`~spcopyro.data.counts`: :class:`CellCounts`, :class:`CellModalityCounts`,
  :func:`cell_counts`, :func:`prepared_cell_counts`.
* :mod:`~spcopyro.data.count_checks`: :func:`scale_features`, :func:`check_count_totals`
  (:data:`MAX_COUNT_TOTAL`), the warnings about observations left out.
* :mod:`~spcopyro.data.dataset`: :class:`House`, :func:`load_house`, :func:`save_house`,
  :func:`find_dataset_root`, :func:`list_houses`.
* :mod:`~spcopyro.data.dataset_files`: the readers and writers of the single files of a house
  folder (CSV files, trials, camera images, ``modality_<name>.csv``).
"""

from spcopyro.data.counts import (
    MAX_COUNT_TOTAL,
    CellCounts,
    CellModalityCounts,
    FeatureScaling,
    cell_counts,
    check_count_totals,
    prepared_cell_counts,
    scale_features,
)
from spcopyro.data.dataset import House, find_dataset_root, list_houses, load_house, save_house
from spcopyro.data.dataset_files import IMAGE_SUFFIXES
from spcopyro.data.observations import (
    RESERVED_MODALITY_NAMES,
    DataFormatError,
    ModalityObservations,
    Observations,
)
from spcopyro.data.placement import (
    DEFAULT_SNAP_DISTANCE,
    ModalityPlacement,
    PlacementReport,
    place_observations,
)
from spcopyro.data.text import WordWeighting, tfidf_weights, tokenize, word_matrix

__all__ = [
    "DEFAULT_SNAP_DISTANCE",
    "IMAGE_SUFFIXES",
    "MAX_COUNT_TOTAL",
    "RESERVED_MODALITY_NAMES",
    "CellCounts",
    "CellModalityCounts",
    "DataFormatError",
    "FeatureScaling",
    "House",
    "ModalityObservations",
    "ModalityPlacement",
    "Observations",
    "PlacementReport",
    "WordWeighting",
    "cell_counts",
    "prepared_cell_counts",
    "check_count_totals",
    "find_dataset_root",
    "list_houses",
    "load_house",
    "place_observations",
    "save_house",
    "scale_features",
    "tfidf_weights",
    "tokenize",
    "word_matrix",
]
