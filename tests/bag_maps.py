"""The import-bag tests' map: a 60 x 60 free occupancy grid at 0.1 m, saved as map_server's
``floor.yaml`` + ``floor.pgm`` (the ``map_yaml`` fixture of tests/conftest.py; the rosbag tests
whose poses want another origin, or a map per module, call :func:`save_free_map` themselves);
and the small ROS 2 bag the overwrite tests import (:func:`four_pose_bag`)."""

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


T0 = 1_600_000_000.0  # the small bag's first stamp, seconds


def four_pose_bag(path: Path) -> Path:
    """A ROS 2 bag at ``path``: four poses 0.5 m apart along x (one a second from :data:`T0`),
    three images between them and the word "kitchen" at T0 + 1 s. Needs rosbags."""
    from spcopyro.robot.rosbag import BagWriter

    with BagWriter(path, ros=2) as w:
        for t in T0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.5 * (t - T0), 0.0, 0.0)
        for k, t in enumerate(T0 + np.array([0.5, 1.5, 2.5])):
            w.image("/camera/image", t, np.full((6, 8, 3), 40 * k, dtype=np.uint8))
        w.text("/speech", T0 + 1.0, "kitchen")
    return path
