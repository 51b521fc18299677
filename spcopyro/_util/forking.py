"""When this process may fork a worker that goes on running Python: :func:`fork_refusal`.

A forked child has only the thread that forked it. A lock another thread held at the fork stays
held in the child forever, and an OpenMP team (torch's intra-op threads) cannot be used there.
So the project forks only on Linux (macOS's system frameworks are not fork-safe, Windows cannot
fork), with no other Python thread running, and, where the child runs torch, at one torch
intra-op thread. tqdm's monitor thread does not count: every progress bar starts it, even a
disabled one, and it only takes tqdm's lock, which a child must replace before it makes a bar
(:func:`fresh_tqdm_lock`). Imports nothing of the package, and torch only when asked about it.
"""

from __future__ import annotations

import sys
import threading
import warnings
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from multiprocessing.process import BaseProcess


def other_threads() -> list[str]:
    """Names of the live Python threads other than this one and tqdm's monitor."""
    current = threading.current_thread()
    return [
        thread.name for thread in threading.enumerate()
        if thread is not current and type(thread).__name__ != "TMonitor"
    ]  # fmt: skip


def fork_refusal(uses_torch: bool = True) -> str | None:
    """None if this process may fork a worker here, else the reason it may not. ``uses_torch``:
    the child runs torch operations (then torch must be at one intra-op thread)."""
    if not sys.platform.startswith("linux"):
        return f"forking is not used on {sys.platform}"
    if uses_torch:
        import torch

        if torch.get_num_threads() != 1:
            return f"torch runs {torch.get_num_threads()} intra-op threads (an OpenMP team)"
    if others := other_threads():
        return f"other threads are running ({', '.join(others)})"
    return None


def start_forked(process: BaseProcess) -> None:
    """``process.start()`` for a process of the fork context, once :func:`fork_refusal` allowed
    it. Python >= 3.12 documents a DeprecationWarning at a fork of a process with OS threads (not
    seen with 3.12.1 / 3.13.0 here): torch keeps native helper threads that the child does not
    use (no torch there, or one intra-op thread), and no Python thread runs; the warning is
    filtered as a precaution for warnings-as-errors."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", r"This process .* is multi-threaded", DeprecationWarning)
        process.start()


def fresh_tqdm_lock() -> None:
    """In a forked child: give its progress bars a lock of their own (tqdm's monitor thread may
    have held the parent's at the fork, and every bar, even a disabled one, takes it)."""
    import tqdm.auto
    import tqdm.std

    for cls in {tqdm.std.tqdm, tqdm.auto.tqdm}:
        cls.set_lock(threading.RLock())
