"""Fitting SpCoMapping to a house: observations -> per-cell counts -> inference -> result.

This is what ``spcopyro fit`` runs; each step is a public function of its own module, so a user
can replace any of them (see :func:`fit_house_chains`' body). The inference method is looked up
by name in :mod:`spcopyro.fit.registry` (``"gibbs"``: Algorithm 1); ``--sweeps auto``
(:func:`fit_house_converged`) is Gibbs-specific.

Gibbs chains can be interrupted and resumed: :func:`fit_house_chains` with ``checkpoint=PATH``
(or a :class:`~spcopyro.fit.gibbs_chains.FitCheckpoint`) saves every chain's state there
(:mod:`spcopyro.gibbs.checkpoint`) when Ctrl-C stops it, then raises
:class:`~spcopyro.fit.gibbs_chains.FitInterrupted`; ``resume=PATH`` continues the saved
chains, exactly as if they had never stopped. Every result records where its data came from,
the package versions and the backend that ran (:func:`provenance`, written to ``config.json``).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import platform
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path

import numpy as np
import torch

from spcopyro import __version__
from spcopyro._util.messages import with_article
from spcopyro._util.number_checks import is_integer
from spcopyro._util.random_draws import check_seed
from spcopyro._util.threads import (
    AUTO,
    chain_threads,
    describe_threads,
    torch_threads,
)
from spcopyro._util.timings import timed
from spcopyro.config import DEFAULT_PRESET, WORDS, SpCoSettings, preset
from spcopyro.data import CellCounts, House, prepared_cell_counts
from spcopyro.data.inverted_map import check_placement
from spcopyro.data.model_grid import model_house
from spcopyro.data.word_weighting import resolved_preparation, resolved_settings
from spcopyro.fit import gibbs_chains  # with_sample_marginals through it: a test's patch reaches
from spcopyro.fit.gibbs_chains import FitCheckpoint, FitInterrupted, gibbs_outputs, marginal_thin
from spcopyro.fit.map_warnings import log_degenerate_map as log_degenerate_map  # re-exported
from spcopyro.fit.map_warnings import log_map_warnings
from spcopyro.fit.preset_fits import log_skipped_preset_inference
from spcopyro.fit.preset_fits import preset_fit_kwargs as preset_fit_kwargs  # re-exported
from spcopyro.fit.refine import (
    COARSE_STAGE_MODEL,
    check_coarse,
    check_refine,
    map_house,
    refine_chains,
)
from spcopyro.fit.registry import DEFAULT_METHOD, get_method

# re-exported: the settings' warnings were defined here (tests and docs import them here)
from spcopyro.fit.setting_warnings import CONCENTRATION_RANGE as CONCENTRATION_RANGE
from spcopyro.fit.setting_warnings import FREEZING_GAMMA as FREEZING_GAMMA
from spcopyro.fit.setting_warnings import config_warnings as config_warnings
from spcopyro.fit.setting_warnings import gamma_warning as gamma_warning
from spcopyro.fit.setting_warnings import preparation_warnings as preparation_warnings
from spcopyro.fit.starts import Init, init_name, initial_labels
from spcopyro.fit.variational_checkpoint import VariationalSaving
from spcopyro.gibbs.chains import resolve_workers
from spcopyro.gibbs.checkpoint import data_fingerprint
from spcopyro.gibbs.convergence import (
    DEFAULT_BLOCK,
    DEFAULT_CHAINS,
    DEFAULT_MAX_SWEEPS,
    DEFAULT_THRESHOLD,
    ConvergenceDiagnostics,
    ConvergenceInterrupted,
    run_until_converged,
)
from spcopyro.gibbs.hyperparameters import config_at_posterior_mean
from spcopyro.gibbs.method import GibbsInference, output_from_run
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.inference.driver import DriveInterrupted
from spcopyro.inference.names import SAMPLERS as SAMPLERS  # re-exported: label maps kept
from spcopyro.inference.protocol import InferenceOutput
from spcopyro.maps.free_space import check_free_cells
from spcopyro.model import ModelData, check_concentration_names, make_model_data
from spcopyro.results.map_checks import coverage_warning
from spcopyro.results.point_estimate import check_point_estimate
from spcopyro.results.posterior_means import (
    concept_totals,
    concept_word_counts,
    with_posterior_means,
)
from spcopyro.results.result import SpCoResult

logger = logging.getLogger("spcopyro")

RANDOM_STREAMS_NOTE = (
    "the torch and numba Gibbs backends draw different random streams from one seed: a seeded "
    "fit reproduces bit for bit only on the backend that ran it (inference.backend_used)"
)


def software_versions() -> dict[str, str | None]:
    """The versions of Python, spcopyro and the packages that shape a fit's draws (None: not
    installed)."""
    versions: dict[str, str | None] = {
        "python": platform.python_version(),
        "spcopyro": __version__,
        "numpy": np.__version__,
        "torch": torch.__version__,
    }
    for name, distribution in (("pyro", "pyro-ppl"), ("numba", "numba")):
        try:
            versions[name] = metadata.version(distribution)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def provenance(
    house: House, data: ModelData, source: str | None = None, counts: CellCounts | None = None
) -> dict[str, object]:
    """What ``config.json`` records beside the settings, to reproduce a fit: ``source`` (the
    data: ``source``, e.g. ``"embedded synthetic house, seed 0"``, or the house's folder, a
    sha256 fingerprint of the model data and, given ``counts``, ``observations``: how many
    observations DATA held and how many of them the counts hold, placed on free cells, snapped
    ones included, which an online update compares with its own), ``software``
    (:func:`software_versions`) and a note on the backends' random streams."""
    if source is None:
        source = (
            str(Path(house.source).resolve())
            if house.source is not None
            else f"in-memory house {house.name!r} (not read from a folder)"
        )
    said: dict[str, object] = {"data": source, "house": house.name}
    said["data_sha256"] = data_fingerprint(data)
    if counts is not None:
        placed = counts.placement
        said["observations"] = {"given": placed.num_observations, "placed": placed.num_placed}
    return {
        "source": said,
        "software": software_versions(),
        "reproducibility": RANDOM_STREAMS_NOTE,
    }


def prepare_model_data(
    house: House,
    settings: SpCoSettings,
    vocabulary: Sequence[str] | None = None,
    method: str | None = None,
) -> tuple[CellCounts, ModelData]:
    """Per-cell counts of the house under the settings' data preparation, and the model's
    tensors. Logs :func:`config_warnings` and :func:`preparation_warnings` (logger
    ``"spcopyro"``), those about the Gibbs sampler only when ``method`` samples
    (:data:`~spcopyro.inference.names.SAMPLERS`) or is None (not known). ``vocabulary``: the
    word columns in order (None: the observations' own; an online update passes the union with
    a saved fit's, :mod:`spcopyro.robot.online`). ``house`` is fitted on its own grid: with a
    ``settings.data.cell_size`` coarser than its cells it logs a warning naming
    :func:`~spcopyro.data.model_grid.model_house`, which :func:`fit_house` applies first.

    Raises:
        ValueError: the map has no free cell, or no observation lands on a free cell (a wrong
            map, origin or negate flag: the fit would learn every concept from the prior);
            counts that are not finite or too large (:func:`~spcopyro.data.check_count_totals`,
            naming the file and line of a loaded house); a further modality without a
            concentration in ``settings.model.concentrations``, or a concentration for a
            modality the house does not have.
    """
    coarse = COARSE_STAGE_MODEL.get()  # a refinement's: its coarse stage logged its warnings
    sampled = method is None or method in SAMPLERS
    said = set() if coarse is None else set(config_warnings(coarse, sampled))
    for warning in config_warnings(settings.model, sampled):
        if warning not in said:
            logger.warning(warning)
    # a refinement's preparation is refined_settings' own (no footprint, the caller's kernel
    # kept): its coarse stage said these, and it names what it replaced itself
    for warning in preparation_warnings(settings.data) if coarse is None else ():
        logger.warning(warning)
    grid = house.grid
    check_free_cells(grid, f"house {house.name!r}")  # ValueError naming the yaml's lines
    size = settings.data.cell_size
    if size is not None and model_house(house, size) is not house:  # fit_house's is already
        logger.warning(
            "house %r: settings cell_size %g m, but prepare_model_data fits the cells it is "
            "given, here map %s's own %g m cells; for the model's grid pass "
            "model_house(house, settings.data.cell_size) (spcopyro.data.model_grid), as "
            "fit_house does",
            house.name, size, house.grid.source or "", house.grid.resolution,
        )  # fmt: skip
    counts = prepared_cell_counts(grid, house.observations, settings.data, vocabulary=vocabulary,
                                  source=house.source, warn=False)  # fmt: skip
    # warnings said once the placement passes, or before the refusal pointing to their lines; a
    # refusal that blames the map comes alone
    check_placement(counts.placement, house.observations, grid, source=house.source)
    coverage = coverage_warning(house)
    if coverage:
        logger.warning(coverage)
    data = make_model_data(house.grid, counts, settings.model.connectivity)
    for modality in data.modalities:
        settings.model.concentration(modality.name)  # ValueError if a further one has none
    fix = "modality_<name>.csv adds one, or correct the name"
    check_concentration_names(data, settings.model, f"house {house.name!r} has", fix)
    return counts, data


def modality_items(counts: CellCounts, data: ModelData) -> dict[str, tuple[str, ...]]:
    """The item names of each modality: the vocabulary for words, each further modality's
    item names (images keep their class numbers)."""
    items = {WORDS: tuple(counts.vocabulary)}
    for modality in getattr(counts, "modalities", ()):
        items[modality.name] = tuple(modality.items)
    return {m.name: items[m.name] for m in data.modalities if m.name in items}


def result_of(
    output: InferenceOutput,
    house: House,
    counts: CellCounts,
    data: ModelData,
    settings: SpCoSettings,
    method: str,
    record: dict[str, object] | None = None,
) -> SpCoResult:
    """The :class:`SpCoResult` of an inference output on ``house`` (``record``: its
    :func:`provenance`). A sampler's drawn pi and emissions are replaced by their posterior means
    given its labels (:mod:`spcopyro.results.posterior_means`; a variational method's are E_q
    already), under the posterior means of any hyperparameters the chain sampled;
    the result records each concept's observed cells and counts (and each word's count in it)
    under the point labels."""
    if output.parameters_drawn:
        config = config_at_posterior_mean(settings.model, output.options.get("hyperparameters"))
        output = with_posterior_means(output, data, config)
    return SpCoResult.from_output(
        output, house.grid, modality_items(counts, data), settings.model,
        modalities=tuple(m.name for m in data.modalities), method=method,
        preparation=resolved_preparation(settings.data, house.observations), name=house.name,
        provenance=record,
        concept_totals=concept_totals(output.labels, data, settings.model),
        word_totals=data.modality(WORDS).counts.sum(0).numpy(),  # [V] over the observed cells
        word_counts=concept_word_counts(output.labels, data, settings.model),  # [L, V]
    )  # fmt: skip


def best_chain(results: Sequence[SpCoResult]) -> int:
    """Index of the chain whose point estimate has the highest objective
    (``result.best_objective``: the MAP-visited state's log joint for Gibbs; the first on ties)."""
    if not results:
        raise ValueError("best_chain needs at least one chain")
    return int(np.argmax([r.best_objective for r in results]))


def _settings(settings: SpCoSettings | None, house: House) -> SpCoSettings:
    """``settings``, or :func:`preset`'s when None, with the word weighting ``"auto"`` resolved
    for ``house``'s utterances (:mod:`spcopyro.data.word_weighting`: what the fit records);
    TypeError for anything else (an ``SpCoConfig`` is its ``.model`` part only)."""
    if settings is None:
        settings = preset()
    if not isinstance(settings, SpCoSettings):
        raise TypeError(
            f"settings must be an SpCoSettings (spcopyro.config.preset(...): .model and .data), "
            f"got {type(settings).__name__}"
        )
    return resolved_settings(settings, house.observations)


def chains_side_by_side(inference: object, chain_workers: int | str | None, chains: int) -> int:
    """How many of ``chains`` chains of ``inference`` (a registered method)
    :func:`fit_house_chains` advances at once: Gibbs chains up to ``chain_workers``
    (:func:`~spcopyro.gibbs.chains.resolve_workers`), any other method's fits one at a time."""
    if not isinstance(inference, GibbsInference):
        return 1
    return resolve_workers(chain_workers, chains)


def fit_house_chains(
    house: House,
    settings: SpCoSettings | None = None,
    *,
    method: str = DEFAULT_METHOD,
    options: object | None = None,
    sweeps: int = 5000,
    seeds: Sequence[int] = (0,),
    init: Init = "random",
    progress: bool | None = None,
    source: str | None = None,
    checkpoint: str | os.PathLike[str] | FitCheckpoint | None = None,
    resume: str | os.PathLike[str] | None = None,
    threads: int | str | None = AUTO,
    marginal_samples: int = 0,
    point_estimate: str = "map-visited",
    chain_workers: int | str | None = AUTO,
) -> list[SpCoResult]:
    """One :class:`SpCoResult` per seed: ``sweeps`` iterations of the inference method from
    ``init`` drawn with that seed. The house's counts are computed once for all chains. See
    :func:`fit_house` for the arguments; :func:`best_chain` picks the one to keep.

    Args:
        source: where the house came from, for ``config.json`` (:func:`provenance`).
        checkpoint: save the chains' state (Gibbs) or the q(C) reached (one seed of a
            variational method that resumes, ``InferenceMethod.resumable``: cavi, lbp,
            stochastic-vi, svi;
            :mod:`spcopyro.guides.checkpoint`) to this file on Ctrl-C, then raise
            :class:`FitInterrupted` (a :class:`FitCheckpoint` keeps the chains for the caller).
        resume: continue the chains, or the variational fit, saved in this checkpoint
            (ValueError if it was made for other data or settings, seeds, sweeps, init or, for
            Gibbs, marginal_samples);
            chains it does not hold start afresh. Gibbs' results equal those of a fit that
            never stopped, as do CAVI's with the torch backend; the other variational methods
            go on from the q(C) reached (a warm start: see the checkpoint module).
        marginal_samples: a sampler (Gibbs, vi-gibbs): keep about this many label maps over the
            second half of the sweeps and store their label frequencies as the result's
            ``marginals`` (the uncertainty map and per-cell "where" probabilities read them); 0:
            none. A variational method returns its q(C) as marginals anyway.
        point_estimate: a sampler: the map to report, ``"map-visited"`` (the state of highest
            log joint) or the partition minimising the expected ``"binder"`` or ``"vi"`` loss
            over those label maps (:mod:`spcopyro.results.point_estimate`; needs marginal_samples).
        chain_workers: Gibbs only: how many chains advance at once, each in a forked process
            or on a thread (:func:`~spcopyro.gibbs.chains.advance_chains`; results identical
            to one after another): ``"auto"`` (one per usable CPU) or a count. With more than
            one, ``threads`` ``"auto"`` means one torch thread per chain.
    """
    marginal_thin(1, marginal_samples)  # ValueError naming a bad marginal_samples
    if check_point_estimate(point_estimate) != "map-visited" and (
        method not in SAMPLERS or not marginal_samples
    ):
        raise ValueError(
            f"point estimate {point_estimate!r} is computed over the label maps a sampler "
            f"({', '.join(SAMPLERS)}) keeps: it needs marginal_samples > 0 (method {method!r}, "
            f"marginal_samples {marginal_samples})"
        )
    if not is_integer(sweeps) or sweeps < 1:
        raise ValueError(f"sweeps must be a positive integer or 'auto', got {sweeps!r}")
    if isinstance(seeds, str) or len(seeds) == 0:
        raise ValueError(f"seeds must name at least one chain, got {seeds!r}")
    seeds = [check_seed(s, "each of seeds") for s in seeds]
    settings = _settings(settings, house)
    house = model_house(house, settings.data.cell_size)  # the model's grid (cell_size)
    inference = get_method(method)
    if not isinstance(inference, GibbsInference) and (checkpoint or resume):
        if not getattr(inference, "resumable", False):  # the protocol alone: False
            raise ValueError(f"checkpoints hold Gibbs chains or a variational q(C); the "
                             f"{method!r} method keeps neither")  # fmt: skip
        if len(seeds) > 1:
            raise ValueError(
                f"{with_article(repr(method))} checkpoint holds one fit; {len(seeds)} seeds asked"
            )
    workers = chains_side_by_side(inference, chain_workers, len(seeds))
    count = chain_threads(threads, house.grid.num_free, workers)  # auto: 1 with workers > 1
    with timed("model_data"):
        counts, data = prepare_model_data(house, settings, method=method)
        record = provenance(house, data, source, counts)
    if method not in SAMPLERS:  # the note is on the Gibbs backends' streams (backend_used)
        record = {key: value for key, value in record.items() if key != "reproducibility"}
    logger.info("threads: %s", describe_threads(threads, house.grid.num_free, workers))
    if checkpoint is not None and not isinstance(checkpoint, FitCheckpoint):
        checkpoint = FitCheckpoint(checkpoint)
    with torch_threads(count) as used:
        record = {**record, "threads": used}  # config.json: the intra-op threads that ran
        if isinstance(inference, GibbsInference):
            outputs = gibbs_outputs(
                data, settings, options, int(sweeps), [int(s) for s in seeds], init_name(init),
                lambda seed, generator: initial_labels(house, counts, settings, init, seed,
                                                       generator),
                progress, checkpoint, resume, marginal_samples, point_estimate, workers,
                cell_area=house.grid.cell_area,  # the model's grid: the specks' area
            )  # fmt: skip
            with timed("result"):
                return [
                    result_of(o, house, counts, data, settings, method, record) for o in outputs
                ]
        fits = []
        saving = VariationalSaving(inference, options, data, settings, sweeps, seeds, init)
        for k, seed in enumerate(seeds):
            generator = torch.Generator().manual_seed(int(seed))
            start = initial_labels(house, counts, settings, init, int(seed), generator)
            # resume= only when resuming: a method may implement the protocol's run alone
            going_on = {} if resume is None else {"resume": saving.load(resume)}
            try:
                output = inference.run(
                    data, settings.model, iterations=int(sweeps), generator=generator,
                    init_labels=start, options=options, progress=progress,
                    thin=marginal_thin(int(sweeps), marginal_samples), **going_on,
                )  # fmt: skip
            except DriveInterrupted as stop:  # the driver's record of how far it got
                done = stop.progress or (
                    f"{len(stop.trajectory.objective)} of {sweeps} iterations done"
                )
                where = f"{method} fit {k + 1} of {len(seeds)}, {done}"
                path = None if checkpoint is None else saving.save(checkpoint.path, stop)
                raise FitInterrupted(where, path) from None
            except KeyboardInterrupt:  # in the method's setup or once its driver had returned
                raise FitInterrupted(
                    f"{method} fit {k + 1} of {len(seeds)}", None,
                    why="it stopped outside the iterations: while the method set up or made "
                    "their result",
                ) from None  # fmt: skip
            try:
                output.options.update(seed=int(seed), init=init_name(init))
                if output.marginals is None:  # a sampler (vi-gibbs): its label frequencies
                    output = gibbs_chains.with_sample_marginals(
                        output, int(sweeps), data, settings, point_estimate,
                        progress=progress, cell_area=house.grid.cell_area,
                    )  # fmt: skip
                fits.append(result_of(output, house, counts, data, settings, method, record))
            except KeyboardInterrupt:  # the run is whole, its q not kept: "no iteration" was false
                done = len(output.trace.objective)
                raise FitInterrupted(
                    f"{method} fit {k + 1} of {len(seeds)}, after its {done} iterations", None,
                    why="it stopped after the iterations, while their result was made",
                ) from None  # fmt: skip
    return fits


def fit_house(
    house: House,
    settings: SpCoSettings | None = None,
    *,
    method: str = DEFAULT_METHOD,
    options: object | None = None,
    sweeps: int | str = 5000,
    seed: int = 0,
    init: Init = "random",
    progress: bool | None = None,
    chains: int = 1,
    threads: int | str | None = AUTO,
    marginal_samples: int = 0,
    point_estimate: str = "map-visited",
    chain_workers: int | str | None = AUTO,
    refine: str = "never",
) -> SpCoResult:
    """Fit SpCoMapping to a house. A degenerate reported map (one concept over most of the
    map while words said at different places lie inside it, or outside it in small concepts) is
    logged as a warning (:func:`log_degenerate_map`), as is a weak-limit DP's map using nearly
    all of its L concepts (:func:`~spcopyro.fit.map_warnings.log_concept_slots`).

    Args:
        settings: model hyperparameters and data preparation (default: :func:`preset`'s); a
            word weighting ``"auto"`` is resolved for the house's utterances (tf-idf when at
            least 30% are sentences, :mod:`spcopyro.data.word_weighting`) and recorded as resolved.
        method: the inference method's name in :mod:`spcopyro.fit.registry` (``"gibbs"``).
        options: the method's options (``GibbsOptions`` for Gibbs; None for its defaults).
        sweeps: iterations (Gibbs sweeps), or ``"auto"`` for Gibbs: :func:`fit_house_converged`
            (``chains`` chains, at least 2; 4 if ``chains`` is 1) until split R-hat < 1.05;
            the diagnostics are logged at INFO level -- call :func:`fit_house_converged` to get
            them.
        init: ``"random"`` labels, ``"gaussian"`` (k-means Gaussians over the observed cells,
            eqs. 21-22), ``"spcoa"`` (the paper's pre-learning: Gaussians of a SpCoA fit), or a
            previous fit's :class:`SpCoResult` on the same map (a warm start, any method from
            any method: e.g. a CAVI result starting Gibbs).
        chains: run that many chains (seeds ``seed``, ``seed + 1``, ...) and keep the one whose
            point estimate has the highest objective ("best of K chains", the remedy for the DP
            variant's instability measured in :mod:`spcopyro.experiments.robustness`).
        threads: torch intra-op threads during the fit (:mod:`spcopyro._util.threads`): ``"auto"``
        (one thread unless the map is large and the machine's other load leaves the cores
            free), 0 or None (torch's own setting), or a count. The previous setting is restored
            afterwards; results do not depend on it. ``config.json`` records the count that ran.
        marginal_samples, point_estimate, chain_workers: see :func:`fit_house_chains`.
        refine: Gibbs: ``"auto"`` refits on the map's own cells, from the fit's map, where its
            concepts tell the images apart, ``"always"``, or ``"never"``
            (:mod:`spcopyro.fit.refine`; preset ``coarse`` recommends ``"auto"``); after
            ``sweeps="auto"`` the refit runs as many sweeps as the coarse chains needed, with
            ``point_estimate`` (which ``sweeps="auto"`` allows only for the refit).
            The decision is logged at INFO level and kept in ``result.inference["refine"]``.
    """
    settings = _settings(settings, house)
    given, house = house, model_house(house, settings.data.cell_size)  # the model's grid
    skipped: dict[str, object] = {}  # the preset's recommended inference this fit does not run
    if method == DEFAULT_METHOD:
        skipped = log_skipped_preset_inference(settings, init, options, point_estimate, refine)
    if check_refine(refine) != "never" and method != "gibbs":
        raise ValueError(
            f"refine={refine!r} refines a Gibbs fit, not method={method!r}: pass refine='never'"
        )
    check_coarse(refine, house)  # before the fit: refine='always' on the map's own cells
    if not isinstance(chains, int) or isinstance(chains, bool) or chains < 1:
        raise ValueError(f"chains must be a positive integer, got {chains!r}")
    check_seed(seed)
    check_seed(seed + chains - 1, f"seed + chains - 1 (seed {seed}, chains {chains})")
    if sweeps == "auto":
        if point_estimate != "map-visited" and refine == "never":
            raise ValueError("sweeps='auto' reports the best visited state (a point estimate is "
                             "for its refinement, refine='auto' or 'always')")  # fmt: skip
        if method != "gibbs":
            raise ValueError(f"sweeps='auto' is Gibbs' convergence rule, not one of method "
                             f"{method!r}: give a number of sweeps")  # fmt: skip
        chains = chains if chains > 1 else DEFAULT_CHAINS
        result, diagnostics = fit_house_converged(
            house, settings, options=options, chains=chains, seed=seed, init=init,
            progress=progress, threads=threads, chain_workers=chain_workers,
        )  # fmt: skip
        logger.info("--sweeps auto: %s", diagnostics.to_json())
        # its anneal_sweeps too, which the refinement's chains run again
        results, kept, refine_sweeps = [result], 0, len(result.trace.objective)
    else:
        results = fit_house_chains(
            house, settings, method=method, options=options, sweeps=sweeps,
            seeds=[seed + k for k in range(chains)], init=init, progress=progress,
            threads=threads, marginal_samples=marginal_samples, point_estimate=point_estimate,
            chain_workers=chain_workers,
        )  # fmt: skip
        kept, refine_sweeps = best_chain(results), sweeps
    if refine != "never":  # after sweeps="auto": as many sweeps as its chains needed
        decision, results = refine_chains(
            results, kept, given, settings, refine, fit_house_chains, method=method,
            options=options, sweeps=refine_sweeps, seeds=[seed + k for k in range(chains)],
            progress=progress, threads=threads, marginal_samples=marginal_samples,
            point_estimate=point_estimate, chain_workers=chain_workers,
        )  # fmt: skip
        logger.info("refine: %s", decision.reason)
        if decision.refine:
            kept, house = best_chain(results), map_house(given)
    if len(results) > 1:
        logger.info(
            "best of %d chains: kept chain %d (seed %d); best objectives %s", chains, kept,
            seed + kept, [round(r.best_objective, 1) for r in results],
        )  # fmt: skip
    default = bool(skipped) if settings.preset == DEFAULT_PRESET else None  # for its advice
    log_map_warnings(results[kept], house, default)  # degenerate, short of concept slots
    return results[kept]


def fit_house_converged(
    house: House,
    settings: SpCoSettings | None = None,
    *,
    options: GibbsOptions | None = None,
    chains: int = DEFAULT_CHAINS,
    block: int = DEFAULT_BLOCK,
    max_sweeps: int = DEFAULT_MAX_SWEEPS,
    threshold: float = DEFAULT_THRESHOLD,
    seed: int = 0,
    init: Init = "random",
    progress: bool | None = None,
    source: str | None = None,
    threads: int | str | None = AUTO,
    chain_workers: int | str | None = AUTO,
) -> tuple[SpCoResult, ConvergenceDiagnostics]:
    """Fit by Gibbs sampling with ``chains`` chains (seeds ``seed``, ``seed + 1``, ...) until
    split R-hat of the log joint and of the number of concepts are below ``threshold``, or
    ``max_sweeps`` sweeps (:func:`spcopyro.gibbs.convergence.run_until_converged`). Returns the
    chain of highest log joint as the result, and the diagnostics. Chain k starts from ``init``
    drawn with seed ``seed + k``; ``options.anneal_sweeps`` of gamma annealing come first.
    ``source``: where the house came from, for ``config.json`` (:func:`provenance`).
    ``threads``, ``chain_workers``: as for :func:`fit_house_chains` (chains advancing at once
    within a block; with more than one, ``threads`` ``"auto"`` means one torch thread per chain).
    """
    settings = _settings(settings, house)
    house = model_house(house, settings.data.cell_size)  # the model's grid (cell_size)
    options = GibbsOptions() if options is None else options
    workers = resolve_workers(chain_workers, chains)  # as chains_side_by_side for Gibbs
    count = chain_threads(threads, house.grid.num_free, workers)  # auto: 1 with workers > 1
    counts, data = prepare_model_data(house, settings, method="gibbs")
    logger.info("threads: %s", describe_threads(threads, house.grid.num_free, workers))
    with torch_threads(count) as used:
        starts = []
        for k in range(chains):
            generator = torch.Generator().manual_seed(int(seed + k))
            starts.append(initial_labels(house, counts, settings, init, seed + k, generator))
        try:
            run, diagnostics = run_until_converged(
                data, settings.model, options=options, chains=chains, block=block,
                max_sweeps=max_sweeps, threshold=threshold, seed=seed, init_labels=starts,
                progress=progress, workers=workers,
            )  # fmt: skip
        except ConvergenceInterrupted as stop:  # said as every fit's interruption is
            raise FitInterrupted(stop.where) from None
    record = {
        "sweeps": "auto", "chains": chains, "seed": seed, "init": init_name(init),
        **dataclasses.asdict(options), "backend_used": run.backend,
    }  # fmt: skip
    output = output_from_run(run, record)
    made = {**provenance(house, data, source, counts), "threads": used}  # the threads that ran
    return result_of(output, house, counts, data, settings, "gibbs", made), diagnostics
