"""Context variables set for the length of a ``with`` block."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar
from typing import TypeVar

_T = TypeVar("_T")


@contextlib.contextmanager
def set_within(var: ContextVar[_T], value: _T) -> Iterator[None]:
    """Within the block, ``var`` holds ``value``; after it (an exception too), what it held
    before (``var.reset``: unset again if it was unset)."""
    token = var.set(value)
    try:
        yield
    finally:
        var.reset(token)
