"""The warnings a cell's fit gives, kept in its record (column ``warnings``) wherever it runs.

A fit warns through the ``spcopyro`` logger (a degenerate map: "one concept (36) holds 64 % of
the free cells while words said at different places ... lie inside it", gamma below the Potts
critical coupling, observations off the free cells) or through :func:`warnings.warn`. In a
study these went to the study's stderr over its progress bar without naming the cell, or, for
a cell run on a Dask worker, to that worker's log or nowhere. :func:`captured_warnings` keeps,
for the thread that runs the cell, every record of the ``spcopyro`` logger tree at WARNING and
above and every Python warning, instead of printing them; other threads' messages, and the
records below WARNING (``--verbose``), go where they went. The record stores the distinct
messages as JSON text (:func:`warnings_text`; empty when none) and ``report.md`` lists the cells
that gave them (:func:`spcopyro.study.report.report_markdown`).

A warning that :func:`spcopyro._util.messages.warn_once` gives once per process is kept in every
cell that meets it: the cell's thread remembers what it said apart from the process
(:func:`spcopyro._util.messages.warned_apart`), so cells that run at once on several threads of
one process (a ``--scheduler`` cluster's worker with more than one thread; the study's own
LocalCluster gives each worker one) each keep it, once. Python's own registries of the
warnings shown under the "default" and "once" actions are per module, not per thread: they are
reset as each cell starts (a warning an earlier cell showed is shown again), but two cells that
meet the same such warning at the same time in one process may keep it in only one of them.
"""

from __future__ import annotations

import json
import logging
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

from spcopyro._util import messages

__all__ = ["MESSAGE_LIMIT", "MESSAGES_KEPT", "captured_warnings", "read_warnings", "warnings_text"]

MESSAGE_LIMIT = 2000
"""Characters of one message kept in a record (as of an error's)."""
MESSAGES_KEPT = 20
"""Distinct messages kept in a record; a further one is counted in a last entry."""
LOGGER = "spcopyro"

_lock = threading.Lock()
_kept: dict[int, list[str]] = {}
"""The messages of each capturing thread, by thread id."""
_router: _Router | None = None


class _Router(logging.Handler):
    """The ``spcopyro`` logger's only handler while a cell captures: keeps a capturing thread's
    records at WARNING and above and hands every other record to the logger's own handlers and
    its parents', as logging would have."""

    def __init__(self, logger: logging.Logger) -> None:
        super().__init__(logging.NOTSET)
        self.logger = logger
        self.handlers = list(logger.handlers)
        self.propagate = logger.propagate
        self.level_set = logger.level
        self.effective = logger.getEffectiveLevel()
        self.showwarning = warnings.showwarning

    def install(self) -> None:
        self.logger.handlers = [self]
        self.logger.propagate = False
        if self.effective > logging.WARNING:  # a warning must reach the router
            self.logger.setLevel(logging.WARNING)
        warnings.showwarning = self.show

    def uninstall(self) -> None:
        added = [h for h in self.logger.handlers if h is not self and h not in self.handlers]
        self.logger.handlers = [*self.handlers, *added]  # one added meanwhile is kept
        self.logger.propagate = self.propagate
        self.logger.setLevel(self.level_set)
        if warnings.showwarning == self.show:  # else someone replaced it meanwhile: theirs
            warnings.showwarning = self.showwarning

    def emit(self, record: logging.LogRecord) -> None:  # noqa: D102
        kept = _kept.get(record.thread) if record.levelno >= logging.WARNING else None
        if kept is not None:
            kept.append(record.getMessage())
        elif record.levelno >= self.effective:
            self._forward(record)

    def _forward(self, record: logging.LogRecord) -> None:
        """:meth:`logging.Logger.callHandlers` with the logger's own handlers and propagation."""
        found = 0
        handlers, logger = self.handlers, self.logger.parent if self.propagate else None
        while True:
            for handler in handlers:
                found += 1
                if record.levelno >= handler.level:
                    handler.handle(record)
            if logger is None:
                break
            handlers, logger = logger.handlers, logger.parent if logger.propagate else None
        if not found and logging.lastResort and record.levelno >= logging.lastResort.level:
            logging.lastResort.handle(record)

    def show(self, message, category, filename, lineno, file=None, line=None) -> None:
        """:func:`warnings.showwarning` while a cell captures."""
        kept = _kept.get(threading.get_ident())
        if kept is None:
            self.showwarning(message, category, filename, lineno, file, line)
        else:
            kept.append(f"{category.__name__}: {message}")


@contextmanager
def captured_warnings() -> Iterator[list[str]]:
    """Within: this thread's ``spcopyro`` records at WARNING and above and its Python warnings
    go into the list given (in order, repeats included), not to stderr (module docstring)."""
    global _router
    kept: list[str] = []
    ident = threading.get_ident()
    with _lock:
        if _router is None:
            _router = _Router(logging.getLogger(LOGGER))
            _router.install()
        _kept[ident] = kept
        mutated = getattr(warnings, "_filters_mutated", None)
        if mutated is not None:  # a "default" warning shown in an earlier cell: shown again
            mutated()
    try:
        with messages.warned_apart():  # warn_once: said in this process, not yet by this cell
            yield kept
    finally:
        with _lock:
            del _kept[ident]
            if not _kept and _router is not None:
                _router.uninstall()
                _router = None


def warnings_text(kept: list[str]) -> str:
    """The distinct messages of ``kept`` in order, each cut to :data:`MESSAGE_LIMIT`
    characters and at most :data:`MESSAGES_KEPT` of them, as JSON text; ``""`` when none."""
    distinct = list(dict.fromkeys(m[:MESSAGE_LIMIT] for m in kept))
    if not distinct:
        return ""
    if len(distinct) > MESSAGES_KEPT:
        more = len(distinct) - MESSAGES_KEPT
        distinct = [*distinct[:MESSAGES_KEPT], f"... and {more} more distinct warnings"]
    return json.dumps(distinct)


def read_warnings(value: object) -> list[str]:
    """A table's ``warnings`` value as the list of messages: empty for none, and for a cell
    stored before records had the column (None)."""
    if not isinstance(value, str) or not value:
        return []
    try:
        loaded = json.loads(value)
    except ValueError:
        return [value]
    return [str(m) for m in loaded] if isinstance(loaded, list) else [str(loaded)]
