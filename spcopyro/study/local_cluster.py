"""A study's Dask ``LocalCluster``, started in the background while cells run in this process.

A worker process has to import torch and spcopyro before its first cell (about 3-4 CPU
seconds). Spawned the usual way, every worker does that itself, all at once: on a 2-core
machine both cores spend the cluster's start-up importing while the study's process waits.
:class:`ClusterStart` does two things instead (issue 26):

* the workers are forked from a ``forkserver`` that imports the cells' code once
  (:data:`WORKER_PRELOAD`) with one BLAS/OpenMP thread (:data:`ONE_THREAD`), so a worker starts
  with everything imported and the import costs one core once, not every core;
* the forkserver, and so every worker, starts with SIGINT and SIGTERM blocked
  (:func:`_stop_signals_blocked`): a terminal's Ctrl-C reaches the whole foreground process
  group, and so does the SIGTERM of ``timeout`` or Slurm's ``scancel``; a worker (or the
  forkserver) that took one died with Dask's tracebacks (``distributed.worker - ERROR``,
  ``KeyboardInterrupt``, ``CancelledError``, ``Failed to start process``: the nannies restarted
  dead workers through a dead forkserver) over the study's own "interrupted after N cells"
  line. The study's process decides when the cells stop: it stores the finished ones and
  closes the cluster, whose nannies ask the workers to close and kill (SIGKILL) those still in
  a cell, as Dask always does (and a worker ends when its parent dies);
* the cluster starts on a background thread, and the caller runs cells in this process until
  the workers are up (:mod:`spcopyro.study.run`): the core the start-up leaves free fits cells.
  The Dask cluster itself is made once the forkserver has imported (it creates the file that
  :data:`READY_FILE` names), so that a close before then (every cell ran here already, or a
  Ctrl-C) stops the start at once: the forkserver, which has forked no worker, is killed
  (:meth:`ClusterStart.close`), where the close waited for the whole start to end. The file
  names the study's pid, and a start removes the ready files left by study processes that
  were killed meanwhile (:func:`remove_stale_ready_files`).

Each worker gives tqdm a thread lock of its own at its start (:func:`dask_setup`, a Dask
worker preload): a cell's fit makes progress bars (disabled), and tqdm's first bar in a process
creates a ``multiprocessing`` lock, a named semaphore that only the process's exit handlers
release. A worker stopped mid-cell (a Ctrl-C'd study closes its cluster, whose nannies kill the
workers still running cells) never runs them, and multiprocessing's resource tracker then
warned at the study's exit of "leaked semaphore objects to clean up at shutdown", one per such
worker.

A forked worker's environment is the forkserver's, so Dask's ``pre-spawn-environ`` cannot reach
it: ``MALLOC_TRIM_THRESHOLD_``, which turns off glibc's dynamic mmap threshold and made cells
1.5-2x slower in workers (docs/studies.md), is left out of the forkserver's environment, and
:data:`PRE_SPAWN_ENVIRON`'s entry is unset too for a cluster that spawns.

The cluster's event loops are also made quieter (:data:`QUIET_LOOPS`): by default every worker
samples its task thread's stack every 10 ms for the dashboard's profile and checks its loop
every 20 ms, which took 5-6 % of a core beside each cell here (a cell's process CPU against its
thread's); with these settings 0.3-0.5 %. A study's cluster has no dashboard user to serve.

Where ``forkserver`` is not available (not POSIX), the workers are spawned as Dask does.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager

from spcopyro._util.forking import fresh_tqdm_lock

__all__ = [
    "HEARTBEAT_FAILED", "ONE_THREAD", "PRE_SPAWN_ENVIRON", "QUIET_LOOPS", "READY_FILE",
    "READY_PREFIX", "STOP_SECONDS", "WORKER_PRELOAD", "ClosingHeartbeatFilter", "ClusterStart",
    "local_cluster", "remove_stale_ready_files", "stop_forkserver", "stop_workers",
    "wait_for_forkserver",
]  # fmt: skip

PRE_SPAWN_ENVIRON = "distributed.nanny.pre-spawn-environ"
"""Dask's config of the environment its nanny gives each spawned worker process."""
MULTIPROCESSING_METHOD = "distributed.worker.multiprocessing-method"
WORKER_PRELOAD = ("spcopyro.study.worker_imports",)
"""What the forkserver imports before it forks a worker: dask's worker and a cell's code, the
cyclic collector paused and their objects frozen after (:mod:`spcopyro.study.worker_imports`)."""
ONE_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
"""The workers' environment: one BLAS / OpenMP thread (a worker runs one cell on one core)."""
MALLOC_TRIM = "MALLOC_TRIM_THRESHOLD_"
QUIET_LOOPS = {
    "distributed.worker.profile.enabled": False,  # Dask's default: a stack sample every 10 ms
    "distributed.admin.tick.interval": "1s",  # 20 ms: the blocked-event-loop watchdog
    "distributed.worker.memory.monitor-interval": "1s",  # 100 ms: spill / pause / restart checks
    "distributed.admin.system-monitor.interval": "2s",  # 500 ms: the dashboard's CPU and memory
}
"""Dask settings of the study's LocalCluster (scheduler, nannies and workers; module docstring).
A run on ``--scheduler ADDRESS`` keeps that cluster's own settings."""


@contextmanager
def _environ(values: Mapping[str, str | None]) -> Iterator[None]:
    """``os.environ`` with ``values`` (None: unset) inside the block, restored after."""
    saved = {name: os.environ.get(name) for name in values}
    try:
        for name, value in values.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextmanager
def _stop_signals_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in this thread inside the block: a process started meanwhile
    (the forkserver) inherits the mask across fork and exec, and so do its children (module
    docstring). Python leaves an inherited mask as it is; Dask never unblocks it, and stops its
    workers with SIGKILL where a stop message does not (SIGTERM first where a worker outgrows
    its memory, SIGKILL a monitor tick later)."""
    import signal

    if not hasattr(signal, "pthread_sigmask"):  # not POSIX: no forkserver either
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def forkserver_available() -> bool:
    """Whether this platform has multiprocessing's ``forkserver`` start method."""
    return "forkserver" in multiprocessing.get_all_start_methods()


READY_FILE = "SPCOPYRO_FORKSERVER_READY"
"""The environment variable naming the file that the forkserver creates once it has imported
:data:`WORKER_PRELOAD` (:mod:`spcopyro.study.worker_imports`; :func:`wait_for_forkserver`)."""
_importing: dict[int, str] = {}
"""The forkservers this process started whose import has not been seen to end: pid -> file."""


def start_forkserver() -> None:
    """Start (if not running yet) multiprocessing's forkserver with :data:`WORKER_PRELOAD`, the
    workers' environment and SIGINT and SIGTERM blocked (module docstring). Returns at once:
    the server imports in its own process, and a worker's fork waits for it
    (:func:`wait_for_forkserver`). A forkserver already running (an earlier study in this
    process) is kept as it is."""
    import multiprocessing.forkserver as forkserver
    import tempfile
    import uuid
    from multiprocessing import resource_tracker

    import dask
    from distributed.utils import get_mp_context

    with dask.config.set({MULTIPROCESSING_METHOD: "forkserver"}):
        get_mp_context()  # dask sets its own preload list once per process: before ours
    forkserver.set_forkserver_preload(list(WORKER_PRELOAD))
    resource_tracker.ensure_running()  # first: starting it unblocks both in this thread
    folder = tempfile.gettempdir()
    remove_stale_ready_files(folder)
    ready = os.path.join(folder, f"{READY_PREFIX}{os.getpid()}-{uuid.uuid4().hex}.ready")
    before = forkserver._forkserver._forkserver_pid
    with _environ({**ONE_THREAD, MALLOC_TRIM: None, READY_FILE: ready}), _stop_signals_blocked():
        forkserver.ensure_running()
    pid = forkserver._forkserver._forkserver_pid
    if pid is not None and pid != before:  # started here: its import has begun
        _importing[pid] = ready
        _stop_at_exit()


_exit_stop_of: list[int] = []
"""The process whose exit stops the forkserver (:func:`_stop_at_exit`), once registered."""


def _stop_at_exit() -> None:
    """Stop the forkserver when this process exits (its :mod:`atexit` handlers, which the
    ``spcopyro`` command runs too). Left to itself, it exits on its pipe's end-of-file once
    this process has ended, and then tears down an interpreter holding torch and the cells'
    code: it outlived the study by about 1 s (2-core machine, load 6), using a core. Killed
    here instead (SIGKILL: it holds nothing to save, its workers closed with their cluster),
    and not waited for (reaping it took 70 ms of the exit): this process ends next. A
    forkserver with workers still alive (a cluster left open: its nannies learn of their
    workers' ends through it) is left to end as before, and a process forked from this one,
    which inherits the handler, leaves its parent's forkserver alone."""
    import atexit

    if _exit_stop_of != [os.getpid()]:
        _exit_stop_of[:] = [os.getpid()]
        atexit.register(_stop_if_mine, os.getpid())


def _stop_if_mine(owner: int) -> None:
    import multiprocessing.forkserver as forkserver

    import psutil  # a dependency of dask.distributed, which started the forkserver

    pid = forkserver._forkserver._forkserver_pid
    if os.getpid() != owner or pid is None:
        return
    try:
        if psutil.Process(pid).children():  # workers of a cluster not closed
            return
    except psutil.Error:  # ended already
        return
    _kill(pid, reap=None)


READY_PREFIX = "spcopyro-forkserver-"
"""A ready file's name: this prefix, the pid of the process that waits for it, a random part."""
UNOWNED_STALE_SECONDS = 3600.0


def remove_stale_ready_files(folder: str) -> None:
    """Remove the forkservers' ready files in ``folder`` whose process is gone. A study's
    process removes its own once it sees it (:func:`wait_for_forkserver`, :func:`stop_forkserver`);
    one killed (SIGKILL, an out-of-memory kill) while its forkserver imported left it behind,
    created by the forkserver after that process's death, and they piled up in the temp folder.
    A file names its process's pid (:data:`READY_PREFIX`); it is stale when no process has that
    pid, or the process that has it started after the file was made (the pid reused). A file
    without a pid in its name (spcopyro before 2026-12-05) is removed once an hour old. Files
    of another user, which this one may not remove, are left."""
    import glob
    import time

    for path in glob.glob(os.path.join(glob.escape(folder), f"{READY_PREFIX}*.ready")):
        owner = os.path.basename(path).removeprefix(READY_PREFIX).split("-", 1)[0]
        try:
            made = os.path.getmtime(path)
            if (_running(int(owner), made) if owner.isdigit()
                    else time.time() - made < UNOWNED_STALE_SECONDS):  # fmt: skip
                continue
            os.remove(path)
        except OSError:  # removed meanwhile, or not this user's
            continue


def wait_for_forkserver(cancelled: threading.Event, poll: float = 0.02) -> bool:
    """Wait until the forkserver that :func:`start_forkserver` started has imported
    :data:`WORKER_PRELOAD` (or has died: the cluster's start then says why); True at once for
    one seen ready before. When ``cancelled`` is set first, the forkserver is stopped
    (:func:`stop_forkserver`: it has forked no worker yet) and False returned: a study whose
    cells all ran in its own process meanwhile, or an interrupted one, does not wait 3-4 s for
    an import whose cluster nobody needs."""
    import multiprocessing.forkserver as forkserver

    pid = forkserver._forkserver._forkserver_pid
    ready = _importing.get(pid) if pid is not None else None
    while ready is not None and not os.path.exists(ready) and _running(pid):
        if cancelled.wait(poll):
            stop_forkserver()
            return False
    _importing.pop(pid, None)  # type: ignore[arg-type]
    if ready is not None and os.path.exists(ready):
        os.remove(ready)
    return True


def _running(pid: int, made: float | None = None) -> bool:
    """Whether process ``pid`` runs (not ended, nor a zombie not reaped yet) and, given
    ``made`` (a file's mtime, seconds), started before it (1 s of slack): the process that
    made the file, not a later one given its pid."""
    import psutil  # a dependency of dask.distributed

    try:
        process = psutil.Process(pid)
        return process.status() != psutil.STATUS_ZOMBIE and (
            made is None or process.create_time() <= made + 1.0
        )
    except psutil.Error:
        return False


def stop_forkserver() -> None:
    """Kill (SIGKILL: it blocks SIGINT and SIGTERM) the forkserver while it imports, before it
    forked any worker, and reap it; the next :func:`start_forkserver` starts a new one."""
    import multiprocessing.forkserver as forkserver

    server = forkserver._forkserver
    pid = server._forkserver_pid
    if pid is None:
        return
    _kill(pid, reap=server._stop)  # closes its pipe, reaps it (waitpid) and forgets it


def _kill(pid: int, reap: Callable[[], object] | None) -> None:
    """SIGKILL the forkserver ``pid``, then ``reap()`` it (its errors ignored: ensure_running
    finds it dead and starts another) unless None, and remove its ready file if any."""
    import signal

    ready = _importing.pop(pid, None)
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    if reap is not None:
        try:
            reap()
        except Exception:  # noqa: S110
            pass
    if ready is not None and os.path.exists(ready):
        os.remove(ready)


def dask_setup(worker: object) -> None:
    """Dask's preload hook (``preload=[__name__]``), run in each worker process of the study's
    LocalCluster as it starts: tqdm's lock a thread lock, not a semaphore (module docstring),
    and a closing worker's heartbeat error dropped (:class:`ClosingHeartbeatFilter`)."""
    fresh_tqdm_lock()
    logging.getLogger("distributed.worker").addFilter(ClosingHeartbeatFilter(worker))


HEARTBEAT_FAILED = "Failed to communicate with scheduler during heartbeat"
"""The start of the error a Dask worker logs when a heartbeat's connection closes under it."""


class ClosingHeartbeatFilter(logging.Filter):
    """Drops ``distributed.worker``'s heartbeat error (:data:`HEARTBEAT_FAILED`) of a worker
    that is closing. ``Worker.close`` closes its connections (``rpc.close()``) while a heartbeat
    may still wait for the scheduler's reply, slow while the study's process writes its table,
    and Dask logs the closed stream as an ERROR with two tracebacks (``StreamClosedError``,
    ``CommClosedError``): 2 of 5 interrupted studies on 2 workers printed them over their
    "interrupted after N cells" line. A running worker's heartbeat error is kept."""

    def __init__(self, worker: object) -> None:
        super().__init__()
        self.worker = worker

    def filter(self, record: logging.LogRecord) -> bool:
        from distributed.core import Status

        closing = (Status.closing, Status.closing_gracefully, Status.closed)
        return not (str(record.msg).startswith(HEARTBEAT_FAILED)
                    and getattr(self.worker, "status", None) in closing)  # fmt: skip


def default_method() -> str:
    """How the workers' processes start: ``forkserver`` where available, else ``spawn``."""
    return "forkserver" if forkserver_available() else "spawn"


def local_cluster(workers: int, method: str | None = None):
    """A ``LocalCluster`` of ``workers`` processes with one thread each, their processes
    started by ``method`` (``forkserver``, ``spawn``; None: :func:`default_method`)."""
    import dask
    from distributed import LocalCluster

    if method is None:
        method = default_method()
    if method == "forkserver":
        start_forkserver()
    config = {
        f"{PRE_SPAWN_ENVIRON}.{MALLOC_TRIM}": None, MULTIPROCESSING_METHOD: method, **QUIET_LOOPS,
    }  # fmt: skip
    with dask.config.set(config):
        return LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
            silence_logs=logging.ERROR, env=dict(ONE_THREAD),
            preload=[*dask.config.get("distributed.worker.preload", []), __name__],
        )  # fmt: skip


class ClusterStart:
    """A ``LocalCluster`` and its ``Client``, started on a background thread.

    ``on_ready(client)`` runs on that thread as soon as the client is connected (the caller
    submits its remaining cells there, so no worker waits for this process's cell to end).
    :meth:`wait` joins the thread and returns the client (or raises the start's error);
    :meth:`close` stops the start where it can and closes whatever was started.
    """

    def __init__(self, workers: int, on_ready: Callable[[object], None] | None = None) -> None:
        self.cluster = None
        self.client = None
        self.error: BaseException | None = None
        self._on_ready = on_ready
        self._cancelled = threading.Event()
        self._thread = threading.Thread(
            target=self._start, args=(workers,), name="spcopyro-cluster-start", daemon=True
        )
        self._thread.start()

    def _start(self, workers: int) -> None:
        try:
            method = default_method()
            if method == "forkserver":
                start_forkserver()  # its import runs while this process imports distributed
            from distributed import Client

            if method == "forkserver" and not wait_for_forkserver(self._cancelled):
                return  # closed while the forkserver imported: nothing else was started
            if self._cancelled.is_set():
                return
            self.cluster = local_cluster(workers, method)
            if self._cancelled.is_set():
                return  # close() closes it
            self.client = Client(self.cluster)
            if self._on_ready is not None:
                self._on_ready(self.client)
        except BaseException as error:  # handed to wait()
            self.error = error

    def ready(self) -> bool:
        """Whether the start has ended (the client is up, or the start failed)."""
        return not self._thread.is_alive()

    def wait(self):
        """The client, once started; raises the start's error."""
        self._thread.join()
        if self.error is not None:
            raise self.error
        return self.client

    def close(self, now: bool = False) -> None:
        """Stop the start, then close the client and the cluster. A start still waiting for
        the forkserver's import (3-4 s) ends at once, the forkserver killed before it forked
        any worker; one past it (the Dask cluster's own start, the last 0.1-0.5 s) is waited
        for. ``now`` (an interrupted study, whose finished cells are collected): a worker still
        in a cell is killed after :data:`STOP_SECONDS`, not after Dask's 4 s
        (:func:`stop_workers`)."""
        self._cancelled.set()
        self._thread.join()
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            if now:
                stop_workers(self.cluster, STOP_SECONDS)
            self.cluster.close()


STOP_SECONDS = 0.5
"""How long an interrupted study's close waits for a worker to end its cell before killing it
(``Nanny.close(timeout)``: 0.8 of it, then SIGKILL)."""


def stop_workers(cluster: object, timeout: float) -> None:
    """Close ``cluster``'s nannies with ``timeout``: each asks its worker to close and kills it
    (SIGKILL) after ``0.8 * timeout`` s if it is still in a cell. The cluster's own close asks
    with Dask's default (5: 4 s), which held an interrupted study's exit 4 s per busy worker
    set, for cells whose result nobody waits for. A nanny closed here is not restarted, and the
    cluster's close then finds it closed; an error here is left to that close."""
    import asyncio

    async def close_all() -> None:
        nannies = list(cluster.workers.values())  # type: ignore[attr-defined]
        await asyncio.gather(*(n.close(timeout=timeout, reason="spcopyro-study-interrupted")
                               for n in nannies), return_exceptions=True)  # fmt: skip

    try:
        cluster.sync(close_all)  # type: ignore[attr-defined]  # on the cluster's event loop
    except Exception:  # noqa: S110  # the cluster's close follows and says what is wrong
        pass
