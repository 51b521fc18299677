"""ROS map_server files: loading a map (yaml + image) as an occupancy grid, and saving one.

Loading (:func:`load_map`) follows map_server's trinary mode: with the pixel value ``v`` (the mean
over all channels for colour images, alpha included, as map_server does in trinary mode) the
occupancy probability is ``p = (255 - v) / 255`` (``negate: 0``) or ``p = v / 255`` (``negate``
nonzero); ``p > occupied_thresh`` is OCCUPIED, ``p < free_thresh`` is FREE and anything else
(including values exactly at a threshold) is UNKNOWN.

The yaml's values are read as ROS reads them (ROS 1's map_server ``main.cpp`` /
``image_loader.cpp``, Nav2's ``map_io.cpp`` ``loadMapYaml``, both with yaml-cpp). ``negate`` is
read as an int (C++ ``int``, prefix ``0x`` hex, a leading 0 octal, quoted or not), which both hand
on as a C++ bool: 0 keeps white free, **any other integer** (``2``, ``-1``) negates; Nav2 also
reads a yaml-cpp boolean (``true``, ``"yes"``, ``y``, ``Off``...) where an int does not parse (ROS
1 refuses it, spcopyro reads it as Nav2 does). A float (``1.0``), ``1_000``, ``09`` or an integer
beyond C++'s ``int`` parse as neither and are refused, as both refuse them. The thresholds are any
numbers, as both read them (neither checks a range on loading; ``p`` lies in [0, 1], so a threshold
outside it reads as 0 or 1): one outside [0, 1] (every pixel or none occupied or free; ``65`` a
percentage?) loads with a warning naming its line. Refused, as making the map meaningless: a
``nan`` threshold (every comparison with it false) and a ``free_thresh`` above ``occupied_thresh``
(swapped: map_server would read every cell free or occupied, occupied first); equal thresholds are
read as map_server reads them (map_io checks no order on loading).

``mode: scale`` and ``mode: raw`` are rejected with a clear error, because they produce values
outside the three codes; semantic maps written by
:func:`~spcopyro.maps.render.save_label_map_server` (``mode: raw``) are read back with
:func:`~spcopyro.maps.render.load_label_map_server`.

This module, :mod:`~spcopyro.maps.map_yaml` (the yaml's keys, parsed and checked) and
:mod:`~spcopyro.maps.map_image` (the image, decoded at its full scale) are the only modules of the
package that read or write image and yaml files (OpenCV, PyYAML), imported where a file is read
or written: every command, ``--help`` too, imports this.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from spcopyro._util.interrupts import remove_tree
from spcopyro._util.messages import echo
from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from spcopyro.maps.map_image import _read_levels, _write_image
from spcopyro.maps.map_yaml import (
    MapFileNotFoundError,
    MapFormatError,
    _MapYaml,
    logger,  # this module's name, its filter shows bytes as \xe9
    read_map_yaml,
)

__all__ = [
    "MAX_MAP_COORDINATE", "PGM_FREE", "PGM_OCCUPIED", "PGM_UNKNOWN", "SAVE_FREE_THRESH",
    "SAVE_OCCUPIED_THRESH", "MapFileNotFoundError", "MapFormatError", "load_map",
    "read_occupancy_yaml", "save_map", "trinary_pixels",
]  # fmt: skip

# Pixel values written by save_map (those of map_server's map_saver).
PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN = 254, 0, 205
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196

MAX_MAP_COORDINATE = 1e6
"""Metres: :func:`load_map` refuses a map that lies wholly farther than this from its frame's
origin along x or y, since the data loader refuses every position there
(``spcopyro.data.dataset.MAX_COORDINATE``, a guard against unit errors): a house simulated or
recorded on such a map (an origin in UTM coordinates) could not be fitted."""


def load_map(yaml_path: str | os.PathLike) -> OccupancyGrid:
    """Load a ROS map_server map (yaml + image) as an :class:`OccupancyGrid`.

    Keys (all required, as in map_server): ``image`` (relative to the yaml's folder, or absolute),
    ``resolution``, ``origin`` ``[x, y, yaw]`` (yaw must be 0; one within
    :data:`~spcopyro.maps.map_yaml.MAX_YAW_NOISE` reads as 0), ``negate`` (an integer, any nonzero
    one negating, or a boolean), ``occupied_thresh``, ``free_thresh`` (numbers, not nan, free <=
    occupied; one outside [0, 1] warned of), read as ROS reads them (module docstring); optional
    ``mode`` must be ``trinary`` (the default). Unknown keys are ignored, as map_server does.
    Numbers may be written ``5e-2`` (YAML 1.2, as map_server's yaml-cpp reads them).

    Cells: ``v`` = pixel value over the image's full scale (a pgm's maxval; else 255, or 65535
    for a 16-bit png: map_server scales by it), averaged over all channels for colour images;
    ``p = 1 - v`` if ``negate == 0`` else ``v`` (computed as ``(full - pixel) / full``, exactly
    as for 8 bits before); ``p > occupied_thresh`` -> OCCUPIED, ``p < free_thresh`` -> FREE,
    otherwise UNKNOWN.

    Warns (logger ``spcopyro.maps.map_server``, naming the yaml's line): an unknown key that
    looks like a misspelt map_server key (ignored, as map_server does), a ``resolution``
    outside :data:`~spcopyro.maps.map_yaml.PLAUSIBLE_RESOLUTION`, and cells of map_saver's
    unknown grey 205 read as FREE (a ``free_thresh`` above 0.196, as Nav2's map_saver writes
    it, or an alpha channel averaged in; in a 16-bit image, the levels whose high byte is 205).

    Raises:
        MapFileNotFoundError: the yaml or its image does not exist.
        MapFormatError: anything malformed; the message names the yaml (with the line where the
            key is), the key and the offending value; also a map lying wholly beyond
            :data:`MAX_MAP_COORDINATE` of its frame's origin.
    """
    spec = read_occupancy_yaml(yaml_path)
    levels, full, jpeg = _read_levels(spec)  # [H, W] or [H, W, C]
    value, p = _occupancy(levels, full, spec.negate)  # [H, W] each
    occupancy = np.full(p.shape, UNKNOWN, dtype=np.int8)  # [H, W]
    occupancy[p > spec.occupied_thresh] = OCCUPIED
    occupancy[p < spec.free_thresh] = FREE
    grid = OccupancyGrid(occupancy, spec.resolution, spec.origin, source=spec.path)
    _check_extent(spec, grid)
    if not spec.negate:
        alpha = levels.ndim == 3 and levels.shape[2] in (2, 4)
        grey = levels[..., :-1].mean(axis=2) if alpha else value  # [H, W] alpha left out
        unknown = _unknown_grey(grey, full) & grid.free  # [H, W] bool
        _warn_unknown_read_as_free(spec, int(np.count_nonzero(unknown)), alpha, full)
    if jpeg and full == 255:
        _warn_lossy(spec, value, occupancy)
    return grid


def _warn_lossy(spec: _MapYaml, grey: np.ndarray, occupancy: np.ndarray) -> None:
    """Warn of a JPEG map image (8-bit; the decoder saw its magic bytes): its compression moves
    greys off map_saver's 0, 205 and 254 (a 205 beside free space turned 206 reads free), and
    map_server reads them as they are; say how many pixels moved and how the ones near the
    unknown grey read. ``grey`` ``[H, W]``."""
    kept = np.isin(grey, (PGM_OCCUPIED, PGM_UNKNOWN, PGM_FREE, 255))  # [H, W] bool
    moved = int(np.count_nonzero(~kept))
    if not moved:
        return
    near = ~kept & (np.abs(grey - PGM_UNKNOWN) <= 10)  # [H, W] bool: an unknown 205, moved?
    freed = int(np.count_nonzero(near & (occupancy == FREE)))
    logger.warning(
        "%s: key 'image': %r is a JPEG, whose lossy compression moves greys: %d pixels are none "
        "of map_saver's greys (0, 205, 254), %d of them within 10 of the unknown grey 205, and "
        "%d of those read free (map_server reads them the same): save the map as pgm or png",
        spec.where("image"), str(spec.image), moved, int(np.count_nonzero(near)), freed,
    )  # fmt: skip


_LOADERS = (
    "a Nav2 costmap filter mask (scale or raw) is read with load_filter_mask, a semantic map "
    "saved by save_label_map_server with load_label_map_server"
)
"""The end of :func:`read_occupancy_yaml`'s refusal of a mode: the loaders that read the other
modes' maps."""


def read_occupancy_yaml(yaml_path: str | os.PathLike, others: str = _LOADERS) -> _MapYaml:
    """The yaml of ``yaml_path`` read and refused as :func:`load_map` reads and refuses it, its
    ``mode`` included (only ``trinary``), without its image. The refusal of a mode says the mode
    and, for ``scale``, how a robot's map saved so reads (shared), then ``others``: by default
    the loaders of the other modes' maps; a study's map source is read here with an ending of
    its own (:func:`spcopyro.study.sources.resolve_source`: those loaders read no map source)."""
    spec = read_map_yaml(yaml_path, accepts=("trinary",))
    if spec.mode != "trinary":  # raw pixels are cell values (0..100): no trinary reading of them
        raise MapFormatError(
            f"{spec.where('mode')}: key 'mode': {spec.shown_mode()} is not supported by load_map "
            "(only 'trinary', an occupancy map)"
            + (
                ": a robot's map saved in scale mode (map_saver --mode scale, a SLAM's graded "
                "map) is an occupancy map: write 'mode: trinary' in its yaml (or leave the key "
                "out, trinary is map_server's default) and each pixel is read against its "
                "occupied_thresh / free_thresh"
                if spec.mode == "scale"
                else ""
            )
            + f"; {others}"
        )
    return spec


def _occupancy(levels: np.ndarray, full: float, negate: bool) -> tuple[np.ndarray, np.ndarray]:
    """(``[H, W]`` grey, averaged over a colour image's channels; ``[H, W]`` occupancy ``p``)."""
    grey = levels if levels.ndim == 2 else levels.mean(axis=2)  # [H, W]
    return grey, grey / full if negate else (full - grey) / full


def _unknown_grey(grey: np.ndarray, full: float) -> np.ndarray:
    """``[H, W]`` bool: pixels of map_saver's unknown grey :data:`PGM_UNKNOWN` -- exactly 205
    in an 8-bit image; in another full scale (a 16-bit pgm or png), those whose level read at 8
    bits (its high byte at 16 bits) is 205: a 205 scaled up by 257 (52685) or by 256 (52480)."""
    if full == 255:
        return grey == PGM_UNKNOWN
    return np.floor(grey * 256.0 / (full + 1.0)) == PGM_UNKNOWN


def _check_extent(spec: _MapYaml, grid: OccupancyGrid) -> None:
    """Refuse a map lying wholly beyond :data:`MAX_MAP_COORDINATE` along x or y."""
    ox, oy, _ = grid.origin
    spans = ((ox, ox + grid.width * grid.resolution), (oy, oy + grid.height * grid.resolution))
    nearest = [0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi)) for lo, hi in spans]
    if max(nearest) > MAX_MAP_COORDINATE:
        (x0, x1), (y0, y1) = spans
        raise MapFormatError(
            f"{spec.where('origin')}: key 'origin' {echo(list(spec.origin))}: the map spans "
            f"x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f} m, wholly farther than "
            f"{MAX_MAP_COORDINATE:g} m from its frame's origin, where spcopyro refuses "
            "positions (a guard against unit errors): give the map and the positions in a "
            "local frame (subtract an offset, e.g. of UTM coordinates)"
        )


def _warn_unknown_read_as_free(spec: _MapYaml, count: int, alpha: bool, full: float) -> None:
    """Warn that ``count`` pixels of map_saver's unknown grey (205; at another full scale
    ``full``, :func:`_unknown_grey`) read as FREE: an alpha channel (map_server's trinary mode
    averages it in, so an opaque 205 reads as 217.5), a ``free_thresh`` above 50/255 (Nav2's
    map_saver writes 0.25 by default, so a map it saved reloads with its unexplored space free,
    in map_server as here), or a 16-bit grey lighter than 205 x 257."""
    if not count:
        return
    scaled = round(PGM_UNKNOWN * full / 255)  # 205 at the image's full scale
    key = "image"
    if alpha:
        why = ("the image has an alpha channel, which map_server's trinary mode averages in: "
               "save it without alpha")  # fmt: skip
    elif spec.free_thresh > (255 - PGM_UNKNOWN) / 255:
        key = "free_thresh"
        why = (f"free_thresh {echo(spec.free_thresh)} is above (255 - {PGM_UNKNOWN}) / 255 = "
               f"{(255 - PGM_UNKNOWN) / 255:.4f}, as Nav2's map_saver writes it (0.25): set "
               f"free_thresh: {SAVE_FREE_THRESH}")  # fmt: skip
    else:
        why = (f"their grey is lighter than {scaled} of {full:g}, 205 of 255 at the image's "
               f"full scale: write unexplored space as {scaled}")  # fmt: skip
    low, high = (math.ceil(level * (full + 1) / 256) for level in (PGM_UNKNOWN, PGM_UNKNOWN + 1))
    grey = f"grey {PGM_UNKNOWN}" if full == 255 else (
        f"grey {PGM_UNKNOWN} read at 8 bits ({low}..{high - 1} of {full:g})"
    )  # fmt: skip
    logger.warning(
        "%s: %d cells of %s, map_saver's unknown, read as free space, as map_server reads "
        "them; if they are unexplored: %s",
        spec.where(key), count, grey, why,
    )  # fmt: skip


# ---------------------------------------------------------------------- writing
def _yaml_target(yaml_path: str | os.PathLike) -> Path:
    path = Path(yaml_path)
    if path.suffix not in (".yaml", ".yml"):
        raise ValueError(f"{path}: a map yaml path must end in .yaml or .yml")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _write_map_yaml(
    path: Path,
    image: Path,
    grid: OccupancyGrid,
    mode: str | None,
    thresholds: tuple[float, float] = (SAVE_FREE_THRESH, SAVE_OCCUPIED_THRESH),
) -> None:
    """The map yaml of ``image``; ``thresholds`` are (free_thresh, occupied_thresh)."""
    doc: dict[str, Any] = {
        "image": image.name,
        "resolution": grid.resolution,
        "origin": list(grid.origin),
        "negate": 0,
        "occupied_thresh": float(thresholds[1]),
        "free_thresh": float(thresholds[0]),
    }
    if mode is not None:
        doc["mode"] = mode
    import yaml

    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None), encoding="utf-8")


def trinary_pixels(values: np.ndarray) -> np.ndarray:
    """``[H, W]`` uint8 map_saver pixels of occupancy ``values`` ``[H, W]``: :data:`PGM_FREE`
    where FREE (0), :data:`PGM_OCCUPIED` where OCCUPIED (100), :data:`PGM_UNKNOWN` elsewhere."""
    pixels = np.full(values.shape, PGM_UNKNOWN, dtype=np.uint8)  # [H, W]
    pixels[values == FREE] = PGM_FREE
    pixels[values == OCCUPIED] = PGM_OCCUPIED
    return pixels


def save_map(grid: OccupancyGrid, yaml_path: str | os.PathLike) -> Path:
    """Write ``grid`` as ``NAME.pgm`` (P5; 254 free, 0 occupied, 205 unknown) + ``NAME.yaml``.

    The yaml has ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196`` and the image
    name relative to its folder, so ``load_map(save_map(grid, path)) == grid``. Returns the yaml
    path.
    """
    path = _yaml_target(yaml_path)
    image = path.with_suffix(".pgm")
    _write_image(image, trinary_pixels(grid.occupancy))
    _write_map_yaml(path, image, grid, mode=None)
    return path


@contextlib.contextmanager
def stage_map(
    grid: OccupancyGrid, yaml_path: str | os.PathLike
) -> Iterator[list[tuple[Path, Path]]]:
    """:func:`save_map` into a staging folder beside ``yaml_path`` (``NAME.yaml.partial-...``:
    :func:`~spcopyro._util.outputs.staging_folder`), for a writer that moves the map in with a
    house folder (:func:`~spcopyro._util.folder_commit.commit_folder`): yields its
    ``(file, target)`` pairs, the ``.pgm`` first, and removes the folder on leaving -- but not
    when a :class:`~spcopyro._util.file_moves.FilesNotMoved` left an old map file in it
    (``stranded``: the error names it). The same bytes as :func:`save_map` at ``yaml_path``."""
    from spcopyro._util.file_moves import FilesNotMoved
    from spcopyro._util.folder_commit import absolute_path  # secrets: not on --help's path
    from spcopyro._util.outputs import staging_folder  # zipfile, secrets: not on --help's path

    target = absolute_path(_yaml_target(yaml_path))
    folder = staging_folder(target)
    image = target.with_suffix(".pgm")
    keep = False
    try:
        save_map(grid, folder / target.name)
        yield [(folder / image.name, image), (folder / target.name, target)]
    except FilesNotMoved as error:
        keep = bool(error.stranded)  # an old map file is still in the folder
        raise
    finally:
        if not keep:  # empty after the commit: its files were moved in
            remove_tree(folder)  # a Ctrl-C meanwhile: that KeyboardInterrupt
