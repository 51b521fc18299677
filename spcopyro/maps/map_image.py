"""ROS map_server images: decoding a map's image (pgm, png, ... at 8 or 16 bits) as map_server
scales it, and encoding one.

``_read_levels`` gives the pixels and the full scale map_server divides them by (a netpbm
image's maxval, else 255, or 65535 for a 16-bit png) and whether it is a JPEG (for
:func:`~spcopyro.maps.load_map`'s warning); ``_read_image`` the 8-bit codes of a
mask or semantic map. Errors name the yaml's ``image`` line and the image file. OpenCV is
imported where an image is read or written, except a map_saver image (a binary 8-bit P5 pgm,
maxval 255), which is read and written here, byte for byte as OpenCV does: a fit of a ROS map or
of the embedded house then skips OpenCV's import (0.03 s of CPU, issue 25's fixed cost).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from spcopyro._util.messages import echo
from spcopyro.maps.map_yaml import MapFileNotFoundError, MapFormatError, _MapYaml

__all__: list[str] = []


def _pnm_maxval(head: bytes) -> int | None:
    """The maxval of a grey or colour netpbm image (P2, P3, P5, P6) from its first bytes, or None
    (another format, or a header that does not parse)."""
    if head[:2] not in (b"P2", b"P3", b"P5", b"P6"):
        return None
    tokens = re.sub(rb"#[^\n\r]*", b" ", head[2:]).split()  # width, height, maxval
    return int(tokens[2]) if len(tokens) > 2 and tokens[2].isdigit() else None


_PNM_GAP = rb"\s(?:\s|#[^\n\r]*)*"  # whitespace, then any whitespace and comments
_PNM_HEADER = re.compile(rb"(P[2356])%s(\d+)%s(\d+)%s(\d+)\s" % ((_PNM_GAP,) * 3))
"""A netpbm image's header (grey or colour, plain or binary) up to its raster: its kind, width,
height, maxval and the one whitespace after it; between the fields whitespace, and comments
(``#`` to the end of the line) after it."""


def _plain_p5(data: np.ndarray) -> np.ndarray | None:
    """The pixels ``[H, W]`` uint8 of a binary pgm of maxval 255 whose raster, after its header
    (:data:`_PNM_HEADER`), is exactly H * W bytes (what OpenCV decodes it to), or None for any
    other image: OpenCV decodes those."""
    match = _PNM_HEADER.match(data[:4096].tobytes())
    if match is None or match[1] != b"P5":
        return None
    width, height = int(match[2]), int(match[3])
    if (
        int(match[4]) != 255
        or width == 0
        or height == 0
        or data.size - match.end() != width * height
    ):
        return None
    return data[match.end() :].reshape(height, width).copy()


def _why_unreadable(data: bytes) -> str:
    """Why OpenCV decodes nothing of an image's bytes ``data``, for the error's end: empty, a
    netpbm image whose raster is shorter than its header says (an interrupted copy or save;
    map_server refuses it too), or, for any other, what it may be."""
    if not data:
        return ": the file is empty (0 bytes)"
    match = _PNM_HEADER.match(data[:4096])
    if match is None:
        return " (damaged, cut short, or a format OpenCV does not read)"
    kind, width, height, maxval = match[1], int(match[2]), int(match[3]), int(match[4])
    channels = 3 if kind in (b"P3", b"P6") else 1
    values = width * height * channels
    if kind in (b"P5", b"P6"):
        need = values * (2 if maxval > 255 else 1)
        held = len(data) - match.end()
        if held < need:
            return (f": cut short, its header gives {width} x {height} pixels of maxval {maxval} "
                    f"({need} bytes after it) but {held} bytes follow it (an interrupted copy "
                    "or save? map_server refuses it too): save the map again")  # fmt: skip
    else:
        held = len(data[match.end() - 1 :].split())
        if held < values:
            return (f": cut short, its header gives {width} x {height} pixels ({values} "
                    f"levels) but {held} follow it (an interrupted copy or save? map_server "
                    "refuses it too): save the map again")  # fmt: skip
    return f" (a {kind.decode()} image of {width} x {height}, maxval {maxval}, damaged)"


def _like_the_image(image: Path, folder: Path) -> str:
    """A hint naming the files in ``image``'s folder, else in the yaml's ``folder``, whose name
    differs from ``image``'s only in case or suffix (``Room.PGM``, ``room.png`` for ``room.pgm``;
    map_server does not look for them), with the ``image:`` to write (relative to ``folder``
    where it is below it), or ""."""
    stem = image.stem.lower()
    for near in dict.fromkeys((image.parent, folder)):
        try:
            files = [p for p in near.iterdir() if p.is_file()]
        except OSError:
            continue
        names = sorted(p.name for p in files if p.suffix.lower() not in (".yaml", ".yml"))
        like = [n for n in names if n.lower() == image.name.lower() or Path(n).stem.lower() == stem]
        if like:
            try:
                write = near.relative_to(folder) / like[0]
            except ValueError:  # an absolute image path elsewhere
                write = near / like[0]
            return (f"; beside {'it' if near == image.parent else 'the yaml'}: "
                    f"{', '.join(repr(n) for n in like[:3])}: write image: {write}?")  # fmt: skip
    return ""


_JPEG_MAGIC = b"\xff\xd8\xff"
"""A JPEG file's first bytes (its format, whatever its suffix)."""


def _decode(spec: _MapYaml) -> tuple[np.ndarray, int | None, bool]:
    """The map image as OpenCV decodes it (any depth, OpenCV channel order), for a netpbm
    image the maxval its header gives (None for other formats), and whether it is a JPEG (its
    magic bytes: a lossy format, which moves map_saver's greys)."""
    if not spec.image.is_file():  # a hint where map_saver's path is wrong but the image is here
        if spec.image.is_dir():  # image: . or a folder's name
            raise MapFormatError(
                f"{spec.where('image')}: key 'image': {str(spec.image)!r} is a folder, not an "
                "image file: name the map's image (pgm, png, ...) in it"
            )
        name = spec.image.name.rsplit("\\", 1)[-1]  # a Windows path's last part
        beside = spec.path.parent / name
        hint = (
            f"; {str(beside)!r}, beside the yaml, has its name: map_saver writes the path it "
            "was given (-f, map_url), which breaks when the map moves or that path has a "
            f"folder (map_server fails too): write image: {name}"
            if beside.is_file()
            else _like_the_image(spec.image.with_name(name), spec.path.parent)
            if name
            else ""
        )
        raise MapFileNotFoundError(
            f"{spec.where('image')}: key 'image': image file {str(spec.image)!r} not found{hint}"
        )
    data = np.fromfile(spec.image, dtype=np.uint8)
    if (img := _plain_p5(data)) is not None:  # map_saver's images, without OpenCV's import
        return img, 255, False
    import cv2

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # the error below says it
    try:
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': {str(spec.image)!r} is not a readable image"
            f"{_why_unreadable(data.tobytes())}"
        )
    if img.ndim not in (2, 3) or img.shape[0] == 0 or img.shape[1] == 0:
        raise MapFormatError(
            f"{spec.where('image')}: key 'image': "
            f"{str(spec.image)!r} has unsupported shape {img.shape}"
        )
    maxval = _pnm_maxval(data[:4096].tobytes())
    if maxval is not None and maxval < 255 and data[:2].tobytes() in (b"P2", b"P3"):
        img = _plain_pnm_levels(spec, data.tobytes(), img.shape)
    return img, maxval, data[:3].tobytes() == _JPEG_MAGIC


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
    img, maxval, _ = _decode(spec)
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


def _read_levels(spec: _MapYaml) -> tuple[np.ndarray, float, bool]:
    """The map image's pixels (``[H, W]`` or ``[H, W, C]`` float64), the full scale map_server
    divides them by: a netpbm image's maxval (any, 8 or 16 bits), else 255 for 8-bit and 65535
    for 16-bit images (a 16-bit png); other depths are refused; and whether it is a JPEG."""
    img, maxval, jpeg = _decode(spec)
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
    return img.astype(np.float64), float(full), jpeg


def _write_image(path: Path, img: np.ndarray) -> None:
    """``img`` encoded by its ``path``'s suffix, as OpenCV's ``imencode`` does; a grey 8-bit pgm
    (the robot map's) without OpenCV: the same bytes."""
    if path.suffix.lower() == ".pgm" and img.dtype == np.uint8 and img.ndim == 2:
        height, width = img.shape
        path.write_bytes(
            b"P5\n%d %d\n255\n" % (width, height) + np.ascontiguousarray(img).tobytes()
        )
        return
    import cv2

    ok, buf = cv2.imencode(path.suffix, img)
    if not ok:
        raise OSError(f"{path}: OpenCV could not encode the image")
    path.write_bytes(buf.tobytes())
