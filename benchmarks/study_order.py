"""A study of mixed cell lengths on a Dask LocalCluster: table order against longest first.

    python benchmarks/study_order.py [--workers 2] [--repeats 2] [--out benchmarks/study_order.json]
    python benchmarks/study_order.py --quick     # smoke test: a few sweeps

One study whose cells differ in length the way a Gibbs-versus-VI study's do (the default
synthetic house, seeds 0-2, Gibbs 1500 sweeps, CAVI 60 iterations, SVI 60 steps: about 1.2,
0.3 and 4-8 s a cell here), run on ``LocalCluster(2 workers)`` into fresh folders, alternately
with the cells started in the table's order (data, seed, variant, method) and longest first as
:func:`spcopyro.study.run.run_study` starts them (:mod:`spcopyro.study.order`), ``--repeats``
times each. Prints each run's wall time (the cluster's start-up and close included), the
best possible (the cells' own seconds over the workers, the start-up left out), and whether
every run's table holds the same numbers; writes the JSON to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path
from unittest.mock import patch

from bench_cli import COUNT, results_path, run_main
from machine import machine_info, progress
from study_dask import differences, scores

from spcopyro.study import run as study_run
from spcopyro.study.run import run_study
from spcopyro.study.spec import Study, study_from_dict
from spcopyro.study.table import read_table


def mixed_study(quick: bool) -> Study:
    """Gibbs, CAVI and SVI cells on the default synthetic house, seeds 0-2 (quick: 0-1)."""
    sweeps = {"gibbs": 20, "cavi": 3, "svi": 5} if quick else {"gibbs": 1500, "cavi": 60,
                                                                 "svi": 60}  # fmt: skip
    size = {"height": 40, "width": 50, "num_rooms": 2} if quick else {}
    return study_from_dict({
        "study": {"name": "study-order-benchmark", "seeds": 2 if quick else 3,
                  "methods": ["gibbs", "cavi", "svi"], "sweeps": sweeps},
        "variants": {"paper-dp": {"preset": "paper-dp"}},
        "data": {"dense": {"synthetic": "default", **size}},
    })  # fmt: skip


def timed_run(study: Study, out: Path, workers: int, table: bool) -> dict[str, object]:
    start = time.perf_counter()
    in_table_order = patch.object(study_run, "longest_first", lambda pending, predicted: pending)
    with in_table_order if table else nullcontext():
        run = run_study(study, out, workers=workers, progress=False, report=progress)
    seconds = time.perf_counter() - start
    rows = read_table(out / "results.csv")
    cells = sum(float(r["seconds"]) for r in rows)
    return {"order": "table" if table else "longest first", "seconds": seconds,
            "cells_seconds": cells, "best": cells / workers, "ran": run.ran,
            "ran_here": run.ran_here, "failed": run.failed,
            "longest_cell": max(float(r["seconds"]) for r in rows)}  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test: a few sweeps")
    parser.add_argument("--workers", type=COUNT, default=2)
    parser.add_argument("--repeats", type=COUNT, default=2, help="runs of each order")
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/study_order.json, "
        "study_order_quick.json with --quick)",
    )
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "study_order", args.quick)
    study = mixed_study(args.quick)
    runs, tables = [], []
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(args.repeats):
            for table in (True, False):
                out = Path(folder) / f"{'table' if table else 'longest'}-{repeat}"
                runs.append(timed_run(study, out, args.workers, table))
                tables.append(scores(out))
    found = [line for t in tables[1:] for line in differences(tables[0], t)]
    same = not found
    print("| run | order | wall s | cells' seconds / workers | longest cell s | ran here |")
    print("|---|---|---|---|---|---|")
    for number, entry in enumerate(runs):
        print(f"| {number + 1} | {entry['order']} | {entry['seconds']:.1f} | {entry['best']:.1f} "
              f"| {entry['longest_cell']:.1f} | {entry['ran_here']} |")  # fmt: skip
    means = {
        order: sum(r["seconds"] for r in runs if r["order"] == order) / args.repeats
        for order in ("table", "longest first")
    }
    ratio = means["longest first"] / means["table"]
    print(f"mean wall: table order {means['table']:.1f} s, longest first "
          f"{means['longest first']:.1f} s (x{ratio:.2f}); same numbers: {same}")  # fmt: skip
    for line in found[:10]:  # which cells differ, against the first run
        print(f"  differs: {line}")
    results = {"machine": machine_info(), "workers": args.workers, "runs": runs,
               "mean_seconds": means, "ratio": ratio, "same_numbers": same,
               "differences": found}  # fmt: skip
    Path(args.out).write_text(json.dumps(results, indent=1, default=str))
    print(f"wrote {args.out}")
    return 0 if same else 1


if __name__ == "__main__":
    run_main(main)
