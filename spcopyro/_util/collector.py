"""The fit's heavy imports without the cyclic garbage collector (issue 25's fixed cost).

Importing torch and pyro creates about 170,000 long-lived objects (modules, classes, functions),
and the collector, counting them as they come, ran three full collections during that import
alone and then, every time the objects alive grew by a quarter (numba's import and its first
compiled call, the figures), a full collection over all of them again: 0.5-1.5 s of collections
in a 50-sweep fit of room2ldk4 with figures (measured with ``gc.callbacks``; 0.45 s without
figures), none of which found more than a few hundred objects to free.

:func:`import_frozen` imports a module with the collector paused and then moves everything alive
into the collector's permanent generation (:func:`gc.freeze`): those objects are never scanned
again, and the later collections scan only what was made after (in the same fit: two full
collections, 0.1 s). Objects are still freed by their reference counts as before; what is
frozen and is garbage (a cycle nobody collected yet) stays until the process exits. Nothing a
fit computes depends on when the collector runs.
"""

from __future__ import annotations

import gc
import importlib
import sys
from types import ModuleType

__all__ = ["import_frozen"]


def import_frozen(name: str) -> ModuleType:
    """The module ``name``, imported (if not yet) with the collector paused, then everything
    alive frozen; the collector is left as it was (enabled or not). A module imported already
    is returned as it is, nothing frozen (a second fit in one process freezes nothing)."""
    module = sys.modules.get(name)
    if module is not None:
        return module
    enabled = gc.isenabled()
    gc.disable()
    try:
        module = importlib.import_module(name)
    finally:
        if enabled:
            gc.enable()
    gc.freeze()
    return module
