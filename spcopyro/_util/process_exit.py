"""Ending the ``spcopyro`` command's process without the interpreter's teardown (issue 25).

When a Python process exits, the interpreter first waits for its non-daemon threads, runs the
:mod:`atexit` handlers and flushes the standard streams, then tears itself down: it clears every
module and frees the objects they hold. After a fit the last step alone takes 0.2-0.4 s on this
project's 2-core machine (``import torch, numba`` then exit: 0.2-0.44 s, against 0.03-0.14 s when
the process ends once the handlers ran), the objects being torch's, numba's and LLVM's.

:func:`exit_process` does the first three steps as the interpreter does, then ends the process
with :func:`os._exit`. What it skips is what Python does not promise at exit anyway: ``__del__``
of objects still alive then. Every output of a command is written and closed before
:func:`~spcopyro.cli.main.console_main` calls it.

It is taken only where the process's ``__main__`` is the program calling it (the ``spcopyro``
console script, ``python -m spcopyro``), with no profiler or tracer set (``python -m cProfile``
writes its statistics after the program returns) and not ``python -i``: a program that calls
``console_main`` itself (``python -c``, a test) gets :class:`SystemExit` as before.
"""

from __future__ import annotations

import atexit
import os
import sys
import threading
from typing import NoReturn

__all__ = ["exit_process", "may_skip_teardown"]


def may_skip_teardown(caller_globals: dict[str, object]) -> bool:
    """Whether a process whose exit is asked for by code running in ``caller_globals`` may end
    without the teardown (module docstring): that code is the top level of the process's
    ``__main__`` file, nothing profiles or traces it, and no interactive prompt follows."""
    main = sys.modules.get("__main__")
    return (
        main is not None
        and getattr(main, "__file__", None) is not None
        and caller_globals is vars(main)
        and sys.getprofile() is None
        and sys.gettrace() is None
        and not sys.flags.inspect
    )


def exit_process(code: int) -> NoReturn:
    """End the process with status ``code``: wait for its non-daemon threads (and the workers of
    its thread pools), run the :mod:`atexit` handlers, flush standard output and error, then
    :func:`os._exit`. Where a stream cannot be flushed (a closed pipe), the interpreter's own exit
    is left to report it (``sys.exit``)."""
    threading._shutdown()  # type: ignore[attr-defined]  # what the interpreter's exit calls first
    atexit._run_exitfuncs()
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):
        sys.exit(code)
    os._exit(code)
