"""The SHA-256 of a file's bytes, read 1 MiB at a time (a backbone checkpoint of 200 MB, a
large fit's ``result.npz``, never held whole in memory): what a fit's request records of the fit
``--update`` continues, and what identifies a backbone checkpoint's weights.

Imports of the package: none.
"""

from __future__ import annotations

import hashlib
import os

BLOCK = 1 << 20
"""Bytes read at a time."""


def file_sha256(path: str | os.PathLike[str]) -> str:
    """The SHA-256 (64 hex digits) of the bytes of the file at ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(BLOCK), b""):
            digest.update(block)
    return digest.hexdigest()
