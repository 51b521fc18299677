"""Names imported from their modules on first use (PEP 562): a package's ``__getattr__`` and
``__dir__`` (:func:`lazy_names`), and :func:`load`, which imports one name from its module.

A package lists each lazy name's module in a table and writes
``__getattr__, __dir__ = lazy_names(__name__, HOMES)``; the names' imports under
``TYPE_CHECKING`` keep them in type checkers' and ``tests/test_architecture.py``'s import graph.
This module imports only the standard library: the command line's start-up goes through it.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names", "load"]


def load(module: str, name: str) -> Any:
    """``name`` of ``module`` (a dotted path), the module imported first."""
    return getattr(importlib.import_module(module), name)


def lazy_names(
    package: str, homes: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package`` (its ``__name__``): a name of
    ``homes`` is imported from ``package.homes[name]`` when first asked for and kept in the
    package's globals (later lookups find it there); another name is an AttributeError."""

    def __getattr__(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = load(f"{package}.{home}", name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *homes})

    return __getattr__, __dir__
