"""Running a study: the cells not yet finished, in this process or on a Dask cluster.

:func:`run_study` plans the grid (:func:`spcopyro.study.cells.cells_of`), skips every cell whose
key the folder's cache holds (:class:`spcopyro.study.table.CellStore`), runs the others and
stores each one the moment it finishes, then rebuilds ``results.csv`` and ``report.md`` from the
cache -- also when interrupted, so a restarted study continues where it stopped and a finished
one runs nothing (and says so). A cell that fails is stored with its error and not run again
unless ``retry_failed``.

Where the cells run:

* ``workers <= 1`` and no ``scheduler``: one after another in this process;
* ``workers > 1``: a ``dask.distributed.LocalCluster`` of that many worker processes, one
  thread each;
* ``scheduler="tcp://HOST:PORT"``: the Dask cluster already running there (e.g. one that
  ``dask-jobqueue`` started on Slurm or PBS; docs/studies.md). Its workers need spcopyro and
  the data at the same paths.

Every cell runs torch with one intra-op thread (:func:`spcopyro.study.evaluate.run_cell`), so a
cell gives the same numbers wherever it runs. Dask is an optional dependency
(``pip install 'spcopyro[study]'``); only the cluster paths import it.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from spcopyro._util.progress import progress_enabled
from spcopyro.gibbs.chains import usable_cpus
from spcopyro.study import evaluate
from spcopyro.study.cells import Cell, cells_of
from spcopyro.study.report import write_report
from spcopyro.study.spec import Study
from spcopyro.study.table import TABLE, CellStore, table_rows, write_table

__all__ = ["StudyRun", "default_workers", "run_study"]

PRE_SPAWN_ENVIRON = "distributed.nanny.pre-spawn-environ"
"""Dask's config of the environment its nanny gives each worker process."""

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
    """``in-process``, ``LocalCluster(N workers)`` or the scheduler's address."""
    interrupted: bool = False

    @property
    def table(self) -> Path:
        """The tidy table."""
        return self.out / TABLE


def default_workers() -> int:
    """The machine's usable cores (the default of ``--workers``)."""
    return usable_cpus()


def _say_nothing(message: str) -> None:
    del message


def run_study(
    study: Study,
    out: str | os.PathLike[str],
    *,
    workers: int = 1,
    scheduler: str | None = None,
    retry_failed: bool = False,
    root: str | os.PathLike[str] | None = None,
    progress: bool | None = None,
    report: Callable[[str], None] = _say_nothing,
) -> StudyRun:
    """Run the cells of ``study`` that ``out`` does not hold yet (module docstring).

    ``root``: the public dataset's folder for sources named by house (default:
    :func:`spcopyro.data.find_dataset_root`). ``report`` receives one line per failed cell and
    a closing line. KeyboardInterrupt stops the run after storing every finished cell and
    rewriting the table, then propagates.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    out = Path(out)
    start = time.perf_counter()
    cells = cells_of(study, root)
    store = CellStore(out)
    finished = store.finished()
    done = {k for k, r in finished.items() if not (retry_failed and r.get("status") == "error")}
    pending = list({c.key: c for c in cells if c.key not in done}.values())  # one per key
    cached = len({c.key for c in cells} & done)
    out.mkdir(parents=True, exist_ok=True)
    (out / "study.json").write_text(json.dumps(study.to_json(), indent=1, default=str))
    where = _where(workers, scheduler)
    if not pending:
        _finish(out, study, cells, store)
        report(f"nothing to run: all {len(cells)} cells of study {study.name!r} are finished "
               f"in {out} (delete cells/ there to run them again)")  # fmt: skip
        return StudyRun(out, len(cells), cached, 0, 0, time.perf_counter() - start, where)
    report(f"study {study.name!r}: {len(pending)} of {len(cells)} cells to run ({cached} "
           f"finished before), {where}")  # fmt: skip
    ran = failed = 0
    interrupted = False
    bar = _bar(len(pending), progress)
    try:
        outcomes = (
            _in_process(pending)
            if scheduler is None and workers <= 1
            else _on_dask(pending, workers, scheduler)
        )
        for cell, record, trace, label_map in outcomes:
            store.put(record, trace, label_map)  # type: ignore[arg-type]
            ran += 1
            if record["status"] != "ok":
                failed += 1
                report(f"cell {cell.row} / {cell.data.name} / {cell.method} / seed {cell.seed} "
                       f"failed: {record['error_type']}: {record['error']}")  # fmt: skip
            if bar is not None:
                bar.update()
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        if bar is not None:
            bar.close()
        _finish(out, study, cells, store)
        seconds = time.perf_counter() - start
        if interrupted:
            report(f"interrupted after {ran} cells: {len(pending) - ran} left; run the same "
                   "command again to continue")  # fmt: skip
    report(f"ran {ran} cells in {seconds:.1f} s ({failed} failed), {cached} finished before; "
           f"wrote {out / TABLE} and {out / 'report.md'}")  # fmt: skip
    return StudyRun(out, len(cells), cached, ran, failed, seconds, where)


def _where(workers: int, scheduler: str | None) -> str:
    if scheduler is not None:
        return f"Dask scheduler {scheduler}"
    return "in-process" if workers <= 1 else f"LocalCluster({workers} workers)"


def _bar(total: int, progress: bool | None):
    if not progress_enabled(progress):
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="cells", unit="cell")


def _finish(out: Path, study: Study, cells: list[Cell], store: CellStore) -> None:
    rows = table_rows(cells, store.finished())
    write_table(out / TABLE, rows)
    write_report(out / TABLE, out / "report.md", title=study.name)


def _in_process(cells: list[Cell]) -> Iterator[Outcome]:
    for cell in cells:
        record, trace, label_map = evaluate.run_cell(cell)
        yield cell, record, trace, label_map


def _on_dask(cells: list[Cell], workers: int, scheduler: str | None) -> Iterator[Outcome]:
    """Each cell a task; outcomes as they finish (``as_completed``). A task lost with its
    worker (or any error outside the cell) is recorded as that cell's error."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ModuleNotFoundError:
        raise ModuleNotFoundError(
            "running a study on Dask needs dask.distributed: pip install 'spcopyro[study]' "
            "(or run in-process with --workers 1)"
        ) from None
    cluster = None
    if scheduler is None:
        import dask

        # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in every worker (any value turns off
        # glibc's dynamic mmap threshold), so each array over 128 KiB is a fresh mmap whose
        # pages fault in on first touch: a cell's sweeps ran 1.5-2x slower in a worker than
        # in-process (measured, thread CPU time). Unset there, they run as fast.
        with dask.config.set({f"{PRE_SPAWN_ENVIRON}.MALLOC_TRIM_THRESHOLD_": None}):
            cluster = LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True,
                dashboard_address=":0", silence_logs=logging.ERROR,
                env={"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"},
            )  # fmt: skip
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        futures = {
            client.submit(evaluate.run_cell, cell, key=f"spcopyro-cell-{cell.key}"): cell
            for cell in cells
        }
        for future in as_completed(futures):
            cell = futures[future]
            try:
                record, trace, label_map = future.result()
            except Exception as error:  # the worker died, or the task could not run
                record = {"key": cell.key, "status": "error", "error_type": type(error).__name__,
                          "error": str(error)[:2000]}  # fmt: skip
                trace = label_map = None
            future.release()
            yield cell, record, trace, label_map
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
