"""``.npz`` files as :func:`numpy.savez_compressed` writes them, faster for very large arrays.

:func:`write_npz` writes the same zip of ``NAME.npy`` members (the same ``.npy`` bytes, deflated,
read back by a plain :func:`numpy.load`), deflating an array of :data:`LARGE` bytes or more with
a cheaper zlib setting than ``savez_compressed``'s level 6: on a 2.9-million-cell map the label
frequencies [N, L] float32 are 1.4 GB of mostly zeros, which level 6 deflated in 3.8 s of CPU
(7.2 MB). Run-length deflate (``Z_RLE``: matches at distance 1 only) takes 1.25 s there for 8.4
MB, level 1 1.18 s for 16.5 MB (both at :data:`MEMORY_LEVEL`); on dense floats (a variational
fit's q(C)) level 1 is 1.2x level 6's size at 0.6x its time, where run-length deflate is 3.3x.
So each large array is deflated with whichever of the two gives fewer bytes on a sample of it
(:func:`_large_strategy`); smaller arrays (all but [N, L] tables on large maps) at level 6, as
before. The whole ``result.npz`` of that map: 4.1-4.7 s -> 1.9-2.1 s of CPU, 7.6 -> 8.8 MB
(docs/speed.md). Same zip layout as numpy's (deflated members, zip64 headers), so any zip reader
and ``np.load`` read it. zipfile has no option for a zlib strategy: the member's deflater
(``_compressor``) is replaced before anything is deflated; without that attribute (another
Python) large arrays are written at level 6 like the rest.

Imports of the package: none.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from collections.abc import Mapping
from typing import BinaryIO

import numpy as np

LARGE = 64 << 20
"""Arrays of this many bytes or more get the cheaper deflate (:func:`_large_strategy`)."""
CHUNK = 16 << 20
"""Bytes handed to zlib at a time (numpy's ``write_array`` buffer too)."""
_SAMPLES, _SAMPLE_BYTES = 8, 128 << 10
"""A large array's sample: 8 evenly spaced pieces of 128 KiB."""


MEMORY_LEVEL = 5
"""zlib's ``memLevel`` for large arrays: smaller tables than its default 8 stay in cache (1.25 s
against 1.67 s run-length, 1.18 against 1.52 s at level 1, on the 1.4 GB above, 2-3% bigger)."""


def _deflater(strategy: int) -> zlib._Compress:
    """Raw deflate (the zip member's data) at level 1 with ``strategy`` (Z_RLE ignores the
    level) and :data:`MEMORY_LEVEL`."""
    return zlib.compressobj(1, zlib.DEFLATED, -15, MEMORY_LEVEL, strategy)


def _deflated_size(pieces: list[memoryview], strategy: int) -> int:
    deflater = _deflater(strategy)
    return sum(len(deflater.compress(piece)) for piece in pieces) + len(deflater.flush())


def _large_strategy(data: memoryview) -> int:
    """``zlib.Z_RLE`` where run-length deflate makes a sample of ``data`` (raw bytes) no bigger
    than level 1 does (mostly zeros: a sampler's label frequencies), else ``Z_DEFAULT_STRATEGY``
    (level 1's LZ77: dense floats)."""
    step = max(len(data) // _SAMPLES, 1)
    pieces = [data[start : start + _SAMPLE_BYTES] for start in range(0, len(data), step)]
    rle = _deflated_size(pieces, zlib.Z_RLE)
    return zlib.Z_RLE if rle <= _deflated_size(pieces, zlib.Z_DEFAULT_STRATEGY) else 0


def _write_member(archive: zipfile.ZipFile, name: str, array: np.ndarray) -> None:
    """``name.npy`` holding ``array``, its ``.npy`` bytes as :func:`numpy.save` writes them."""
    with archive.open(name + ".npy", "w", force_zip64=True) as member:
        large = array.nbytes >= LARGE and array.flags.c_contiguous and not array.dtype.hasobject
        if not large or not hasattr(member, "_compressor"):  # zipfile's deflater: level 6
            np.lib.format.write_array(member, array, allow_pickle=False)
            return
        data = memoryview(array.reshape(-1)).cast("B")  # [nbytes], no copy
        # nothing deflated yet: zipfile's own deflater (level 6) is replaced before any write
        member._compressor = _deflater(_large_strategy(data))
        header = np.lib.format.header_data_from_array_1_0(array)
        np.lib.format.write_array_header_1_0(member, header)  # write_array's header for it
        for start in range(0, len(data), CHUNK):  # CRC and deflate from the array's memory
            member.write(data[start : start + CHUNK])


def write_npz(file: str | os.PathLike[str] | BinaryIO, arrays: Mapping[str, object]) -> None:
    """``np.savez_compressed(file, **arrays)``: the same members and ``.npy`` bytes, each array
    of :data:`LARGE` bytes or more deflated faster (module docstring). ``file``: a path (no
    ``.npz`` added) or a binary file open for writing. Object arrays are refused (ValueError)."""
    with zipfile.ZipFile(file, "w", zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for name, value in arrays.items():
            _write_member(archive, name, np.asanyarray(value))
