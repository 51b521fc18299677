"""The ``spcopyro fit`` command: check the arguments, fit, write OUT whole, keep a checkpoint.

:func:`run_fit` runs it on the parsed arguments; its options are in :mod:`spcopyro.cli.fit_parser`,
the writing of OUT once fitted in :mod:`spcopyro.cli.fit_write`.
What imports torch, pyro or numba (the sampler, the inference methods) is imported inside the
functions that use it.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from spcopyro._util.interrupts import interrupts_raised, sigterm_as_interrupt
from spcopyro._util.messages import plural
from spcopyro._util.progress import progress_stage
from spcopyro._util.threads import describe_threads
from spcopyro._util.timings import Phases
from spcopyro.cli.common import (
    FIT_SWEEPS,
    UPDATE_SWEEPS,
    _load,
    _summary,
    load_start,
)
from spcopyro.cli.fit_figures import FigurePrefetch
from spcopyro.cli.fit_finished import keep_finished, restore_finished, resumes_finished_fit
from spcopyro.cli.fit_job import FitJob
from spcopyro.cli.fit_options import (
    SAMPLERS,
    backend_used,
    check_sweeps,
    given_start,
    warm_start_kept,
)
from spcopyro.cli.fit_refine import check_refinable, refine, report_unrefined
from spcopyro.cli.fit_resume import (
    check_resume_file,
    error_note,
    interrupted_before_fit,
    interrupted_message,
    keeps_checkpoint,
    keeps_finished_fit,
    no_checkpoint_flags,
    resumable_methods,
)
from spcopyro.cli.fit_settings import (
    apply_preset_inference,
    check_update_args,
    fit_settings,
    word_weighting_note,
)
from spcopyro.cli.fit_summary import data_line, inference_line, model_line
from spcopyro.cli.fit_update import (
    check_update,
    relative_records,
    report_update,
    update_settings,
)
from spcopyro.cli.fit_warnings import recorded_warnings
from spcopyro.cli.fit_write import Fitted, write_outputs
from spcopyro.config import preset_inference
from spcopyro.data.footprint import release_shared_footprints, shared_footprints
from spcopyro.data.model_grid import model_house
from spcopyro.gibbs.chains import when_chains_start
from spcopyro.maps.free_space import check_free_cells

if TYPE_CHECKING:
    from spcopyro.results.result import SpCoResult

__all__ = ["run_fit"]

_clock = time.perf_counter  # wall clock of a whole fit (all chains)


def run_fit(args: argparse.Namespace) -> int:
    """Check the arguments and OUT, then fit into a staging folder moved to OUT at the end
    (:mod:`spcopyro._util.outputs`); Ctrl-C or SIGTERM keeps a checkpoint beside OUT and exits with
    130. The warnings it gives are printed and kept in OUT's ``config.json``
    (:mod:`spcopyro.cli.fit_warnings`)."""
    with sigterm_as_interrupt(), recorded_warnings() as said:
        return _fit_interruptible(args, said)


def _fit_interruptible(args: argparse.Namespace, said: list[str]) -> int:
    from spcopyro._util.outputs import checkpoint_path

    stage = ["importing the inference methods"]  # what a Ctrl-C before the fit interrupted
    try:
        job = _set_up(args, said, stage)
    except KeyboardInterrupt:  # nothing written yet, a resumed checkpoint untouched: say so
        print(interrupted_before_fit(args, stage[-1]), file=sys.stderr)
        return 130
    staged, keeper = job.staged, job.keeper
    try:
        # interrupts_raised: one a compiled call reported as a SystemError; shared_footprints:
        # the summary's footprint counts are the model data's, spread once
        with interrupts_raised(), shared_footprints():
            return _fit_staged(job)
    except KeyboardInterrupt as stop:
        from spcopyro.fit.gibbs_chains import FitInterrupted  # imported by _set_up

        if staged.committed:  # the fit a checkpoint of OUT held is complete or replaced
            checkpoint_path(staged.out).unlink(missing_ok=True)  # Ctrl-C before the writing did
            print(f"interrupted after {staged.out} was written", file=sys.stderr)
            return 130
        if isinstance(stop, FitInterrupted):  # while sampling
            where, kept = f" ({stop.where})", stop.checkpoint
        else:  # reading the data, after the sweeps (their point estimate), or writing
            kept = _keep(job)
            where = " after the sweeps" if kept and keeper and keeper.finished() else ""
            again = " (only the first stage is kept: resuming refines again)" if job.refined else ""
            where = f" while writing the outputs{again}" if job.sampled else where
        unchanged = kept is None and args.resume is not None and Path(args.resume).is_file()
        if unchanged:  # this run saved nothing: it holds what the run resumed from, no more
            kept = Path(args.resume)
        why = getattr(stop, "why", None)
        print(interrupted_message(args, where, kept, staged.out, why, finished=job.sampled,
                                  unchanged=unchanged), file=sys.stderr)  # fmt: skip
        return 130
    except Exception:
        writing = job.sampled or bool(keeper and keeper.finished())  # or after the sweeps
        writing = writing and not (staged.committed or staged.kept)
        kept = _keep(job) if writing else None
        if writing and (note := error_note(args, kept, staged.out, job.sampled)) is not None:
            print(note, file=sys.stderr)  # what is kept, and the command; or that it is lost
        raise
    finally:
        staged.discard()  # nothing once committed; else the run's partial outputs


def _keep(job: FitJob) -> Path | None:
    """What a stopped fit keeps: its chains' checkpoint (Gibbs), else its finished result (not
    Gibbs, :func:`keep_finished`); the file, or None (no chain had started, nothing finished)."""
    kept = job.keeper.save() if job.keeper else None
    return keep_finished(job) if kept is None else kept


def _set_up(args: argparse.Namespace, said: list[str], stage: list[str]) -> FitJob:
    """Check the arguments, load the data, resolve the settings and stage OUT: the job to fit.
    ``stage[-1]`` says what it is doing, for the line a Ctrl-C here prints; a staging folder it
    made is removed when it is stopped."""
    from spcopyro._util.outputs import checkpoint_path, stage_output
    from spcopyro.fit.gibbs_chains import FitCheckpoint
    from spcopyro.fit.registry import get_method

    get_method(args.method)  # ValueError naming the registered methods
    stage.append("checking the arguments")
    args.phases = Phases()  # seconds per phase, written to $SPCOPYRO_TIMINGS if set
    if args.sweeps is None:  # the parser's default: fewer sweeps continue a fit than start one
        args.sweeps = UPDATE_SWEEPS if args.update is not None else FIT_SWEEPS
    if args.update is not None:  # before the preset fills --init: an explicit one is refused
        check_update_args(args)
    apply_preset_inference(args)
    check_sweeps(args)
    checkpointed = keeps_checkpoint(args)
    if args.resume is not None and not (checkpointed or resumes_finished_fit(args)):
        raise ValueError(
            "--resume continues Gibbs chains run for a number of --sweeps, or one fit "
            f"(--chains 1) of {', '.join(resumable_methods())}, or a finished fit kept while "
            f"its outputs were written; {no_checkpoint_flags(args)} keeps no checkpoint"
        )
    if args.point_estimate != "map-visited" and (
        args.sweeps == "auto" or args.method not in SAMPLERS or not args.marginal_samples
    ):
        raise ValueError(
            f"--point-estimate {args.point_estimate} is made over the label maps of "
            "--marginal-samples (> 0) of a gibbs or vi-gibbs fit with a number of --sweeps"
        )
    sampler = args.method in SAMPLERS  # another refuses it (cli.fit_options)
    if sampler and args.sweeps != "auto" and args.anneal_sweeps > args.sweeps:
        raise ValueError(f"anneal_sweeps ({args.anneal_sweeps}) must not exceed num_sweeps "
                         f"({args.sweeps})")  # fmt: skip
    if args.resume is not None:
        stage.append(f"checking the checkpoint {args.resume}")
        check_resume_file(args.resume)
    stage.append("loading the data")
    loaded = _load(args.data)
    check_free_cells(loaded.grid, f"house {loaded.name!r}")  # before the summary lists them
    args.phases.mark("load")
    stage.append("preparing the settings")
    settings, options = fit_settings(args, loaded)
    if args.update is not None:  # a refined fit goes on on the map's cells, as refined
        settings = update_settings(args, settings, loaded.grid.num_free)
    house = model_house(loaded, settings.data.cell_size)  # the model's grid (cell_size)
    check_refinable(args, settings, house, loaded)  # --refine always: a coarser grid to refine
    stage.append("preparing the output folder")
    staged = stage_output(
        args.out, overwrite=args.overwrite, resume=args.resume,
        inputs=(house.source, house.grid.source, args.update),
    )  # fmt: skip
    try:
        args.phases.mark("settings")
        keeper = FitCheckpoint(checkpoint_path(staged.out)) if checkpointed else None
        return FitJob(args, house, settings, options, staged, keeper, map_house=loaded, said=said)
    except BaseException:
        staged.discard()
        raise


def _fit_staged(job: FitJob) -> int:
    """Print what is fitted, fit, write every output into ``staged.path``, then move it to
    OUT."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    args, house, settings, options = job.args, job.house, job.settings, job.options
    config = settings.model
    saved = None
    if args.update is not None:  # refused before the summary: a refusal prints none of it
        from spcopyro.results.result import SpCoResult

        saved = SpCoResult.load(args.update)
        check_update(args, saved, house, settings)
    # The config's warnings are logged by prepare_model_data (main prints them once); the
    # fit's own counts say what is left out (once), under the run's feature scaling.
    print(_summary(house, warn=False, preparation=settings.data))
    # a house of words only: the model in effect, words only; config.json keeps use_images
    print(model_line(config, settings.preset, images_missing=not house.observations.num_images))
    note = word_weighting_note(args, house, settings.data.word_weighting)
    print(data_line(settings.data, house.grid, note))
    default = INFERENCE_METHODS[args.method].default_options()
    print(inference_line(args.method, options if options is not None else default,
                         given_start(args), _budget(args), args.out))  # fmt: skip
    workers = _side_by_side(args)  # auto: one thread per chain where several run at once
    print(f"threads          {describe_threads(args.threads, house.grid.num_free, workers)}")
    if (used := backend_used(options or default, config)) is not None:
        print(f"backend used     {used}")
    if args.resume is not None:
        saved_fit = "fit" if keeps_finished_fit(args) else "chains"
        print(f"resuming         the {saved_fit} saved in {args.resume}")
    init = args.init
    if saved is not None:
        steps = plural(len(saved.trace.objective), "sweep" if saved.method == "gibbs" else
                       "iteration")  # fmt: skip
        print(f"updating         the {saved.method} fit in {args.update} ({steps}) with all "
              "of this data"
              f"{warm_start_kept(options or default)}")  # fmt: skip
    if args.init_from is not None:
        init = load_start(args.init_from)  # a coarse fit with the map it coarsened
        kept = warm_start_kept(options or default)  # svi smooths it toward uniform
        print(f"starting from    the {init.method} fit in {args.init_from}{kept}")
    args.phases.mark("summary")
    # house.png and the figures' imports, drawn on a thread of their own while the chains run;
    # with several Gibbs chains, started once they run: a thread alive when they would be forked
    # into processes keeps them on threads (spcopyro.gibbs.chain_processes)
    several = args.method == "gibbs" and _chain_count(args) > 1
    prefetch = None
    if not args.no_figures:
        prefetch = FigurePrefetch(house, job.staged.path, start=not several,
                                  concepts=config.num_concepts)  # fmt: skip
    try:
        with contextlib.nullcontext() if prefetch is None else when_chains_start(prefetch.start):
            fitted = _fit(job, init, saved, prefetch)
        results = fitted.chain_results or [fitted.result]
        job.sampled, job.finished = True, (results, fitted.kept, list(job.said))
        return write_outputs(job, fitted, prefetch)
    except BaseException:  # stopped: never wait on the thread without bound (abandon's doc)
        if prefetch is not None:
            prefetch.abandon()
        raise
    finally:
        if prefetch is not None:  # nothing written into the staging folder after this
            prefetch.join()


def _chain_count(args: argparse.Namespace) -> int:
    """How many chains (or fits) ``--chains`` asks for: 4 by default with ``--sweeps auto``,
    else 1."""
    if args.chains is not None:
        return int(args.chains)
    return 4 if args.sweeps == "auto" else 1


def _budget(args: argparse.Namespace) -> str:
    """The inference line's budget: ``5000 sweeps`` (``iterations`` for a method that does
    not sample), ``sweeps until converged``, and the chains (or fits) where there are several."""
    sampler = args.method in SAMPLERS
    if args.sweeps == "auto":
        most = f" (at most {args.max_sweeps})" if args.max_sweeps is not None else ""
        budget = f"sweeps until converged{most}"
    else:
        budget = plural(int(args.sweeps), "sweep" if sampler else "iteration")
    chains = _chain_count(args)
    return budget + (f", {chains} {'chains' if sampler else 'fits'}" if chains > 1 else "")


def _side_by_side(args: argparse.Namespace) -> int:
    """The chains :func:`_fit` advances at once: ``fit_house_chains``' (and
    ``fit_house_converged``'s, ``--sweeps auto``) for ``--chains`` chains of the method, up to
    ``--chain-workers`` (1 under ``--update``, which runs none side by side)."""
    from spcopyro.fit.house import chains_side_by_side
    from spcopyro.fit.registry import get_method

    if args.update is not None:
        return 1
    return chains_side_by_side(get_method(args.method), args.chain_workers, _chain_count(args))


def _fit(
    job: FitJob, init: object, saved: SpCoResult | None, prefetch: FigurePrefetch | None = None
) -> Fitted:
    """The fit itself: ``--sweeps auto``'s chains, ``--update``'s, or ``--chains`` chains from
    ``init`` (:func:`_fit_staged`)."""
    from spcopyro.fit.house import best_chain, fit_house_chains

    args, house, settings, options = job.args, job.house, job.settings, job.options
    source = "embedded synthetic house, seed 0" if args.data is None else None
    diagnostics, refine_sweeps, estimate = None, args.sweeps, None
    start = _clock()
    if (restored := restore_finished(job)) is not None:  # --resume a finished fit's file
        results, kept = restored
        return Fitted(results[kept], results, len(results), kept, None, _clock() - start)
    # a refinement may follow: the bars name the stage (both read "Gibbs sweeps")
    stage = "model grid" if args.refine != "never" and house.grid.coarsened_from else None
    with progress_stage(stage):
        if args.sweeps == "auto":
            from spcopyro.fit.house import fit_house_converged

            chains = _chain_count(args)
            result, diagnostics = fit_house_converged(
                house, settings, options=options, chains=chains, seed=args.seed, init=init,
                max_sweeps=args.max_sweeps or FIT_SWEEPS, source=source, threads=args.threads,
                chain_workers=args.chain_workers,
            )  # fmt: skip
            chain_results, kept = None, 0
            # a refinement runs as many sweeps as the chains needed (their --anneal-sweeps too,
            # though it does not anneal: spcopyro.fit.refine), with the preset's estimate
            refine_sweeps = len(result.trace.objective)
            estimate = preset_inference(args.preset).get("point_estimate", "map-visited")
            estimate = estimate if args.marginal_samples > 0 else "map-visited"
        elif saved is not None:  # checked against the run before the summary: check_update
            from spcopyro.robot.online import fit_update

            chains = _chain_count(args)
            chain_results = fit_update(
                saved, house, settings, method=args.method, options=options,
                sweeps=args.sweeps, seeds=[args.seed + k for k in range(chains)],
                source=source, threads=args.threads, marginal_samples=args.marginal_samples,
                point_estimate=args.point_estimate, where=args.update,
            )  # fmt: skip
            this_data = chain_results[0].provenance.get("source", {})  # to tell unchanged data
            this_sha = this_data.get("data_sha256") if isinstance(this_data, dict) else None
            relative_records(chain_results, job.staged.out)  # update_of.fit: relative to OUT
            report_update(chain_results[0].inference["update_of"], args.update, this_sha)
            kept = best_chain(chain_results)
            result = chain_results[kept]
        else:
            chains = _chain_count(args)
            chain_results = fit_house_chains(
                house, settings, method=args.method, options=options, sweeps=args.sweeps,
                seeds=[args.seed + k for k in range(chains)], init=init, source=source,
                checkpoint=job.keeper, resume=args.resume, threads=args.threads,
                marginal_samples=args.marginal_samples, point_estimate=args.point_estimate,
                chain_workers=args.chain_workers,
            )  # fmt: skip
            kept = best_chain(chain_results)
            result = chain_results[kept]
    if args.refine != "never":
        # once the refinement's chains run (it refines): house.png of the map's cells meanwhile
        redraw = contextlib.nullcontext() if prefetch is None else when_chains_start(
            functools.partial(prefetch.redraw, job.map_house))  # fmt: skip
        with redraw, progress_stage("map's cells"):
            job.refined, refits = refine(
                args, chain_results or [result], kept, model=house, on_map=job.map_house,
                settings=settings, options=options, keeper=job.keeper, chains=chains,
                sweeps=refine_sweeps, point_estimate=estimate, source=source,
            )  # fmt: skip
        if job.refined:
            job.house = job.map_house
        if job.refined or chain_results is not None:  # --sweeps auto's stay one result
            chain_results = refits
        kept = best_chain(refits)
        result = refits[kept]
    else:  # a fit the preset would refine but another --method or --update cannot: why
        report_unrefined(args, house)
    release_shared_footprints()  # the spread counts are no fit's any more
    return Fitted(result, chain_results, chains, kept, diagnostics, _clock() - start)
