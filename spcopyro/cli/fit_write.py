"""``spcopyro fit``'s outputs: every file of a fit written into the staging folder, what the fit
found printed, then the folder moved to OUT (:func:`write_outputs`).

:mod:`spcopyro.cli.fit` fits and calls it once the fit is done; what imports torch or matplotlib
(the hyperparameters' description, the figures) is imported inside the function.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import sys
from typing import TYPE_CHECKING

import numpy as np

from spcopyro._util.messages import plural
from spcopyro._util.outputs import ROBOT_MAP_FILE
from spcopyro._util.progress import setup_bar
from spcopyro._util.timings import timed
from spcopyro.cli.common import pace
from spcopyro.cli.concept_listing import next_step, print_concepts
from spcopyro.cli.fit_figures import figures_drawn
from spcopyro.cli.fit_resume import again_command
from spcopyro.cli.fit_summary import estimate_line, objective_line
from spcopyro.cli.fit_warnings import write_config
from spcopyro.config import DEFAULT_PRESET
from spcopyro.maps import save_map
from spcopyro.results.specks import in_use_text

if TYPE_CHECKING:
    from spcopyro.cli.fit_figures import FigurePrefetch
    from spcopyro.cli.fit_job import FitJob
    from spcopyro.gibbs.convergence import ConvergenceDiagnostics
    from spcopyro.results.result import SpCoResult

__all__ = ["Fitted", "write_outputs"]


@dataclasses.dataclass
class Fitted:
    """What the fit of a :class:`~spcopyro.cli.fit_job.FitJob` gave, before anything is written:
    what :func:`write_outputs` writes."""

    result: SpCoResult
    """The chain kept (the best of ``chain_results``)."""
    chain_results: list[SpCoResult] | None
    """Every chain's result (None for ``--sweeps auto``, which reports ``diagnostics``)."""
    chains: int
    kept: int
    diagnostics: ConvergenceDiagnostics | None
    wall: float
    """Seconds of wall clock the fit took (all chains)."""


def write_outputs(job: FitJob, fitted: Fitted, prefetch: FigurePrefetch | None) -> int:
    """Every output of ``fitted`` into ``job.staged.path``, what the fit found printed, then the
    staging folder moved to OUT (``_fit_staged`` of :mod:`spcopyro.cli.fit`)."""
    from spcopyro._util.outputs import checkpoint_path
    from spcopyro.fit.map_warnings import log_map_warnings
    from spcopyro.gibbs.hyperparameters import describe_hyperparameters
    from spcopyro.results.concept_words import near_uniform
    from spcopyro.results.uncertainty import cell_entropy, free_cells_image

    args, house, staged, config = job.args, job.house, job.staged, job.settings.model
    result, chain_results, chains = fitted.result, fitted.chain_results, fitted.chains
    kept, diagnostics, wall = fitted.kept, fitted.diagnostics, fitted.wall
    phases = args.phases
    phases.mark("fit")
    command = again_command(args)  # runs again without the checkpoint
    resumed = {} if args.resume is None else {"resumed_from": str(args.resume)}
    provenance = {**result.provenance, "command": command, **resumed}
    result = dataclasses.replace(result, provenance=provenance)
    # On a large map each takes seconds (2.9 million cells: result.npz compresses the [N, L]
    # marginals 5 s, uncertainty 2 s, the figures 6 s): a bar as the setup steps have
    bar = setup_bar(result.grid.num_free, 3, "writing the outputs", "step")
    # the figures drawn while the rest is written: in a child forked for them where it may be
    # (figures_drawn), which starts with the semantic map while the result is saved here
    figures: contextlib.AbstractContextManager[None] = contextlib.nullcontext()
    with timed("uncertainty"):  # before the fork: the child's uncertainty.png inherits it
        entropy = cell_entropy(result)
    if prefetch is not None:  # matplotlib is imported only for the figures
        # trace.png draws the kept chain's trace only (--sweeps auto's: the best of its chains)
        shown = kept if chain_results is not None or diagnostics is None else diagnostics.best_chain
        # said: the child's figures' warnings too, in the figures' order (config.json's)
        figures = figures_drawn(result, house, staged.path, entropy is not None,
                                prefetch=prefetch, kept=(shown, chains), said=job.said)  # fmt: skip
    with figures:
        out = result.save(staged.path, with_config=False)  # config.json last, with the warnings
        robot_map = house.grid.coarsened_from  # a coarse fit's map: navigate plans on it
        if robot_map is not None:
            save_map(robot_map, out / ROBOT_MAP_FILE)
        bar.update()
        phases.mark("save")
        if chain_results is not None and chains > 1:
            best_values = [r.best_objective for r in chain_results]
            objective = result.trace.objective_name  # "log joint", or a variational objective
            sampled = objective == "log joint"  # Gibbs chains, vi-gibbs's too; else q's objective
            # "best_log_joint" of sampled chains; a variational fit's "final_elbo" (its q's)
            values_key = (
                "best_log_joint" if sampled else "final_" + objective.lower().replace(" ", "_")
            )
            report = {"seeds": [args.seed + k for k in range(chains)], "best_chain": kept,
                      values_key: best_values, "objective": objective}  # fmt: skip
            (out / "chains.json").write_text(json.dumps(report, indent=1) + "\n")
            run = ("refined " if job.refined else "") + ("chain" if sampled else "fit")
            value = "best" if sampled else "final"  # a variational fit reports q
            print(f"best of {chains} {run}s: kept {run} {kept} (seed {args.seed + kept}), {value} "
                  f"{objective}s {', '.join(f'{v:.1f}' for v in best_values)}")  # fmt: skip
        sweeps_run = len(result.trace.objective)
        if diagnostics is not None:
            (out / "convergence.json").write_text(
                json.dumps(diagnostics.to_json(), indent=1) + "\n"
            )
            last = diagnostics.checks[-1]
            state = "converged" if diagnostics.converged else "NOT converged (hit --max-sweeps)"
            print(f"--sweeps auto: {chains} chains {state} after {diagnostics.sweeps} sweeps each "
                  f"(split R-hat: log joint {last.rhat_log_joint:.3f}, concepts "
                  f"{last.rhat_num_concepts:.3f}); kept chain {diagnostics.best_chain} "
                  f"(seed {diagnostics.seeds[diagnostics.best_chain]}), highest log joint"
                  f"{', the refinement started from it' if job.refined else ''}")  # fmt: skip
        with timed("uncertainty"):
            if entropy is not None:
                np.save(out / "uncertainty.npy", free_cells_image(result, entropy))
            if result.agreement is not None:
                np.save(out / "agreement.npy", free_cells_image(result, result.agreement))
        bar.update()
        phases.mark("save")
    bar.update()
    bar.close()
    phases.mark("figures")
    if result.agreement is not None:
        print(estimate_line(result, args.point_estimate, figures=not args.no_figures))
    unit = "sweep" if result.trace.objective_name == "log joint" else "iteration"
    several = f"{chains} chains x " if chains > 1 else ""
    seconds = result.trace.seconds  # [sweeps] cumulative
    # vi-gibbs's sweeps' clock starts after its CAVI start (inference.vi_seconds), said apart
    start = float(result.inference.get("vi_seconds", 0.0))  # type: ignore[arg-type]
    rate = (pace(seconds[0] - start, seconds[-1] - start, sweeps_run, unit) if len(seconds)
            else "no sweeps")  # fmt: skip
    # a chain's own clock: chains run side by side (forked workers) share the CPUs, so that pace
    # is slower than one chain's alone while the wall clock is not; say whose pace it is
    own = "the kept chain's own pace: " if several and len(seconds) else ""
    rate = own + rate
    clock = f"{wall:.1f} s wall clock"
    if args.resume is not None:  # the trace's seconds (the paces) go on from the checkpoint's
        clock += f" this run (resumed: the paces include the {unit}s run before the interruption)"
    runs = f"{several}{plural(sweeps_run, unit)} in {clock} ({rate})"
    if chains > 1 and unit != "sweep":  # variational fits: each stops when it converges
        runs = f"{chains} fits, the kept one {plural(sweeps_run, unit)}, in {clock} ({rate})"
    if job.refined:  # the coarse stage's sweeps, then the refinement's, each at its own pace
        coarse = result.inference["refine"]["coarse"]
        total = coarse.get("seconds", math.nan)
        coarse_rate = own + pace(coarse.get("first_seconds", 0.0), total, coarse["sweeps"])
        runs = (f"{several}{coarse['sweeps']} sweeps on {coarse['cell_size']:g} m cells "
                f"({coarse_rate}), then {several}{sweeps_run} on the map's "
                f"{result.grid.resolution:g} m cells ({rate}) in {clock}")  # fmt: skip
    print(f"fitted {runs}; {in_use_text(result)}")
    if (line := objective_line(result)) is not None:  # VI: why it stopped, its final objective
        print(line)  # (a sampler: its highest log joint, and when)
    if result.inference.get("vi_stopped"):  # vi-gibbs: the CAVI whose labels start the sweeps
        print(f"CAVI start       {result.inference['vi_stopped']} ({start:.2f} s, not in the "
              "sweeps' pace above); the sweeps began at its labels")  # fmt: skip
    if result.inference.get("hyperparameters"):
        line = describe_hyperparameters(result.inference["hyperparameters"])  # type: ignore[arg-type]
        stage = ", of the refinement on the map's cells" if job.refined else ""
        print(f"hyperparameters  {line} (posterior mean +- sd over the second half{stage})")
    if house.truth is not None:
        from spcopyro.metrics import adjusted_rand_index

        ari = adjusted_rand_index(result.label_image(), house.truth)
        np.save(out / "truth.npy", house.truth)
        scores, where = {"ari": ari}, ""
        on_map = job.map_house
        if on_map is not None and on_map.truth is not None and on_map.grid is not house.grid:
            # a fit left on a coarser model grid: its ARI is of the truth by block there, where
            # a refined fit's is on the map's cells; give both
            from spcopyro.maps.coarse import labels_on_grid

            fine = labels_on_grid(result.label_image(), on_map.grid, job.settings.data.cell_size)
            scores["ari_map_cells"] = adjusted_rand_index(fine, on_map.truth)
            where = (f" {ari:.3f} on the model's {house.grid.num_free} free cells of "
                     f"{house.grid.resolution:g} m (the truth by block), "
                     f"{scores['ari_map_cells']:.3f} on the map's {on_map.grid.num_free} of "
                     f"{on_map.grid.resolution:g} m, as a refined fit is scored")  # fmt: skip
        (out / "scores.json").write_text(json.dumps(scores) + "\n")
        print(f"adjusted Rand index against the ground truth:{where or f' {ari:.3f}'}")
    concepts = result.concepts()  # listed, then the next step's word
    print_concepts(result, concepts=concepts)
    log_map_warnings(result, house, False if job.settings.preset == DEFAULT_PRESET else None)
    vocabulary_size = len(result.vocabulary)
    used = result.concepts_in_use()
    if vocabulary_size == 1:  # "close to uniform" always, and for no reason below
        print(f"note: the vocabulary holds one word ({result.vocabulary[0]!r}): the words cannot "
              "tell places apart, so the map follows the images and the coupling alone",
              file=sys.stderr)  # fmt: skip
    elif near_uniform(result.w[used]):
        if config.beta > 0.1:
            why = (f"beta = {config.beta:g} outweighs the {house.observations.num_utterances} "
                   "utterances (each list still follows the counts heard there); for sharper "
                   "words try --beta 0.1 (or --preset original-code --gamma 3)")  # fmt: skip
        else:
            why = (f"with beta = {config.beta:g} this comes from the words themselves: every "
                   "place heard much the same words (e.g. only fillers or stopwords); "
                   "--word-weighting tfidf weighs down words said everywhere")  # fmt: skip
        print(f"note: every concept's word distribution is close to uniform: {why}",
              file=sys.stderr)  # fmt: skip
    phases.mark("report")
    # every warning the fit gave, printed above; an interrupted fit's staging folder is discarded
    write_config(out / "config.json", result.settings_json(), job.said)
    out = staged.commit()
    checkpoint = checkpoint_path(out)
    if checkpoint.is_file():  # the one resumed from, or an old one --overwrite replaces
        checkpoint.unlink(missing_ok=True)
        print(f"removed {checkpoint}: the fit it held is complete or replaced")
    if args.no_figures:
        print(f"wrote {out}/: labels.npy concepts.json trace.csv ... (figures skipped: "
              "--no-figures)")  # fmt: skip
    else:
        print(f"wrote {out}/: labels.npy semantic_map.png concepts.json trace.csv trace.png ...")
    if (step := next_step(result, concepts, out, figures=not args.no_figures)) is not None:
        print(step)
    phases.mark("commit")
    refined = result.inference["refine"]["coarse"] if job.refined else {}  # and the coarse's
    phases.write(sweeps=sweeps_run + refined.get("sweeps", 0),
                 sweep_seconds=float(result.trace.seconds[-1]),
                 first_sweep_seconds=float(result.trace.seconds[0]), chains=chains,
                 figures=not args.no_figures)  # fmt: skip
    return 0
