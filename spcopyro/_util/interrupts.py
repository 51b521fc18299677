"""Ctrl-C and SIGTERM as the commands see them.

A signal handler that raises (Python's own for SIGINT, ``fit``'s for SIGTERM) runs when the
interpreter next checks for signals. When that check falls inside a compiled call -- a numba
dispatcher boxing its result, e.g. :func:`spcopyro.gibbs.region_numba.grow_region` -- the call
ends with ``SystemError: CPUDispatcher(...) returned a result with an exception set`` whose
``__cause__`` is the :class:`KeyboardInterrupt` (measured: three of four signals landing in a loop
of ``grow_region`` calls came out so). :func:`caused_by_interrupt` recognises it, so that the
interrupt is handled as one (the chain's checkpoint kept, exit code 130, a study's cell not
stored as failed) instead of as a crash.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import signal
import threading
from collections.abc import Callable, Iterator

__all__ = [
    "caused_by_interrupt",
    "interrupts_raised",
    "remove_tree",
    "sigterm_as_interrupt",
    "signals_blocked",
    "signals_deferred",
]


def caused_by_interrupt(error: BaseException | None) -> bool:
    """Whether ``error`` is a :class:`KeyboardInterrupt`, or a :class:`SystemError` (any number of
    them, each the ``__cause__`` of the one before) that compiled code raised because the
    interrupt's handler ran inside it (module doc)."""
    while isinstance(error, SystemError):
        error = error.__cause__
    return isinstance(error, KeyboardInterrupt)


@contextlib.contextmanager
def interrupts_raised() -> Iterator[None]:
    """Raise a :class:`SystemError` caused by an interrupt (:func:`caused_by_interrupt`) as the
    :class:`KeyboardInterrupt` it was."""
    try:
        yield
    except SystemError as error:
        if not caused_by_interrupt(error):
            raise
        raise KeyboardInterrupt("interrupted inside compiled code") from error


def remove_tree(path: str | os.PathLike[str]) -> None:
    """``shutil.rmtree(path, ignore_errors=True)``, a Ctrl-C meanwhile raised as the
    :class:`KeyboardInterrupt` it is. One that lands just after rmtree closed a folder's
    descriptor, before it noted so, makes rmtree's ``finally`` close it again (Python 3.11): the
    ``EBADF`` :class:`OSError` raised there, the interrupt its context, stood for the interrupt
    (``spcopyro`` said ``error: [Errno 9] Bad file descriptor``, with status 2 where no Ctrl-C was
    held before, instead of only its Ctrl-C line and 130). What is left of ``path`` stays."""
    try:
        shutil.rmtree(path, ignore_errors=True)
    except OSError as error:
        if error.errno == errno.EBADF and isinstance(error.__context__, KeyboardInterrupt):
            raise error.__context__ from None
        raise


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (what ``timeout``, systemd, docker and Slurm send) stops a fit as Ctrl-C does:
    a KeyboardInterrupt in the main thread, so the chains stop at a completed sweep and the
    checkpoint and the command to continue are kept. The previous handler comes back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def signals_deferred(handler: Callable[[int, object], None]) -> Iterator[None]:
    """In the block, SIGINT and SIGTERM, where Python handlers turn them into an interrupt (the
    default one for SIGINT; ``spcopyro fit``'s for SIGTERM), call ``handler`` instead of raising
    :class:`KeyboardInterrupt` wherever this thread is, so that what the block does is done
    whole (a chain worker's message read and applied: :mod:`spcopyro.gibbs.chain_processes`; a
    study's table and report written: :mod:`spcopyro.study.run`). A signal ignored or left to
    the OS stays so. The previous handlers come back after, every one even where putting one
    back raises (a signal pending: its handler's KeyboardInterrupt, raised once all are back).
    Only the main thread can set handlers; elsewhere no signal is raised in this thread anyway."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {
        number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)
        if callable(signal.getsignal(number))
    }  # fmt: skip
    for number in previous:
        signal.signal(number, handler)
    try:
        yield
    finally:
        raised: BaseException | None = None
        for number, old in previous.items():  # every one, even if a pending signal's raises
            try:
                signal.signal(number, old)
            except BaseException as error:  # noqa: BLE001 - re-raised once all are restored
                raised = raised or error
        if raised is not None:
            raise raised


@contextlib.contextmanager
def signals_blocked() -> Iterator[set[signal.Signals] | None]:
    """In the block, SIGINT and SIGTERM blocked in this thread (:func:`signal.pthread_sigmask`):
    one that comes meanwhile waits, and its handler runs as the block ends (in the call that
    unblocks it, a :class:`KeyboardInterrupt` raised there). A child forked in the block starts
    with them blocked: no handler it inherited can raise in it (in its copy of this process's
    code) before it puts its own in place and unblocks them (with the mask yielded: the one
    before the block; None where there is no ``pthread_sigmask``, nothing blocked)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield None
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield previous
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
