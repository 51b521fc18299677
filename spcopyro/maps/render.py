"""Semantic-map output: label colours, RGB rendering, label PNGs and map_server semantic maps.

A semantic map is an ``[H, W]`` integer array of concept labels (-1 where unlabelled, a concept
id >= 0 on free cells only). :func:`render_labels` draws it in colour (:func:`label_colours`),
:func:`save_label_png` writes that as a PNG, and :func:`save_label_map_server` /
:func:`load_label_map_server` write and read it as a ROS map_server map with ``mode: raw`` (plus
a json sidecar naming the concept of each grey value).
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from spcopyro._util.number_checks import is_integer
from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from spcopyro.maps.map_image import _read_image, _write_image
from spcopyro.maps.map_server import _write_map_yaml, _yaml_target
from spcopyro.maps.map_yaml import MapFileNotFoundError, MapFormatError, read_map_yaml

logger = logging.getLogger(__name__)

__all__ = [
    "RAW_CONCEPT_VALUES",
    "RAW_FREE_UNLABELLED",
    "RAW_OCCUPIED",
    "RAW_UNKNOWN",
    "RGB_BACKGROUND",
    "RGB_OCCUPIED",
    "RGB_UNKNOWN",
    "label_colours",
    "load_label_map_server",
    "render_labels",
    "save_label_map_server",
    "save_label_png",
]

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


def label_colours(num_labels: int) -> np.ndarray:
    """``[num_labels, 3]`` uint8 RGB colours, pairwise distinct and deterministic.

    The first 18 are matplotlib's tab20 without its two greys (strong shades first, then the
    light ones); further colours follow a golden-ratio hue sequence at a few saturation/value
    levels. None is black, white or the unknown grey (205, 205, 205) used by
    :func:`render_labels`.
    """
    if not is_integer(num_labels):
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


def render_labels(
    labels: Any, grid: OccupancyGrid | None = None, colours: Any = None
) -> np.ndarray:
    """``[H, W]`` concept labels -> ``[H, W, 3]`` uint8 RGB image.

    Concept ``k >= 0`` gets ``colours[k]`` (``[K, 3]`` uint8 with K > every label; default
    ``label_colours(max + 1)``, or :func:`~spcopyro.maps.palette.concept_colours` for colours a
    reader can tell apart); with a grid, OCCUPIED cells are black and UNKNOWN cells grey (205);
    cells labelled -1 that are free (or every -1 cell when no grid is given) are white. Labels
    >= 0 on non-free cells are an error.
    """
    lab = _check_labels(labels, grid)
    rgb = np.empty((*lab.shape, 3), dtype=np.uint8)  # [H, W, 3]
    rgb[...] = RGB_BACKGROUND
    if grid is not None:
        rgb[grid.occupancy == OCCUPIED] = RGB_OCCUPIED
        rgb[grid.occupancy == UNKNOWN] = RGB_UNKNOWN
    labelled = lab >= 0  # [H, W] bool
    if labelled.any():
        if colours is None:
            colours = label_colours(int(lab.max()) + 1)  # [K, 3]
        colours = np.asarray(colours)
        if colours.ndim != 2 or colours.shape[1] != 3 or colours.shape[0] <= lab.max():
            raise ValueError(
                f"colours must be [K, 3] with K > {int(lab.max())} (the largest label), got "
                f"shape {colours.shape}"
            )
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
    ascending order, get the grey values 1, 2, ..., 99, 101, ..., 254 (253 available; Nav2's
    map_server publishes a raw value above 100 as unknown, so a ROS node sees only the first 99
    concepts, and a warning says so when there are more). The json
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
    if concepts.size > RAW_OCCUPIED - 1:
        logger.warning(
            "%s: %d distinct concepts; the grey values of all but the first %d (concepts %s, "
            "...) are above 100, which Nav2's map_server (mode: raw) publishes as unknown (-1): "
            "load_label_map_server reads them back, a ROS node subscribing to the map does not",
            yaml_path, concepts.size, RAW_OCCUPIED - 1, concepts[RAW_OCCUPIED - 1],
        )  # fmt: skip
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
    spec = read_map_yaml(yaml_path, accepts=("raw",))
    if spec.mode != "raw" or spec.negate:
        raise MapFormatError(
            f"{spec.where('mode' if spec.mode != 'raw' else 'negate')}: a semantic map needs "
            f"'mode: raw' and 'negate: 0', got mode "
            f"{spec.shown_mode()}, negate {spec.shown_negate()}"
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
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} must be single-channel, got shape "
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
