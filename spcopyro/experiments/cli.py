"""The ``spcopyro experiment`` command (``spcopyro ablation`` and ``spcopyro compare-inference``
run shipped studies: :mod:`spcopyro.study.commands`).

:func:`add_parser` registers it on the main parser's subparsers (:mod:`spcopyro.cli.main`); the
experiments' own modules are imported only when one of them runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

__all__ = ["add_parser"]


def _experiment(args: argparse.Namespace) -> int:
    from spcopyro.data import find_dataset_root, list_houses
    from spcopyro.experiments.methods import METHODS, RunSettings
    from spcopyro.experiments.table import ExperimentSettings, run_experiment

    root = None if args.no_public else find_dataset_root(args.data)
    if args.data is None and root is None and not args.no_public:
        print("note: public dataset not found ($SPCOPYRO_DATA, ../shared/data/spcomapping); "
              "skipping the public houses", file=sys.stderr)  # fmt: skip
    command = "spcopyro " + " ".join(sys.argv[1:] if args.argv is None else args.argv)
    changes: dict[str, object] = dict(dataset_root=root, command=command)
    if args.houses:
        changes["houses"] = tuple(args.houses)
    if args.methods:
        unknown = sorted(set(args.methods) - set(METHODS))
        if unknown:
            raise ValueError(f"unknown --methods {unknown}; choose from {list(METHODS)}")
        changes["methods"] = tuple(m for m in METHODS if m in args.methods)
    if args.quick and args.houses is None and root is not None:
        changes["houses"] = tuple(list_houses(root)[:1])
    if args.quick:
        settings = ExperimentSettings.quick(**changes)
    else:
        settings = ExperimentSettings(**changes)  # type: ignore[arg-type]
    run = settings.run
    if args.sweeps is not None or args.spcoa_iterations is not None:
        run = RunSettings(
            sweeps=args.sweeps if args.sweeps is not None else run.sweeps,
            spcoa_iterations=args.spcoa_iterations or run.spcoa_iterations,
            trace_every=max(1, (args.sweeps or run.sweeps) // 100),
        )
    seeds = args.seeds if args.seeds is not None else settings.seeds
    settings = dataclasses.replace(settings, run=run, seeds=seeds)
    summary = run_experiment(args.out, settings, report=print)
    out = Path(args.out)
    print((out / "table.md").read_text())
    print(f"wrote {out / 'table.md'}, {out / 'table.json'} and {len(summary['figures'])} "
          f"figures under {out / 'figures'}")  # fmt: skip
    if args.studies:
        from spcopyro.experiments.studies import write_studies

        count = seeds if isinstance(seeds, int) else len(seeds)
        print(write_studies(out, sweeps=min(run.sweeps, 1000), seeds=tuple(range(min(count, 3)))))
        print(f"wrote {out / 'studies.md'} and {out / 'studies.json'}")
    if args.robustness:
        from spcopyro.experiments.robustness import write_robustness

        count = seeds if isinstance(seeds, int) else len(seeds)
        print(write_robustness(out, sweeps=min(run.sweeps, 1000),
                               seeds=tuple(range(min(count, 3))), chains=3,
                               dataset_root=settings.dataset_root))  # fmt: skip
        print(f"wrote {out / 'robustness.md'} and {out / 'robustness.json'}")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``experiment`` (Table 4, Figs. 5-7)."""
    p = subparsers.add_parser("experiment", help="the paper's comparison (Table 4, Figs. 5-7)")
    p.add_argument("--out", required=True, help="results folder (table.md, table.json, figures/)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: small synthetic house, 2 seeds, 20 sweeps, one public house",
    )
    p.add_argument("--seeds", type=int, help="synthetic houses (default 5)")
    p.add_argument("--sweeps", type=int, help="SpCoMapping Gibbs sweeps (default 5000)")
    p.add_argument("--spcoa-iterations", type=int, help="SpCoA iterations (default 200)")
    p.add_argument("--data", help="public dataset folder (default: found automatically)")
    p.add_argument("--no-public", action="store_true", help="synthetic houses only")
    p.add_argument("--houses", nargs="+", help="public houses to score (default: all)")
    p.add_argument("--methods", nargs="+", help="rows to run (default: all)")
    p.add_argument(
        "--studies",
        action="store_true",
        help="also the modality ablation and the sentence (tf-idf) study (studies.md)",
    )
    p.add_argument(
        "--robustness",
        action="store_true",
        help="also the stability (seeds, chains, init) and sensitivity studies (robustness.md)",
    )
    p.set_defaults(func=_experiment, argv=None)
