"""The ``spcopyro study`` command: run a study file (:mod:`spcopyro.study`, docs/studies.md).

``spcopyro study STUDY.toml --out OUT [--workers N] [--scheduler ADDRESS]`` runs the cells of
the study that OUT does not hold yet and writes ``OUT/results.csv`` (and ``results.parquet``
with pyarrow) and ``OUT/report.md``.
STUDY may also name a study shipped with the package (``experiment``, ``ablation_small``, ...).
:func:`add_parser` registers the command; nothing heavy (torch, pyro, dask) is imported before
it runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from spcopyro.cli.common import _HelpFormatter, _positive_int

__all__ = ["add_parser", "study_path"]


def study_path(text: str) -> Path:
    """A study file: a path, or the name of one shipped in ``spcopyro/study/studies``."""
    from spcopyro.study import STUDIES

    path = Path(text)
    if path.is_file():
        return path
    shipped = STUDIES / (text if text.endswith(".toml") else f"{text}.toml")
    if len(path.parts) == 1 and shipped.is_file():
        return shipped
    if path.is_dir():  # it said the folder does not exist
        raise IsADirectoryError(f"study file {text} is a folder: give a STUDY.toml")
    names = sorted(p.stem for p in STUDIES.glob("*.toml"))
    with_suffix = path.with_name(f"{path.name}.toml")
    if path.suffix != ".toml" and with_suffix.is_file():  # "my_study" for my_study.toml
        raise FileNotFoundError(
            f"study file {text} does not exist; did you mean {with_suffix}? "
            f"(a name without .toml is one of the shipped studies: {names})"
        )
    raise FileNotFoundError(f"study file {text} does not exist (shipped studies: {names})")


def _study(args: argparse.Namespace) -> int:
    from spcopyro._util.collector import import_frozen

    # torch's, pyro's and the study's objects, frozen: the collector does not scan them again
    import_frozen("spcopyro.study.run")  # (spcopyro._util.collector, as `spcopyro fit` does)
    from spcopyro._util.folder_lock import FolderBusyError, folder_lock
    from spcopyro._util.interrupts import sigterm_as_interrupt
    from spcopyro.study.cells import cells_of
    from spcopyro.study.report import write_report
    from spcopyro.study.run import (
        DASK_MISSING,
        check_out_folder,
        dask_installed,
        default_workers,
        plan_markdown,
        plan_study,
        run_study,
    )
    from spcopyro.study.spec import load_study
    from spcopyro.study.table import TABLE

    if args.report_only and args.dry_run:  # --report-only writes report.md: not a dry run
        raise ValueError("--report-only and --dry-run contradict each other: --report-only "
                         "writes report.md, --dry-run writes nothing")  # fmt: skip
    path = study_path(args.study)
    study = load_study(path)
    out = check_out_folder(args.out)
    if args.data is not None and all(d.kind == "synthetic" for d in study.data):  # was ignored
        raise ValueError(f"--data {args.data}: study {path} has no public house or map to find "
                         "there (its sources are synthetic houses)")  # fmt: skip
    defaulted = study.sweeps_defaulted()
    if defaulted:
        print(f"note: {path}: [study] sweeps names neither {', '.join(defaulted)} nor '*': "
              "they run 1000 iterations (add \"*\" = N to the table)", file=sys.stderr)  # fmt: skip
    if args.report_only:
        if not (out / TABLE).is_file():
            raise FileNotFoundError(f"--report-only: {out / TABLE} does not exist; run the study")
        try:  # the study's cells: an interrupted run's report still says how many are missing
            expected: int | None = len(cells_of(study, args.data))
        except (OSError, ValueError):  # a source no longer found or read: the report without it
            expected = None
        try:  # not while a run writes the cells and the table: it could read them half written
            with folder_lock(out, "study run"):
                report = write_report(out / TABLE, out / "report.md", title=study.name,
                                      expected=expected)  # fmt: skip
        except FolderBusyError as error:
            raise FolderBusyError(
                f"--report-only: {out} is in use by a study run ({error.holder}), which is "
                f"writing its cells and {TABLE}: wait for it to finish (it writes "
                f"{out / 'report.md'} itself at its end), then run --report-only again",
                error.holder,
            ) from None
        print(f"wrote {report}")
        return 0
    workers = args.workers if args.workers is not None else default_workers()
    if (args.scheduler is not None or workers > 1) and not args.dry_run and not dask_installed():
        if args.workers is not None or args.scheduler is not None:  # asked for: before any write
            raise ValueError(f"--{'workers' if args.scheduler is None else 'scheduler'}: "
                             f"{DASK_MISSING}")  # fmt: skip
        print(f"note: dask.distributed is not installed (pip install 'spcopyro[study]'): "
              f"running the cells in this process, not on {workers} workers",
              file=sys.stderr)  # fmt: skip
        workers = 1
    if args.dry_run:
        plan = plan_study(study, out, args.retry_failed, args.rerun_stale, args.data)
        print(plan_markdown(plan, study, 1 if args.scheduler else workers))
        return 0
    with sigterm_as_interrupt():  # `timeout`, Slurm: the finished cells' table and report kept
        run = run_study(
            study, out, workers=workers, scheduler=args.scheduler,
            retry_failed=args.retry_failed, rerun_stale=args.rerun_stale, root=args.data,
            report=print,
        )  # fmt: skip
    if run.ran:
        print((out / "report.md").read_text())
    return 1 if run.failed or run.failed_before else 0  # a study with failed cells is not done


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``study`` on the main parser's subparsers."""
    p = sub.add_parser(
        "study",
        help="run a study: variants x data x methods x seeds, cached, in-process or on Dask",
        description="Run the cells of a study file that OUT does not hold yet, then write "
        "OUT/results.csv (one row per variant x data x method x seed: every input and score) "
        "and OUT/report.md (mean +- sd over seeds). A restarted study continues where it "
        "stopped; see docs/studies.md.",
        formatter_class=_HelpFormatter,
    )
    p.add_argument("study", help="study file (TOML; docs/studies.md), or the name of a shipped "
                   "one: experiment, ablation, compare_inference (each also as NAME_quick), "
                   "modality, sentences, stability, sensitivity, ablation_small")  # fmt: skip
    p.add_argument("--out", required=True, help="results folder: cells/ (the cache), traces/, "
                   "results.csv, report.md; finished cells there are not run again")  # fmt: skip
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="1: run the cells one after another in this process; N > 1: a Dask "
                        "LocalCluster of N processes, one thread each (default: the machine's "
                        "usable cores; 1, with a note, where dask.distributed is not "
                        "installed)")  # fmt: skip
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on the Dask cluster whose scheduler is at ADDRESS "
                        "(tcp://host:8786); --workers is then ignored (default: none)")  # fmt: skip
    p.add_argument("--data", help="public dataset root for sources named by house (default: "
                   "$SPCOPYRO_DATA or ../shared/data/spcomapping)")  # fmt: skip
    p.add_argument("--retry-failed", action="store_true",
                   help="run again the cells stored with an error (default: keep it)")  # fmt: skip
    p.add_argument("--rerun-stale", action="store_true",
                   help="run again the finished cells that other spcopyro source computed "
                        "(their source_digest is not this install's; default: keep them and "
                        "say how many)")  # fmt: skip
    p.add_argument("--dry-run", action="store_true",
                   help="print the cells a run would run (per data, variant and method, with "
                        "their iterations); fit and write nothing")  # fmt: skip
    p.add_argument("--report-only", action="store_true",
                   help="redraw report.md from OUT/results.csv; fit nothing")  # fmt: skip
    p.set_defaults(func=_study)
