"""Commands that are shipped studies under their old names (issue 26 item 1).

``spcopyro experiment`` runs the study engine on ``spcopyro/study/studies/experiment.toml``
(``experiment_quick.toml`` with ``--quick``), its options changing that study
(:func:`spcopyro.study.experiment.experiment_study`), and writes the paper's comparison
(``table.md``, ``table.json``, ``figures/``) from the study's table and stored maps; its
``--studies`` and ``--robustness`` run the shipped studies ``modality`` and ``sentences``
(:mod:`spcopyro.study.side_studies`), ``stability`` and ``sensitivity``
(:mod:`spcopyro.study.robustness`) into ``OUT/studies/`` and ``OUT/robustness/``.
``spcopyro compare-inference`` runs the study engine on the grid of its options
(:func:`spcopyro.study.comparison.comparison_study`; its defaults and ``--quick`` are the cells of
the shipped ``compare_inference.toml`` and ``compare_inference_quick.toml``) and writes the
comparison's ``comparison.md``, ``comparison.json`` and figures from the study's table.
``spcopyro ablation`` runs the study engine on ``spcopyro/study/studies/ablation.toml``
(``ablation_quick.toml`` with ``--quick``), its options changing that study
(:func:`spcopyro.study.ablation.ablation_settings`), and writes the ablation's tables
(``ablation.md``, ``ablation.json``, ``ablation.png``) from the study's ``results.csv``. As a
study, it is cached and resumable: rerun the same command in the same ``--out`` and only the
missing cells run. :func:`add_parser` registers it; nothing heavy is imported before it runs.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from spcopyro._util.arguments import integer_at_least as _integer_at_least
from spcopyro.config import DEFAULT_PRESET, PRESETS

__all__ = ["add_parser"]


def _flag(name: str) -> str:
    """``public_houses`` -> ``--public-houses``."""
    return "--" + name.replace("_", "-")


def _first_given(**options: object) -> tuple[str, str] | None:
    """``(--flag, "--flag value")`` of the first option of ``options`` given (not None)."""
    for name, value in options.items():
        if value is not None:
            shown = " ".join(map(str, value)) if isinstance(value, list | tuple) else value
            return _flag(name), f"{_flag(name)} {shown}"
    return None


def _contradicts(given: str, **options: object) -> None:
    """ValueError when an option of ``options`` (None: not given) is given beside ``given``,
    which leaves it nothing to do (it was ignored)."""
    other = _first_given(**options)
    if other is not None:
        flag, shown = other
        raise ValueError(f"{shown} and {given} contradict each other: {given} leaves {flag} "
                         "nothing to do")  # fmt: skip


def _reads_nothing(given: str, flag: str, values: Sequence[str], why: str) -> None:
    """ValueError: ``given`` sets what no row of ``flag values`` runs (it was ignored)."""
    shown = f"{flag} {' '.join(values)}" if values else f"{flag} (none)"
    raise ValueError(f"{given} and {shown} contradict each other: {shown} runs {why}, so "
                     f"{given.split()[0]} would change nothing")  # fmt: skip


def _without_dataset(**options: object) -> None:
    """The public dataset was not found: ValueError when an option of ``options`` (None: not
    given) names public houses (the run skipped them and exited 0, its table holding none of
    the houses asked for), else a note that the public houses are skipped."""
    asked = _first_given(**options)
    if asked is not None:
        raise ValueError(
            f"{asked[1]} asks for public houses, but the public dataset was not found "
            "($SPCOPYRO_DATA, ../shared/data/spcomapping): give --data DIR"
        )
    print("note: public dataset not found ($SPCOPYRO_DATA, ../shared/data/spcomapping); "
          "skipping the public houses", file=sys.stderr)  # fmt: skip


def _known_houses(flag: str, houses: Sequence[str] | None, root: object) -> None:
    """ValueError naming ``flag``, the houses of ``houses`` that the dataset ``root`` lacks and
    the houses it has (the error named the study file's ``[data.HOUSE]`` table or the missing
    folder, not the option); nothing when ``houses`` or ``root`` is None."""
    if root is None or houses is None:
        return
    from spcopyro.data import list_houses

    known = list_houses(root)  # type: ignore[arg-type]
    unknown = [h for h in houses if h not in known]
    if unknown:
        listed = ", ".join(known) or "none"
        raise ValueError(f"{flag} {' '.join(unknown)}: not a house of {root} (a folder with "
                         f"map/NAME.yaml); its houses: {listed}")  # fmt: skip


def _command_line(args: argparse.Namespace) -> str:
    """The command as typed, quoted where the shell needs it ("Made by:" of the reports; an
    --out with a space read as two words, and the line did not run when pasted)."""
    import shlex

    return shlex.join(["spcopyro", *(sys.argv[1:] if args.argv is None else args.argv)])


def _stoppable(command: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``command`` with SIGTERM (``timeout``, Slurm) stopping it as Ctrl-C does: the study
    engine then rewrites the finished cells' table and report before the exit (130), as
    ``spcopyro study`` does; without it the process ended at once, the table unwritten. Its
    ``--workers N > 1`` without dask.distributed is one line (ValueError), not a traceback."""

    @functools.wraps(command)
    def run(args: argparse.Namespace) -> int:
        from spcopyro._util.collector import import_frozen
        from spcopyro._util.interrupts import sigterm_as_interrupt

        # torch's, pyro's and the study's objects, frozen, as `spcopyro fit` imports its own
        import_frozen("spcopyro.study.run")  # (spcopyro._util.collector)
        from spcopyro.study.run import DASK_MISSING, dask_installed

        if args.workers > 1 and not dask_installed():
            raise ValueError(f"--workers {args.workers}: {DASK_MISSING}")
        with sigterm_as_interrupt():
            return command(args)

    return run


_COMMANDS = ("experiment", "ablation", "compare-inference")
"""The commands that run a shipped study into their --out, each with reports of its own."""


def _not_another_commands_folder(out: str, command: str) -> None:
    """ValueError when ``out`` holds another of :data:`_COMMANDS`' results (its ``study.json``
    names that command's study, quick or not): the run replaced that folder's ``results.csv``,
    ``report.md`` and ``study.json`` silently (its cells stayed cached), leaving its own report
    beside the new one."""
    path = Path(out) / "study.json"
    try:
        name = json.loads(path.read_text(encoding="utf-8")).get("name")
    except (OSError, ValueError, AttributeError):
        return  # none, or not a study's: the study engine says what is wrong with it
    family = name.removesuffix("-quick") if isinstance(name, str) else None
    if family in _COMMANDS and family != command:
        raise ValueError(
            f"--out {out} holds the results of `spcopyro {family}` ({path}): give this "
            f"{command} another folder (it would replace their results.csv, report.md and "
            "study.json)"
        )


@contextlib.contextmanager
def _reports_of_an_earlier_run(out: str, *names: str) -> Iterator[None]:
    """On Ctrl-C or SIGTERM, name the command's own reports in ``out`` (``comparison.md``, ...)
    that are still an earlier run's: the study engine rewrote ``results.csv`` and ``report.md``
    from the cells finished so far, but the command writes these only at its end (each replaced
    whole), so those it had not replaced when stopped stayed the earlier run's beside them
    without a word. One it had replaced is this run's, whole, and not named: each is replaced
    through :func:`spcopyro._util.outputs.replace_text` (or ``replace_figure``), a new inode, so
    (device, inode) tells the two apart."""
    from spcopyro._util.outputs import file_identity  # at a run only: nothing on the --help path

    seen = {path: file_identity(path) for path in (Path(out) / name for name in names)}
    try:
        yield
    except KeyboardInterrupt:
        earlier = [p for p, version in seen.items() if version and file_identity(p) == version]
        if earlier:
            print(f"{', '.join(map(str, earlier))}: an earlier run's, not rewritten (they are "
                  "written at the end); run the same command again to finish them",
                  file=sys.stderr)  # fmt: skip
        raise


def _experiment(args: argparse.Namespace) -> int:
    from spcopyro.data import find_dataset_root
    from spcopyro.study.experiment import (
        EXPERIMENT,
        EXPERIMENT_QUICK,
        experiment_study,
        run_experiment,
    )
    from spcopyro.study.spec import check_once, load_study

    check_once("--houses", args.houses)
    check_once("--methods", args.methods)
    if args.no_public:
        _contradicts("--no-public", houses=args.houses, data=args.data)
    study = load_study(EXPERIMENT_QUICK if args.quick else EXPERIMENT)
    if args.methods is not None:  # an option no row chosen reads was ignored
        spcomapping = {v.name for v in study.variants}
        if args.sweeps is not None and not spcomapping & set(args.methods):
            _reads_nothing(f"--sweeps {args.sweeps}", "--methods", args.methods,
                           f"no SpCoMapping row ({', '.join(sorted(spcomapping))})")  # fmt: skip
        if args.spcoa_iterations is not None and "C-spcoa" not in args.methods:
            _reads_nothing(f"--spcoa-iterations {args.spcoa_iterations}", "--methods",
                           args.methods, "no C-spcoa row")  # fmt: skip
    root = None if args.no_public else find_dataset_root(args.data)
    if args.data is None and root is None and not args.no_public:
        _without_dataset(houses=args.houses)
    _known_houses("--houses", args.houses, root)
    command = _command_line(args)
    study = experiment_study(
        study, public=root is not None, houses=args.houses, methods=args.methods,
        seeds=args.seeds, sweeps=args.sweeps, spcoa_iterations=args.spcoa_iterations,
        command=command,
    )  # fmt: skip
    _not_another_commands_folder(args.out, "experiment")
    with _reports_of_an_earlier_run(args.out, "table.md", "table.json"):
        summary = run_experiment(args.out, study, root=root, workers=args.workers,
                                 retry_failed=args.retry_failed, rerun_stale=args.rerun_stale,
                                 report=print)  # fmt: skip
    out = Path(args.out)
    print((out / "table.md").read_text())
    print(f"wrote {out / 'table.md'}, {out / 'table.json'} and {len(summary['figures'])} "
          f"figures under {out / 'figures'} (the study's table: "
          f"{out / 'results.csv'})")  # fmt: skip
    sweeps = study.sweeps_for("gibbs")
    count = summary["settings"]["seeds"]  # type: ignore[index]
    if args.studies:
        from spcopyro.study.side_studies import write_studies

        print(write_studies(out, sweeps=min(sweeps, 1000), seeds=tuple(range(min(count, 3))),
                            workers=args.workers, rerun_stale=args.rerun_stale,
                            report=print))  # fmt: skip
        print(f"wrote {out / 'studies.md'} and {out / 'studies.json'}")
    if args.robustness:
        from spcopyro.study.robustness import write_robustness

        print(write_robustness(out, sweeps=min(sweeps, 1000),
                               seeds=tuple(range(min(count, 3))), chains=3,
                               dataset_root=root,
                               public_houses=[d.target for d in study.data if d.kind == "public"],
                               workers=args.workers, rerun_stale=args.rerun_stale,
                               report=print))  # fmt: skip
        print(f"wrote {out / 'robustness.md'} and {out / 'robustness.json'}")
    return 1 if summary["failed"] else 0


def _ablation(args: argparse.Namespace) -> int:
    from spcopyro.data import find_dataset_root
    from spcopyro.experiments.ablation_variants import parse_variant
    from spcopyro.study.ablation import ABLATION, ABLATION_QUICK, ablation_settings, run_ablation
    from spcopyro.study.spec import BASELINES, check_once, load_study

    for option in ("houses", "baselines", "public_houses"):
        check_once(_flag(option), getattr(args, option))
    if args.no_public:
        _contradicts("--no-public", public_houses=args.public_houses, data=args.data,
                     public_seeds=args.public_seeds or None)  # fmt: skip
    if args.public_seeds == 0:
        _contradicts("--public-seeds 0", public_houses=args.public_houses)
    if args.seeds == 0:
        _contradicts("--seeds 0", houses=args.houses)
    study = load_study(ABLATION_QUICK if args.quick else ABLATION)
    baselines = study.baselines if args.baselines is None else args.baselines
    if args.spcoa_iterations is not None and "C-spcoa" not in baselines:  # it was ignored
        _reads_nothing(f"--spcoa-iterations {args.spcoa_iterations}", "--baselines", baselines,
                       "no C-spcoa row")  # fmt: skip
    root = None if args.no_public else find_dataset_root(args.data)
    if root is None and not args.no_public:
        _without_dataset(public_houses=args.public_houses)
    _known_houses("--public-houses", args.public_houses, root)
    command = _command_line(args)
    changes: dict[str, object] = dict(command=command, workers=args.workers)
    if args.no_off:
        changes["observations_off"] = False
    if args.variant:
        variants = tuple(parse_variant(text) for text in args.variant)
        names = [v.name for v in variants]
        if len(set(names)) != len(names):
            raise ValueError(f"--variant names must differ, got {names}")
        changes["variants"] = variants
    if args.baselines is not None:
        unknown = sorted(set(args.baselines) - set(BASELINES))
        if unknown:
            raise ValueError(f"unknown --baselines {unknown}; choose from {list(BASELINES)}")
        changes["baselines"] = tuple(args.baselines)
    for key in ("seeds", "public_seeds", "sweeps", "spcoa_iterations"):
        if getattr(args, key) is not None:
            changes[key] = getattr(args, key)
    if args.public_houses:
        changes["public_houses"] = tuple(args.public_houses)
    settings = ablation_settings(study, root, **changes)
    if args.houses:
        missing = sorted(set(args.houses) - set(settings.houses))
        if missing:
            which = "--quick's" if args.quick else "the ablation's"  # --quick has two of five
            offered = ", ".join(settings.houses)
            raise ValueError(f"--houses {' '.join(missing)}: not a synthetic setting of "
                             f"{which} study; choose from {offered}")  # fmt: skip
        settings = ablation_settings(study, root, **changes, synthetic=tuple(args.houses))
    public = settings.dataset_root is not None and settings.public_seeds > 0
    if not (settings.seeds > 0 and settings.synthetic) and not public:  # an empty study exited 0
        raise ValueError(
            "the ablation would run no cell: --seeds 0 (or no --houses) leaves no synthetic "
            "house, and there is no public house (--no-public, --public-seeds 0 or no dataset)"
        )
    _not_another_commands_folder(args.out, "ablation")
    with _reports_of_an_earlier_run(args.out, "ablation.md", "ablation.json", "ablation.png"):
        summary = run_ablation(args.out, settings, report=print, retry_failed=args.retry_failed,
                               rerun_stale=args.rerun_stale, name=study.name)  # fmt: skip
    out = Path(args.out)
    print((out / "ablation.md").read_text())
    print(f"wrote {out / 'ablation.md'}, {out / 'ablation.json'} and {out / 'ablation.png'} "
          f"(the study's table: {out / 'results.csv'})")  # fmt: skip
    return 1 if summary["failed"] else 0


def _iterations(
    items: Sequence[str], variants: Sequence[str], known: Sequence[str]
) -> dict[str, int]:
    """``--iterations METHOD=N ...`` as {METHOD: N}: N read as int() reads it (``1_000``, as
    every integer option takes it), a METHOD of ``known`` that is among the compared
    ``variants``."""
    iterations: dict[str, int] = {}
    for item in items:
        key, _, value = item.partition("=")
        try:
            count = int(value)
        except ValueError:
            count = 0
        if key not in known or count < 1:
            raise ValueError(f"--iterations takes METHOD=N (N >= 1, METHOD one of "
                             f"{list(known)}), got {item!r}")  # fmt: skip
        if key in iterations:
            raise ValueError(f"--iterations: {key} is given twice ({key}={iterations[key]}, "
                             f"{item})")  # fmt: skip
        if key not in variants:
            raise ValueError(f"--iterations {item}: {key} is not compared (--methods "
                             f"{' '.join(variants)})")  # fmt: skip
        iterations[key] = count
    return iterations


def _compare_inference(args: argparse.Namespace) -> int:
    from spcopyro.data import find_dataset_root
    from spcopyro.experiments.inference_comparison import (
        HOUSE_TYPES,
        VARIANTS,
        ComparisonSettings,
        check_variants,
    )
    from spcopyro.study.comparison import run_comparison
    from spcopyro.study.spec import check_once

    check_once("--methods", args.methods)
    check_once("--public-houses", args.public_houses)
    if args.houses == "synthetic":
        _contradicts("--houses synthetic", public_houses=args.public_houses, folds=args.folds,
                     data=args.data)  # fmt: skip
    elif args.houses == "public":
        _contradicts("--houses public", seeds=args.seeds)
    variants = check_variants(args.methods) if args.methods else tuple(VARIANTS)
    iterations = _iterations(args.iterations or (), variants, tuple(VARIANTS))
    if args.gamma is not None:  # named here: it failed as "variant 'gibbs': settings ..."
        from spcopyro.config import preset

        try:
            preset(args.preset, gamma=args.gamma, num_concepts=PRESETS[args.preset].get(
                "num_concepts") or 6)  # fmt: skip
        except ValueError as error:
            raise ValueError(f"--gamma {args.gamma:g}: {error}") from None
    house_types = HOUSE_TYPES if args.houses == "both" else (args.houses,)
    root = find_dataset_root(args.data) if "public" in house_types else None
    if "public" in house_types and root is None:
        _without_dataset(public_houses=args.public_houses,
                       houses=args.houses if args.houses == "public" else None)  # fmt: skip
    _known_houses("--public-houses", args.public_houses, root)
    public_houses = tuple(args.public_houses) if args.public_houses else None
    folds = args.folds
    if args.quick and root is not None:
        from spcopyro.data import list_houses

        public_houses = public_houses or tuple(list_houses(root)[:1])
        folds = 1 if folds is None else folds
    command = _command_line(args)
    settings = ComparisonSettings(
        variants=variants, seeds=args.seeds if args.seeds is not None else (1 if args.quick else 5),
        house_types=house_types, dataset_root=root, public_houses=public_houses, folds=folds,
        preset=args.preset, overrides={} if args.gamma is None else {"gamma": args.gamma},
        iterations=iterations, quick=args.quick, command=command,
    )  # fmt: skip
    _not_another_commands_folder(args.out, "compare-inference")
    with _reports_of_an_earlier_run(args.out, "comparison.md", "comparison.json"):
        summary = run_comparison(args.out, settings, report=print, workers=args.workers,
                                 retry_failed=args.retry_failed,
                                 rerun_stale=args.rerun_stale)  # fmt: skip
    out = Path(args.out)
    print((out / "comparison.md").read_text())
    print(f"wrote {out / 'comparison.md'}, {out / 'comparison.json'} and "
          f"{', '.join(str(out / f) for f in summary['figures'])} (the study's table: "
          f"{out / 'results.csv'})")  # fmt: skip
    return 1 if summary["failed"] else 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``experiment`` (Table 4, Figs. 5-7), ``compare-inference`` (issue #10) and
    ``ablation`` (issue #14), the shipped studies ``experiment``, ``compare_inference`` and
    ``ablation``."""
    p = subparsers.add_parser(
        "experiment",
        help="the paper's comparison (Table 4, Figs. 5-7); the shipped study 'experiment' "
        "(docs/studies.md)",
    )
    p.add_argument("--out", required=True, help="results folder: table.md, table.json, "
                   "figures/, and the study's cells/ (cache), maps/, traces/, results.csv, "
                   "report.md; finished cells there are not run again")  # fmt: skip
    p.add_argument(
        "--quick",
        action="store_true",
        help="smoke run (the study experiment_quick): small synthetic house, 2 seeds, 20 "
        "sweeps, one public house",
    )
    p.add_argument("--seeds", type=_integer_at_least(1), help="synthetic houses (default 5)")
    p.add_argument(
        "--sweeps", type=_integer_at_least(1), help="SpCoMapping Gibbs sweeps (default 5000)"
    )
    p.add_argument(
        "--spcoa-iterations", type=_integer_at_least(1), help="SpCoA iterations (default 200)"
    )
    p.add_argument("--data", help="public dataset folder (default: found automatically)")
    p.add_argument("--no-public", action="store_true", help="synthetic houses only")
    p.add_argument("--houses", nargs="+", help="public houses to score, in the table and in "
                   "--robustness's sensitivity (default: the five of the public dataset; "
                   "--quick: room1dk5)")  # fmt: skip
    p.add_argument("--methods", nargs="+", help="rows to run (default: all: A-dp A-orig-g3 "
                   "B-dirichlet C-spcoa D-cnn E-nearest F-geometry)")  # fmt: skip
    p.add_argument("--workers", type=_integer_at_least(1), default=1,
                   help="1: in this process; N > 1: a Dask "
                   "LocalCluster of N processes, one torch thread each")  # fmt: skip
    p.add_argument("--retry-failed", action="store_true",
                   help="run again the cells stored with an error in --out")  # fmt: skip
    p.add_argument("--rerun-stale", action="store_true",
                   help="run again the finished cells in --out that other spcopyro source "
                   "computed (default: keep them and say how many)")  # fmt: skip
    p.add_argument(
        "--studies",
        action="store_true",
        help="also the modality ablation and the sentence (tf-idf) study (OUT/studies.md)",
    )
    p.add_argument(
        "--robustness",
        action="store_true",
        help="also the stability (seeds, chains, init) and sensitivity studies (OUT/robustness.md)",
    )
    p.set_defaults(func=_stoppable(_experiment), argv=None)

    p = subparsers.add_parser(
        "compare-inference",
        help="Gibbs against variational inference: quality against wall-clock time; "
        "the shipped study 'compare_inference' (docs/studies.md)",
        description="Gibbs against variational inference: quality against wall-clock time. "
        "The default is the whole study: 140 fits (7 methods x 5 synthetic houses and the "
        "public houses' 15 held-out trials) at each method's full budget, about 2 hours of fits "
        "on 2 cores (more on a loaded machine); it says how many fits and their predicted time "
        "before the first. Shorter: --quick (a smoke run, seconds), --houses synthetic --seeds "
        "2, or --iterations gibbs=500 ...",
    )
    p.add_argument(
        "--out",
        required=True,
        help="results folder: comparison.md, comparison.json, comparison_*.png, and the "
        "study's cells/ (cache), results.csv, report.md",
    )
    p.add_argument(
        "--houses",
        choices=("synthetic", "public", "both"),
        default="both",
        help="which house types",
    )
    p.add_argument(
        "--seeds",
        type=_integer_at_least(1),
        help="synthetic houses, seeds 0..n-1 (default: 5; 1 with --quick)",
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
    p.add_argument(
        "--folds", type=_integer_at_least(1), help="held-out trials per public house (default: all)"
    )
    p.add_argument(
        "--preset", default="original-code", choices=sorted(PRESETS),
        help="the model's and data's settings of a preset (not fit's start, moves, point "
        "estimate or refinement: every line starts from random labels, so auto fits as "
        "original-code with gamma 3)",
    )  # fmt: skip
    p.add_argument(
        "--gamma", type=float, default=3.0, help="the Potts coupling, replacing the preset's"
    )
    p.add_argument("--workers", type=_integer_at_least(1), default=1,
                   help="1: in this process, one fit at a "
                   "time (comparable times); N > 1: a Dask LocalCluster of N")  # fmt: skip
    p.add_argument("--retry-failed", action="store_true",
                   help="run again the cells stored with an error in --out")  # fmt: skip
    p.add_argument("--rerun-stale", action="store_true",
                   help="run again the finished cells in --out that other spcopyro source "
                   "computed (default: keep them and say how many)")  # fmt: skip
    p.set_defaults(func=_stoppable(_compare_inference), argv=None)

    p = subparsers.add_parser(
        "ablation",
        help="every variant (named overrides) on dense, sparse and other synthetic houses and "
        "the public houses, beside SpCoA and geometry; the shipped study "
        "'ablation' (docs/studies.md)",
    )
    p.add_argument("--out", required=True, help="results folder: ablation.md, .json, .png, and "
                   "the study's cells/ (cache), results.csv, report.md")  # fmt: skip
    p.add_argument(
        "--variant",
        action="append",
        metavar="NAME:KEY=VALUE,...",
        help="a row: a preset, SpCoConfig/DataPreparation fields, GibbsOptions fields (nested "
        "as a.b) and fit_house arguments, e.g. 'sw:preset=paper-dp,cluster_moves=0.2'; "
        f"repeat for more rows; without preset=, the default preset {DEFAULT_PRESET} (default: "
        "the study file's: paper-dp, original-code gamma 3, paper-dp + cluster moves)",
    )
    p.add_argument(
        "--baselines", nargs="*", help="baseline rows (default: C-spcoa F-geometry; none: no value)"
    )
    p.add_argument(
        "--houses",
        nargs="+",
        help="synthetic settings (default: dense sparse dense-large sparse-small open-plan)",
    )
    p.add_argument("--seeds", type=_integer_at_least(0),
                   help="synthetic seeds 0..n-1 (default 10; 0: public houses only)")  # fmt: skip
    p.add_argument(
        "--public-seeds", type=_integer_at_least(0), help="seeds per public house (default 3)"
    )
    p.add_argument("--public-houses", nargs="+", help="public houses (default: the five of the "
                   "public dataset)")  # fmt: skip
    p.add_argument(
        "--sweeps", type=_integer_at_least(1), help="Gibbs sweeps per fit (default 1000)"
    )
    p.add_argument(
        "--spcoa-iterations", type=_integer_at_least(1), help="SpCoA iterations (default 100)"
    )
    p.add_argument("--workers", type=_integer_at_least(1), default=1,
                   help="1: in this process; N > 1: a Dask "
                   "LocalCluster of N processes, one torch thread each")  # fmt: skip
    p.add_argument("--no-off", action="store_true", help="skip the fits without observations")
    p.add_argument("--data", help="public dataset folder (default: found automatically)")
    p.add_argument("--no-public", action="store_true", help="synthetic houses only")
    p.add_argument("--retry-failed", action="store_true",
                   help="run again the cells stored with an error in --out")  # fmt: skip
    p.add_argument(
        "--quick",
        action="store_true",
        help="smoke run (the study ablation_quick): two small houses, 2 seeds, 30 sweeps, one "
        "public house and seed",
    )
    p.add_argument("--rerun-stale", action="store_true",
                   help="run again the finished cells in --out that other spcopyro source "
                   "computed (default: keep them and say how many)")  # fmt: skip
    p.set_defaults(func=_stoppable(_ablation), argv=None)
