"""The warnings ``spcopyro fit`` gave, kept in its ``config.json`` (``"warnings"``) as printed.

A fit warns through the ``spcopyro`` logger (a degenerate map, gamma below the Potts critical
coupling, observations off the free cells, a variational method's flat q) or through
:func:`warnings.warn`; these went to the terminal only, so a saved fit's folder read later could
not tell that its map was flagged. :func:`recorded_warnings` keeps, while a fit runs, every record
of the ``spcopyro`` logger tree at WARNING and above and every Python warning shown, and still
prints them (a study's cells keep theirs instead of printing them:
:func:`spcopyro.study.cell_warnings.captured_warnings`). :func:`write_config` writes
``config.json`` once, last, with the distinct messages in order, by the study's rule
(:func:`~spcopyro.study.cell_warnings.warnings_text`: each cut to 2000 characters, at most 20
and a count of the rest), as a list of strings (empty when the fit gave none).

A chain run in a forked worker process (``--chains K`` on Linux,
:mod:`spcopyro.gibbs.chain_processes`) sends its warnings to the fit's process, which prints
and keeps them as it does a chain's on a thread. The figures drawn in the child that ``fit``
forks for them (:func:`spcopyro.cli.fit_figures.figures_drawn`) print their warnings there and
send them back as it ends; the figures' warnings are kept in the figures' order, as drawn in one
process, whichever process drew which.
"""

from __future__ import annotations

import json
import logging
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from spcopyro.study.cell_warnings import LOGGER, warnings_text

__all__ = ["WARNINGS_KEY", "fit_warnings_note", "recorded_warnings", "write_config"]

WARNINGS_KEY = "warnings"
"""The entry of ``config.json`` that lists the fit's warnings."""


class _Keeper(logging.Handler):
    """Keeps the message of each record at WARNING and above; the logger's other handlers
    print it as before."""

    def __init__(self, said: list[str]) -> None:
        super().__init__(logging.WARNING)
        self.said = said

    def emit(self, record: logging.LogRecord) -> None:  # noqa: D102
        self.said.append(record.getMessage())


@contextmanager
def recorded_warnings() -> Iterator[list[str]]:
    """Within: the ``spcopyro`` logger's records at WARNING and above and the Python warnings
    shown go into the list given (in order, repeats included) as well as where they went."""
    said: list[str] = []
    logger = logging.getLogger(LOGGER)
    keeper = _Keeper(said)
    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        said.append(f"{category.__name__}: {message}")
        shown(message, category, filename, lineno, file, line)

    logger.addHandler(keeper)
    warnings.showwarning = show
    try:
        yield said
    finally:
        logger.removeHandler(keeper)
        if warnings.showwarning is show:  # else someone replaced it meanwhile: theirs
            warnings.showwarning = shown


def write_config(config_path: Path, settings: dict[str, object], said: list[str]) -> None:
    """Write ``config.json``: ``settings`` (the result's
    :meth:`~spcopyro.results.result.SpCoResult.settings_json`) with ``"warnings"`` set to the
    distinct messages of ``said`` in order (the study's rule, module docstring); ``[]`` when
    none. The fit writes it once, after everything else (it was written by the result's save and
    again here)."""
    settings = {**settings, WARNINGS_KEY: json.loads(warnings_text(said) or "[]")}
    config_path.write_text(json.dumps(settings, indent=2) + "\n")


def fit_warnings_note(out: Path) -> str:
    """``"; its fit gave N warnings (...)"`` for a fit folder whose ``config.json`` lists
    warnings, else ``""`` (also for an unreadable one or one written before the entry)."""
    try:
        said = json.loads((out / "config.json").read_text(encoding="utf-8")).get(WARNINGS_KEY)
    except (OSError, ValueError, AttributeError):
        return ""
    if not isinstance(said, list) or not said:
        return ""
    first = str(said[0])
    noun = "warning" if len(said) == 1 else "warnings"
    return (f"; its fit gave {len(said)} {noun} (listed as {WARNINGS_KEY!r} in "
            f"{out / 'config.json'}), the first: {first}")  # fmt: skip
