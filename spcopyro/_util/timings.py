"""Wall-clock phases of one ``spcopyro fit``, for the fixed-cost benchmark
(``benchmarks/fixed_cost.py``, issue #15 item 2).

``fit`` times its phases with a :class:`Phases` clock (loading the house, the settings and the
output folder, the fit itself, saving the result, the figures, the printed report, moving the
output into place). Nothing is printed or written unless the environment variable
``SPCOPYRO_TIMINGS`` names a file: then :meth:`Phases.write` writes there, as JSON, the seconds of
every phase and the wall-clock time (``time.time()``, seconds since the epoch) at which ``fit``
started its work, so a caller that noted when it launched the process can tell the interpreter's
start and the imports (launch to ``entered``) from the rest. The outputs of a fit (OUT) do not
change.

Inside a phase, the library times its parts with :func:`timed` (the model data, the chain's
start, the sweeps, the point estimate, the label frequencies, each figure, ...): the seconds add
up per name in this process (:func:`parts`) and :meth:`Phases.to_json` writes them under
``"parts"``, so ``benchmarks/end_to_end.py`` splits a fit into its start-up, data, sweeps and
post-processing (issue 25 item 1). Timing a part costs two clock reads.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path

TIMINGS_ENV = "SPCOPYRO_TIMINGS"
"""The environment variable naming the JSON file :meth:`Phases.write` writes (unset: none)."""
OPTIONAL_HEAVY = (
    "cv2",
    "matplotlib",
    "pyro",
    "sklearn",
    "torchvision",
    "scipy.ndimage",
    "scipy.optimize",
    "scipy.sparse",
    "scipy.spatial",
)
"""Modules a fit imports only where it uses them (images other than map_saver's pgm, figures,
the svi method, Pyro's MCMC kernel and ``--sweeps auto``'s R-hat, footprints, cluster and merge
moves, snapping, a point estimate): :func:`imported_heavy` lists those loaded."""


def imported_heavy() -> list[str]:
    """Those of :data:`OPTIONAL_HEAVY` this process has imported."""
    return [name for name in OPTIONAL_HEAVY if name in sys.modules]


_PARTS: dict[str, float] = {}


@contextlib.contextmanager
def timed(name: str) -> Iterator[None]:
    """Add the wall seconds of the ``with`` block to the part ``name`` (:func:`parts`)."""
    start = time.perf_counter()
    try:
        yield
    finally:
        _PARTS[name] = _PARTS.get(name, 0.0) + time.perf_counter() - start


def parts() -> dict[str, float]:
    """Seconds of every part :func:`timed` so far in this process, by name (a copy)."""
    return dict(_PARTS)


def reset_parts() -> None:
    """Forget the parts timed so far (a command that times one fit starts here)."""
    _PARTS.clear()


class Phases:
    """A clock of consecutive phases: :meth:`mark` ends the current one under a name (a name
    marked again adds up)."""

    def __init__(self) -> None:
        self.entered = time.time()  # epoch seconds: when the command started its own work
        reset_parts()
        self.seconds: dict[str, float] = {}
        self._last = time.perf_counter()

    def mark(self, name: str) -> float:
        """End the phase running since the last mark as ``name``; its seconds."""
        now = time.perf_counter()
        elapsed = now - self._last
        self.seconds[name] = self.seconds.get(name, 0.0) + elapsed
        self._last = now
        return elapsed

    def to_json(self, **extra: object) -> dict[str, object]:
        return {
            "entered": self.entered,
            "seconds": {k: round(v, 6) for k, v in self.seconds.items()},
            "total": round(sum(self.seconds.values()), 6),
            "parts": {k: round(v, 6) for k, v in _PARTS.items()},
            "imported": imported_heavy(),
            **extra,
        }

    def write(self, **extra: object) -> Path | None:
        """Write :meth:`to_json` (with ``extra``) to ``$SPCOPYRO_TIMINGS``, if set."""
        target = os.environ.get(TIMINGS_ENV)
        if not target:
            return None
        path = Path(target)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_json(**extra), indent=1) + "\n")
        return path
