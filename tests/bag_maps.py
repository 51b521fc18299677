"""The import-bag tests' map: a 60 x 60 free occupancy grid at 0.1 m, saved as map_server's
``floor.yaml`` + ``floor.pgm`` (the ``map_yaml`` fixture of tests/conftest.py; the rosbag tests
whose poses want another origin, or a map per module, call :func:`save_free_map` themselves)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spcopyro.maps.grid import FREE, OCCUPIED, OccupancyGrid
from spcopyro.maps.map_server import save_map

CELLS = 60  # the map is CELLS x CELLS
RESOLUTION = 0.1  # metres per cell: the map is 6 m across


def free_grid(origin: float = -3.0, *, wall: bool = False) -> OccupancyGrid:
    """A 60 x 60 free map at 0.1 m, origin (``origin``, ``origin``): x, y in [origin,
    origin + 6) m; with ``wall``, its top row occupied (another map of the same size, for the
    tests of a map replaced or kept)."""
    cells = np.full((CELLS, CELLS), FREE, dtype=np.int8)  # [60, 60]
    if wall:
        cells[0, :] = OCCUPIED
    return OccupancyGrid(cells, RESOLUTION, (origin, origin, 0.0))


def save_free_map(folder: Path, origin: float = -3.0) -> Path:
    """:func:`free_grid` saved as ``folder/floor.yaml`` (+ ``floor.pgm``): the yaml's path."""
    return save_map(free_grid(origin), folder / "floor.yaml")
