"""``.npz`` files as :func:`numpy.savez_compressed` writes them, faster for very large arrays.

:func:`write_npz` writes the same zip of ``NAME.npy`` members (the same ``.npy`` bytes, deflated,
read back by a plain :func:`numpy.load`), deflating an array of :data:`LARGE` bytes or more at
zlib level 1 instead of ``savez_compressed``'s level 6: on a 2.9-million-cell map the label
frequencies [N, L] float32 are 1.4 GB of mostly zeros, which level 6 deflates in 3.1 s of CPU
(7.2 MB), level 1 in 1.5 s (16.8 MB); on dense floats (a variational fit's q(C)) level 1 is
1.2x level 6's size at 0.5x its time. The whole ``result.npz`` of that map: 3.9-4.1 s -> 2.3 s
of CPU, 7.6 -> 17.2 MB (docs/speed.md). Smaller arrays (all but [N, L] tables on large maps)
at level 6, as before. Same zip layout as numpy's (deflated members, zip64 headers), so any zip
reader and ``np.load`` read it.

The level is zipfile's public one: ``ZipFile.open(name, "w")`` gives the new member the
archive's ``compresslevel`` (Python 3.10-3.13), so it is set to 1 for the ``open`` of a large
array's member and put back after. A C-contiguous large array is deflated from its own memory in
:data:`CHUNK` pieces (numpy's ``write_array`` copies it 16 MiB at a time).

Imports of the package: none.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Mapping
from typing import IO, BinaryIO

import numpy as np

LARGE = 64 << 20
"""Arrays of this many bytes or more are deflated at zlib level 1 (:data:`LARGE_LEVEL`)."""
LARGE_LEVEL = 1
"""zlib level of the arrays of :data:`LARGE` bytes or more; smaller ones get zlib's default, 6."""
CHUNK = 16 << 20
"""Bytes handed to zlib at a time (numpy's ``write_array`` buffer too)."""


def _open_member(archive: zipfile.ZipFile, name: str, level: int | None) -> IO[bytes]:
    """``archive``'s new member ``name`` for writing, deflated at zlib ``level`` (None: 6)."""
    kept = archive.compresslevel
    archive.compresslevel = level  # copied into the member by open: zipfile's public setting
    try:
        return archive.open(name, "w", force_zip64=True)
    finally:
        archive.compresslevel = kept


def _write_member(archive: zipfile.ZipFile, name: str, array: np.ndarray) -> None:
    """``name.npy`` holding ``array``, its ``.npy`` bytes as :func:`numpy.save` writes them."""
    large = array.nbytes >= LARGE
    with _open_member(archive, name + ".npy", LARGE_LEVEL if large else None) as member:
        if not large or not array.flags.c_contiguous or array.dtype.hasobject:
            np.lib.format.write_array(member, array, allow_pickle=False)
            return
        data = array.reshape(-1).view(np.uint8)  # [nbytes], no copy (C-contiguous)
        header = np.lib.format.header_data_from_array_1_0(array)
        np.lib.format.write_array_header_1_0(member, header)  # write_array's header for it
        for start in range(0, len(data), CHUNK):  # CRC and deflate from the array's memory
            member.write(data[start : start + CHUNK])


def write_npz(file: str | os.PathLike[str] | BinaryIO, arrays: Mapping[str, object]) -> None:
    """``np.savez_compressed(file, **arrays)``: the same members and ``.npy`` bytes, each array
    of :data:`LARGE` bytes or more deflated at level 1 (module docstring). ``file``: a path (no
    ``.npz`` added) or a binary file open for writing. Object arrays are refused (ValueError)."""
    with zipfile.ZipFile(file, "w", zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for name, value in arrays.items():
            _write_member(archive, name, np.asanyarray(value))
