"""Where a key of a study file is written: the line a :class:`~spcopyro.study.spec.StudyError`
names (``study.toml:12: [data.small] num_roms = 2: ...``).

``tomllib`` gives values without their lines, so :func:`key_line` reads the text again: every
table header (``[data."my house"]``) and every ``key = value`` line (dotted and quoted keys
included) gets its full path of names, and the line asked for is the one whose path is the
longest beginning of the wanted path: the key's own line, else the inline table holding it
(``sweeps = { gibbs = 5 }`` for ``sweeps.gibbs``), else its table's header.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

__all__ = ["file_line", "key_line", "named_key", "where_path"]

_PART = r'(?:"(?:[^"\\]|\\.)*"|\'[^\']*\'|[A-Za-z0-9_-]+)'
_PATH = rf"{_PART}(?:\s*\.\s*{_PART})*"
_HEADER = re.compile(rf"^\s*\[\s*({_PATH})\s*\]")
_KEY = re.compile(rf"^\s*({_PATH})\s*=")


def file_line(source: str, where: str) -> str:
    """``FILE:LINE`` of ``where`` in the study file ``source``, or ``source`` alone when it is no
    file (``<python>``) or names no such key."""
    try:
        text = Path(source).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return source
    line = key_line(text, where_path(where))
    return source if line is None else f"{source}:{line}"


def _parts(path: str) -> tuple[str, ...]:
    """``variants."og3+sw"`` -> ``("variants", "og3+sw")``."""
    parts = []
    for match in re.finditer(_PART, path):
        part = match.group(0)
        if part[0] in "\"'":
            part = part[1:-1]
            if match.group(0)[0] == '"':
                part = part.replace('\\"', '"').replace("\\\\", "\\")
        parts.append(part)
    return tuple(parts)


def where_path(where: str) -> tuple[str, ...]:
    """The names of an error's ``where``: ``[data.small] num_rooms`` -> ``("data", "small",
    "num_rooms")``; ``[study] sweeps.gibbs`` -> ``("study", "sweeps", "gibbs")``;
    ``variants.a`` -> ``("variants", "a")``. A table name may hold dots (``[data.a.b]``:
    the source ``a.b``), so the part in brackets splits at its first dot only."""
    match = re.match(r"^\[([^\]]*)\]\s*(.*)$", where)
    if match is None:
        table, key = where, ""
    else:
        table, key = match.group(1), match.group(2)
    head, _, name = table.partition(".")
    path = (head, name) if name else (head,)
    return path + tuple(k for k in key.split(".") if k) if key else path


def key_line(text: str, path: tuple[str, ...]) -> int | None:
    """The line number (from 1) of ``path`` in the TOML ``text`` (module docstring); None when
    no line names it or a beginning of it."""
    table: tuple[str, ...] = ()
    best: tuple[int, int] | None = None  # (length of the path matched, line)
    for number, line in enumerate(text.splitlines(), start=1):
        header = _HEADER.match(line)
        if header is not None and not line.lstrip().startswith("[["):
            table = _parts(header.group(1))
            full = table
        else:
            key = _KEY.match(line)
            if key is None:
                continue
            full = table + _parts(key.group(1))
        if _joined_prefix(full, path) and (best is None or len(full) > best[0]):
            best = (len(full), number)
    return None if best is None else best[1]


def _joined_prefix(full: tuple[str, ...], path: tuple[str, ...]) -> bool:
    """Whether ``full`` begins ``path``; a quoted key with dots (``"hyper.alpha" = true``) is
    the same as the dotted one."""
    if full == path[: len(full)]:
        return True
    joined, wanted = ".".join(full), ".".join(path)
    return wanted == joined or wanted.startswith(joined + ".")


def named_key(message: str, keys: Sequence[str]) -> str | None:
    """The first of ``keys`` an error's ``message`` names, or None: the line its error points
    at. The forms are tried in turn over all keys, the surest first: ``gama=3`` (a whole key
    set), ``'gamma'``, ``HouseSpec.num_rooms 9``, then a nested key's last name (``alpha=3``
    for ``hyper.alpha``); so ``hyper.log_gamma_sd=2.0 ... (hyper.gamma ...)`` is not ``gamma``."""
    forms = (
        lambda key: rf"(?<![\w.]){re.escape(key)}=",
        lambda key: rf"'{re.escape(key)}'",
        lambda key: rf"\.{re.escape(key)}[ =]",
        lambda key: rf"(?<![\w.]){re.escape(key.rpartition('.')[2])}=",
    )
    for form in forms:
        for key in keys:
            if re.search(form(key), message):
                return key
    return None
