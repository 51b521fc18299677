r"""Costmap-filter masks: map_server maps whose cells carry a value 0..100, not occupancy.

Nav2's costmap filters (KeepoutFilter, SpeedFilter, ...) read a *filter mask*: an ordinary
map_server map (yaml + image) published as a ``nav_msgs/OccupancyGrid`` whose cell values the
filter decodes as ``filter_value = base + multiplier * mask_value`` (``base`` and ``multiplier``
come from the ``costmap_filter_info_server``). How map_server turns a pixel into a cell value
depends on the yaml's ``mode`` (nav2_map_server ``map_io.cpp``, ``loadMapFromFile``): with
``shade`` the pixel's mean over its colour channels in [0, 1] and ``occ = 1 - shade``
(``negate: 0``) or ``occ = shade`` (``negate: 1``),

* ``trinary``: ``occ > occupied_thresh`` -> 100, ``occ < free_thresh`` -> 0, else -1 (unknown;
  the alpha channel, if any, is averaged in as it is, 255 opaque: map_io pushes
  ``MaxRGB - alphaQuantum()``, GraphicsMagick's opacity, and :func:`~spcopyro.maps.load_map` does
  the same);
* ``scale``: a transparent pixel -> -1; ``occ > occupied_thresh`` -> 100, ``occ < free_thresh``
  -> 0, else ``rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100)`` (equal
  thresholds, which trinary maps may have, are refused: 0/0 at them);
* ``raw``: ``v = round(shade * 255)``; ``v`` if ``0 <= v <= 100``, else -1.

:func:`save_filter_mask` writes masks in ``scale`` mode with ``free_thresh: 0.0`` and
``occupied_thresh: 1.0`` (the Nav2 speed-filter tutorial's choice: the whole lightness range maps
linearly onto 0..100, so darker is a higher value), the pixel of value ``m`` being
``round(255 (100 - m) / 100)``; this reads back exactly as ``m`` (the rounding moves ``occ``
by at most 0.5/255, 0.2 of a step). Scale has no pixel for -1 (no information: a costmap filter
leaves such a cell alone), which a keepout mask needs (Nav2's KeepoutFilter writes a mask's 0
into a costmap cell that has no information, making unknown space free), so with
``mode="trinary"`` it writes the values 100, 0 and -1 as map_saver writes a map (pixels 0, 254, 205;
thresholds 0.65 / 0.196), as the Nav2 keepout tutorial's mask, a copy of the map, has them.
:func:`load_filter_mask` reads any mask the way map_server does, in all three modes. The
image's first row is the map's top (largest world y), as for every map of the package
(:mod:`spcopyro.maps.grid`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spcopyro._util.messages import echo
from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from spcopyro.maps.map_image import _read_image, _write_image
from spcopyro.maps.map_server import (
    SAVE_FREE_THRESH,
    SAVE_OCCUPIED_THRESH,
    _write_map_yaml,
    _yaml_target,
    trinary_pixels,
)
from spcopyro.maps.map_yaml import MapFormatError, read_map_yaml

__all__ = [
    "MASK_FREE_THRESH",
    "MASK_OCCUPIED_THRESH",
    "FilterMask",
    "load_filter_mask",
    "mask_pixels",
    "save_filter_mask",
]

MASK_FREE_THRESH, MASK_OCCUPIED_THRESH = 0.0, 1.0
"""Thresholds of the masks written by :func:`save_filter_mask` (``mode: scale``)."""


@dataclass(frozen=True)
class FilterMask:
    """A filter mask as map_server publishes it."""

    values: np.ndarray
    """[H, W] int8 cell values in image row order (row 0 = top): 0..100, -1 unknown."""
    resolution: float
    origin: tuple[float, float, float]
    mode: str
    """The yaml's ``mode``: ``trinary``, ``scale`` or ``raw``."""
    negate: bool
    free_thresh: float
    occupied_thresh: float
    source: Path
    """The yaml."""


def mask_pixels(values: np.ndarray) -> np.ndarray:
    """[H, W] uint8 grey pixels that map_server reads as ``values`` ([H, W] integers in 0..100)
    under ``mode: scale``, ``negate: 0``, thresholds 0.0 / 1.0: ``round(255 (100 - m) / 100)``."""
    m = np.asarray(values)
    if m.dtype.kind not in "iu":
        raise ValueError(f"mask values must be integers, got dtype {m.dtype}")
    if m.size and (m.min() < 0 or m.max() > 100):
        raise ValueError(f"mask values must lie in 0..100, got {int(m.min())}..{int(m.max())}")
    return np.rint(255.0 * (100.0 - m.astype(np.float64)) / 100.0).astype(np.uint8)


def _trinary_pixels(values: np.ndarray) -> np.ndarray:
    """[H, W] uint8 map_saver pixels (254, 0, 205) of ``values`` in {0, 100, -1}."""
    bad = ~np.isin(values, (FREE, OCCUPIED, UNKNOWN))
    if bad.any():
        raise ValueError(f"a trinary mask holds 0, 100 and -1 only, got {int(values[bad].flat[0])}")
    return trinary_pixels(values)


def save_filter_mask(
    values: np.ndarray,
    grid: OccupancyGrid,
    yaml_path: str | os.PathLike[str],
    mode: str = "scale",
) -> Path:
    """Write ``values`` ([H, W] integers, image row order) as ``NAME.pgm`` + ``NAME.yaml`` with
    ``grid``'s resolution and origin and ``negate: 0``: ``mode`` ``"scale"`` (values 0..100,
    ``free_thresh: 0.0``, ``occupied_thresh: 1.0``) or ``"trinary"`` (values 0, 100 and -1, no
    information; map_saver's pixels and thresholds: module docstring); returns the yaml path."""
    values = np.asarray(values)
    if values.shape != tuple(grid.shape):
        raise ValueError(f"mask of shape {values.shape} for a map of shape {tuple(grid.shape)}")
    if mode == "scale":
        pixels, thresholds = mask_pixels(values), (MASK_FREE_THRESH, MASK_OCCUPIED_THRESH)
    elif mode == "trinary":
        pixels, thresholds = _trinary_pixels(values), (SAVE_FREE_THRESH, SAVE_OCCUPIED_THRESH)
    else:
        raise ValueError(f"mode must be 'scale' or 'trinary', got {mode!r}")
    path = _yaml_target(yaml_path)
    image = path.with_suffix(".pgm")
    _write_image(image, pixels)
    _write_map_yaml(path, image, grid, mode=mode, thresholds=thresholds)
    return path


def load_filter_mask(yaml_path: str | os.PathLike[str]) -> FilterMask:
    """Read a map_server map as the ``OccupancyGrid`` data map_server publishes for it (module
    docstring: ``trinary``, ``scale`` and ``raw`` modes, ``negate``, alpha), image row order.

    Raises:
        MapFileNotFoundError, MapFormatError: as :func:`spcopyro.maps.load_map`.
    """
    spec = read_map_yaml(yaml_path)
    if spec.mode == "scale" and spec.free_thresh == spec.occupied_thresh:
        raise MapFormatError(
            f"{spec.where('free_thresh')}: key 'free_thresh' {echo(spec.free_thresh)} equals "
            f"'occupied_thresh' ({spec.where('occupied_thresh')}): mode 'scale' divides by "
            "their difference (map_server's value of a pixel at them is undefined)"
        )
    if spec.mode == "scale" and spec.free_thresh == -math.inf:  # occupied_thresh is above it
        raise MapFormatError(
            f"{spec.where('free_thresh')}: key 'free_thresh' {echo(spec.free_thresh)} with "
            f"'occupied_thresh' {echo(spec.occupied_thresh)} ({spec.where('occupied_thresh')}): "
            "mode 'scale' gives a pixel between them (occ - free_thresh) / (occupied_thresh - "
            "free_thresh) = inf / inf, no value"
        )
    img = _read_image(spec)  # [H, W] or [H, W, C] uint8
    has_alpha = img.ndim == 3 and img.shape[2] in (2, 4)
    if img.ndim == 2:
        colour = img.astype(np.float64)[..., None]  # [H, W, 1]
    else:
        colour = img[..., : img.shape[2] - 1 if has_alpha else img.shape[2]].astype(np.float64)
    alpha = img[..., -1] if has_alpha else np.full(img.shape[:2], 255, dtype=np.uint8)  # [H, W]
    if spec.mode == "trinary" and has_alpha:
        colour = np.concatenate([colour, alpha[..., None].astype(np.float64)], axis=2)
    shade = colour.mean(axis=2) / 255.0  # [H, W]
    occ = shade if spec.negate else 1.0 - shade  # [H, W]
    values = np.empty(shade.shape, dtype=np.int8)  # [H, W]
    if spec.mode == "raw":
        v = np.round(shade * 255.0)
        values[:] = np.where((v >= 0) & (v <= 100), v, -1)
    elif spec.mode == "trinary":
        values[:] = -1
        values[occ < spec.free_thresh] = 0
        values[occ > spec.occupied_thresh] = 100
    else:  # scale
        span = spec.occupied_thresh - spec.free_thresh
        values[:] = np.rint((occ - spec.free_thresh) / span * 100.0).clip(0, 100)
        values[occ < spec.free_thresh] = 0
        values[occ > spec.occupied_thresh] = 100
        values[alpha != 255] = -1
    return FilterMask(
        values=values,
        resolution=spec.resolution,
        origin=spec.origin,
        mode=spec.mode,
        negate=spec.negate,
        free_thresh=spec.free_thresh,
        occupied_thresh=spec.occupied_thresh,
        source=spec.path,
    )
