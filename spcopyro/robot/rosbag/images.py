"""Camera images from ROS messages: the bytes to store for one ``sensor_msgs`` image.

A ``CompressedImage`` holding a JPEG or PNG is stored as it is (its own bytes, ``.jpg`` /
``.png``: no second lossy compression), after checking that OpenCV decodes it; but a 16-bit PNG
(image_transport's png of a mono16 camera) is scaled to 8 bits as a raw 16-bit image is. Any
other image (a raw ``sensor_msgs/Image`` in any encoding rosbags-image converts -- rgb8, bgr8,
mono8, mono16, bayer_*, ... -- rows padded to ``step`` bytes included, or another compressed
format) is decoded to 8-bit BGR and stored as a lossless PNG; a 16-bit one is scaled from the
bit depth its values use (:func:`to_8_bits`: a 12-bit camera's 0..4095 to 0..255). An image that
cannot be decoded raises :class:`ImageDecodeError` with the reason; the import reports it (with
its timestamp) in skipped.csv rather than stopping.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import cv2
import numpy as np

from spcopyro.robot.rosbag.bag import INSTALL_HINT, RosbagsMissingError

__all__ = ["SENSOR_BITS", "ImageDecodeError", "decode_image", "encoded_image", "to_8_bits"]

_JPEG_MAGIC = b"\xff\xd8\xff"
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class ImageDecodeError(ValueError):
    """One image message could not be decoded (the message says why)."""


def decode_image(msg: Any, bits: int | None = None, seen: set[int] | None = None) -> np.ndarray:
    """``[H, W, 3]`` uint8 BGR of an Image or CompressedImage message; a 16-bit one is scaled
    by :func:`to_8_bits` (``bits``, and the depth used added to ``seen``)."""
    if hasattr(msg, "format"):  # CompressedImage
        data = np.frombuffer(bytes(msg.data), dtype=np.uint8)  # [bytes]
        flags = cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH  # a 16-bit PNG (mono16, png compressed)
        image = cv2.imdecode(data, flags) if data.size else None
        if image is None:
            raise ImageDecodeError(
                f"compressed image (format {msg.format!r}, {data.size} bytes) does not decode"
            )
        if image.dtype == np.uint16:  # IMREAD_COLOR alone keeps the high byte
            return to_8_bits(image, bits, seen)
        return image if image.dtype == np.uint8 else cv2.imdecode(data, cv2.IMREAD_COLOR)
    try:
        from rosbags.image import message_to_cvimage
        from rosbags.image.image import to_cvtype
    except ImportError as error:
        raise RosbagsMissingError(
            f"decoding sensor_msgs/Image needs 'rosbags-image' ({error}); install it with: "
            f"{INSTALL_HINT}"
        ) from None
    expected = int(msg.height) * int(msg.step)
    if int(msg.height) * int(msg.width) == 0 or len(msg.data) < expected:
        raise ImageDecodeError(
            f"image {msg.width} x {msg.height} ({msg.encoding}) holds {len(msg.data)} bytes, "
            f"expected {expected}"
        )
    try:
        _, _, typestr, channels = to_cvtype(msg.encoding)
        row_bytes = int(msg.width) * channels * np.dtype(typestr).itemsize
        if int(msg.step) > row_bytes:  # rows padded to `step` bytes: drop the padding
            rows = np.frombuffer(bytes(msg.data), np.uint8)[:expected]  # [H * step]
            data = rows.reshape(int(msg.height), int(msg.step))[:, :row_bytes].reshape(-1)
            msg = dataclasses.replace(msg, data=data, step=row_bytes)
        if typestr == "uint16":  # rosbags-image's bgr8 keeps the high byte: 12 bits -> 0..15
            return to_8_bits(np.asarray(message_to_cvimage(msg, "bgr16")), bits, seen)
        image = message_to_cvimage(msg, "bgr8")
    except Exception as error:  # noqa: BLE001 - rosbags-image raises several kinds
        raise ImageDecodeError(f"image encoding {msg.encoding!r}: {error}") from None
    return np.ascontiguousarray(image)


SENSOR_BITS = (8, 10, 12, 14, 16)
"""The bit depths a 16-bit image's values are taken to span (:func:`to_8_bits`)."""


def to_8_bits(
    image: np.ndarray, bits: int | None = None, seen: set[int] | None = None
) -> np.ndarray:
    """A uint16 image as uint8: its values scaled from ``bits`` (the camera's bit depth, values
    above it clipped) or, with None, from the smallest bit depth of :data:`SENSOR_BITS` that
    holds its largest value (a 12-bit camera's 0..4095 to 0..255; a camera's bit depth is not
    in the message, so a dark frame comes out brighter than the others). The depth used is
    added to ``seen``."""
    if bits is None:
        bits = next(b for b in SENSOR_BITS if int(image.max(initial=0)) < 1 << b)
    if seen is not None:
        seen.add(bits)
    top = (1 << bits) - 1
    scaled = np.rint(np.minimum(image, top).astype(np.float64) * (255.0 / top))
    return np.ascontiguousarray(scaled.astype(np.uint8))


def _png_16_bit(data: bytes) -> bool:
    """Whether PNG ``data`` holds 16 bits a sample (its IHDR's bit depth, byte 24)."""
    return data.startswith(_PNG_MAGIC) and data[24:25] == b"\x10"


def encoded_image(
    msg: Any, bits: int | None = None, seen: set[int] | None = None
) -> tuple[bytes, str]:
    """The file content and suffix (``.jpg`` or ``.png``) to store for an image message
    (``bits``, ``seen``: a 16-bit image's, :func:`to_8_bits`)."""
    image = decode_image(msg, bits, seen)  # [H, W, 3] uint8: it decodes
    if hasattr(msg, "format"):
        data = bytes(msg.data)
        for magic, suffix in ((_JPEG_MAGIC, ".jpg"), (_PNG_MAGIC, ".png")):
            if data.startswith(magic) and not _png_16_bit(data):  # 16 bits: stored as 8
                return data, suffix
    ok, png = cv2.imencode(".png", image)
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 BGR image
        raise ImageDecodeError("OpenCV could not encode it as PNG")
    return png.tobytes(), ".png"
