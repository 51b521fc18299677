"""Running a study: the cells not yet finished, in this process or on a Dask cluster.

:func:`run_study` plans the grid (:func:`spcopyro.study.cells.cells_of`), skips every cell whose
key the folder's cache holds (:class:`spcopyro.study.table.CellStore`), runs the others and
stores each one the moment it finishes, then rebuilds ``results.csv`` and ``report.md`` from the
cache -- also when interrupted, so a restarted study continues where it stopped and a finished
one runs nothing (and says so). A cell that fails is stored with its error and not run again
unless ``retry_failed``; a cell that other spcopyro source computed (its record's
``source_digest``, :mod:`spcopyro.study.cells`) is kept, and named, unless ``rerun_stale``.

Where the cells run:

* ``workers <= 1`` and no ``scheduler``: one after another in this process;
* ``workers > 1``: a ``dask.distributed.LocalCluster`` of that many worker processes, one
  thread each, forked from a server that imported the cells' code once
  (:mod:`spcopyro.study.local_cluster`). The cluster starts on a thread while this process runs
  cells one after another, shortest first; the moment the workers are up they take every cell
  not started yet, longest first (:mod:`spcopyro.study.order`), and the cluster closes while
  the table is written. A run whose cells left to run are predicted to end sooner in this
  process than on the cluster (one cell, or a few seconds of them:
  :func:`spcopyro.study.order.cluster_pays`; with ``start_in_process``) runs them here and
  starts no cluster: the workers would get little or nothing to run, and their start would
  take a core from those cells;
* ``scheduler="tcp://HOST:PORT"``: the Dask cluster already running there (e.g. one that
  ``dask-jobqueue`` started on Slurm or PBS; docs/studies.md), cells longest first. Its workers
  need spcopyro and the data at the same paths.

Every cell runs torch with one intra-op thread (:func:`spcopyro.study.evaluate.run_cell`), so a
cell gives the same numbers wherever it runs, and keeps the warnings its fit gives in its record
(:mod:`spcopyro.study.cell_warnings`): they are not printed over the progress bar, nor lost in
a worker's log; the closing line counts the cells that gave some and ``report.md`` lists them.
Dask is an optional dependency (``pip install 'spcopyro[study]'``); only the cluster paths
import it.
"""

from __future__ import annotations

import functools
import json
import os
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from spcopyro._util.folder_lock import folder_lock
from spcopyro._util.interrupts import signals_deferred
from spcopyro._util.messages import plural
from spcopyro._util.outputs import check_folder_path, replace_text
from spcopyro._util.progress import progress_enabled
from spcopyro._util.threads import usable_cpus
from spcopyro.study import evaluate
from spcopyro.study.cells import Cell, cells_of, source_digest
from spcopyro.study.local_cluster import PRE_SPAWN_ENVIRON, ClusterStart
from spcopyro.study.order import (
    cluster_pays,
    duration,
    longest_first,
    predicted_seconds,
    run_seconds,
)
from spcopyro.study.report import table_cell, write_report
from spcopyro.study.spec import Study
from spcopyro.study.table import TABLE, CellStore, table_rows, write_table

__all__ = [
    "DASK_MISSING", "PRE_SPAWN_ENVIRON", "StudyPlan", "StudyRun", "check_out_folder",
    "dask_installed", "default_workers", "plan_markdown", "plan_study", "run_study",
]  # fmt: skip

Outcome = tuple[Cell, dict[str, object], object, object]
"""A finished cell, its record, its trace and its label map."""


@dataclass(frozen=True)
class StudyRun:
    """What :func:`run_study` did."""

    out: Path
    cells: int
    """Cells of the study."""
    cached: int
    """Cells finished before this run (skipped)."""
    ran: int
    """Cells run and stored by this run."""
    failed: int
    """Of those, how many failed (recorded with their error)."""
    seconds: float
    where: str
    """``in-process``, ``LocalCluster(N workers)`` or the scheduler's address; ``in-process (a
    single cell: no LocalCluster of N workers started)`` where ``N > 1`` workers were asked for
    one cell (:func:`_where`)."""
    interrupted: bool = False
    ran_here: int = 0
    """Of ``ran``, the cells a LocalCluster run ran in this process while its workers started
    (all of them for an in-process run: ``ran``)."""
    failed_before: int = 0
    """Of ``cached``, the cells that failed in an earlier run and were not run again (without
    ``retry_failed``): the study is not complete while there are any."""

    @property
    def table(self) -> Path:
        """The tidy table."""
        return self.out / TABLE


def default_workers() -> int:
    """The machine's usable cores (the default of ``--workers``)."""
    return usable_cpus()


DASK_MISSING = (
    "running a study on Dask needs dask.distributed: pip install 'spcopyro[study]' (or run "
    "in-process with --workers 1)"
)


def dask_installed() -> bool:
    """Whether ``dask.distributed`` can be imported (the ``study`` extra: ``workers > 1`` and
    ``scheduler`` need it)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def check_out_folder(out: str | os.PathLike[str]) -> Path:
    """``out`` as a Path; NotADirectoryError naming it when it, or the nearest of its parents
    that exists, is a file (a study's results folder would fail there after its first cell, or
    at once with a bare ``[Errno 17] File exists``)."""
    path = Path(out)
    check_folder_path(path, f"--out {out}")
    return path


def _say_nothing(message: str) -> None:
    del message


def _count_lines(study: Study, plan: StudyPlan, where: str) -> list[str]:
    """:func:`run_study`'s default ``describe``: how many cells are to run and ``where``, one
    line (``study 'NAME': N of M cells to run (K finished before), in-process``)."""
    return [f"study {study.name!r}: {len(plan.pending)} of {len(plan.cells)} cells to run "
            f"({plan.cached} finished before), {where}"]  # fmt: skip


def run_study(
    study: Study,
    out: str | os.PathLike[str],
    *,
    workers: int = 1,
    scheduler: str | None = None,
    retry_failed: bool = False,
    rerun_stale: bool = False,
    root: str | os.PathLike[str] | None = None,
    progress: bool | None = None,
    report: Callable[[str], None] = _say_nothing,
    start_in_process: bool = True,
    describe: Callable[[Study, StudyPlan, str], list[str]] = _count_lines,
) -> StudyRun:
    """Run the cells of ``study`` that ``out`` does not hold yet (module docstring).

    ``rerun_stale``: also run the finished cells that other spcopyro source computed (their
    record's ``source_digest`` is not this process's :func:`spcopyro.study.cells.source_digest`;
    without it they are kept and counted in a line of ``report``). ``root``: the public
    dataset's folder for sources named by house (default:
    :func:`spcopyro.data.find_dataset_root`). ``report`` receives one line per failed cell and
    a closing line. ``start_in_process``: with a LocalCluster, run cells in this process while
    its workers start (module docstring). ``describe(study, plan, where)``: the lines said
    before the first cell, from the plan run and where its cells run (``in-process``; default
    ``_count_lines``; compare-inference's :func:`~spcopyro.study.comparison.plan_lines` says
    its count, budgets and predicted time in their place), called only when cells are to run.
    KeyboardInterrupt stops the run after storing every finished cell and rewriting the table,
    then propagates. ``workers > 1`` or ``scheduler`` without dask.distributed raise
    :class:`ModuleNotFoundError` before anything is written. Another run into ``out`` while
    this one lasts raises :class:`~spcopyro._util.folder_lock.FolderBusyError` at once (the
    folder's lock).
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if (scheduler is not None or workers > 1) and not dask_installed():
        raise ModuleNotFoundError(DASK_MISSING)  # before anything is written (not a stopped run)
    out = check_out_folder(out)
    with folder_lock(out, "study run"):  # FolderBusyError while another run writes there
        return _run_study(study, out, workers, scheduler, retry_failed, rerun_stale, root,
                          progress, report, start_in_process, describe)  # fmt: skip


def _run_study(
    study: Study,
    out: Path,
    workers: int,
    scheduler: str | None,
    retry_failed: bool,
    rerun_stale: bool,
    root: str | os.PathLike[str] | None,
    progress: bool | None,
    report: Callable[[str], None],
    start_in_process: bool,
    describe: Callable[[Study, StudyPlan, str], list[str]],
) -> StudyRun:
    """:func:`run_study` once it holds ``out``'s lock."""
    start = time.perf_counter()
    plan = plan_study(study, out, retry_failed, rerun_stale, root)
    cells, pending, cached, stale = plan
    client = _connect(scheduler) if scheduler is not None and pending else None  # before writing
    store = CellStore(out)
    out.mkdir(parents=True, exist_ok=True)
    replace_text(out / "study.json", json.dumps(study.to_json(), indent=1, default=str))
    predicted = [plan.predicted.get(cell.key, 0.0) for cell in pending]
    short = start_in_process and not cluster_pays(predicted, workers)  # one cell, or a few s
    alone = scheduler is None and workers > 1 and short
    where = _where(workers, scheduler, len(pending) if alone else 0, run_seconds(predicted))
    if not pending:
        _finish(out, study, cells, store)
        report(f"nothing to run: all {len(cells)} cells of study {study.name!r} are finished "
               f"in {out} (delete cells/ there to run them again)")  # fmt: skip
        if stale:
            report(_stale_line(len(stale)))
        if plan.failed_before:
            report(_failed_before_line(plan.failed_before, out))
        return StudyRun(out, len(cells), cached, 0, 0, time.perf_counter() - start, where,
                        failed_before=plan.failed_before)  # fmt: skip
    for line in describe(study, plan, where):  # the count, said once
        report(line)
    if client is not None and not client.nthreads():  # type: ignore[attr-defined]
        report(f"note: the Dask scheduler {scheduler} has no workers yet: the cells wait for "
               "them (start workers, or wait for the cluster's jobs to start)")  # fmt: skip
    if stale and not rerun_stale:
        report(_stale_line(len(stale)))
    ran = failed = warned = 0
    interrupted = False
    bar = _bar(pending, plan.predicted, progress)
    in_process = scheduler is None and (workers <= 1 or alone)  # alone: no cluster to start
    started_in_order = [] if in_process else longest_first(pending, plan.predicted)
    background = _Background()

    def keep(cell: Cell, record: dict[str, object], trace: object, label_map: object) -> None:
        nonlocal ran, failed, warned
        store.put(record, trace, label_map)  # type: ignore[arg-type]
        ran += 1
        warned += bool(record.get(evaluate.WARNINGS))  # kept in the record, said at the end
        if record["status"] != "ok":
            failed += 1
            report(f"cell {cell.row} / {cell.data.name} / {cell.method} / seed {cell.seed} "
                   f"failed: {record['error_type']}: {record['error']}")  # fmt: skip
        if bar is not None:
            bar.advance(cell)

    outcomes = (
        _in_process(pending)
        if in_process
        else _on_dask(started_in_order, workers, client, background, start_in_process)
    )
    try:
        for outcome in outcomes:
            keep(*outcome)
    except KeyboardInterrupt as stop:
        interrupted = True
        outcomes.close()  # (if it stopped here) the Dask run's close, after it took what ended
        for outcome in background.finished:  # ended on a worker, not collected yet: kept too
            keep(*outcome)
        stop.said = report is not _say_nothing  # type: ignore[attr-defined]  # the line below
        raise
    finally:
        _release_import_lock()
        if bar is not None:
            bar.close()
        signalled: list[int] = []  # a Ctrl-C (or another) while the table is written: after it
        with signals_deferred(lambda signum, frame: signalled.append(signum)):
            _finish(out, study, cells, store)
        background.join()  # the LocalCluster's close, left running while the table was written
        seconds = time.perf_counter() - start
        if interrupted or signalled:
            left = len(pending) - ran  # 0: the signal came after the last cell
            report(f"interrupted after {plural(ran, 'cell')}: {left} left; "
                   + ("run the same command again to continue" if left else
                      f"the study is complete in {out / TABLE} and report.md"))  # fmt: skip
    if signalled:  # the run ended whole, its table and report written: stopped all the same
        stop = KeyboardInterrupt(f"signal {signalled[0]}")
        stop.said = report is not _say_nothing  # type: ignore[attr-defined]
        raise stop
    ran_here = ran if in_process else background.ran_here
    if not in_process and ran_here:
        report(f"{ran_here} of them ran in this process while the LocalCluster started")
    report(f"ran {plural(ran, 'cell')} in {seconds:.1f} s ({failed} failed), {cached} finished "
           f"before; wrote {out / TABLE} and {out / 'report.md'}")  # fmt: skip
    if warned:
        report(f"{warned} of them gave warnings while fitted: listed, with each cell, in "
               f"{out / 'report.md'} (column warnings of {TABLE})")  # fmt: skip
    if plan.failed_before:
        report(_failed_before_line(plan.failed_before, out))
    return StudyRun(out, len(cells), cached, ran, failed, seconds, where, ran_here=ran_here,
                    failed_before=plan.failed_before)  # fmt: skip


def _failed_before_line(count: int, out: Path) -> str:
    return (f"{count} cell(s) failed in an earlier run and were not run again (their errors are "
            f"in {out / 'report.md'}); --retry-failed runs them")  # fmt: skip


@dataclass(frozen=True)
class StudyPlan:
    """What a run of a study into a folder would run (:func:`plan_study`)."""

    cells: list[Cell]
    """Every cell of the study, in table order."""
    pending: list[Cell]
    """The cells to run (one per key)."""
    cached: int
    """Cells finished before (not run)."""
    stale: set[str]
    """Keys of finished cells that other spcopyro source computed."""
    predicted: dict[str, float] = field(default_factory=dict)
    """Each pending cell's predicted seconds, by key (:mod:`spcopyro.study.order`)."""
    failed_before: int = 0
    """Of ``cached``, the cells whose stored record is a failure (kept: no ``retry_failed``)."""

    def __iter__(self):
        return iter((self.cells, self.pending, self.cached, self.stale))


def plan_study(
    study: Study, out: str | os.PathLike[str], retry_failed: bool = False,
    rerun_stale: bool = False, root: str | os.PathLike[str] | None = None,
) -> StudyPlan:  # fmt: skip
    """What :func:`run_study` with these arguments would run; writes nothing."""
    cells = cells_of(study, root)
    finished = CellStore(out).finished()
    done = {k for k, r in finished.items() if not (retry_failed and r.get("status") == "error")}
    stale = _stale(cells, finished, done)
    if rerun_stale:
        done -= stale
    pending = list({c.key: c for c in cells if c.key not in done}.values())  # one per key
    predicted = predicted_seconds(pending, cells, finished)
    kept = {c.key for c in cells} & done
    failed = sum(1 for k in kept if finished[k].get("status") == "error")
    return StudyPlan(cells, pending, len(kept), stale, predicted, failed)


def plan_markdown(plan: StudyPlan, study: Study, workers: int = 1) -> str:
    """The cells a run would run, per data source, variant and method: how many (seeds), at
    how many iterations and their predicted time (``spcopyro study --dry-run``); the whole
    run's predicted time one after another and on ``workers``, each process's first-cell
    warm-up included (:func:`spcopyro.study.order.run_seconds`), or that the run would not
    start its LocalCluster (:func:`spcopyro.study.order.cluster_pays`)."""
    groups: dict[tuple[str, str, str, int], list[float]] = {}
    for cell in plan.pending:
        group = (cell.data.name, cell.row, cell.method, cell.sweeps)
        groups.setdefault(group, []).append(plan.predicted.get(cell.key, 0.0))
    lines = [
        f"study {study.name!r}: {len(plan.pending)} of {len(plan.cells)} cells to run "
        f"({plan.cached} finished before, {len(plan.stale)} of them by other source)",
        "", "| data | variant | method | iterations | cells | predicted |",
        "|---|---|---|---|---|---|",
    ]  # fmt: skip
    lines += [
        f"| {table_cell(d)} | {table_cell(v)} | {m} | {n} | {len(times)} | {duration(sum(times))} |"
        for (d, v, m, n), times in groups.items()
    ]
    predicted = [plan.predicted.get(cell.key, 0.0) for cell in plan.pending]
    if plan.pending:
        total = run_seconds(predicted)  # each process's first-cell warm-up once
        spread = f"; on {workers} workers at least {duration(run_seconds(predicted, workers))}"
        if not cluster_pays(predicted, workers):
            spread = (f"; with --workers {workers} run in this process all the same: too "
                      "short for a LocalCluster to pay for its start")  # fmt: skip
        lines += ["", (
            f"predicted: {duration(total)} of fits one after another"
            f"{spread if workers > 1 else ''} (times per iteration of this study's finished "
            "cells where it has some, else of a 2-core machine in 2026, and each process's "
            "first-cell warm-up: a guide, not a promise)"
        )]  # fmt: skip
    return "\n".join(lines)


def _stale(cells: list[Cell], finished: dict[str, dict[str, object]], done: set[str]) -> set[str]:
    """The keys of the study's finished cells (of ``done``) whose record other spcopyro source
    computed (or no digest names: stored before records had one)."""
    current = source_digest()
    keys = {c.key for c in cells} & done
    return {k for k in keys if finished[k].get("source_digest") != current}


def _stale_line(count: int) -> str:
    return (
        f"{count} of the finished cells were computed by other spcopyro source than this "
        f"(source_digest is not {source_digest()}): kept; --rerun-stale runs them again"
    )


def _where(workers: int, scheduler: str | None, alone: int = 0, predicted: float = 0.0) -> str:
    """Where the cells run. ``alone``: the number of cells left to run with ``workers > 1``,
    run in this process without starting the LocalCluster (0: none), since it is predicted not
    to pay (``predicted``: their predicted seconds; :func:`spcopyro.study.order.cluster_pays`):
    this process runs cells while the cluster starts anyway (:func:`_on_dask`), and the
    forkserver's import (3-4 CPU seconds) only took a core from them."""
    if scheduler is not None:
        return f"Dask scheduler {scheduler}"
    if alone == 1:
        return f"in-process (a single cell: no LocalCluster of {workers} workers started)"
    if alone:
        return (f"in-process ({alone} cells predicted at {duration(predicted)} of fits, too "
                f"short for a LocalCluster of {workers} workers to pay for its start: none "
                "started)")  # fmt: skip
    return "in-process" if workers <= 1 else f"LocalCluster({workers} workers)"


class _CellBar:
    """A progress bar over the cells, advanced by each finished cell's predicted seconds, so
    that its remaining time holds when the cells differ in length (and the cluster starts the
    longest first); the count of cells is in its description, and the share says it is of
    the predicted time (``cells 1/6:  85% of the predicted time``: not 85 % of the cells)."""

    def __init__(self, cells: list[Cell], predicted: dict[str, float]) -> None:
        from tqdm.auto import tqdm

        self._weight = {c.key: max(predicted.get(c.key, 1.0), 1e-3) for c in cells}
        self._cells, self._done = len(cells), 0
        self._bar = tqdm(
            total=sum(self._weight.values()), desc=f"cells 0/{self._cells}",
            bar_format="{desc}: {percentage:3.0f}% of the predicted time|{bar}| "
            "[{elapsed}<{remaining}]",
        )  # fmt: skip

    def advance(self, cell: Cell) -> None:
        self._done += 1
        self._bar.set_description_str(f"cells {self._done}/{self._cells}", refresh=False)
        self._bar.update(self._weight.get(cell.key, 0.0))

    def close(self) -> None:
        self._bar.close()


def _bar(cells: list[Cell], predicted: dict[str, float], progress: bool | None) -> _CellBar | None:
    if not progress_enabled(progress):
        return None
    return _CellBar(cells, predicted)


def _finish(out: Path, study: Study, cells: list[Cell], store: CellStore) -> None:
    rows = table_rows(cells, store.finished())
    write_table(out / TABLE, rows)
    write_report(out / TABLE, out / "report.md", title=study.name, expected=len(cells))


def _in_process(cells: list[Cell]) -> Iterator[Outcome]:
    for cell in cells:
        record, trace, label_map = evaluate.run_cell(cell)
        yield cell, record, trace, label_map


def _connect(scheduler: str):
    """A ``Client`` of the Dask scheduler at ``scheduler`` (connected before the run writes
    anything); ValueError (a bad address) or OSError (no scheduler answering) naming it."""
    from distributed import Client

    try:
        return Client(scheduler)
    except ValueError as error:
        raise ValueError(f"--scheduler {scheduler}: {error}") from error
    except OSError as error:
        raise OSError(f"--scheduler {scheduler}: {error} (is a Dask scheduler running there? "
                      "docs/studies.md; no cell was run)") from error  # fmt: skip


def _on_dask(
    cells: list[Cell], workers: int, client: object | None, background: _Background,
    start_in_process: bool = True,
) -> Iterator[Outcome]:  # fmt: skip
    """Each cell a task; outcomes as they finish (``as_completed``). A task lost with its
    worker (or any error outside the cell) is recorded as that cell's error. ``cells`` in the
    order the workers should start them (the first first). ``client``: connected to the
    ``--scheduler`` cluster (:func:`_connect`); None: start a LocalCluster of ``workers``.

    A LocalCluster starts on a background thread (:class:`spcopyro.study.local_cluster.
    ClusterStart`); with ``start_in_process`` this process runs cells meanwhile, one after
    another from the end of ``cells`` (so that the cell still running here when the workers are
    up ends soon), and the cluster takes every cell not started yet the moment it is up. Its
    close is left running in ``background`` (the caller writes the table meanwhile)."""
    try:
        from distributed import as_completed
    except ModuleNotFoundError:
        raise ModuleNotFoundError(DASK_MISSING) from None
    waiting = deque(cells)
    stopped = False
    lock = threading.Lock()
    futures: dict[object, Cell] = {}

    def submit_waiting(client) -> None:
        with lock:
            futures.update(
                (client.submit(evaluate.run_cell, cell, key=f"spcopyro-cell-{cell.key}",
                               priority=len(waiting) - rank), cell)
                for rank, cell in enumerate(waiting)
            )  # fmt: skip
            waiting.clear()

    if client is not None:
        start = None
        submit_waiting(client)
    else:
        start = ClusterStart(workers, on_ready=submit_waiting)
    try:
        while start is not None and start_in_process:
            with lock:
                cell = waiting.pop() if waiting else None
            if cell is None:  # all run here, or the cluster took the rest
                break
            record, trace, label_map = evaluate.run_cell(cell)
            background.ran_here += 1
            yield cell, record, trace, label_map
        with lock:
            needed = bool(futures or waiting)
        if start is not None and needed:  # else every cell ran here: the close stops the start
            _release_import_lock()  # before waiting for a thread that imports
            start.wait()
        for future in as_completed(list(futures)) if needed else ():
            cell = futures.pop(future)
            try:
                record, trace, label_map = future.result()
            except Exception as error:  # the worker died, or the task could not run
                record = {"key": cell.key, "status": "error", "error_type": type(error).__name__,
                          "error": str(error)[:2000], "source_digest": source_digest()}  # fmt: skip
                trace = label_map = None
            future.release()
            yield cell, record, trace, label_map
    except (KeyboardInterrupt, GeneratorExit):  # in this process's cell, or in the caller's
        stopped = True
        with lock:
            background.finished = _finished_on_workers(futures)
        raise
    finally:
        _release_import_lock()  # before the close's thread imports anything
        if start is None:
            client.close()  # type: ignore[union-attr]
        elif stopped:  # the cells still on the workers are not waited for: killed at once
            background.close_later(functools.partial(start.close, now=True))
        else:
            background.close_later(start.close)


def _release_import_lock() -> None:
    """Release Python's global import lock where this thread holds it, as a Ctrl-C can leave
    it. A KeyboardInterrupt raised just as a thread took the lock leaves it held (CPython 3.11's
    ``importlib._bootstrap._get_module_lock``, and the weakref callback it makes, take it
    outside their ``try``; in the callback the interrupt is even swallowed, "Exception ignored
    in ... cb", and the run goes on), and every other thread's next import then waits for ever:
    a study whose cluster start or close, which it joins, imports hung for good (twice in about
    twenty Ctrl-Cs during a LocalCluster's start). Here, in the study's own code, this thread
    holds it for no import."""
    import _imp

    while _imp.lock_held():
        try:
            _imp.release_lock()
        except RuntimeError:  # another thread's (in an import of its own): not ours to release
            return


def _finished_on_workers(futures: dict[object, Cell]) -> list[Outcome]:
    """The outcomes of the tasks that ended on a worker but were not collected yet, when an
    interrupt came first (a worker's cell ends while this process runs one of its own, whose
    end the collection waits for): stored, not lost with the cluster. A task that failed is
    left to the next run."""
    outcomes = []
    for future, cell in futures.items():
        if future.status == "finished":  # type: ignore[attr-defined]
            try:
                outcomes.append((cell, *future.result(timeout=30)))  # type: ignore[attr-defined]
            except Exception:  # noqa: S112  # e.g. the worker gone meanwhile: run next time
                continue
    return outcomes


@dataclass
class _Background:
    """What a Dask run left behind: the cells it ran in this process while its LocalCluster
    started, the cells its workers had finished when an interrupt came (not collected yet),
    and the cluster's close, running on a thread until :meth:`join`."""

    ran_here: int = 0
    closing: threading.Thread | None = None
    finished: list[Outcome] = field(default_factory=list)

    def close_later(self, close: Callable[[], None]) -> None:
        self.closing = threading.Thread(target=close, name="spcopyro-cluster-close")
        self.closing.start()

    def join(self) -> None:
        if self.closing is not None:
            self.closing.join()
