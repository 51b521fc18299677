"""Occupancy grids in ROS map_server format: loading, geometry, neighbourhoods, semantic-map output.

Conventions
-----------
All ``[H, W]`` arrays are in the map IMAGE's row order: row 0 is the TOP of the map (largest world
y), exactly as the pgm is stored on disk. A cell is addressed as ``(row, col)``.

A world point ``(x, y)`` in metres falls in the cell (paper eq. 11, plus map_server's image
convention that the last image row is grid row 0)::

    col    = floor((x - origin_x) / resolution)
    grid_j = floor((y - origin_y) / resolution)
    row    = H - 1 - grid_j

``origin`` is the world pose of the lower-left corner of the lower-left cell (map_server
semantics). Rotated maps (``origin`` yaw != 0) are not supported: map_server itself ignores the yaw
for most consumers, and silently ignoring it here would misplace every observation, so a non-zero
yaw is an error.

Cell codes are map_server's trinary ``int8`` values ``FREE = 0``, ``OCCUPIED = 100``,
``UNKNOWN = -1``. Every FREE cell carries a latent spatial concept in SpCoMapping; free cells are
numbered ``0 .. N-1`` in raster (row-major image) order by :attr:`OccupancyGrid.free_index`, and
all per-free-cell arrays elsewhere in the package use that order.

Loading (:func:`load_map`) follows map_server's trinary mode: with the pixel value ``v`` (the mean
over all channels for colour images, alpha included, as map_server does in trinary mode) the
occupancy probability is ``p = (255 - v) / 255`` (``negate: 0``) or ``p = v / 255``
(``negate: 1``); ``p > occupied_thresh`` is OCCUPIED, ``p < free_thresh`` is FREE and anything
else (including values exactly at a threshold) is UNKNOWN. ``mode: scale`` and ``mode: raw`` are
rejected with a clear error, because they produce values outside the three codes; semantic maps
written by :func:`save_label_map_server` (``mode: raw``) are read back with
:func:`load_label_map_server`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

FREE, OCCUPIED, UNKNOWN = 0, 100, -1  # map_server trinary values (int8)

# Pixel values written by save_map (those of map_server's map_saver).
PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN = 254, 0, 205
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196

# Raw pixel values of a semantic map written by save_label_map_server ("mode: raw": ROS reads the
# byte as the int8 cell value, so 100 stays OCCUPIED and 255 reads as -1 = UNKNOWN).
RAW_FREE_UNLABELLED, RAW_OCCUPIED, RAW_UNKNOWN = 0, 100, 255
# Grey values available to concepts: 1..254 except 100 (253 values).
RAW_CONCEPT_VALUES = np.array([v for v in range(1, 255) if v != RAW_OCCUPIED], dtype=np.uint8)
RAW_CONCEPT_VALUES.setflags(write=False)

# Colours of render_labels (RGB).
RGB_OCCUPIED = (0, 0, 0)
RGB_UNKNOWN = (205, 205, 205)
RGB_BACKGROUND = (255, 255, 255)

_REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_CONNECTIVITIES = (4, 8)
# (d_row, d_col) of the neighbour columns of neighbour_table: up, down, left, right, then
# up-left, up-right, down-left, down-right.
_OFFSETS = ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1))


class MapFormatError(ValueError):
    """A map yaml or image is malformed; the message names the file (and the key and value)."""


class MapFileNotFoundError(MapFormatError, FileNotFoundError):
    """A map yaml or the image it names does not exist."""


def _check_connectivity(connectivity: int) -> None:
    if connectivity not in _CONNECTIVITIES:
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")


def _as_cells(cells: Any, what: str = "cells") -> np.ndarray:
    """``[..., 2]`` integer (row, col) array as int64; raises ValueError otherwise."""
    arr = np.asarray(cells)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{what} must have shape [..., 2] (row, col), got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        raise ValueError(f"{what} must be an integer array, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=False)


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A map_server occupancy grid in image row order (row 0 = top = largest world y).

    Attributes:
        occupancy: ``[H, W]`` int8 in ``{FREE, OCCUPIED, UNKNOWN}``; stored as a read-only copy.
        resolution: metres per cell, > 0.
        origin: world pose ``(x, y, yaw)`` of the lower-left cell's lower-left corner (yaw 0).
        source: the yaml the grid was loaded from, if any (not part of equality).

    Two grids are equal when their cells, resolution and origin are equal.
    """

    occupancy: np.ndarray  # [H, W] int8
    resolution: float
    origin: tuple[float, float, float]
    source: Path | None = None

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.ndim != 2:
            raise ValueError(f"occupancy must be a 2-D [H, W] array, got shape {occ.shape}")
        if occ.dtype.kind not in "iu":
            raise ValueError(f"occupancy must be an integer array, got dtype {occ.dtype}")
        bad = ~np.isin(occ, (FREE, OCCUPIED, UNKNOWN))  # [H, W] bool
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise ValueError(
                f"occupancy values must be FREE (0), OCCUPIED (100) or UNKNOWN (-1); "
                f"cell (row {row}, col {col}) is {occ[row, col]} ({int(bad.sum())} bad cells)"
            )
        object.__setattr__(self, "occupancy", _readonly(occ.astype(np.int8, copy=True)))

        if isinstance(self.resolution, bool) or not isinstance(
            self.resolution, (int, float, np.integer, np.floating)
        ):
            raise ValueError(f"resolution must be a number, got {self.resolution!r}")
        resolution = float(self.resolution)
        if not (math.isfinite(resolution) and resolution > 0):
            raise ValueError(f"resolution must be positive and finite, got {resolution!r}")
        object.__setattr__(self, "resolution", resolution)

        try:
            origin = tuple(float(v) for v in self.origin)
        except (TypeError, ValueError) as err:
            raise ValueError(f"origin must be 3 numbers (x, y, yaw), got {self.origin!r}") from err
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise ValueError(f"origin must be 3 finite numbers (x, y, yaw), got {self.origin!r}")
        if origin[2] != 0.0:
            raise ValueError(f"rotated maps are not supported: origin yaw is {origin[2]!r}")
        object.__setattr__(self, "origin", origin)

        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return (
            self.resolution == other.resolution
            and self.origin == other.origin
            and np.array_equal(self.occupancy, other.occupancy)
        )

    __hash__ = None  # type: ignore[assignment]  # holds an ndarray

    def __repr__(self) -> str:
        return (
            f"OccupancyGrid(shape={self.shape}, resolution={self.resolution}, "
            f"origin={self.origin}, num_free={self.num_free}, source={self.source})"
        )

    # ------------------------------------------------------------------ shape and free cells
    @property
    def height(self) -> int:
        return int(self.occupancy.shape[0])

    @property
    def width(self) -> int:
        return int(self.occupancy.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    @cached_property
    def free(self) -> np.ndarray:
        """``[H, W]`` bool, True on FREE cells (read-only)."""
        return _readonly(self.occupancy == FREE)

    @cached_property
    def num_free(self) -> int:
        return int(np.count_nonzero(self.free))

    @cached_property
    def free_index(self) -> np.ndarray:
        """``[H, W]`` int64: raster-order index ``0..N-1`` of each free cell, -1 elsewhere."""
        index = np.full(self.shape, -1, dtype=np.int64)  # [H, W]
        index[self.free] = np.arange(self.num_free, dtype=np.int64)
        return _readonly(index)

    @cached_property
    def free_cells(self) -> np.ndarray:
        """``[N, 2]`` int64 (row, col) of the free cells in :attr:`free_index` order."""
        return _readonly(np.argwhere(self.free).astype(np.int64))

    # ------------------------------------------------------------------ geometry
    def world_to_cell(self, xy: Any) -> np.ndarray:
        """World points ``[..., 2]`` (x, y) in metres -> ``[..., 2]`` int64 (row, col).

        ``col = floor((x - ox) / res)``, ``row = H - 1 - floor((y - oy) / res)`` (paper eq. 11).
        No clipping: points off the map give indices outside ``[0, H) x [0, W)`` (see
        :meth:`in_bounds`). Raises ValueError on NaN/inf input.
        """
        pts = np.asarray(xy, dtype=np.float64)
        if pts.ndim == 0 or pts.shape[-1] != 2:
            raise ValueError(f"xy must have shape [..., 2] (x, y), got shape {pts.shape}")
        finite = np.isfinite(pts).all(axis=-1)  # [...] bool
        if not finite.all():
            first = np.argwhere(~finite)[0]
            raise ValueError(
                f"xy must be finite; point at index {tuple(int(i) for i in first)} is "
                f"{pts[tuple(first)].tolist()}"
            )
        ox, oy, _ = self.origin
        grid = np.floor((pts - np.array([ox, oy])) / self.resolution)  # [..., 2] (i, j) float
        if pts.size and np.abs(grid).max() >= 2.0**62:
            raise ValueError("xy is too far from the map origin to index a cell")
        grid = grid.astype(np.int64)
        cells = np.empty_like(grid)  # [..., 2] (row, col)
        cells[..., 0] = self.height - 1 - grid[..., 1]
        cells[..., 1] = grid[..., 0]
        return cells

    def cell_to_world(self, cells: Any) -> np.ndarray:
        """Cells ``[..., 2]`` int (row, col) -> ``[..., 2]`` float64 world (x, y) of the centre.

        ``x = ox + (col + 1/2) res``, ``y = oy + (H - 1 - row + 1/2) res``; so
        ``world_to_cell(cell_to_world(c)) == c`` exactly. Cells off the map are allowed.
        """
        c = _as_cells(cells)
        ox, oy, _ = self.origin
        xy = np.empty(c.shape, dtype=np.float64)  # [..., 2]
        xy[..., 0] = ox + (c[..., 1] + 0.5) * self.resolution
        xy[..., 1] = oy + (self.height - 1 - c[..., 0] + 0.5) * self.resolution
        return xy

    def in_bounds(self, cells: Any) -> np.ndarray:
        """``[...]`` bool: the (row, col) lies inside ``[0, H) x [0, W)``."""
        c = _as_cells(cells)
        return (
            (c[..., 0] >= 0)
            & (c[..., 0] < self.height)
            & (c[..., 1] >= 0)
            & (c[..., 1] < self.width)
        )

    def is_free(self, cells: Any) -> np.ndarray:
        """``[...]`` bool: the (row, col) is on the map and FREE (False when out of bounds)."""
        c = _as_cells(cells)
        inside = self.in_bounds(c)  # [...] bool
        rows = np.where(inside, c[..., 0], 0)
        cols = np.where(inside, c[..., 1], 0)
        return inside & self.free[rows, cols]

    # ------------------------------------------------------------------ neighbourhoods
    def neighbour_table(self, connectivity: int = 4) -> np.ndarray:
        """``[N, connectivity]`` int64 free-cell indices of each free cell's neighbours.

        Columns: up, down, left, right (row-1, row+1, col-1, col+1); for 8-connectivity then
        up-left, up-right, down-left, down-right. -1 where the neighbour is off the map or not free.
        """
        _check_connectivity(connectivity)
        padded = np.pad(self.free_index, 1, constant_values=-1)  # [H+2, W+2]
        h, w = self.shape
        table = np.empty((self.num_free, connectivity), dtype=np.int64)  # [N, C]
        for k, (dr, dc) in enumerate(_OFFSETS[:connectivity]):
            shifted = padded[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]  # [H, W]
            table[:, k] = shifted[self.free]
        return table

    def neighbour_pairs(self, connectivity: int = 4) -> np.ndarray:
        """``[P, 2]`` int64 unordered free-neighbour pairs ``(a, b)``, ``a < b``, each once.

        Sorted lexicographically by ``(a, b)``.
        """
        table = self.neighbour_table(connectivity)  # [N, C]
        own = np.arange(self.num_free, dtype=np.int64)
        # down, right, down-left, down-right lie later in raster order, so each pair appears once.
        forward = [k for k, (dr, dc) in enumerate(_OFFSETS[:connectivity]) if (dr, dc) > (0, 0)]
        parts = []
        for k in forward:
            has = table[:, k] >= 0  # [N] bool
            parts.append(np.stack([own[has], table[has, k]], axis=1))
        pairs = np.concatenate(parts, axis=0)  # [P, 2]
        order = np.lexsort((pairs[:, 1], pairs[:, 0]))
        return pairs[order]

    def colour_classes(self, connectivity: int = 4) -> list[np.ndarray]:
        """Graph colouring of the free cells into blocks with no neighbours inside a block.

        4-connectivity: 2 classes by ``(row + col) % 2`` (checkerboard); 8-connectivity: 4
        classes by ``2 * (row % 2) + col % 2``. Each entry is an ascending int64 array of free-cell
        indices (possibly empty); given the other classes, the cells of one class are
        conditionally independent under a pairwise MRF, so they can be Gibbs-updated together.
        """
        _check_connectivity(connectivity)
        rows, cols = self.free_cells[:, 0], self.free_cells[:, 1]  # [N]
        if connectivity == 4:
            colour, num_colours = (rows + cols) % 2, 2
        else:
            colour, num_colours = 2 * (rows % 2) + cols % 2, 4
        return [np.flatnonzero(colour == k).astype(np.int64) for k in range(num_colours)]

    def with_occupancy(self, occupancy: Any) -> OccupancyGrid:
        """The same geometry (resolution, origin, source) with new ``[H, W]`` cells."""
        occ = np.asarray(occupancy)
        if occ.shape != self.shape:
            raise ValueError(f"occupancy must have shape {self.shape}, got {occ.shape}")
        return dataclasses.replace(self, occupancy=occ)


# ---------------------------------------------------------------------- yaml parsing
@dataclass(frozen=True)
class _MapYaml:
    path: Path
    image: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _read_map_yaml(yaml_path: str | os.PathLike) -> _MapYaml:
    """Parse and validate a map_server yaml; errors name the file, line, key and value."""
    path = Path(yaml_path)
    if not path.is_file():
        raise MapFileNotFoundError(f"{path}: map yaml not found")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise MapFormatError(f"{path}: cannot read map yaml: {err}") from err
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise MapFormatError(f"{path}: invalid yaml: {err}") from err
    if not isinstance(doc, dict) or not isinstance(root, yaml.MappingNode):
        raise MapFormatError(
            f"{path}: map yaml must be a mapping of keys to values, got {type(doc).__name__}"
        )
    lines: dict[Any, int] = {}
    for key_node, _ in root.value:
        if not isinstance(key_node, yaml.ScalarNode):
            raise MapFormatError(
                f"{path}:{key_node.start_mark.line + 1}: map yaml keys must be plain names"
            )
        key = key_node.value
        if key in lines:
            raise MapFormatError(
                f"{path}:{key_node.start_mark.line + 1}: duplicate key {key!r} "
                f"(first at line {lines[key]})"
            )
        lines[key] = key_node.start_mark.line + 1

    def where(key: str) -> str:
        return f"{path}:{lines[key]}" if key in lines else str(path)

    for key in _REQUIRED_KEYS:
        if key not in doc:
            raise MapFormatError(f"{path}: missing required key {key!r}")

    def bad(key: str, expected: str) -> MapFormatError:
        return MapFormatError(f"{where(key)}: key {key!r} must be {expected}, got {doc[key]!r}")

    resolution = doc["resolution"]
    if not _is_number(resolution) or not (math.isfinite(resolution) and resolution > 0):
        raise bad("resolution", "a positive finite number")

    origin = doc["origin"]
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(_is_number(v) and math.isfinite(v) for v in origin)
    ):
        raise bad("origin", "a list of 3 finite numbers [x, y, yaw]")
    if origin[2] != 0:
        raise MapFormatError(
            f"{where('origin')}: key 'origin' has yaw {origin[2]!r}; rotated maps are not "
            "supported (yaw must be 0)"
        )

    negate = doc["negate"]
    if not isinstance(negate, (int, bool)) or negate not in (0, 1):
        raise bad("negate", "0 or 1")

    for key in ("occupied_thresh", "free_thresh"):
        value = doc[key]
        if not _is_number(value) or not 0.0 <= value <= 1.0:
            raise bad(key, "a number in [0, 1]")
    if not doc["free_thresh"] < doc["occupied_thresh"]:
        raise MapFormatError(
            f"{where('free_thresh')}: key 'free_thresh' ({doc['free_thresh']!r}) must be less "
            f"than 'occupied_thresh' ({doc['occupied_thresh']!r})"
        )

    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise bad("mode", "one of 'trinary', 'scale', 'raw'")

    image = doc["image"]
    if not isinstance(image, str) or not image:
        raise bad("image", "a non-empty file name")
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path

    return _MapYaml(
        path=path,
        image=image_path,
        resolution=float(resolution),
        origin=(float(origin[0]), float(origin[1]), float(origin[2])),
        negate=bool(negate),
        occupied_thresh=float(doc["occupied_thresh"]),
        free_thresh=float(doc["free_thresh"]),
        mode=mode,
    )


def _read_image(spec: _MapYaml) -> np.ndarray:
    """The map image as uint8 ``[H, W]`` (grey) or ``[H, W, C]`` (colour, OpenCV channel order)."""
    if not spec.image.is_file():
        raise MapFileNotFoundError(
            f"{spec.path}: key 'image': image file {str(spec.image)!r} not found"
        )
    data = np.fromfile(spec.image, dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise MapFormatError(
            f"{spec.path}: key 'image': {str(spec.image)!r} is not a readable image"
        )
    if img.dtype != np.uint8:
        raise MapFormatError(
            f"{spec.path}: key 'image': {str(spec.image)!r} has {img.dtype} pixels; only 8-bit "
            "images are supported"
        )
    if img.ndim not in (2, 3) or img.shape[0] == 0 or img.shape[1] == 0:
        raise MapFormatError(
            f"{spec.path}: key 'image': {str(spec.image)!r} has unsupported shape {img.shape}"
        )
    return img


def load_map(yaml_path: str | os.PathLike) -> OccupancyGrid:
    """Load a ROS map_server map (yaml + image) as an :class:`OccupancyGrid`.

    Keys (all required, as in map_server): ``image`` (relative to the yaml's folder, or
    absolute), ``resolution``, ``origin`` ``[x, y, yaw]`` (yaw must be 0), ``negate`` (0/1),
    ``occupied_thresh``, ``free_thresh`` (in [0, 1], free < occupied); optional ``mode`` must be
    ``trinary`` (the default). Unknown keys are ignored, as map_server does.

    Cells: ``v`` = pixel value, averaged over all channels for colour images;
    ``p = (255 - v) / 255`` if ``negate == 0`` else ``v / 255``; ``p > occupied_thresh`` ->
    OCCUPIED, ``p < free_thresh`` -> FREE, otherwise UNKNOWN.

    Raises:
        MapFileNotFoundError: the yaml or its image does not exist.
        MapFormatError: anything malformed; the message names the yaml (with the line where the
            key is), the key and the offending value.
    """
    spec = _read_map_yaml(yaml_path)
    if spec.mode != "trinary":
        raise MapFormatError(
            f"{spec.path}: key 'mode': {spec.mode!r} is not supported by load_map (only "
            "'trinary'); semantic maps saved by save_label_map_server are read with "
            "load_label_map_server"
        )
    img = _read_image(spec)
    value = img.astype(np.float64) if img.ndim == 2 else img.mean(axis=2, dtype=np.float64)
    p = value / 255.0 if spec.negate else (255.0 - value) / 255.0  # [H, W] occupancy probability
    occupancy = np.full(p.shape, UNKNOWN, dtype=np.int8)  # [H, W]
    occupancy[p > spec.occupied_thresh] = OCCUPIED
    occupancy[p < spec.free_thresh] = FREE
    return OccupancyGrid(occupancy, spec.resolution, spec.origin, source=spec.path)


# ---------------------------------------------------------------------- writing
def _yaml_target(yaml_path: str | os.PathLike) -> Path:
    path = Path(yaml_path)
    if path.suffix not in (".yaml", ".yml"):
        raise ValueError(f"{path}: a map yaml path must end in .yaml or .yml")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _write_image(path: Path, img: np.ndarray) -> None:
    ok, buf = cv2.imencode(path.suffix, img)
    if not ok:
        raise OSError(f"{path}: OpenCV could not encode the image")
    path.write_bytes(buf.tobytes())


def _write_map_yaml(path: Path, image: Path, grid: OccupancyGrid, mode: str | None) -> None:
    doc: dict[str, Any] = {
        "image": image.name,
        "resolution": grid.resolution,
        "origin": list(grid.origin),
        "negate": 0,
        "occupied_thresh": SAVE_OCCUPIED_THRESH,
        "free_thresh": SAVE_FREE_THRESH,
    }
    if mode is not None:
        doc["mode"] = mode
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None), encoding="utf-8")


def save_map(grid: OccupancyGrid, yaml_path: str | os.PathLike) -> Path:
    """Write ``grid`` as ``NAME.pgm`` (P5; 254 free, 0 occupied, 205 unknown) + ``NAME.yaml``.

    The yaml has ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196`` and the image
    name relative to its folder, so ``load_map(save_map(grid, path)) == grid``. Returns the yaml
    path.
    """
    path = _yaml_target(yaml_path)
    image = path.with_suffix(".pgm")
    pgm = np.full(grid.shape, PGM_UNKNOWN, dtype=np.uint8)  # [H, W]
    pgm[grid.occupancy == FREE] = PGM_FREE
    pgm[grid.occupancy == OCCUPIED] = PGM_OCCUPIED
    _write_image(image, pgm)
    _write_map_yaml(path, image, grid, mode=None)
    return path


def label_colours(num_labels: int) -> np.ndarray:
    """``[num_labels, 3]`` uint8 RGB colours, pairwise distinct and deterministic.

    The first 18 are matplotlib's tab20 without its two greys (strong shades first, then the
    light ones); further colours follow a golden-ratio hue sequence at a few saturation/value
    levels. None is black, white or the unknown grey (205, 205, 205) used by
    :func:`render_labels`.
    """
    if isinstance(num_labels, bool) or not isinstance(num_labels, (int, np.integer)):
        raise ValueError(f"num_labels must be an integer, got {num_labels!r}")
    num_labels = int(num_labels)
    if not 0 <= num_labels <= 2**24 - 3:
        raise ValueError(f"num_labels must be in [0, 2**24 - 3], got {num_labels}")
    import matplotlib
    import matplotlib.colors

    tab20 = np.asarray(matplotlib.colormaps["tab20"].colors)  # [20, 3] float
    tab = np.concatenate([tab20[0::2], tab20[1::2]])  # strong shades first
    tab = np.delete(tab, [7, 17], axis=0)  # the greys (tab20 indices 14 and 15)
    reserved = np.array([RGB_OCCUPIED, RGB_BACKGROUND, RGB_UNKNOWN], dtype=np.int64)  # [3, 3]

    def codes(rgb: np.ndarray) -> np.ndarray:  # [M, 3] uint8 -> [M] int64 24-bit code
        rgb = rgb.astype(np.int64)
        return (rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]

    num_candidates = 2 * num_labels + 64
    while True:
        i = np.arange(num_candidates)
        levels = np.array([(0.85, 0.9), (0.55, 0.95), (0.9, 0.6)])  # (saturation, value)
        hsv = np.stack([(i * 0.6180339887498949) % 1.0, levels[i % 3, 0], levels[i % 3, 1]], axis=1)
        floats = np.concatenate([tab, matplotlib.colors.hsv_to_rgb(hsv)])  # [M, 3]
        candidates = np.round(floats * 255).astype(np.uint8)
        code = codes(candidates)
        if num_candidates > 2**17:  # hue resolution exhausted: fall back to every 24-bit colour
            code = np.concatenate([code, np.arange(2**24, dtype=np.int64)])
        _, first = np.unique(code, return_index=True)
        code = code[np.sort(first)]
        code = code[~np.isin(code, codes(reserved))]
        if code.size >= num_labels:
            break
        num_candidates *= 4
    code = code[:num_labels]
    return np.stack([(code >> 16) & 255, (code >> 8) & 255, code & 255], axis=1).astype(np.uint8)


def _check_labels(labels: Any, grid: OccupancyGrid | None) -> np.ndarray:
    """Validate ``[H, W]`` integer labels (-1 or a concept id >= 0) against ``grid``."""
    lab = np.asarray(labels)
    if lab.ndim != 2:
        raise ValueError(f"labels must be a 2-D [H, W] array, got shape {lab.shape}")
    if lab.dtype.kind not in "iu":
        raise ValueError(f"labels must be an integer array, got dtype {lab.dtype}")
    lab = lab.astype(np.int64, copy=False)
    if lab.size and lab.min() < -1:
        row, col = np.argwhere(lab < -1)[0]
        raise ValueError(
            f"labels must be -1 or a concept id >= 0; cell (row {row}, col {col}) is "
            f"{lab[row, col]}"
        )
    if grid is not None:
        if lab.shape != grid.shape:
            raise ValueError(f"labels shape {lab.shape} differs from the map shape {grid.shape}")
        off_free = (lab >= 0) & ~grid.free  # [H, W] bool
        if off_free.any():
            row, col = np.argwhere(off_free)[0]
            raise ValueError(
                f"{int(off_free.sum())} labelled cells are not free in the map, e.g. cell "
                f"(row {row}, col {col}) with label {lab[row, col]} and map code "
                f"{grid.occupancy[row, col]}"
            )
    return lab


def render_labels(labels: Any, grid: OccupancyGrid | None = None) -> np.ndarray:
    """``[H, W]`` concept labels -> ``[H, W, 3]`` uint8 RGB image.

    Concept ``k >= 0`` gets ``label_colours(max + 1)[k]``; with a grid, OCCUPIED cells are black
    and UNKNOWN cells grey (205); cells labelled -1 that are free (or every -1 cell when no grid
    is given) are white. Labels >= 0 on non-free cells are an error.
    """
    lab = _check_labels(labels, grid)
    rgb = np.empty((*lab.shape, 3), dtype=np.uint8)  # [H, W, 3]
    rgb[...] = RGB_BACKGROUND
    if grid is not None:
        rgb[grid.occupancy == OCCUPIED] = RGB_OCCUPIED
        rgb[grid.occupancy == UNKNOWN] = RGB_UNKNOWN
    labelled = lab >= 0  # [H, W] bool
    if labelled.any():
        colours = label_colours(int(lab.max()) + 1)  # [K, 3]
        rgb[labelled] = colours[lab[labelled]]
    return rgb


def save_label_png(labels: Any, path: str | os.PathLike, grid: OccupancyGrid | None = None) -> Path:
    """Write :func:`render_labels` as a colour PNG (row 0 at the top); returns the path."""
    out = Path(path)
    if out.suffix.lower() != ".png":
        raise ValueError(f"{out}: label image path must end in .png")
    rgb = render_labels(labels, grid)
    out.parent.mkdir(parents=True, exist_ok=True)
    _write_image(out, np.ascontiguousarray(rgb[..., ::-1]))  # OpenCV wants BGR
    return out


def _sidecar_path(yaml_path: Path) -> Path:
    return yaml_path.with_suffix(".labels.json")


def save_label_map_server(labels: Any, grid: OccupancyGrid, yaml_path: str | os.PathLike) -> Path:
    """Write a semantic map that map_server loads with ``mode: raw``.

    Files: ``NAME.pgm``, ``NAME.yaml`` (same resolution/origin, ``negate: 0``, ``mode: raw`` so
    ROS takes each byte as the cell value) and ``NAME.labels.json``. Pixel values: OCCUPIED 100,
    UNKNOWN 255 (int8 -1 in ROS), free unlabelled 0, and the distinct concept ids present, in
    ascending order, get the grey values 1, 2, ..., 99, 101, ..., 254 (253 available). The json
    holds ``{"image": NAME.pgm, "grey_to_concept": {"1": id, ...}, "free_unlabelled": 0,
    "occupied": 100, "unknown": 255}``. Returns the yaml path; read back with
    :func:`load_label_map_server`.

    Raises:
        ValueError: more than 253 distinct concepts, or labels on non-free cells.
    """
    lab = _check_labels(labels, grid)
    concepts = np.unique(lab[lab >= 0])  # [K] ascending
    if concepts.size > RAW_CONCEPT_VALUES.size:
        raise ValueError(
            f"{concepts.size} distinct concepts do not fit in a raw map_server image: only "
            f"{RAW_CONCEPT_VALUES.size} grey values (1..254 except 100) are available"
        )
    path = _yaml_target(yaml_path)
    image = path.with_suffix(".pgm")
    grey = RAW_CONCEPT_VALUES[: concepts.size]  # [K] uint8
    pgm = np.full(grid.shape, RAW_UNKNOWN, dtype=np.uint8)  # [H, W]
    pgm[grid.occupancy == OCCUPIED] = RAW_OCCUPIED
    pgm[grid.occupancy == FREE] = RAW_FREE_UNLABELLED
    labelled = lab >= 0  # [H, W] bool
    pgm[labelled] = grey[np.searchsorted(concepts, lab[labelled])]
    _write_image(image, pgm)
    _write_map_yaml(path, image, grid, mode="raw")
    sidecar = {
        "image": image.name,
        "grey_to_concept": {str(int(g)): int(c) for g, c in zip(grey, concepts, strict=True)},
        "free_unlabelled": RAW_FREE_UNLABELLED,
        "occupied": RAW_OCCUPIED,
        "unknown": RAW_UNKNOWN,
    }
    _sidecar_path(path).write_text(json.dumps(sidecar, indent=2) + "\n", encoding="utf-8")
    return path


def load_label_map_server(yaml_path: str | os.PathLike) -> tuple[np.ndarray, OccupancyGrid]:
    """Read a semantic map written by :func:`save_label_map_server`.

    Returns ``(labels, grid)``: ``labels`` ``[H, W]`` int64 concept ids (-1 on unlabelled and
    non-free cells) and the occupancy grid (labelled and free-unlabelled cells are FREE).

    Raises:
        MapFormatError: the yaml is not ``mode: raw`` with ``negate: 0``, the sidecar json is
            missing or malformed, or a pixel value is neither a cell code nor a listed grey value.
    """
    spec = _read_map_yaml(yaml_path)
    if spec.mode != "raw" or spec.negate:
        raise MapFormatError(
            f"{spec.path}: a semantic map needs 'mode: raw' and 'negate: 0', got mode "
            f"{spec.mode!r}, negate {int(spec.negate)}"
        )
    sidecar_path = _sidecar_path(spec.path)
    if not sidecar_path.is_file():
        raise MapFileNotFoundError(f"{sidecar_path}: label sidecar json not found")
    try:
        sidecar = json.loads(sidecar_path.read_text(encoding="utf-8"))
        table = sidecar["grey_to_concept"]
        if not isinstance(table, Mapping):
            raise TypeError("'grey_to_concept' is not an object")
        grey_to_concept = {int(g): int(c) for g, c in table.items()}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise MapFormatError(f"{sidecar_path}: malformed label sidecar: {err}") from err
    for g, c in grey_to_concept.items():
        if g not in RAW_CONCEPT_VALUES or c < 0:
            raise MapFormatError(
                f"{sidecar_path}: key 'grey_to_concept': entry {g} -> {c} is not a concept grey "
                "value (1..254 except 100) mapped to a concept id >= 0"
            )
    img = _read_image(spec)
    if img.ndim != 2:
        raise MapFormatError(
            f"{spec.path}: key 'image': {str(spec.image)!r} must be single-channel, got shape "
            f"{img.shape}"
        )
    lut_label = np.full(256, -1, dtype=np.int64)  # pixel value -> concept id
    lut_code = np.full(256, 127, dtype=np.int8)  # pixel value -> cell code (127 = invalid)
    lut_code[[RAW_FREE_UNLABELLED, RAW_OCCUPIED, RAW_UNKNOWN]] = [FREE, OCCUPIED, UNKNOWN]
    for g, c in grey_to_concept.items():
        lut_label[g] = c
        lut_code[g] = FREE
    occupancy = lut_code[img]  # [H, W]
    invalid = occupancy == 127  # [H, W] bool
    if invalid.any():
        row, col = np.argwhere(invalid)[0]
        raise MapFormatError(
            f"{spec.image}: pixel (row {row}, col {col}) has value {img[row, col]}, which is "
            f"neither a cell code nor listed in {sidecar_path.name} ({int(invalid.sum())} such "
            "pixels)"
        )
    grid = OccupancyGrid(occupancy, spec.resolution, spec.origin, source=spec.path)
    return lut_label[img], grid
