"""The ``spcopyro`` command line: simulate, show, fit, where.

DATA is a house folder in the public dataset's layout (its map at ``DATA/../map/NAME.yaml``), e.g.
``../shared/data/spcomapping/room1dk5``, or one written by ``spcopyro simulate``. Where DATA is
left out, the embedded default is used: the synthetic house of seed 0, generated in memory.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from spcopyro import __version__
from spcopyro.config import DEFAULT_PRESET, DEFAULT_SNAP_DISTANCE, PRESETS, SpCoSettings, preset
from spcopyro.data import House, cell_counts, load_house
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.options import BACKENDS, GibbsOptions
from spcopyro.inference import with_options
from spcopyro.outputs import StagedOutput

if TYPE_CHECKING:
    from spcopyro.fit import FitCheckpoint
from spcopyro.registry import DEFAULT_METHOD, INFERENCE_METHODS
from spcopyro.threads import AUTO, MIN_CELLS_FOR_MORE_THREADS, describe_threads

logger = logging.getLogger("spcopyro")
_clock = time.perf_counter  # wall clock of a whole fit (all chains)


def _load(data: str | None, seed: int = 0) -> House:
    if data is None:
        from spcopyro.synthetic import make_house

        return make_house(seed=seed)
    return load_house(Path(data))


def _simulate(args: argparse.Namespace) -> int:
    from spcopyro.synthetic import HouseSpec, write_synthetic

    spec = HouseSpec.scaled(*args.size, sentence_fraction=args.sentences) if args.size else None
    if spec is None and args.sentences:
        spec = HouseSpec(sentence_fraction=args.sentences)
    try:
        room = write_synthetic(args.out, seed=args.seed, spec=spec, name=args.name,
                               overwrite=args.overwrite)  # fmt: skip
    except FileExistsError as error:  # the library names its keyword, the command its flag
        raise FileExistsError(
            str(error).replace("pass overwrite=True", "pass --overwrite to replace it")
        ) from None
    print(f"wrote synthetic house (seed {args.seed}) to {room}")
    print(f"  fit it with: spcopyro fit {room} --out {Path(args.out) / 'fit'}")
    return 0


def _summary(house: House) -> str:
    counts = cell_counts(house.grid, house.observations, source=house.source)
    p = counts.placement
    obs = house.observations
    lines = [
        f"house            {house.name}",
        f"map              {house.grid.height} x {house.grid.width} cells at "
        f"{house.grid.resolution} m, {house.grid.num_free} free",
        f"images           {obs.num_images} ({obs.num_feature_classes} feature classes) in "
        f"{len(obs.trials)} trial(s)",
        f"utterances       {obs.num_utterances}, vocabulary of {len(counts.vocabulary)} words",
        f"observed cells   {len(counts.cells)}",
        f"placement        images: {p.images_on_free} on free cells, {p.images_snapped} snapped, "
        f"{p.images_unplaced} unplaced; words: {p.words_on_free} on free cells, "
        f"{p.words_snapped} snapped, {p.words_unplaced} unplaced "
        f"(snap distance {p.snap_distance} m)",
    ]
    if house.category_names:
        lines.append(f"ground truth     {len(house.category_names)} categories: "
                     + ", ".join(house.category_names))  # fmt: skip
    return "\n".join(lines)


def _show(args: argparse.Namespace) -> int:
    from spcopyro.plotting import plot_house

    house = _load(args.data)
    print(_summary(house))
    print(f"wrote {plot_house(house, args.out)}")
    return 0


def _fit(args: argparse.Namespace) -> int:
    """Check the arguments and OUT, then fit into a staging folder moved to OUT at the end
    (:mod:`spcopyro.outputs`); Ctrl-C keeps a checkpoint beside OUT and exits with 130."""
    from spcopyro.fit import FitCheckpoint, FitInterrupted
    from spcopyro.outputs import checkpoint_path, stage_output

    if args.sweeps == "auto" and args.method != "gibbs":
        raise ValueError(f"--sweeps auto is Gibbs' convergence rule, not {args.method!r}'s")
    if args.resume is not None and (args.sweeps == "auto" or args.method != "gibbs"):
        raise ValueError(
            "--resume continues Gibbs chains run for a number of --sweeps; "
            f"--sweeps {args.sweeps} --method {args.method} keeps no checkpoint"
        )
    if args.sweeps != "auto" and args.anneal_sweeps > args.sweeps:
        raise ValueError(f"anneal_sweeps ({args.anneal_sweeps}) must not exceed num_sweeps "
                         f"({args.sweeps})")  # fmt: skip
    if args.resume is not None and not Path(args.resume).is_file():
        raise FileNotFoundError(f"--resume {args.resume}: no such checkpoint file")
    house = _load(args.data)
    settings, options = _fit_settings(args, house)
    staged = stage_output(args.out, overwrite=args.overwrite, resume=args.resume)
    keeper = None  # keeps the Gibbs chains for a checkpoint beside OUT
    if args.method == "gibbs" and args.sweeps != "auto":
        keeper = FitCheckpoint(checkpoint_path(staged.out))
    sampled: list[bool] = []  # set once sampling has ended
    try:
        return _fit_staged(args, house, settings, options, staged, keeper, sampled)
    except KeyboardInterrupt as stop:
        if staged.committed:
            print(f"interrupted after {staged.out} was written", file=sys.stderr)
            return 130
        if isinstance(stop, FitInterrupted):  # while sampling
            where, kept = f" ({stop.where})", stop.checkpoint
        else:  # while reading the data, or writing the outputs
            where = " while writing the outputs" if sampled else ""
            kept = keeper.save() if keeper and sampled else None
        print(_interrupted(args, where, kept, staged.out), file=sys.stderr)
        return 130
    except Exception:
        writing = sampled and not (staged.committed or staged.kept)
        kept = keeper.save() if keeper and writing else None
        if kept is not None:  # an error while writing: the sampling is not lost
            print(f"note: nothing written to {staged.out}; the finished chains are saved in "
                  f"{kept} -- once fixed, continue with: {_resume_command(args, kept)}",
                  file=sys.stderr)  # fmt: skip
        raise
    finally:
        staged.discard()  # nothing once committed; else the run's partial outputs


def _interrupted(args: argparse.Namespace, where: str, kept: Path | None, out: Path) -> str:
    """The one line ``fit`` prints when Ctrl-C stops it (``kept``: the checkpoint, if any)."""
    line = f"interrupted{where}: nothing written to {out}"
    if kept is None:
        why = "--sweeps auto" if args.sweeps == "auto" else f"the {args.method!r} method"
        if args.sweeps != "auto" and args.method == "gibbs":
            why = "no sweep was done"
        return f"{line}; no checkpoint kept ({why})"
    command = _resume_command(args, kept)
    return f"{line}; the state reached is saved in {kept} -- continue with: {command}"


def _command(args: argparse.Namespace) -> list[str]:
    """The command line this run was started with (without the program's name)."""
    return list(args.argv if getattr(args, "argv", None) else sys.argv[1:])


def _resume_command(args: argparse.Namespace, checkpoint: Path) -> str:
    """This run's command line with ``--resume CHECKPOINT`` (in place of an earlier one)."""
    argv = _command(args)
    for k in range(len(argv) - 1, -1, -1):
        if argv[k] == "--resume":
            del argv[k : k + 2]
        elif argv[k].startswith("--resume="):
            del argv[k]
    return shlex.join(["spcopyro", *argv, "--resume", str(checkpoint)])


def _fit_settings(
    args: argparse.Namespace, house: House
) -> tuple[SpCoSettings, object | None]:
    """The model and data settings and the method's options (None: its defaults) of ``fit``."""
    overrides = dict(
        prior=args.prior, num_concepts=args.concepts, gamma=args.gamma, alpha=args.alpha,
        beta=args.beta, chi=args.chi, connectivity=args.connectivity,
        concentrations=_concentrations(args.concentration),
        word_weighting="tfidf" if args.tfidf else None,
        feature_scaling=_feature_scaling(args.feature_scaling),
        snap_distance=args.snap_distance,
    )  # fmt: skip
    if args.preset == "paper-dirichlet" and args.concepts is None and house.category_names:
        overrides["num_concepts"] = len(house.category_names)
    settings = preset(args.preset, **overrides)
    options = None  # a method other than Gibbs runs with its defaults and --method-option
    if args.method_option:
        default = INFERENCE_METHODS[args.method].default_options()
        options = with_options(default, args.method_option)
    if args.method == "gibbs":
        options = GibbsOptions(
            backend=args.backend, anneal_sweeps=args.anneal_sweeps,
            unobserved_refresh=1.0 if args.unobserved_refresh is None else args.unobserved_refresh,
            cluster_moves=0.0 if args.cluster_moves is None else args.cluster_moves,
        )  # fmt: skip
        options = with_options(options, args.method_option or [])
        try:
            get_backend(options.backend)
        except ImportError as error:  # --backend numba without numba: before anything is written
            raise ValueError(str(error)) from None
    return settings, options


def _fit_staged(
    args: argparse.Namespace,
    house: House,
    settings: SpCoSettings,
    options: object | None,
    staged: StagedOutput,
    keeper: FitCheckpoint | None,
    sampled: list[bool],
) -> int:
    """Fit, write every output into ``staged.path``, then move it to OUT."""
    from spcopyro.fit import best_chain, fit_house_chains
    from spcopyro.outputs import checkpoint_path
    from spcopyro.plotting import plot_house, plot_semantic_map, plot_trace, plot_uncertainty
    from spcopyro.uncertainty import cell_entropy, free_cells_image

    config = settings.model
    source = "embedded synthetic house, seed 0" if args.data is None else None
    # The config's warnings (gamma, extreme concentrations) are logged by prepare_model_data,
    # which the fit runs; main's logging handler prints them once, as "warning: ...".
    print(_summary(house))
    print(f"model            {config}")
    print(f"data             {settings.data}")
    default = INFERENCE_METHODS[args.method].default_options()
    print(f"inference        {args.method}: {options if options is not None else default}")
    print(f"threads          {describe_threads(args.threads, house.grid.num_free)}")
    if isinstance(options, GibbsOptions):
        print(f"backend used     {get_backend(options.backend).name}")
    if args.resume is not None:
        print(f"resuming         the chains saved in {args.resume}")
    init = args.init
    if args.init_from is not None:
        from spcopyro.results import SpCoResult

        init = SpCoResult.load(args.init_from)
        print(f"starting from     the {init.method} fit in {args.init_from}")
    diagnostics = None
    start = _clock()
    if args.sweeps == "auto":
        from spcopyro.fit import fit_house_converged

        chains = 4 if args.chains is None else args.chains
        result, diagnostics = fit_house_converged(
            house, settings, options=options, chains=chains, max_sweeps=args.max_sweeps,
            seed=args.seed, init=init, source=source, threads=args.threads,
        )  # fmt: skip
        chain_results = None
    else:
        chains = 1 if args.chains is None else args.chains
        chain_results = fit_house_chains(
            house, settings, method=args.method, options=options, sweeps=args.sweeps,
            seeds=[args.seed + k for k in range(chains)], init=init, source=source,
            checkpoint=keeper, resume=args.resume, threads=args.threads,
            marginal_samples=args.marginal_samples,
        )  # fmt: skip
        kept = best_chain(chain_results)
        result = chain_results[kept]
    wall = _clock() - start
    sampled.append(True)
    command = shlex.join(["spcopyro", *_command(args)])
    result = dataclasses.replace(result, provenance={**result.provenance, "command": command})
    out = result.save(staged.path)
    if chain_results is not None and chains > 1:
        best_values = [r.best_objective for r in chain_results]
        report = {"seeds": [args.seed + k for k in range(chains)], "best_chain": kept,
                  "best_log_joint": best_values}  # fmt: skip
        (out / "chains.json").write_text(json.dumps(report, indent=1) + "\n")
        print(f"best of {chains} chains: kept chain {kept} (seed {args.seed + kept}), best log "
              f"joints {', '.join(f'{v:.1f}' for v in best_values)}")  # fmt: skip
    sweeps_run = len(result.trace.objective)
    if diagnostics is not None:
        (out / "convergence.json").write_text(json.dumps(diagnostics.to_json(), indent=1) + "\n")
        last = diagnostics.checks[-1]
        state = "converged" if diagnostics.converged else "NOT converged (hit --max-sweeps)"
        print(f"--sweeps auto: {chains} chains {state} after {sweeps_run} sweeps each "
              f"(split R-hat: log joint {last.rhat_log_joint:.3f}, concepts "
              f"{last.rhat_num_concepts:.3f}); kept chain {diagnostics.best_chain} "
              f"(seed {diagnostics.seeds[diagnostics.best_chain]}), highest log joint")  # fmt: skip
    plot_semantic_map(result, out / "semantic_map.png")
    plot_trace(result, out / "trace.png")
    plot_house(house, out / "house.png")
    entropy = cell_entropy(result)
    if entropy is not None:
        np.save(out / "uncertainty.npy", free_cells_image(result, entropy))
        plot_uncertainty(result, out / "uncertainty.png")
    unit = "sweep" if result.trace.objective_name == "log joint" else "iteration"
    runs = f"{chains} chains x " if chains > 1 else ""
    runs += f"{sweeps_run} {unit}s"
    print(f"fitted {runs} in {wall:.1f} s wall clock "
          f"({1e3 * result.trace.seconds[-1] / sweeps_run:.2f} ms per {unit}); "
          f"{len(result.concepts_in_use())} concepts in use")  # fmt: skip
    if house.truth is not None:
        from spcopyro.metrics import adjusted_rand_index

        ari = adjusted_rand_index(result.label_image(), house.truth)
        np.save(out / "truth.npy", house.truth)
        (out / "scores.json").write_text(json.dumps({"ari": ari}) + "\n")
        print(f"adjusted Rand index against the ground truth: {ari:.3f}")
    further = [t.name for t in result.emissions if t.name not in ("images", "words")]
    for concept in result.concepts()[:10]:
        words = ", ".join(f"{w} ({p:.2f})" for w, p in concept["top_words"][:3])
        for name in further:
            top = concept[f"top_{name}"][:2]
            words += f"; {name}: " + ", ".join(f"{item} ({p:.2f})" for item, p in top)
        print(f"  concept {concept['concept']:>3}: {concept['cells']:>6} cells  {words}")
    vocabulary_size = len(result.vocabulary)
    used = result.concepts_in_use()
    if vocabulary_size and result.w[used].max() < 2.0 / vocabulary_size:
        print(
            f"note: every concept's word distribution is close to uniform: beta = "
            f"{config.beta:g} outweighs the {house.observations.num_utterances} utterances; "
            "for sharper words try --beta 0.1 (or --preset original-code --gamma 3)",
            file=sys.stderr,
        )
    out = staged.commit()
    checkpoint = checkpoint_path(out)
    if checkpoint.is_file():  # the one resumed from, or an old one --overwrite replaces
        checkpoint.unlink(missing_ok=True)
        print(f"removed {checkpoint}: the fit it held is complete or replaced")
    print(f"wrote {out}/: labels.npy semantic_map.png concepts.json trace.csv trace.png ...")
    return 0


def _integer_at_least(minimum: int) -> Callable[[str], int]:
    def parse(value: str) -> int:
        try:
            number = int(value)
        except ValueError:
            number = minimum - 1
        if number < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {value!r}")
        return number

    return parse


_positive_int = _integer_at_least(1)
_non_negative_int = _integer_at_least(0)


def _sweeps(value: str) -> int | str:
    if value == "auto":
        return value
    try:
        sweeps = int(value)
    except ValueError:
        sweeps = 0
    if sweeps < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer or 'auto', got {value!r}")
    return sweeps


def _threads(value: str) -> int | str:
    """``--threads``: ``auto`` or an integer >= 0 (0: torch's own setting)."""
    if value == AUTO:
        return value
    try:
        return _non_negative_int(value)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be 'auto' or an integer >= 0 (0: torch's own setting), got {value!r}"
        ) from None


def _concentrations(values: list[str] | None) -> dict[str, float] | None:
    """``NAME=VALUE`` options as a mapping (None when there are none)."""
    if not values:
        return None
    pairs = {}
    for value in values:
        name, sep, number = value.partition("=")
        try:
            pairs[name.strip()] = float(number)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ValueError(f"--concentration must be NAME=NUMBER, got {value!r}")
    return pairs


def _feature_scaling(value: str | None) -> str | float | None:
    if value is None or value in ("probability", "floor100"):
        return value
    try:
        return float(value)
    except ValueError:
        raise SystemExit(
            f"--feature-scaling must be probability, floor100 or a number, got {value!r}"
        ) from None


def _where(args: argparse.Namespace) -> int:
    from spcopyro.results import SpCoResult, UnknownWordError

    result = SpCoResult.load(args.result)
    try:
        answer = result.where(args.word, prior=args.prior)
    except UnknownWordError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    grid = result.grid
    cells = np.argwhere(answer.region)  # [n, 2] (row, col)
    xy = grid.cell_to_world(cells)
    words = ", ".join(f"{w} ({p:.2f})" for w, p in result.top_words(answer.concept, 3))
    print(f"'{answer.word}' is concept {answer.concept} (p = {answer.probability:.3f}, "
          f"{answer.prior} prior; its words: {words})")  # fmt: skip
    if answer.runner_up is not None:
        print(f"runner-up: concept {answer.runner_up} (p = {answer.runner_up_probability:.3f}); "
              f"Bayes factor of the word for concept {answer.concept}: "
              f"{answer.evidence:.2f}")  # fmt: skip
    if len(cells):
        (x0, y0), (x1, y1) = xy.min(0), xy.max(0)
        cx, cy = xy.mean(0)
        print(f"region: {len(cells)} cells ({len(cells) * grid.resolution**2:.2f} m^2), "
              f"centre x={cx:.2f} y={cy:.2f}, spanning x {x0:.2f}..{x1:.2f}, "
              f"y {y0:.2f}..{y1:.2f} m")  # fmt: skip
    for warning in answer.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    from spcopyro.uncertainty import where_probability

    probability = where_probability(result, args.word, args.prior)  # [N]
    source = "marginals" if result.marginals is not None else "point estimate"
    print(f"cells whose probability of being the place exceeds 0.5: "
          f"{int((probability > 0.5).sum())} ({source})")  # fmt: skip
    if args.out:
        from spcopyro.plotting import plot_where, plot_where_probability

        print(f"wrote {plot_where(result, answer, args.out)}")
        out = Path(args.out)
        probability_png = out.with_name(f"{out.stem}_probability.png")
        print(f"wrote {plot_where_probability(result, args.word, probability_png, args.prior)}")
    return 0


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


_PRESET_DEFAULT = "(default: the --preset's value)"


class _HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default, unless the help already says it: ``(default:
    off)`` for a flag, ``(default: VALUE)`` otherwise (an option whose default is None says in
    its own help what happens without it)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if (
            not action.option_strings
            or action.default in (None, argparse.SUPPRESS)
            or "default" in text.lower()
        ):
            return text
        if action.nargs == 0:  # a flag
            return f"{text} (default: {'on' if action.default else 'off'})"
        return f"{text} (default: %(default)s)"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="spcopyro",
        description="SpCoMapping: semantic maps from an occupancy grid, images and words.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details (INFO)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("simulate", help="write a synthetic house in the public dataset's layout")
    p.add_argument("--out", required=True, help="root folder (gets map/ and NAME/)")
    p.add_argument("--seed", type=int, default=0, help="seed of the house's random draws")
    p.add_argument("--name", default="synthetic", help="the house's folder name (NAME)")
    p.add_argument("--size", type=int, nargs=2, metavar=("H", "W"),
                   help="map size in cells; the number of rooms grows with the area "
                        "(default: 60 x 80 cells, 5 rooms)")  # fmt: skip
    p.add_argument("--sentences", type=float, default=0.0,
                   help="share of utterances given as sentences (tf-idf setting)")  # fmt: skip
    p.add_argument("--overwrite", action="store_true",
                   help="replace a house of the same name under --out")  # fmt: skip
    p.set_defaults(func=_simulate)

    p = sub.add_parser("show", help="draw a house and its observations; print a summary")
    p.add_argument("data", nargs="?", help="house folder (default: the synthetic house)")
    p.add_argument("--out", required=True, help="PNG file to write")
    p.set_defaults(func=_show)

    p = sub.add_parser("fit", help="fit SpCoMapping (Gibbs sampling) and write the semantic map")
    p.add_argument("data", nargs="?", help="house folder (default: the synthetic house)")
    p.add_argument("--out", required=True,
                   help="output folder (written whole at the end; new or empty)")  # fmt: skip
    p.add_argument("--overwrite", action="store_true",
                   help="replace the --out folder of an earlier fit (all its files)")  # fmt: skip
    p.add_argument("--resume", metavar="CHECKPOINT",
                   help="continue the interrupted fit saved in CHECKPOINT (OUT.checkpoint.npz; "
                        "Ctrl-C writes it), with the same data and settings (default: a new "
                        "fit)")  # fmt: skip
    p.add_argument("--sweeps", type=_sweeps, default=5000,
                   help="Gibbs iterations (paper: 5000), or 'auto': run --chains chains until "
                        "split R-hat of the log joint and of the number of concepts < 1.05 "
                        "(at most --max-sweeps)")  # fmt: skip
    p.add_argument("--chains", type=_positive_int,
                   help="run this many chains (seeds --seed, --seed + 1, ...) and keep the one of "
                        "highest log joint (default 1; 4 with --sweeps auto)")  # fmt: skip
    p.add_argument("--anneal-sweeps", type=_non_negative_int, default=0,
                   help="ramp gamma up from gamma/N to gamma over the first N sweeps (burn-in; "
                        "default 0)")  # fmt: skip
    p.add_argument("--max-sweeps", type=int, default=5000,
                   help="cap per chain for --sweeps auto (default 5000)")  # fmt: skip
    p.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                   help="the model's hyperparameters and data preparation; the options below "
                        "override its values")  # fmt: skip
    p.add_argument("--prior", choices=("dp", "dirichlet"),
                   help="prior of the concept weights pi: weak-limit DP or Dirichlet "
                        f"{_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--concepts", type=int,
                   help=f"L, the number (upper bound) of concepts {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--gamma", type=float, help=f"Potts coupling {_PRESET_DEFAULT}")
    p.add_argument("--alpha", type=float,
                   help=f"concentration of the concept weights pi {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--beta", type=float, help=f"word prior concentration {_PRESET_DEFAULT}")
    p.add_argument("--chi", type=float,
                   help=f"image-feature prior concentration {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--concentration", action="append", metavar="NAME=VALUE",
                   help="Dirichlet concentration of a further modality (a modality_NAME.csv of "
                        "the house); repeat for several (default: none)")  # fmt: skip
    p.add_argument("--connectivity", type=int, choices=(4, 8),
                   help=f"MRF neighbourhood of a cell {_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument("--tfidf", action="store_true", help="weight words by tf-idf (eq. 20)")
    p.add_argument(
        "--unobserved-refresh",
        type=float,
        help="share of sweeps that redraw theta/w of concepts without observations (default 1)",
    )
    p.add_argument(
        "--cluster-moves",
        type=float,
        help="share of sweeps that start with a Swendsen-Wang move: whole regions change concept "
        "at once (default 0)",
    )
    p.add_argument("--feature-scaling",
                   help="image features as probability, floor100 or a number s (s * f) "
                        f"{_PRESET_DEFAULT}")  # fmt: skip
    p.add_argument(
        "--init",
        choices=("random", "gaussian", "spcoa"),
        default="random",
        help="starting labels: random, k-means Gaussians, or SpCoA pre-learning",
    )
    p.add_argument("--init-from", metavar="OUT",
                   help="start from the labels of an earlier fit's output folder on the same map "
                        "(a warm start from any method to any method, e.g. a cavi fit starting "
                        "gibbs); replaces --init (default: none)")  # fmt: skip
    p.add_argument("--marginal-samples", type=_non_negative_int, default=50,
                   help="Gibbs: label maps kept over the second half of the sweeps for the "
                        "per-cell probabilities of uncertainty.png (0: none)")  # fmt: skip
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the sampler (chain k of --chains gets seed + k)")  # fmt: skip
    p.add_argument("--method", choices=sorted(INFERENCE_METHODS), default=DEFAULT_METHOD,
                   help="inference method (default: gibbs, Algorithm 1)")  # fmt: skip
    p.add_argument("--method-option", action="append", metavar="NAME=VALUE",
                   help="set a field of the method's options, e.g. anneal_iterations=30 (cavi), "
                        "damping=0.5 (lbp), lr=0.05 (svi), block_size=32 (stochastic-vi), "
                        "variational.anneal_iterations=30 (vi-gibbs); repeat for several "
                        "(default: the method's defaults, printed by the fit)")  # fmt: skip
    p.add_argument("--backend", choices=BACKENDS, default="auto",
                   help="Gibbs sweep implementation: torch (reference), numba (compiled) or "
                        "auto (numba where installed, else torch); the two draw different "
                        "random streams from one seed")  # fmt: skip
    p.add_argument("--snap-distance", type=float, default=DEFAULT_SNAP_DISTANCE,
                   help="metres an observation may be moved onto free space")  # fmt: skip
    p.add_argument("--threads", type=_threads, default=AUTO,
                   help="torch intra-op threads during the fit: auto (default: one thread unless "
                        f"the map has >= {MIN_CELLS_FOR_MORE_THREADS} free cells), 0 (torch's own "
                        "setting) or N; labels do not depend on it")  # fmt: skip
    p.set_defaults(func=_fit)

    p = sub.add_parser("where", help='answer "where is WORD?" from a fitted result')
    p.add_argument("result", help="output folder of `spcopyro fit`")
    p.add_argument("word", help="the word to look up")
    p.add_argument("--out", help="also draw the answer over the semantic map into this PNG, "
                   "and the per-cell probability of the word's place into "
                   "<name>_probability.png (default: no PNG)")  # fmt: skip
    p.add_argument(
        "--prior",
        choices=("area", "pi"),
        default="area",
        help="p(C) in eq. (19): a concept's share of the map (default) or pi (the paper's eq. 19, "
        "which weighs a one-cell speck like a room)",
    )
    p.set_defaults(func=_where)

    p = sub.add_parser("experiment", help="the paper's comparison (Table 4, Figs. 5-7)")
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

    from spcopyro.features.cli import add_parser as add_features_parsers

    add_features_parsers(sub)  # features, features-head
    for command in (parser, *sub.choices.values()):
        command.formatter_class = _HelpFormatter
    return parser


class _LowerCaseLevel(logging.Formatter):
    """``warning: message`` (as the command's own messages), not ``WARNING: message``."""

    def format(self, record: logging.LogRecord) -> str:
        return f"{record.levelname.lower()}: {record.getMessage()}"


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a message comes (not when it was made)."""

    @property
    def stream(self):  # noqa: D102
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        del value


def _configure_logging(level: int) -> None:
    """The library's messages (logger ``spcopyro``) on stderr, each once."""
    logger.setLevel(level)
    if not any(isinstance(h, _StderrHandler) for h in logger.handlers):
        handler = _StderrHandler()
        handler.setFormatter(_LowerCaseLevel())
        logger.addHandler(handler)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if argv is not None:
        args.argv = list(argv)
    _configure_logging(logging.INFO if args.verbose else logging.WARNING)
    try:
        return args.func(args)
    except (OSError, ValueError) as error:  # bad input: one clear line, no traceback
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: one line, no traceback (fit says more itself)
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
