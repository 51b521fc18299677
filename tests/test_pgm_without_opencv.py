"""map_saver's images (binary 8-bit P5 pgm, maxval 255) are read and written without OpenCV
(:mod:`spcopyro.maps.map_image`, issue 25's fixed cost): the same pixels and the same bytes as
OpenCV's, and every other image still goes to OpenCV."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from spcopyro.maps.map_image import _plain_p5, _write_image


def _opencv(data: bytes) -> np.ndarray | None:
    return cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)


HEADERS = [
    b"P5\n%d %d\n255\n",
    b"P5 %d %d 255 ",
    b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n%d %d\n255\n",
    b"P5\r\n%d\t%d\r\n# a comment\r\n255\r",
    b"P5\n#x\n%d\n#y\n%d #z\n0255\n",
    b"P5\n\n%03d  %d\n\n255\n",
]


@pytest.mark.parametrize("header", HEADERS)
def test_a_binary_pgm_reads_as_opencv_decodes_it(header, rng):
    for height, width in ((1, 1), (3, 7), (40, 33)):
        pixels = rng.integers(0, 256, size=(height, width), dtype=np.uint8)
        data = header % (width, height) + pixels.tobytes()
        expected = _opencv(data)
        assert expected is not None and np.array_equal(expected, pixels)
        read = _plain_p5(np.frombuffer(data, dtype=np.uint8))
        assert read is not None and read.dtype == np.uint8 and read.flags.writeable
        assert np.array_equal(read, expected)


def test_the_public_maps_read_as_opencv_decodes_them(dataset_root: Path):
    maps = sorted((dataset_root / "map").glob("*.pgm"))
    assert maps, f"no map/*.pgm in the public dataset at {dataset_root}"
    for path in maps:
        data = np.fromfile(path, dtype=np.uint8)
        read = _plain_p5(data)
        assert read is not None, path
        assert np.array_equal(read, _opencv(data.tobytes())), path


@pytest.mark.parametrize(
    "data",
    [
        b"P5\n2 2\n254\n\x00\x01\x02\x03",  # another maxval: map_server scales by it
        b"P5\n2 2\n65535\n" + bytes(8),  # 16 bits
        b"P5\n2 2\n255\n\x00\x01\x02",  # cut short
        b"P5\n2 2\n255\n\x00\x01\x02\x03\x04",  # a byte too many
        b"P5\n2 2\n255\n# late\n\x00\x01\x02\x03",  # a comment after the maxval
        b"P5\n2 2\n255\r\n\x00\x01\x02\x03",  # two whitespace bytes after it
        b"P5#x\n2 2\n255\n\x00\x01\x02\x03",  # a comment with no whitespace before it
        b"P5\n2 2#x\n255\n\x00\x01\x02\x03",
        b"P5\n0 2\n255\n",  # no pixel
        b"P2\n2 2\n255\n0 1 2 3\n",  # plain (ASCII)
        b"P6\n1 1\n255\n\x00\x01\x02",  # colour
        b"\x89PNG\r\n\x1a\n",
        b"",
    ],
)
def test_any_other_image_is_left_to_opencv(data):
    assert _plain_p5(np.frombuffer(data, dtype=np.uint8)) is None


def test_a_grey_pgm_is_written_as_opencv_encodes_it(tmp_path, rng):
    for height, width in ((1, 1), (5, 3), (64, 97)):
        pixels = rng.integers(0, 256, size=(height, width), dtype=np.uint8)
        for image in (pixels, pixels[:, ::-1], pixels.T):  # non-contiguous views too
            _write_image(tmp_path / "map.PGM", image)
            ok, expected = cv2.imencode(".pgm", image)
            assert ok and (tmp_path / "map.PGM").read_bytes() == expected.tobytes()


def test_other_images_are_still_written_by_opencv(tmp_path, monkeypatch):
    pixels = np.arange(12, dtype=np.uint8).reshape(3, 4)
    _write_image(tmp_path / "map.png", pixels)
    assert np.array_equal(cv2.imread(str(tmp_path / "map.png"), cv2.IMREAD_UNCHANGED), pixels)
    _write_image(tmp_path / "map.pgm", pixels.astype(np.uint16) * 1000)  # 16 bits: OpenCV's
    assert (tmp_path / "map.pgm").read_bytes().startswith(b"P5\n4 3\n65535\n")
    with pytest.raises(OSError, match="OpenCV could not encode"):  # colour: OpenCV refuses it
        _write_image(tmp_path / "map.pgm", np.zeros((2, 2, 3), dtype=np.uint8))
