"""Short echoes of bad input in error messages: enough to recognise the value, never kilobytes.

A loader that rejects a line echoes it, so the reader can find it; a ragged 205-column Ft.csv
row is about 5 KB, which buries the message. :func:`echo` gives the ``repr`` of a value when it is
short, else the first :data:`ECHO_LIMIT` characters and how long the whole is; :func:`listed`
lists words (or entries) the same way, the first few and how many more (:func:`shown_count`:
one over the few is named, not counted). :func:`warn_once`
logs a warning once a process, for what a study's hundreds of fits would repeat.
:func:`setting` names a setting a message tells the user to change, for both of its readers: a
library caller and ``spcopyro fit``. :func:`shown_bytes` shows a byte that is not UTF-8 (a map
yaml's, a path's) as ``\\xe9``. Imports nothing of the package, so every layer (maps, data,
features) can use it.
"""

from __future__ import annotations

import logging
import re
import threading
from collections.abc import Hashable, Iterator, Sequence, Sized
from contextlib import contextmanager

__all__ = [
    "ECHO_LIMIT", "KNOWN_WORDS_SHOWN", "area_text", "echo", "fixed", "listed", "one_of", "plural",
    "seconds_text", "setting", "shown_bytes", "shown_count", "warn_once", "warned_apart",
    "with_article",
]  # fmt: skip

ECHO_LIMIT = 80
"""Characters of a value that an error message shows."""


def echo(value: object, limit: int = ECHO_LIMIT) -> str:
    """``repr(value)``, shortened to its first ``limit`` characters when longer.

    A long string (a line of a file) shows its first ``limit`` characters, then ``...`` and its
    number of comma-separated values (when it holds commas) and characters, e.g.
    ``'0.1,0.2,...'... (205 values, 4100 characters)``; another value's ``repr`` is cut the same
    way, with its number of entries when it has a length.
    """
    if isinstance(value, str):
        if len(value) <= limit:
            return repr(value)
        values = value.count(",") + 1
        count = f"{values} values, " if values > 1 else ""
        return f"{value[:limit]!r}... ({count}{len(value)} characters)"
    text = repr(value)
    if len(text) <= limit:
        return text
    count = f"{len(value)} entries, " if isinstance(value, Sized) else ""
    return f"{text[:limit]}... ({count}{len(text)} characters)"


KNOWN_WORDS_SHOWN = 30
"""Known words an unknown word's error lists when none is close (a home's vocabulary, 14-17
words in the public houses, whole: the list stopped at 10)."""


def shown_count(total: int, shown: int) -> int:
    """How many of ``total`` entries a list that names at most ``shown`` and counts the rest
    names: ``min(total, shown)``, but all of them when one is over, since one over the limit is
    named, not counted ("..., ... (1 more)" or "and 1 more word" takes as much of the line as
    the entry it hides: ``where``'s note on room1dk6's 'bedroom' hid 'table' so)."""
    return total if total == shown + 1 else min(total, shown)


def listed(words: Sequence[str], shown: int = KNOWN_WORDS_SHOWN) -> str:
    """``words`` joined by ", ", the first ``shown`` of them, then ", ... (N more)" for the
    rest (:func:`shown_count`: all ``shown + 1`` where one is over): how an error or a warning
    lists words (``where``'s unknown word, ``navigate``'s instruction, ``fit --update``'s unheard
    words, renamed saved words, a St.csv's words with invisible characters or written without
    spaces). Its default, a home's whole vocabulary: ``navigate``'s list stopped at 12 and hid
    room1dk5's 'washroom' from "go to the bathroom"."""
    named = shown_count(len(words), shown)
    more = len(words) - named
    return ", ".join(words[:named]) + (f", ... ({more} more)" if more > 0 else "")


def one_of(values: Sequence[object]) -> str:
    """``"'count', 'tfidf' or 'auto'"``: the allowed ``values`` as an error lists them, each as
    Python writes it, the last after "or"."""
    said = [repr(value) for value in values]
    return " or ".join([", ".join(said[:-1]), said[-1]] if len(said) > 1 else said)


def setting(python: str, flag: str, command: str = "fit") -> str:
    """``"gamma=2 (fit's --gamma 2)"``: a setting as Python gives it (``python``: a field,
    keyword or argument, with its value where the message suggests one), then as ``command``
    does (``flag``). The model's, the fit's and the methods' warnings and errors reach a library
    caller (``fit_house``, ``SpCoGibbs`` under ``pyro.infer.MCMC``, a guide under ``SVI``) as
    they reach ``spcopyro fit``, so they name both, in this one form; a message only the
    command line gives names its flag alone."""
    return f"{python} ({command}'s {flag})"


def plural(number: int, noun: str) -> str:
    """``"1 room"``, ``"3 rooms"``: ``number`` and ``noun``, plural but for one."""
    return f"{number} {noun}{'' if number == 1 else 's'}"


def area_text(area: float) -> str:
    """An area in square metres as the outputs write it (no unit): one decimal from 1 m^2, two
    below. With one, a place of 0.25 m^2, kept by the place graph's default ``min_area`` 0.25,
    read "0.2 m^2" under "regions under 0.25 m^2 left out", and navigate's goal of 0.25 m^2
    read "0.3 m^2" beside its warning's "the goal is in the largest, 0.25 m^2"."""
    return f"{area:.1f}" if area >= 1.0 else f"{area:.2f}"


_SPELT_OUT = frozenset({"em", "lbp", "mcmc", "svi", "vi"})  # method names said letter by letter


def with_article(name: str) -> str:
    """``name`` after its indefinite article as said aloud: "an lbp", "an svi", "a cavi",
    "a gibbs", "a vi-gibbs", "a stochastic-vi". A name (its part before a ``-``) said letter
    by letter (one of a few initialisms, or one without a vowel) takes the article of its first
    letter's name ("el", "ess": "an"; "vee": "a"), another that of its first letter. Quotes
    around the name are not said: "an 'svi'", "a 'cavi'"."""
    first = name.strip("'\"").split("-", 1)[0].lower()
    spelt = first in _SPELT_OUT or not any(c in "aeiou" for c in first)
    vowel_sound = first[:1] in ("aefhilmnorsx" if spelt else "aeiou")
    return f"{'an' if vowel_sound else 'a'} {name}"


def fixed(value: float, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals and never a negative zero: an ARI of -0.0001 (chance)
    printed "-0.000" in the study and experiment tables."""
    return f"{round(value, digits) + 0.0:.{digits}f}"


def seconds_text(value: float) -> str:
    """Seconds as the reports' tables print them: one decimal from 0.1 s on, two significant
    digits below (a baseline fitted in 3 ms read "0.0", the same as no time at all)."""
    if value != value or abs(value) >= 0.095:  # NaN, or where one decimal says enough
        return f"{value:.1f}"
    return f"{value:.2g}"


def command_time(seconds: float, cached: int) -> str:
    """The wall-clock sentence of a report drawn by a study command: ``cached`` cells found
    finished are not in ``seconds`` (a resumed or repeated run read "Whole command: 0 s", as if
    the whole study had taken no time)."""
    if not cached:
        return f"Whole command: {seconds:.0f} s wall-clock."
    were = "was" if cached == 1 else "were"
    return (
        f"This command: {seconds:.0f} s wall-clock; {plural(cached, 'cell')} of the table "
        f"{were} finished before it (read from the cache, their fits not in that time)."
    )


_WARNED: set[Hashable] = set()
"""The keys :func:`warn_once` has warned about in this process."""
_apart = threading.local()
"""``warned``: the keys of this thread's :func:`warned_apart` block, where one is open."""


def warn_once(key: Hashable, message: str) -> bool:
    """Log ``message`` (logger ``"spcopyro"``, WARNING) the first time this process meets
    ``key`` (name what the warning is about in it, e.g. ``("stick-breaking", alpha, L)``), or
    inside :func:`warned_apart` the first time its block meets it; whether it was logged."""
    apart: set[Hashable] | None = getattr(_apart, "warned", None)
    memory = _WARNED if apart is None else apart
    if key in memory:
        return False
    memory.add(key)
    _WARNED.add(key)  # said in this process
    logging.getLogger("spcopyro").warning(message)
    return True


@contextmanager
def warned_apart() -> Iterator[None]:
    """Within: :func:`warn_once` in this thread remembers what it said in the block alone, so it
    says again once what this process said before (a study cell keeps the warnings its own fit
    gives). Other threads keep the process's memory, and their blocks their own: cells run on
    several threads of one process (a Dask worker with ``--nthreads`` > 1) neither lose nor
    repeat each other's warnings, as emptying the process's memory for each cell did."""
    outer = getattr(_apart, "warned", None)
    _apart.warned = set()
    try:
        yield
    finally:
        _apart.warned = outer


_SHOWN_STAND_IN = re.compile(
    r"[\U000F0080-\U000F00FF\uDC80-\uDCFF]|\\(?:U000f00|udc)[89a-f][0-9a-f]"
)
"""A byte that is not UTF-8 in a message: its stand-in, itself or as repr writes it
(``\\U000f00e9``), or a path's surrogate, itself (``'\\udce9'``: ``os.fsdecode`` of a folder
named ``b"caf\\xe9"``, as an f-string puts a path in) or as repr writes it (``\\udce9``): each
shown as ``\\xe9``. A lone surrogate printed raw read ``caf\\udce9`` on stderr, and raised
UnicodeEncodeError on a strict UTF-8 stream. The stand-ins (U+F0080..U+F00FF) are those
:mod:`spcopyro.maps.map_yaml` reads a yaml's bytes that are not UTF-8 as."""


def _stand_in_byte(shown: str) -> int:
    """The byte a :data:`_SHOWN_STAND_IN` match stands for."""
    return (ord(shown) if len(shown) == 1 else int(shown[-2:], 16)) & 0xFF


def shown_bytes(message: str) -> str:
    """``message`` with each byte that is not UTF-8 (:data:`_SHOWN_STAND_IN`) shown as ``\\xe9``:
    every :class:`~spcopyro.maps.map_yaml.MapFormatError`'s message, the map logger's warnings,
    and the command line's error and warning lines."""
    return _SHOWN_STAND_IN.sub(lambda m: f"\\x{_stand_in_byte(m[0]):02x}", message)
