"""One run at a time in an output folder that runs resume from (a study's cells).

:func:`folder_lock` holds an advisory lock (``fcntl.flock``) on a small file in the folder for as
long as the run lasts; a second run into the same folder while the first holds it is refused at
once, naming the first run's process, instead of both running the same unfinished cells and
rewriting one table. The operating system drops the lock when its process ends, however it ends
(Ctrl-C, a kill, a crash), so a stopped run never leaves the folder locked. The lock file stays
behind (removing it could let two runs lock two different files). Where ``fcntl`` is missing
(Windows) nothing is locked.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows: no advisory locks of this kind
    fcntl = None  # type: ignore[assignment]

__all__ = ["LOCK_NAME", "FolderBusyError", "folder_lock"]

LOCK_NAME = ".spcopyro-run.lock"
"""The lock file's name inside the folder."""


class FolderBusyError(OSError):
    """Another process holds the folder's lock; :attr:`holder` is what it wrote there (its
    process id and start time), or ``"another process"``."""

    def __init__(self, message: str, holder: str = "another process") -> None:
        super().__init__(message)
        self.holder = holder


@contextmanager
def folder_lock(folder: Path, what: str) -> Iterator[None]:
    """Hold ``folder``'s run lock (created with the folder) while the body runs.

    Raises:
        FolderBusyError: another process holds it; the message names the folder, the holder's
            process id and start time (as it wrote them), and ``what`` (e.g. ``"study run"``).
    """
    folder.mkdir(parents=True, exist_ok=True)
    if fcntl is None:
        yield
        return
    path = folder / LOCK_NAME
    with open(path, "a+", encoding="utf-8") as handle:
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            raise FolderBusyError(
                f"{folder} is in use by another {what} ({holder}): wait for it to finish, "
                "or write to another --out; two runs into one folder would run the same cells "
                "and rewrite one table",
                holder,
            ) from None
        try:
            handle.seek(0)
            handle.truncate()
            started = time.strftime("%Y-%m-%d %H:%M:%S")
            handle.write(f"process {os.getpid()}, started {started}")
            handle.flush()
            yield
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
