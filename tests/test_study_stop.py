"""An interrupted study on a LocalCluster ended 7-11 s after its Ctrl-C when the cluster had
just started: the close asked every worker still in a cell (whose result nobody waited for any
more) to close and killed it only 4 s later (Dask's ``Nanny.close(timeout=5)``). The close of an
interrupted run kills them after :data:`spcopyro.study.local_cluster.STOP_SECONDS`."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
import threading
import time

import pytest
from study_setup import counting_start, fake_cluster, on_a_cluster, one_variant_study

from spcopyro.study import run as study_run
from spcopyro.study.run import run_study


def test_an_interrupted_dask_run_closes_its_cluster_now(tmp_path, monkeypatch):
    """Ctrl-C in a cell this process runs while the cluster starts: the cluster's close is
    asked to stop the workers now; a run that ends whole closes it as before."""
    closes: list[dict[str, object]] = []

    class FakeStart:
        def __init__(self, workers, on_ready=None):
            pass

        def wait(self):
            return None

        def close(self, **kwargs):
            closes.append(kwargs)

    def interrupted(cell):
        raise KeyboardInterrupt

    fake_cluster(monkeypatch, FakeStart)
    on_a_cluster(monkeypatch)  # 2 short cells: the cluster path all the same
    monkeypatch.setattr(study_run.evaluate, "run_cell", interrupted)
    study = one_variant_study("stop", seeds=2, num_trials=1)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, tmp_path / "out", workers=2, progress=False)
    assert closes == [{"now": True}]


STOPPED_NOW = """
import json, os, time

from spcopyro.study.local_cluster import ClusterStart


def cell(seconds):
    time.sleep(seconds)


start = ClusterStart(1)
client = start.wait()
future = client.submit(cell, 120)
while not any(client.processing().values()):
    time.sleep(0.1)
pids = [w.process.process.pid for w in start.cluster.workers.values()]
begin = time.perf_counter()
start.close(now=True)  # as an interrupted study closes its cluster: its worker is mid-cell
seconds = time.perf_counter() - begin
gone = []
for pid in pids:
    try:
        os.kill(pid, 0)
        gone.append(False)
    except ProcessLookupError:
        gone.append(True)
print(json.dumps({"seconds": seconds, "gone": gone}))
"""


def test_a_cluster_closed_now_kills_a_worker_in_a_cell_at_once():
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    done = subprocess.run([sys.executable, "-c", STOPPED_NOW], capture_output=True, text=True,
                          timeout=300, check=True)  # fmt: skip
    record = json.loads(done.stdout.strip().splitlines()[-1])
    assert record["gone"] == [True]
    assert record["seconds"] < 3.0, record  # Dask's own close: 4 s before the kill, and more


def test_a_run_whose_cells_all_ran_here_does_not_wait_for_the_cluster(tmp_path, monkeypatch):
    """Every cell ran in this process before the cluster was up (a short study): the run did not
    wait for the cluster's start (3-4 s of the forkserver's import, then Dask's) only to close
    it; it closes the start, which stops it (:class:`ClusterStart`'s close)."""
    calls: list[str] = []

    class FakeStart:
        def __init__(self, workers, on_ready=None):
            pass

        def wait(self):
            calls.append("wait")
            raise AssertionError("waited for a cluster no cell needs")

        def close(self, **kwargs):
            calls.append("close")

    fake_cluster(monkeypatch, FakeStart)
    on_a_cluster(monkeypatch)  # 2 short cells: the cluster path all the same
    study = one_variant_study("here", seeds=2, num_trials=1)
    done = run_study(study, tmp_path / "out", workers=2, progress=False)
    assert (done.ran, done.ran_here, done.failed) == (2, 2, 0)
    assert calls == ["close"]


def test_a_run_with_one_cell_left_starts_no_cluster(tmp_path, monkeypatch):
    """One cell left to run with --workers 2: this process runs it while the cluster starts, so
    the start (the forkserver's 3-4 CPU seconds of imports, on a core the cell needs) served
    nothing; it is not begun, and the run's line says so instead of naming the workers."""
    started: list[int] = []
    fake_cluster(monkeypatch, counting_start(started))
    study = one_variant_study("one", seeds=1, num_trials=1)
    lines: list[str] = []
    done = run_study(study, tmp_path / "out", workers=2, progress=False, report=lines.append)
    assert started == []
    assert (done.ran, done.ran_here, done.failed) == (1, 1, 0)
    assert done.where == "in-process (a single cell: no LocalCluster of 2 workers started)"
    assert lines[0].endswith("1 of 1 cells to run (0 finished before), " + done.where), lines
    assert not any("while the LocalCluster started" in line for line in lines), lines


CLOSED_AT_ONCE = """
import glob, json, multiprocessing.forkserver as forkserver, os, tempfile, time

import psutil

from spcopyro.study.local_cluster import ClusterStart

if __name__ == "__main__":
    begin = time.perf_counter()
    start = ClusterStart(1)
    while forkserver._forkserver._forkserver_pid is None:  # the forkserver's import has begun
        time.sleep(0.01)
    server = forkserver._forkserver._forkserver_pid
    start.close()  # as a run whose cells all ran in this process closes it
    seconds = time.perf_counter() - begin
    tracker = psutil.Process().children()  # the resource tracker alone, not the forkserver
    print(json.dumps({
        "seconds": seconds, "cluster": start.cluster is not None,
        "server_left": psutil.pid_exists(server),
        "children": sorted(" ".join(p.cmdline())[-60:] for p in tracker),
        "ready_files": glob.glob(os.path.join(tempfile.gettempdir(), "spcopyro-forkserver-*")),
    }))
"""


def test_a_cluster_closed_while_its_forkserver_imports_stops_at_once(tmp_path):
    """ClusterStart.close() while the forkserver still imports the cells' code: the forkserver
    is killed (it has forked no worker yet) and nothing else starts; the close waited 3-4 s
    for the whole start (and more on a loaded machine) only to close the cluster."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    env = {**os.environ, "TMPDIR": str(tmp_path)}  # the ready files of this run's forkserver
    done = subprocess.run([sys.executable, "-c", CLOSED_AT_ONCE], capture_output=True, text=True,
                          timeout=300, check=True, env=env, cwd=tmp_path)  # fmt: skip
    record = json.loads(done.stdout.strip().splitlines()[-1])
    assert not record["cluster"], record
    assert not record["server_left"], record
    assert all("resource_tracker" in c for c in record["children"]), record
    assert record["ready_files"] == [], record
    assert record["seconds"] < 3.0, record


@pytest.mark.parametrize("interrupted", [True, False])
def test_a_ctrl_c_that_leaves_the_import_lock_held_does_not_hang_the_close(
    tmp_path, monkeypatch, interrupted
):
    """A KeyboardInterrupt raised just as the main thread took Python's global import lock
    (CPython 3.11 takes it outside a ``try``) left it held: the cluster's close, on its own
    thread, then waited for ever in its next import, and the study with it. Where the interrupt
    was swallowed (in importlib's weakref callback) the run went on to the same end. The run
    releases it before the close starts."""
    import _imp

    real_run_cell = study_run.evaluate.run_cell

    module = tmp_path / f"spcopyro_close_imports_this_{interrupted}.py"  # not imported yet
    module.write_text("VALUE = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    imported: list[bool] = []

    class FakeStart:
        def __init__(self, workers, on_ready=None):
            pass

        def wait(self):
            return None

        def close(self, **kwargs):  # imports on its thread, as Dask's close may
            done = threading.Event()

            def load() -> None:
                importlib.import_module(module.stem)
                done.set()

            threading.Thread(target=load, daemon=True).start()
            imported.append(done.wait(10))

    def run_cell(cell):
        _imp.acquire_lock()  # what the unlucky Ctrl-C leaves behind
        if interrupted:
            raise KeyboardInterrupt
        return real_run_cell(cell)

    fake_cluster(monkeypatch, FakeStart)
    on_a_cluster(monkeypatch)  # 2 short cells: the cluster path all the same
    monkeypatch.setattr(study_run.evaluate, "run_cell", run_cell)
    study = one_variant_study("locked", seeds=2, num_trials=1)  # a cluster
    try:
        if interrupted:
            with pytest.raises(KeyboardInterrupt):
                run_study(study, tmp_path / "out", workers=2, progress=False)
        else:
            assert run_study(study, tmp_path / "out", workers=2, progress=False).ran == 2
    finally:
        while True:  # whatever happened, the rest of the tests import freely
            try:
                _imp.release_lock()
            except RuntimeError:
                break
    assert imported == [True]


def _dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])  # noqa: S603
    process.wait()
    return process.pid


def test_stale_ready_files_are_removed(tmp_path):
    """A forkserver's ready file whose study process is gone is removed; one of a running
    process (made after its start) is kept, and so is a fresh one without a pid in its name."""
    from spcopyro.study.local_cluster import READY_PREFIX, remove_stale_ready_files

    def ready(owner: object, age: float = 0.0):
        path = tmp_path / f"{READY_PREFIX}{owner}-{age:.0f}{'ab' * 16}.ready"
        path.touch()
        made = time.time() - age
        os.utime(path, (made, made))
        return path

    dead = ready(_dead_pid())
    mine = ready(os.getpid())
    reused = ready(os.getpid(), age=10 * 365 * 86400)  # made before this process started
    old = tmp_path / f"{READY_PREFIX}{'cd' * 16}.ready"  # the name before pids
    fresh = tmp_path / f"{READY_PREFIX}{'ef' * 16}.ready"
    for path, age in ((old, 7200.0), (fresh, 0.0)):
        path.touch()
        os.utime(path, (time.time() - age,) * 2)
    other = tmp_path / "spcopyro-forkserver.txt"
    other.touch()
    remove_stale_ready_files(str(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in (mine, fresh, other)
    ), (dead, reused, old)


KILLED_WHILE_IMPORTING = """
import multiprocessing.forkserver as forkserver, os, signal, sys, time

from spcopyro.study.local_cluster import ClusterStart

if __name__ == "__main__":
    start = ClusterStart(1)
    while forkserver._forkserver._forkserver_pid is None:  # the forkserver's import has begun
        time.sleep(0.01)
    print(forkserver._forkserver._forkserver_pid, flush=True)
    os.kill(os.getpid(), signal.SIGKILL)
"""

NEXT_START = """
from spcopyro.study.local_cluster import start_forkserver, stop_forkserver

if __name__ == "__main__":
    start_forkserver()
    stop_forkserver()
"""


def test_a_study_killed_while_its_forkserver_imports_leaves_no_ready_file_for_good(tmp_path):
    """A study SIGKILLed while its forkserver imported left the empty ready file the server
    creates when its import ends (after the study's death), one per kill, for good. The next
    start removes it."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    from spcopyro.study import local_cluster

    if not local_cluster.forkserver_available():
        pytest.skip("no forkserver on this platform")
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    killed = subprocess.run([sys.executable, "-c", KILLED_WHILE_IMPORTING], capture_output=True,
                            text=True, timeout=300, env=env, cwd=tmp_path)  # fmt: skip
    assert killed.returncode == -9, killed.stderr
    server = int(killed.stdout.split()[0])
    deadline = time.monotonic() + 120
    while local_cluster._running(server) and time.monotonic() < deadline:  # imports, then EOF
        time.sleep(0.1)
    left = sorted(tmp_path.glob(f"{local_cluster.READY_PREFIX}*.ready"))
    assert len(left) == 1, left  # what the killed study left behind
    subprocess.run([sys.executable, "-c", NEXT_START], capture_output=True, text=True,
                   timeout=300, check=True, env=env, cwd=tmp_path)  # fmt: skip
    assert not left[0].exists()


STOPPED_AT_EXIT = """
import atexit, os, threading, time
import multiprocessing.forkserver as forkserver

from spcopyro.study.local_cluster import _running, start_forkserver, wait_for_forkserver

if __name__ == "__main__":
    start_forkserver()
    assert wait_for_forkserver(threading.Event())  # its import ended, as after a study's cells
    server = forkserver._forkserver._forkserver_pid
    child = os.fork()
    if child == 0:  # a process forked from this one runs its inherited exit handlers
        atexit._run_exitfuncs()
        os._exit(0)
    os.waitpid(child, 0)
    time.sleep(1.0)  # a SIGKILL the child sent lands in a moment: it would have by now
    after_child = _running(server)
    atexit._run_exitfuncs()  # what this process's exit runs first (the spcopyro command's too)
    deadline = time.monotonic() + 5.0  # killed, not waited for: it ends in a moment
    while _running(server) and time.monotonic() < deadline:
        time.sleep(0.01)
    print(server, after_child, _running(server), flush=True)
"""


def test_the_forkserver_ends_with_the_study_process():
    """The forkserver exited on its pipe's end-of-file once the study's process had ended, then
    tore down an interpreter holding torch: it outlived the study by about 1 s. It is killed by
    the study process's exit handlers now, and not by those of a process forked from it."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    from spcopyro.study import local_cluster

    if not local_cluster.forkserver_available():
        pytest.skip("no forkserver on this platform")
    done = subprocess.run([sys.executable, "-c", STOPPED_AT_EXIT], capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    server, after_child, after_exit = done.stdout.split()
    assert (after_child, after_exit) == ("True", "False"), done.stdout
    assert not local_cluster._running(int(server))


def test_a_closing_workers_heartbeat_error_is_not_printed():
    """A worker of an interrupted study's LocalCluster closed its connections while a heartbeat
    waited for the scheduler, and Dask logged it as an ERROR with two tracebacks over the
    study's "interrupted after N cells" line (2 of 5 interrupts on 2 workers). The workers'
    preload drops that error while the worker closes; a running worker's, and other errors,
    are kept."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    import logging
    import types

    from distributed.core import Status

    from spcopyro.study import local_cluster

    logger = logging.getLogger("distributed.worker")
    seen: list[str] = []
    handler = logging.Handler(logging.ERROR)
    handler.emit = lambda record: seen.append(record.getMessage())  # type: ignore[method-assign]
    worker = types.SimpleNamespace(status=Status.running)
    before = list(logger.filters)
    logger.addHandler(handler)
    try:
        local_cluster.dask_setup(worker)
        heartbeat = "Failed to communicate with scheduler during heartbeat."
        logger.error(heartbeat)  # a running worker's: kept
        for status in (Status.closing, Status.closing_gracefully, Status.closed):
            worker.status = status
            logger.error(heartbeat)
        logger.error("Unexpected exception during heartbeat. Closing worker.")
    finally:
        logger.removeHandler(handler)
        logger.filters[:] = before
    assert seen == [heartbeat, "Unexpected exception during heartbeat. Closing worker."]
