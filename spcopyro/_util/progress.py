"""Progress bars for long runs (tqdm), on unless switched off or under CI."""

from __future__ import annotations

import os

SETUP_PROGRESS_CELLS = 100_000
"""From this many free cells, a fit's setup steps show a progress bar of their own
(:func:`setup_bar`: spreading the observation footprints, memoized VI's memo and coefficients):
on a map of 10^6 cells each takes tens of seconds before the first sweep's bar."""


def progress_enabled(progress: bool | None) -> bool:
    """Progress bars are on unless switched off, or when running under CI (``$CI`` set)."""
    if progress is None:
        return not os.environ.get("CI")
    return progress


class _NoBar:
    """The bar of a small map: nothing shown."""

    def update(self, n: int = 1) -> None:  # noqa: D102
        del n

    def set_postfix_str(self, text: str) -> None:  # noqa: D102
        del text

    def close(self) -> None:  # noqa: D102
        pass


def setup_bar(cells: int, total: int, desc: str, unit: str, progress: bool | None = None):
    """A tqdm bar of ``total`` ``unit`` for a setup step on a map of ``cells`` free cells, shown
    from :data:`SETUP_PROGRESS_CELLS` where bars are on (:func:`progress_enabled`); else an
    object with the same ``update``, ``set_postfix_str`` and ``close`` that shows nothing (and
    imports no tqdm, 60 ms)."""
    if cells < SETUP_PROGRESS_CELLS or not progress_enabled(progress):
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit)
