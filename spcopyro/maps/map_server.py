"""ROS map_server files: loading a map (yaml + image) as an occupancy grid, and saving one.

Loading (:func:`load_map`) follows map_server's trinary mode: with the pixel value ``v`` (the mean
over all channels for colour images, alpha included, as map_server does in trinary mode) the
occupancy probability is ``p = (255 - v) / 255`` (``negate: 0``) or ``p = v / 255``
(``negate: 1``); ``p > occupied_thresh`` is OCCUPIED, ``p < free_thresh`` is FREE and anything
else (including values exactly at a threshold) is UNKNOWN. ``negate`` may also be a yaml-cpp
boolean (``true``, ``"yes"``, ``y``...), which Nav2's map_io reads when an int does not parse
(ROS 1's map_server wants 0 or 1). Equal thresholds are read as map_server reads them (map_io
checks no order on loading); a ``free_thresh`` above ``occupied_thresh`` is refused as swapped
(map_server would read every cell free or occupied, occupied first). ``mode: scale`` and
``mode: raw`` are rejected with a clear error, because they produce values outside the three
codes; semantic maps written by :func:`~spcopyro.maps.render.save_label_map_server`
(``mode: raw``) are read back with :func:`~spcopyro.maps.render.load_label_map_server`.

This is the only module of the package that reads or writes image and yaml files (OpenCV,
PyYAML), imported where a file is read or written: every command, ``--help`` too, imports this.
"""

from __future__ import annotations

import difflib
import functools
import logging
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spcopyro._util.messages import echo
from spcopyro.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

logger = logging.getLogger(__name__)

__all__ = [
    "MAX_MAP_COORDINATE", "PGM_FREE", "PGM_OCCUPIED", "PGM_UNKNOWN", "SAVE_FREE_THRESH",
    "SAVE_OCCUPIED_THRESH", "MapFileNotFoundError", "MapFormatError", "load_map", "save_map",
    "trinary_pixels",
]  # fmt: skip

# Pixel values written by save_map (those of map_server's map_saver).
PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN = 254, 0, 205
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196

_REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_KNOWN_KEYS = (*_REQUIRED_KEYS, "mode")

MAX_YAW_NOISE = 1e-6
"""Radians: an origin yaw this small is read as 0 (a quaternion's float noise, as a mapping
package may save it): it turns a cell 1 km from the origin by 1 mm. A larger yaw is refused
(rotated maps are not supported)."""

MAX_MAP_COORDINATE = 1e6
"""Metres: :func:`load_map` refuses a map that lies wholly farther than this from its frame's
origin along x or y, since the data loader refuses every position there
(``spcopyro.data.dataset.MAX_COORDINATE``, a guard against unit errors): a house simulated or
recorded on such a map (an origin in UTM coordinates) could not be fitted."""


PLAUSIBLE_RESOLUTION = (1e-3, 2.0)
"""Metres: :func:`load_map` warns of a ``resolution`` outside this range, naming the yaml's line
and the value: a cell wider than 2 m holds a room (a fit's coarse model cells, ``--cell-size``,
may be 1 or 2 m; its map.yaml loads without a word), and a robot's map is usually 0.05 m a cell
(one of 50 or 5 is 0.05 written in millimetres or centimetres)."""


class MapFormatError(ValueError):
    """A map yaml or image is malformed; the message names the file (and the key and value)."""


class MapFileNotFoundError(MapFormatError, FileNotFoundError):
    """A map yaml or the image it names does not exist."""


# ---------------------------------------------------------------------- yaml parsing
@functools.cache
def _map_yaml_loader() -> type:
    """PyYAML's safe loader, also reading ``5e-2`` and ``1E3`` as floats (YAML 1.2, yaml-cpp and
    so map_server do; YAML 1.1 wants a dot, so PyYAML reads them as strings)."""
    import yaml

    loader = type("_MapYamlLoader", (yaml.SafeLoader,), {})
    loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
        list("-+0123456789."),
    )
    return loader


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
    lines: dict[str, int] = field(default_factory=dict, compare=False)
    """Line of each key in the yaml (1-based)."""

    def where(self, key: str) -> str:
        """``YAML:LINE`` of ``key``, or the yaml alone where the key is absent."""
        return f"{self.path}:{self.lines[key]}" if key in self.lines else str(self.path)


def _close_key(key: Any) -> str | None:
    """The map_server key that ``key``, not one of them, looks like a misspelling of
    (``mdoe``, ``Mode``, ``occupied_tresh``), or None."""
    close = difflib.get_close_matches(str(key).lower(), _KNOWN_KEYS, n=1, cutoff=0.75)
    return close[0] if close else None


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_nan(value: Any) -> bool:
    """``nan``, ``-nan``, ``.nan`` (any case) as yaml reads them: a float nan or the text."""
    if isinstance(value, float):
        return math.isnan(value)
    return isinstance(value, str) and value.strip().lstrip("+-").lower() in ("nan", ".nan")


_QUOTED_NUMBER = re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?$")


def _unquoted(value: Any) -> Any:
    """A quoted number (``resolution: "0.05"``) as the number: map_server reads values with
    yaml-cpp's ``as<double>()`` / ``as<int>()``, which convert a scalar's text whether or not it
    was quoted. Anything else unchanged (and refused by the checks that follow)."""
    if isinstance(value, str) and _QUOTED_NUMBER.match(value):
        number = float(value)
        return int(number) if re.fullmatch(r"[-+]?[0-9]+", value) else number
    return value


_YAML_CPP_BOOLS = {
    text: word in ("y", "yes", "true", "on")
    for word in ("y", "yes", "true", "on", "n", "no", "false", "off")
    for text in (word, word.upper(), word.capitalize())
}
"""The texts yaml-cpp's ``as<bool>()`` reads (quoted or not): Nav2's map_io reads ``negate`` as
an int, else as a bool, so ``negate: "true"`` or ``negate: y`` (a string to PyYAML) negate there.
(ROS 1's map_server reads only an int: ``negate: true`` fails there.)"""


_SEPARATING_TABS = re.compile(r"(?<=[:,\[\]])[ \t]*\t[ \t]*|[ \t]*\t[ \t]*(?=#|$)", re.MULTILINE)
"""Runs of blanks holding a tab after a key's or a flow list's separator, or before a comment or
a line's end: white space to yaml-cpp, an error to PyYAML (tabs that indent are not YAML)."""


def _parse_yaml(text: str) -> tuple[Any, Any]:
    """(the root node, the document) of a map yaml; yaml.YAMLError if it does not parse."""
    import yaml

    return yaml.compose(text, Loader=_map_yaml_loader()), yaml.load(text, Loader=_map_yaml_loader())


def _read_map_yaml(yaml_path: str | os.PathLike) -> _MapYaml:
    """Parse and validate a map_server yaml; errors name the file, line, key and value."""
    import yaml

    path = Path(yaml_path)
    if not path.is_file():
        raise MapFileNotFoundError(f"{path}: map yaml not found")
    if path.suffix.lower() in (".pgm", ".png", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff"):
        raise MapFormatError(f"{path}: the map's image; give its yaml (the file that names "
                             "this image, its resolution and origin)")  # fmt: skip
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise MapFormatError(f"{path}: cannot read map yaml: {err}") from err
    try:
        root, doc = _parse_yaml(text)
    except yaml.YAMLError as err:
        untabbed = _SEPARATING_TABS.sub(lambda m: m.group().replace("\t", " "), text)
        try:  # PyYAML refuses a tab after "key:", which yaml-cpp (map_server) reads as a space
            root, doc = _parse_yaml(untabbed)
        except yaml.YAMLError:
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
                f"{path}:{key_node.start_mark.line + 1}: duplicate key {echo(key)} "
                f"(first at line {lines[key]})"
            )
        lines[key] = key_node.start_mark.line + 1

    def where(key: str) -> str:
        return f"{path}:{lines[key]}" if key in lines else str(path)

    misspelt = {
        key: close
        for key in doc
        if key not in _KNOWN_KEYS and (close := _close_key(key)) is not None
    }
    for key in _REQUIRED_KEYS:
        if key not in doc:
            typo = [f"{where(k)} has {echo(k)}" for k, close in misspelt.items() if close == key]
            hint = f" ({', '.join(typo)}: misspelt?)" if typo else ""
            raise MapFormatError(f"{path}: missing required key {key!r}{hint}")
    for key, close in misspelt.items():
        logger.warning(
            "%s: unknown key %s ignored, as map_server ignores it: did you mean %r?",
            where(key), echo(key), close,
        )  # fmt: skip

    for key in ("resolution", "negate", "occupied_thresh", "free_thresh"):
        doc[key] = _unquoted(doc[key])
    if isinstance(doc["origin"], list):
        doc["origin"] = [_unquoted(v) for v in doc["origin"]]

    def bad(key: str, expected: str) -> MapFormatError:
        return MapFormatError(f"{where(key)}: key {key!r} must be {expected}, got {echo(doc[key])}")

    resolution = doc["resolution"]
    if not _is_number(resolution) or not (math.isfinite(resolution) and resolution > 0):
        raise bad("resolution", "a positive finite number")
    low, high = PLAUSIBLE_RESOLUTION
    if not low <= resolution <= high:
        logger.warning(
            "%s: key 'resolution' %s: cells of %s m%s (a robot's map is usually 0.05 m a cell): "
            "is it written in %s?",
            where("resolution"), echo(resolution), f"{resolution:g}",
            f", wider than {high:g} m, would hold whole rooms" if resolution > high
            else f", narrower than {low:g} m, make a house a few centimetres across",
            "millimetres or centimetres" if resolution > high else "kilometres",
        )  # fmt: skip

    origin = doc["origin"]
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(_is_number(v) and math.isfinite(v) for v in origin)
    ):
        error = bad("origin", "a list of 3 finite numbers [x, y, yaw]")
        if isinstance(origin, list) and len(origin) == 3 and _is_nan(origin[2]):
            error = MapFormatError(
                f"{error}: ROS 1's map_saver writes a yaw of nan for a map published with an "
                "invalid (zero) orientation quaternion, as some mapping packages do; "
                "map_server refuses it too: the map is not rotated, write 0"
            )
        raise error
    if abs(origin[2]) > MAX_YAW_NOISE:
        raise MapFormatError(
            f"{where('origin')}: key 'origin' has yaw {echo(origin[2])}; rotated maps are not "
            "supported (yaw must be 0)"
        )

    negate = doc["negate"]
    negate = _YAML_CPP_BOOLS.get(negate, negate) if isinstance(negate, str) else negate
    if not isinstance(negate, (int, bool)) or negate not in (0, 1):
        raise bad("negate", "0 or 1 (or true / false)")

    for key in ("occupied_thresh", "free_thresh"):
        value = doc[key]
        if not _is_number(value) or not 0.0 <= value <= 1.0:
            raise bad(key, "a number in [0, 1]")
    if doc["free_thresh"] > doc["occupied_thresh"]:  # equal: map_server reads them (module doc)
        raise MapFormatError(
            f"{where('free_thresh')}: key 'free_thresh' ({echo(doc['free_thresh'])}) must not "
            f"exceed 'occupied_thresh' ({echo(doc['occupied_thresh'])}): swapped?"
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
        origin=(float(origin[0]), float(origin[1]), 0.0),  # yaw: 0 or noise (MAX_YAW_NOISE)
        negate=bool(negate),
        occupied_thresh=float(doc["occupied_thresh"]),
        free_thresh=float(doc["free_thresh"]),
        mode=mode,
        lines=dict(lines),
    )


def _pnm_maxval(head: bytes) -> int | None:
    """The maxval of a grey or colour netpbm image (P2, P3, P5, P6) from its first bytes, or None
    (another format, or a header that does not parse)."""
    if head[:2] not in (b"P2", b"P3", b"P5", b"P6"):
        return None
    tokens = re.sub(rb"#[^\n\r]*", b" ", head[2:]).split()  # width, height, maxval
    return int(tokens[2]) if len(tokens) > 2 and tokens[2].isdigit() else None


def _decode(spec: _MapYaml) -> tuple[np.ndarray, int | None]:
    """The map image as OpenCV decodes it (any depth, OpenCV channel order) and, for a netpbm
    image, the maxval its header gives (None for other formats)."""
    if not spec.image.is_file():  # a hint where map_saver's path is wrong but the image is here
        beside = spec.path.parent / spec.image.name
        hint = (
            f"; {str(beside)!r}, beside the yaml, has its name: map_saver writes the path it "
            "was given (-f, map_url), which breaks when the map moves or that path has a "
            f"folder (map_server fails too): write image: {spec.image.name}"
            if beside.is_file()
            else ""
        )
        raise MapFileNotFoundError(
            f"{spec.where('image')}: key 'image': image file {str(spec.image)!r} not found{hint}"
        )
    import cv2

    data = np.fromfile(spec.image, dtype=np.uint8)
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # the error below says it
    try:
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': {str(spec.image)!r} is not a readable image"
        )
    if img.ndim not in (2, 3) or img.shape[0] == 0 or img.shape[1] == 0:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} has unsupported shape {img.shape}"
        )
    maxval = _pnm_maxval(data[:4096].tobytes())
    if maxval is not None and maxval < 255 and data[:2].tobytes() in (b"P2", b"P3"):
        img = _plain_pnm_levels(spec, data.tobytes(), img.shape)
    return img, maxval


def _plain_pnm_levels(spec: _MapYaml, text: bytes, shape: tuple[int, ...]) -> np.ndarray:
    """A plain (ASCII) P2 / P3 image's own levels, uint8 of OpenCV's ``shape`` (a P3 in its
    BGR order): for a maxval below 255 OpenCV returns them scaled up to 0..255 (those of a binary
    P5 / P6 it leaves as they are), which map_server's division by maxval would count twice."""
    tokens = re.sub(rb"#[^\n\r]*", b" ", text[2:]).split()  # width, height, maxval, levels
    count, maxval = math.prod(shape), int(tokens[2])
    words = tokens[3 : 3 + count]
    levels = [int(t) if t.isdigit() else -1 for t in words]
    bad = next((t for t, v in zip(words, levels, strict=True) if not 0 <= v <= maxval), None)
    if bad is not None:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': {str(spec.image)!r}: level "
            f"{echo(bad.decode(errors='replace'))} is not in 0..{maxval}"
        )
    if len(levels) != count:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': {str(spec.image)!r} holds {len(levels)} "
            f"levels, its header {count}"
        )
    levels = np.array(levels, dtype=np.uint8).reshape(shape)  # [H, W] or [H, W, 3]
    return levels[..., ::-1].copy() if levels.ndim == 3 else levels  # RGB -> OpenCV's BGR


def _read_image(spec: _MapYaml) -> np.ndarray:
    """The map image as uint8 ``[H, W]`` (grey) or ``[H, W, C]`` (colour, OpenCV channel order):
    the readers of masks and semantic maps, whose values are 8-bit codes."""
    img, maxval = _decode(spec)
    if img.dtype == np.uint8 and maxval not in (None, 255):
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} has maxval {maxval}; only 255 is "
            "supported here (map_server scales the pixels by maxval, OpenCV does not: "
            "save the image with maxval 255)"
        )
    if img.dtype != np.uint8:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} has {img.dtype} pixels; only 8-bit "
            "images are supported here"
        )
    return img


def _read_levels(spec: _MapYaml) -> tuple[np.ndarray, float]:
    """The map image's pixels (``[H, W]`` or ``[H, W, C]`` float64) and the full scale map_server
    divides them by: a netpbm image's maxval (any, 8 or 16 bits), else 255 for 8-bit and 65535
    for 16-bit images (a 16-bit png); other depths are refused."""
    img, maxval = _decode(spec)
    if img.dtype not in (np.uint8, np.uint16):
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} has {img.dtype} pixels; only 8- and "
            "16-bit images are supported"
        )
    full = maxval if maxval is not None else 255 if img.dtype == np.uint8 else 65535
    if not 0 < full <= np.iinfo(img.dtype).max:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} has maxval {full}, which its "
            f"{img.dtype} pixels cannot hold"
        )
    return img.astype(np.float64), float(full)


def load_map(yaml_path: str | os.PathLike) -> OccupancyGrid:
    """Load a ROS map_server map (yaml + image) as an :class:`OccupancyGrid`.

    Keys (all required, as in map_server): ``image`` (relative to the yaml's folder, or
    absolute), ``resolution``, ``origin`` ``[x, y, yaw]`` (yaw must be 0; one within
    :data:`MAX_YAW_NOISE` reads as 0), ``negate`` (0/1), ``occupied_thresh``, ``free_thresh`` (in
    [0, 1], free <= occupied); optional ``mode`` must be ``trinary`` (the default). Unknown keys
    are ignored, as map_server does. Numbers may be written ``5e-2`` (YAML 1.2, as map_server's
    yaml-cpp reads them).

    Cells: ``v`` = pixel value over the image's full scale (a pgm's maxval; else 255, or 65535
    for a 16-bit png: map_server scales by it), averaged over all channels for colour images;
    ``p = 1 - v`` if ``negate == 0`` else ``v`` (computed as ``(full - pixel) / full``, exactly
    as for 8 bits before); ``p > occupied_thresh`` -> OCCUPIED, ``p < free_thresh`` -> FREE,
    otherwise UNKNOWN.

    Warns (logger ``spcopyro.maps.map_server``, naming the yaml's line): an unknown key that
    looks like a misspelt map_server key (ignored, as map_server does), a ``resolution``
    outside :data:`PLAUSIBLE_RESOLUTION`, and cells of map_saver's unknown grey 205 read as
    FREE (a ``free_thresh`` above 0.196, as Nav2's map_saver writes it, or an alpha channel
    averaged in; in a 16-bit image, the levels whose high byte is 205).

    Raises:
        MapFileNotFoundError: the yaml or its image does not exist.
        MapFormatError: anything malformed; the message names the yaml (with the line where the
            key is), the key and the offending value; also a map lying wholly beyond
            :data:`MAX_MAP_COORDINATE` of its frame's origin.
    """
    spec = _read_map_yaml(yaml_path)
    if spec.mode != "trinary":
        raise MapFormatError(
            f"{spec.where('mode')}: key 'mode': {echo(spec.mode)} is not supported by load_map "
            "(only 'trinary', an occupancy map)"
            + (
                ": a robot's map saved in that mode (map_saver --mode scale, a SLAM's graded "
                "map) reads as one with 'mode: trinary', each pixel against the thresholds"
                if spec.mode == "scale"
                else ""
            )
            + "; a Nav2 costmap filter mask (scale or raw) is read with load_filter_mask, a "
            "semantic map saved by save_label_map_server with load_label_map_server"
        )
    levels, full = _read_levels(spec)  # [H, W] or [H, W, C]
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
    return grid


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


def _write_image(path: Path, img: np.ndarray) -> None:
    import cv2

    ok, buf = cv2.imencode(path.suffix, img)
    if not ok:
        raise OSError(f"{path}: OpenCV could not encode the image")
    path.write_bytes(buf.tobytes())


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
