"""`spcopyro study` as a user meets it: stopping it (Ctrl-C in a terminal, SIGTERM), redrawing
the report of a stopped run, and a machine without the ``study`` extra (dask.distributed).

The tiny study of tests/study_setup.py (6 cells of 8 sweeps); numbers are never checked here.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from study_setup import _write, on_a_cluster

from spcopyro.cli.main import main
from spcopyro.study import evaluate, run
from spcopyro.study.table import read_table

STOPPED = "2 cells in the table of the study's 6: 4 not run yet"
"""The report's line after a run stopped at its third cell."""

FORKSERVER_MASK = """
import os
import signal
import threading
import multiprocessing.forkserver as forkserver

from spcopyro.study.local_cluster import start_forkserver

thread = threading.Thread(target=start_forkserver)  # as ClusterStart does: not the main thread
thread.start()
thread.join()
pid = forkserver._forkserver._forkserver_pid
with open(f"/proc/{pid}/status") as status:
    print(next(line.split()[1] for line in status if line.startswith("SigBlk:")))
os.kill(pid, signal.SIGKILL)  # it is still importing the cells' code: not needed here
"""
"""In a fresh process (no resource tracker yet): the study's forkserver's blocked signals (hex)."""

WORKER_MASK = """
import signal

from spcopyro.study.local_cluster import ClusterStart

start = ClusterStart(1)  # on a thread, as a study starts it
try:
    blocked = start.wait().run(eval, '{signal.SIGINT, signal.SIGTERM} <= '
                               'signal.pthread_sigmask(signal.SIG_BLOCK, ())'
                               .replace("signal.", "__import__('signal')."))
finally:
    start.close()
mask = signal.pthread_sigmask(signal.SIG_BLOCK, ())
print(list(blocked.values()), signal.SIGINT in mask or signal.SIGTERM in mask)
"""
"""In a fresh process (Dask's threads stay behind in the process that starts a cluster, and
forbid forking chain workers there): whether its worker, and whether the process itself, block
SIGINT."""

STOPPED_MID_CELL = """
import time

from spcopyro.study.local_cluster import ClusterStart


def cell(seconds):
    from tqdm.auto import tqdm

    with tqdm(total=1, disable=True):  # a cell's fit makes bars, disabled
        time.sleep(seconds)


start = ClusterStart(1)
client = start.wait()
future = client.submit(cell, 120)
while not any(client.processing().values()):
    time.sleep(0.1)
time.sleep(0.5)
start.close()  # as an interrupted study closes its cluster: its worker is stopped mid-cell
"""
"""In a fresh process: a LocalCluster closed while its worker runs a cell that made a progress
bar (what a Ctrl-C'd study does)."""


class Terminated(Exception):
    """What SIGTERM raises in these tests outside the study command (not the process's end)."""


def _stop_at_the_third_cell(monkeypatch, stop) -> None:
    """``evaluate.run_cell`` calls ``stop()`` instead of running the third cell."""
    real, calls = evaluate.run_cell, []

    def stops(cell):
        if len(calls) == 2:
            stop()
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", stops)


def _sigterm_to_self() -> None:
    signal.raise_signal(signal.SIGTERM)


def _terminate(signum: int, frame: object) -> None:
    raise Terminated(f"signal {signum}")


def test_sigterm_stops_the_study_command_as_ctrl_c_does(tmp_path, monkeypatch, capsys):
    """`timeout 1h spcopyro study ...` (or Slurm's SIGTERM) ended the process at once: the
    finished cells were kept in cells/, but results.csv and report.md were not rewritten and
    nothing was said. It now stops as Ctrl-C does (exit 130)."""
    monkeypatch.setenv("CI", "1")  # no progress bar
    path = _write(tmp_path)
    _stop_at_the_third_cell(monkeypatch, _sigterm_to_self)
    previous = signal.signal(signal.SIGTERM, _terminate)  # without the command's own: Terminated
    try:
        code = main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"])
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert code == 130
    said = capsys.readouterr().out
    assert "interrupted after 2 cells: 4 left; run the same command again" in said
    assert len(read_table(tmp_path / "out" / "results.csv")) == 2
    assert STOPPED in (tmp_path / "out" / "report.md").read_text()
    assert signal.getsignal(signal.SIGTERM) is previous


@pytest.mark.parametrize(
    ("command", "module", "runner"),
    [
        (["experiment", "--no-public", "--seeds", "1"], "experiment", "run_experiment"),
        (["ablation", "--no-public", "--seeds", "1"], "ablation", "run_ablation"),
        (["compare-inference", "--houses", "synthetic"], "comparison", "run_comparison"),
    ],
)  # fmt: skip
def test_sigterm_stops_the_shipped_study_commands_as_ctrl_c_does(
    tmp_path, monkeypatch, command, module, runner
):  # fmt: skip
    """`spcopyro experiment / ablation / compare-inference` run the study engine too: SIGTERM
    ended them at once (no table), as it did `spcopyro study`."""
    import importlib

    def terminated(*args, **kwargs):
        _sigterm_to_self()
        raise AssertionError("SIGTERM did not stop the run")

    monkeypatch.setattr(importlib.import_module(f"spcopyro.study.{module}"), runner, terminated)
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        assert main([*command, "--out", str(tmp_path / "out")]) == 130
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_report_only_of_a_stopped_run_says_how_many_cells_are_not_run_yet(
    tmp_path, monkeypatch, capsys
):  # fmt: skip
    """`--report-only` redrew the report of a stopped study as if its 2 cells were all of it:
    the run's "4 not run yet" was gone."""
    monkeypatch.setenv("CI", "1")
    path, out = _write(tmp_path), tmp_path / "out"

    def ctrl_c() -> None:
        raise KeyboardInterrupt

    _stop_at_the_third_cell(monkeypatch, ctrl_c)
    assert main(["study", str(path), "--out", str(out), "--workers", "1"]) == 130
    drawn = (out / "report.md").read_text()
    assert STOPPED in drawn
    (out / "report.md").unlink()
    assert main(["study", str(path), "--out", str(out), "--report-only"]) == 0
    assert (out / "report.md").read_text() == drawn


def test_without_dask_the_default_runs_here_and_workers_asked_for_are_an_error(
    tmp_path, monkeypatch, capsys
):  # fmt: skip
    """Without dask.distributed, `spcopyro study STUDY --out OUT` (default: --workers = the
    machine's cores) ended in a ModuleNotFoundError traceback, after writing a report that
    called the study an interrupted run. Now the default runs in this process with a note, and
    an explicit --workers N > 1 (or --scheduler) is one error line before anything is
    written."""
    monkeypatch.setenv("CI", "1")
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` fails
    monkeypatch.setattr(run, "default_workers", lambda: 2)
    path = _write(tmp_path)
    for option in (["--workers", "2"], ["--scheduler", "tcp://127.0.0.1:1"]):
        assert main(["study", str(path), "--out", str(tmp_path / "asked"), *option]) == 2
        error = capsys.readouterr().err
        assert error.startswith(f"error: {option[0]}: ") and "spcopyro[study]" in error
        assert not (tmp_path / "asked").exists()
    assert main(["study", str(path), "--out", str(tmp_path / "default")]) == 0
    captured = capsys.readouterr()
    assert "note: dask.distributed is not installed" in captured.err
    assert "in-process" in captured.out
    assert len(read_table(tmp_path / "default" / "results.csv")) == 6
    for command in ("experiment", "ablation", "compare-inference"):  # a traceback before
        assert main([command, "--out", str(tmp_path / command), "--workers", "2"]) == 2
        assert "error: --workers 2: running a study on Dask needs" in capsys.readouterr().err
        assert not (tmp_path / command).exists()


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="reads /proc (Linux)")
def test_the_local_clusters_forkserver_and_workers_block_sigint_and_sigterm():
    """A terminal's Ctrl-C reaches the whole process group. The LocalCluster's workers (and the
    forkserver, still importing while the study's first cells ran here) took it too and died
    with pages of Dask tracebacks (``distributed.worker - ERROR``, ``Failed to start process``)
    over the study's own "interrupted after N cells" line. They start with SIGINT blocked now,
    also when the cluster starts on a thread (starting multiprocessing's resource tracker
    unblocks SIGINT in the thread that starts it). So does the SIGTERM that ``timeout`` sends
    to its process group (and Slurm's scancel to the job's processes): the forkserver died of
    it, and the nannies restarting the dead workers through it printed ``Failed to start
    process ... EOFError`` tracebacks; SIGTERM is blocked there too now."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    from spcopyro.study import local_cluster

    if not local_cluster.forkserver_available():
        pytest.skip("no forkserver on this platform")
    done = subprocess.run([sys.executable, "-c", FORKSERVER_MASK], capture_output=True,
                          text=True, timeout=300, check=True)  # fmt: skip
    for blocked in (signal.SIGINT, signal.SIGTERM):  # a group's SIGTERM: timeout, scancel
        assert int(done.stdout.strip(), 16) & (1 << (blocked - 1)), done.stdout
    done = subprocess.run([sys.executable, "-c", WORKER_MASK], capture_output=True, text=True,
                          timeout=300, check=True)  # fmt: skip
    assert done.stdout.split("\n")[-2] == "[True] False", done.stdout  # the worker, not this one


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="POSIX semaphores (Linux)")
def test_a_study_stopped_mid_cell_leaks_no_semaphore():
    """Ctrl-C during a study on a LocalCluster ended with multiprocessing's resource tracker
    warning "There appear to be 2 leaked semaphore objects to clean up at shutdown": a cell's
    (disabled) progress bar made tqdm create a multiprocessing lock in the worker, which the
    worker, killed mid-cell by the cluster's close, never released. The workers now give tqdm
    a thread lock when they start."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    done = subprocess.run([sys.executable, "-c", STOPPED_MID_CELL], capture_output=True,
                          text=True, timeout=300, check=True)  # fmt: skip
    assert "leaked semaphore" not in done.stderr, done.stderr


def test_cells_a_worker_finished_before_a_ctrl_c_are_kept(tmp_path, monkeypatch):
    """While this process ran a cell of its own (the LocalCluster starting, or a loaded machine),
    the cells the workers finished meanwhile waited for that cell's end to be collected; a
    Ctrl-C then lost them with the cluster, where the docs promise that it loses only the cells
    in flight. They are stored now."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    import os
    import time

    from spcopyro.study.spec import load_study
    from spcopyro.study.table import CellStore

    marks, here, real, seen = tmp_path / "marks", os.getpid(), evaluate.run_cell, set()
    marks.mkdir()

    def run_cell(cell):
        if os.getpid() != here:  # a worker: the cell, then a mark that it ended
            outcome = real(cell)
            (marks / cell.key).touch()
            return outcome
        deadline = time.monotonic() + 240  # this process: Ctrl-C once a worker's cell ended
        while not any(marks.iterdir()) and time.monotonic() < deadline:
            time.sleep(0.1)
        seen.update(path.name for path in marks.iterdir())
        time.sleep(5.0)  # their results reached the client (a margin for a loaded CI machine)
        raise KeyboardInterrupt

    monkeypatch.setattr(evaluate, "run_cell", run_cell)
    on_a_cluster(monkeypatch)  # a tiny study: the cluster path all the same
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run.run_study(load_study(_write(tmp_path)), out, workers=2, progress=False)
    assert seen, "no worker ended a cell"
    assert seen <= set(CellStore(out).finished())  # and in the table written after the stop:
    assert len(read_table(out / "results.csv")) >= len(seen)


def test_a_scheduler_without_workers_says_the_cells_wait(tmp_path):
    """A --scheduler cluster whose workers have not started (dask-jobqueue's jobs still queued)
    showed a bar at 0 % and nothing else, for as long as the queue took."""
    distributed = pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    import os
    import threading

    from spcopyro.study.spec import load_study

    lines: list[str] = []
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster:
        ctrl_c = threading.Timer(5, os.kill, (os.getpid(), signal.SIGINT))
        ctrl_c.start()
        try:
            with pytest.raises(KeyboardInterrupt):
                run.run_study(load_study(_write(tmp_path)), tmp_path / "out", progress=False,
                              scheduler=cluster.scheduler_address, report=lines.append)  # fmt: skip
        finally:
            ctrl_c.cancel()
    note = f"note: the Dask scheduler {cluster.scheduler_address} has no workers yet"
    assert any(line.startswith(note) for line in lines), lines
    assert "interrupted after 0 cells: 6 left" in lines[-1]


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"init": "bogus"}, r"init='bogus': fit_house's init must be one of \['random'"),
        ({"refine": "sometimes"}, r"fit_house's refine must be one of \['auto', 'never'"),
        ({"point_estimate": "median"}, r"point_estimate must be one of \['map-visited'"),
        ({"marginal_samples": -1}, r"marginal_samples must be an integer >= 0"),
    ],
)
def test_a_variants_fit_values_are_checked_when_read(overrides, message):
    """``init = "bogus"`` passed the study's checks and failed every cell at run time ("the
    docs' 'Everything is checked when the file is read' is not true for fit_house values")."""
    from spcopyro.experiments.ablation_variants import VariantError, make_variant

    with pytest.raises(VariantError, match=message):
        make_variant("v", overrides)
    assert make_variant("v", {"init": "rooms", "marginal_samples": "20"}).fit_kwargs() == {
        "init": "rooms", "marginal_samples": 20,
    }  # fmt: skip


def test_a_ctrl_c_while_the_table_is_written_waits_for_it(tmp_path, monkeypatch, capsys):
    """A Ctrl-C landing while the study wrote its table and report (after the last cell, or a
    second one) cut the write: report.md missing or the last run's, "interrupted" alone said.
    The write now ends whole, then the run stops as any interrupted run does. With no cell
    left it said "0 left; run the same command again to continue": it says the study is
    complete."""
    monkeypatch.setenv("CI", "1")
    path = _write(tmp_path)
    write_report = run.write_report

    def interrupted_write(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)  # Ctrl-C, while the table is written
        return write_report(*args, **kwargs)

    monkeypatch.setattr(run, "write_report", interrupted_write)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 130
    said = capsys.readouterr().out
    assert "interrupted after 6 cells: 0 left; the study is complete in " in said
    assert "run the same command again" not in said  # nothing is left to run
    assert len(read_table(tmp_path / "out" / "results.csv")) == 6
    assert "# " in (tmp_path / "out" / "report.md").read_text()  # written whole
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_bad_scheduler_address_is_named(tmp_path, capsys):
    """``error: missing port number in address 'head'`` did not say which option it was. And
    the run wrote an empty results.csv, report.md and study.json into --out before it tried the
    address (after 30 s where no scheduler answers): it connects first now."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    import dask

    path, out = _write(tmp_path), tmp_path / "out"
    argv = ["study", str(path), "--out", str(out), "--scheduler", "head"]
    assert main(argv) == 2
    assert "error: --scheduler head: missing port number in address 'head'" in (
        capsys.readouterr().err
    )
    assert [p.name for p in out.iterdir()] == [".spcopyro-run.lock"]  # nothing written
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        assert main([*argv[:-1], "tcp://127.0.0.1:1"]) == 2  # nothing listens on port 1
    err = capsys.readouterr().err
    assert "error: --scheduler tcp://127.0.0.1:1: Timed out trying to connect" in err
    assert "is a Dask scheduler running there?" in err
    assert [p.name for p in out.iterdir()] == [".spcopyro-run.lock"]
