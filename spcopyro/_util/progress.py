"""Progress bars for long runs (tqdm), on unless switched off or under CI."""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from typing import Any

from spcopyro._util.context import set_within

SETUP_PROGRESS_CELLS = 100_000
"""From this many free cells, a fit's setup steps show a progress bar of their own
(:func:`setup_bar`: spreading the observation footprints, memoized VI's memo and coefficients):
on a map of 10^6 cells each takes tens of seconds before the first sweep's bar."""


def progress_enabled(progress: bool | None) -> bool:
    """Progress bars are on unless switched off, or when running under CI (``$CI`` set)."""
    if progress is None:
        return not os.environ.get("CI")
    return progress


def clears_when_done() -> bool:
    """tqdm's ``leave=False`` where it clears a bar: a bar that is gone once done clears its
    line on a terminal (stderr, tqdm's stream) and its widget in a Jupyter notebook (whose
    stderr, ipykernel's ``OutStream``, is no terminal), and leaves its last state on its own
    line elsewhere. Cleared in a log file (``spcopyro fit 2> log.txt``), it wrote a carriage
    return, a line of spaces and a carriage return: a blank line in the log. Pass ``leave=not
    clears_when_done()``."""
    stream = sys.stderr
    if type(stream).__module__.startswith("ipykernel"):  # a notebook's, without importing it
        return True
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no stream, or a closed one
        return False


_STAGE: ContextVar[str | None] = ContextVar("progress_stage", default=None)


@contextlib.contextmanager
def progress_stage(name: str | None) -> Iterator[None]:
    """Within it, the bars of a fit (:func:`staged`) name the stage they count: a refined fit's
    two Gibbs stages both read "Gibbs sweeps", so its bar went 5000/5000, then 0/5000 under
    the same label; now "Gibbs sweeps (model grid)", then "Gibbs sweeps (map's cells)". None:
    no stage named."""
    with set_within(_STAGE, name):
        yield


def staged(description: str) -> str:
    """``description`` of a bar with the stage :func:`progress_stage` names, in parentheses
    (read where the bar is made, in the thread that entered the stage)."""
    stage = _STAGE.get()
    return f"{description} ({stage})" if stage else description


COMPILE_ITERATIONS = 20
"""Iterations a bar keeps its compile note (:func:`noted_updates`) for. The first sweep compiles
the sweep's code, and the merge and region moves compile at their first use a few sweeps on
(each in 0.2 of the sweeps: both have run within 20 sweeps in about 98 of 100 fits)."""

_NO_RATE = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]"  # tqdm's, less rate and ETA


def noted_updates(bar: Any, description: str, note: str | None) -> Callable[[int], None]:
    """``bar.update`` for a tqdm ``bar`` whose first :data:`COMPILE_ITERATIONS` iterations compile
    code (``note``, e.g. "compiling the numba code: first run only"; None: plain ``bar.update``).

    Over those iterations the bar reads "``description`` (``note``)" (give the bar that
    description: its first line is drawn as it is made) and shows no rate and no time left; then
    ``description`` alone, its rate counted from there. Extrapolated from the
    compiling iterations, the time left read 12:55:58 for a default ``spcopyro fit`` of 57 s
    (a first sweep of 9.3 s times 4999 sweeps), then 4:24:18, for seconds.
    """
    if note is None or bar.disable:
        return bar.update
    bar.bar_format = _NO_RATE
    limit = min(COMPILE_ITERATIONS, bar.total) if bar.total else COMPILE_ITERATIONS

    def update(done: int = 1) -> None:
        if bar.bar_format is None:  # the note is gone: tqdm's own update and rate
            bar.update(done)
            return
        bar.n += done
        if bar.n >= limit:
            bar.set_description_str(description, refresh=False)
        bar.refresh()  # with no rate: bar.update would put these iterations into tqdm's rate
        bar.last_print_n, bar.last_print_t = bar.n, time.time()  # the rate starts here
        if bar.n >= limit:
            bar.bar_format = None

    return update


def noted_bar(
    total: int | None, description: str, note: str | None, unit: str, disable: bool
) -> tuple[Any, Callable[[int], None]]:
    """A tqdm bar of ``total`` ``unit``s named ``description`` and its update
    (:func:`noted_updates`): "``description`` (``note``)" over the first iterations, then
    ``description``; None: no note. ``description`` comes :func:`staged` already: the stage is
    read in the thread that entered it, which need not be the one that makes the bar."""
    from tqdm.auto import tqdm  # here: importing this module imports no tqdm (setup_bar)

    desc = f"{description} ({note})" if note else description
    bar = tqdm(total=total, desc=desc, unit=unit, disable=disable)
    return bar, noted_updates(bar, description, note)


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
