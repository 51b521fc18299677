"""The ``spcopyro experiment`` and ``spcopyro compare-inference`` commands (``spcopyro ablation``
is a shipped study: :mod:`spcopyro.study.commands`).

:func:`add_parser` registers both on the main parser's subparsers (:mod:`spcopyro.cli.main`); the
experiments' own modules are imported only when one of them runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from spcopyro.config import PRESETS

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


def _compare_inference(args: argparse.Namespace) -> int:
    from spcopyro.data import find_dataset_root
    from spcopyro.experiments.comparison_report import run_comparison
    from spcopyro.experiments.inference_comparison import (
        HOUSE_TYPES,
        VARIANTS,
        ComparisonSettings,
        check_variants,
    )

    variants = check_variants(args.methods) if args.methods else tuple(VARIANTS)
    iterations = {}
    for item in args.iterations or ():
        key, _, value = item.partition("=")
        if key not in VARIANTS or not value.isdigit() or int(value) < 1:
            raise ValueError(f"--iterations takes METHOD=N (N >= 1, METHOD one of "
                             f"{list(VARIANTS)}), got {item!r}")  # fmt: skip
        iterations[key] = int(value)
    house_types = HOUSE_TYPES if args.houses == "both" else (args.houses,)
    root = find_dataset_root(args.data) if "public" in house_types else None
    if "public" in house_types and root is None:
        print("note: public dataset not found ($SPCOPYRO_DATA, ../shared/data/spcomapping); "
              "skipping the public houses", file=sys.stderr)  # fmt: skip
    public_houses = tuple(args.public_houses) if args.public_houses else None
    folds = args.folds
    if args.quick and root is not None:
        from spcopyro.data import list_houses

        public_houses = public_houses or tuple(list_houses(root)[:1])
        folds = 1 if folds is None else folds
    command = "spcopyro " + " ".join(sys.argv[1:] if args.argv is None else args.argv)
    settings = ComparisonSettings(
        variants=variants, seeds=args.seeds if args.seeds is not None else (1 if args.quick else 5),
        house_types=house_types, dataset_root=root, public_houses=public_houses, folds=folds,
        preset=args.preset, overrides={} if args.gamma is None else {"gamma": args.gamma},
        iterations=iterations, quick=args.quick, command=command,
    )  # fmt: skip
    summary = run_comparison(args.out, settings, report=print)
    out = Path(args.out)
    print((out / "comparison.md").read_text())
    print(f"wrote {out / 'comparison.md'}, {out / 'comparison.json'} and "
          f"{', '.join(str(out / f) for f in summary['figures'])}")  # fmt: skip
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``experiment`` (Table 4, Figs. 5-7) and ``compare-inference`` (issue #10)."""
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

    p = subparsers.add_parser(
        "compare-inference",
        help="Gibbs against variational inference: quality against wall-clock time (issue #10)",
    )
    p.add_argument(
        "--out",
        required=True,
        help="results folder (comparison.md, comparison.json, comparison_*.png)",
    )
    p.add_argument(
        "--houses",
        choices=("synthetic", "public", "both"),
        default="both",
        help="which house types",
    )
    p.add_argument(
        "--seeds", type=int, help="synthetic houses, seeds 0..n-1 (default: 5; 1 with --quick)"
    )
    p.add_argument(
        "--methods",
        nargs="+",
        help="methods to compare (default: all; those the "
        "registry lacks are skipped with a message)",
    )
    p.add_argument(
        "--iterations",
        nargs="+",
        metavar="METHOD=N",
        help="replace a method's iteration budget, e.g. gibbs=2000 cavi=50 (default: each "
        "method's own, e.g. gibbs 5000 sweeps, cavi 100 iterations; --quick: a few)",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: a tiny synthetic house, "
        "1 seed, a few iterations, one public house and one held-out trial",
    )
    p.add_argument("--data", help="public dataset folder (default: found automatically)")
    p.add_argument("--public-houses", nargs="+", help="public houses (default: all)")
    p.add_argument("--folds", type=int, help="held-out trials per public house (default: all)")
    p.add_argument(
        "--preset", default="original-code", choices=sorted(PRESETS), help="model settings"
    )
    p.add_argument(
        "--gamma", type=float, default=3.0, help="the Potts coupling, replacing the preset's"
    )
    p.set_defaults(func=_compare_inference, argv=None)
