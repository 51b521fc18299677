"""The Gibbs chains of a fit: started, advanced side by side, saved on Ctrl-C and resumed, and
turned into outputs (label frequencies, the point estimate, posterior means).

:func:`gibbs_outputs` is what :func:`spcopyro.fit.house.fit_house_chains` runs for the Gibbs method;
:class:`FitCheckpoint` and :class:`FitInterrupted` are how a caller (``spcopyro fit``) keeps the
chains of an interrupted fit.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch

from spcopyro._util.number_checks import is_integer
from spcopyro._util.progress import setup_bar
from spcopyro._util.timings import timed
from spcopyro.config import SpCoSettings
from spcopyro.gibbs.chains import advance_chains
from spcopyro.gibbs.checkpoint import load_chains, read_record, save_chains
from spcopyro.gibbs.hyperparameters import config_at_posterior_mean
from spcopyro.gibbs.method import gibbs_record, output_from_run
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsChain, start_chain
from spcopyro.inference.protocol import InferenceOutput, method_options
from spcopyro.model import ModelData
from spcopyro.results.point_estimate import with_point_estimate
from spcopyro.results.posterior_means import with_posterior_means, words_per_cell
from spcopyro.results.uncertainty import align_samples, count_steps, label_frequencies


class FitInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a fit (a :class:`KeyboardInterrupt`, so code unaware of it still stops).

    ``checkpoint``: the file holding the chains' state (None where none was kept);
    ``where``: how far the fit had got, e.g. ``"chain 1 of 2, 120 of 5000 sweeps done"``;
    ``why``: why no checkpoint was kept, where the fit knows (None: the caller says).
    """

    def __init__(self, where: str, checkpoint: Path | None = None, why: str | None = None) -> None:
        super().__init__(where)
        self.where, self.checkpoint, self.why = where, checkpoint, why


class FitCheckpoint:
    """Where a Gibbs fit's chains are saved (:func:`~spcopyro.gibbs.checkpoint.save_chains`)
    when it is interrupted.

    :func:`fit_house_chains` fills :attr:`chains` (the very list it advances) and :attr:`record`
    (its settings, checked on resuming), saves them on Ctrl-C, and leaves them here, so that the
    caller can :meth:`save` the finished chains later too -- e.g. when Ctrl-C stops the writing of
    the results.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.chains: list[GibbsChain | None] = []
        self.record: dict[str, object] = {}

    def save(self) -> Path | None:
        """Save the chains reached so far; None (nothing written) if none has started."""
        if all(chain is None for chain in self.chains):
            return None
        return save_chains(self.chains, self.path, record=self.record)

    def finished(self) -> bool:
        """Whether every chain has run the sweeps its fit asked for."""
        sweeps = self.record.get("sweeps")
        return bool(self.chains) and all(
            chain is not None and chain.sweeps_done == sweeps for chain in self.chains
        )


def gibbs_outputs(
    data: ModelData,
    settings: SpCoSettings,
    options: object | None,
    sweeps: int,
    seeds: list[int],
    init: str,
    start_labels: Callable[[int, torch.Generator], torch.Tensor],
    progress: bool | None,
    checkpoint: FitCheckpoint | None,
    resume: str | os.PathLike[str] | None,
    marginal_samples: int = 0,
    point_estimate: str = "map-visited",
    workers: int = 1,
    cell_area: float | None = None,
) -> list[InferenceOutput]:
    """One output per seed: Gibbs chains (:func:`~spcopyro.gibbs.run.start_chain`,
    :func:`~spcopyro.gibbs.run.advance`: the same draws as
    :class:`~spcopyro.gibbs.method.GibbsInference`), saved on Ctrl-C into ``checkpoint`` and
    continued from ``resume``; up to ``workers`` of them advance at once
    (:func:`~spcopyro.gibbs.chains.advance_chains`). ``init``: the start's name as recorded;
    ``start_labels(seed, generator)``: chain ``seed``'s initial labels, drawn with its
    generator; ``cell_area``: the square metres of one of ``data``'s cells, which the point
    estimates ``vi`` and ``binder`` need (:func:`with_sample_marginals`)."""
    options = method_options(options, GibbsOptions, "Gibbs sampling")
    if options.anneal_sweeps > sweeps:
        raise ValueError(
            f"anneal_sweeps ({options.anneal_sweeps}) must not exceed num_sweeps ({sweeps})"
        )
    # marginal_samples sets which sweeps keep a label map: a chain resumed with another count
    # would mix two spacings (the samples of no fit that never stopped)
    record = {"method": "gibbs", "sweeps": sweeps, "seeds": seeds, "init": init,
              "data_preparation": preparation_record(settings),
              "marginal_samples": marginal_samples}  # fmt: skip
    chains: list[GibbsChain | None] = [None] * len(seeds)
    if resume is not None:
        checked = dict(record)
        if "marginal_samples" not in read_record(resume).get("caller", {}):  # type: ignore[operator]
            del checked["marginal_samples"]  # a checkpoint made before it was recorded
        chains = load_chains(resume, data, settings.model, options, record=checked)
    if checkpoint is not None:
        checkpoint.chains, checkpoint.record = chains, record
    try:
        with timed("chain_start"):
            for k, seed in enumerate(seeds):
                if chains[k] is None:
                    generator = torch.Generator().manual_seed(seed)
                    start = start_labels(seed, generator)
                    chains[k] = start_chain(
                        data, settings.model, options=options, generator=generator,
                        init_labels=start,
                    )  # fmt: skip
        runs = [(chain, sweeps - chain.sweeps_done) for chain in chains if chain is not None]
        thin = marginal_thin(sweeps, marginal_samples)
        with timed("sweeps"):
            advance_chains(runs, workers=workers, thin=thin, progress=progress)
    except KeyboardInterrupt:
        saved = None if checkpoint is None else checkpoint.save()
        raise FitInterrupted(_where_stopped(chains, sweeps), saved) from None
    outputs = []
    for chain, seed in zip(chains, seeds, strict=True):
        assert chain is not None
        entry = gibbs_record(options, sweeps, chain.backend.name)
        output = output_from_run(chain.to_run(), {**entry, "seed": seed, "init": init})
        outputs.append(
            with_sample_marginals(
                output,
                sweeps,
                data,
                settings,
                point_estimate,
                progress=progress,
                cell_area=cell_area,
            )  # fmt: skip
        )
    return outputs


def preparation_record(settings: SpCoSettings) -> dict[str, object]:
    """The data preparation as a checkpoint records it: the footprint fields only where they
    are read, so checkpoints made before they existed still resume and a resume changing one
    that does nothing is not refused: ``footprint_radius`` and ``footprint_kernel`` where any
    footprint is on (the words' own too), ``footprint_fov`` where the images' is
    (:meth:`~spcopyro.config.preparation.DataPreparation.reads`), ``word_footprint_radius`` where it
    differs from ``footprint_radius`` (equal, it changes nothing: ``--word-footprint 0
    --footprint 0``)."""
    data = settings.data
    record = data.to_json()  # word_footprint_radius only where set
    if data.words_radius == data.footprint_radius:  # set to footprint_radius's: no change
        record.pop("word_footprint_radius", None)
    if not data.has_footprint:
        record.pop("footprint_radius")
    for name in ("footprint_kernel", "footprint_fov"):
        if not data.reads(name):
            record.pop(name)
    return record


def marginal_thin(sweeps: int, marginal_samples: int) -> int:
    """Every how many iterations to keep a label map so that about ``marginal_samples`` fall in
    the second half of ``sweeps`` (0: keep none)."""
    # A negative count made thin 1 (every sweep kept); 2.5 failed naming thin, not this.
    if not is_integer(marginal_samples) or marginal_samples < 0:
        raise ValueError(f"marginal_samples must be an integer >= 0, got {marginal_samples!r}")
    return max(1, sweeps // (2 * marginal_samples)) if marginal_samples else 0


def with_sample_marginals(
    output: InferenceOutput,
    sweeps: int,
    data: ModelData,
    settings: SpCoSettings,
    point_estimate: str = "map-visited",
    progress: bool | None = False,
    cell_area: float | None = None,
) -> InferenceOutput:
    """``output`` with the label frequencies of its samples from the second half of the sweeps
    as its marginals (unchanged if it kept none there), reporting ``point_estimate`` over them
    (:func:`spcopyro.results.point_estimate.with_point_estimate`; ``vi`` and ``binder`` without
    specks, told by the words ``data`` counts at each cell, footprint included: its word
    counts divided by ``settings.data.word_scaling``, the units of ``result.heard``, and the
    square metres ``cell_area`` of one of its cells: the grid's resolution squared), and a
    sampler's pi and emissions as their posterior means (the model ``settings.model``): given
    the point estimate's labels when it is one, else averaged over those samples
    (:func:`~spcopyro.results.posterior_means.with_posterior_means`)."""
    config = settings.model
    if output.label_samples is None or output.sample_iterations is None:
        return output
    samples = second_half(
        np.asarray(output.label_samples), np.asarray(output.sample_iterations), sweeps
    )  # [S', N]
    if not len(samples):
        return output
    output = with_point_estimate(
        output, samples, point_estimate, config.num_concepts, progress=progress,
        cell_words=words_per_cell(data, settings.data.word_scaling),  # vi, binder: the specks
        cell_area=cell_area,
    )  # fmt: skip
    # One set of concept names per result: the kept samples renamed to the reported map's
    # concepts before their frequencies are counted (issue 22 item 1).
    with timed("label_frequencies"):
        # 0.2-0.3 s per sample at 2.9 million cells (a warehouse at 0.05 m): a bar on such maps
        # then one step per million cells counted (at 2.9 million, L = 120: 1 s of CPU and the
        # first writes of the 1.4 GB result, up to 8 s in all under load)
        steps = len(samples) + count_steps(samples.shape[1])
        bar = setup_bar(samples.shape[1], steps, "label frequencies", "sample", progress)
        samples = align_samples(samples, np.asarray(output.labels), config.num_concepts, bar)
        marginals = label_frequencies(samples, config.num_concepts, bar)  # [N, L]
        bar.close()
    if output.parameters_drawn:
        given = None if point_estimate != "map-visited" else samples  # tables of its clusters
        sampled = config_at_posterior_mean(config, output.options.get("hyperparameters"))
        with timed("posterior_means"):
            output = with_posterior_means(output, data, sampled, given)
    return dataclasses.replace(
        output,
        marginals=marginals,
        label_samples=None,
        options={**output.options, "marginal_samples": len(samples)},
    )


def second_half(samples: np.ndarray, iterations: np.ndarray, sweeps: int) -> np.ndarray:
    """[S', N] the maps of ``samples`` [S, N] kept at ``iterations`` [S] (0-based sweeps,
    ascending, as :func:`~spcopyro.gibbs.run.advance` keeps them) of ``sweeps // 2`` or later,
    as a view ``samples[first:]`` (``first`` the first such sample: :func:`numpy.searchsorted`,
    ``side="left"``), so that the kept maps are not copied again (0.39 GB for 50 maps of 3.87
    million cells). Read-only where ``samples`` is: the chain's maps
    (:meth:`~spcopyro.gibbs.run.GibbsChain.sample_stack`). ValueError if ``iterations`` do not
    ascend."""
    if np.any(np.diff(iterations) <= 0):
        raise ValueError(f"second_half: the sample iterations must ascend, got {iterations}")
    first = int(np.searchsorted(iterations, sweeps // 2, side="left"))
    return samples[first:]


def _where_stopped(chains: Sequence[GibbsChain | None], sweeps: int) -> str:
    """``"chain k of K, s of S sweeps done"`` for the first chain not finished, or, for chains
    that advanced side by side, ``"K chains at s1, s2, ... of S sweeps done"`` (the first one's
    count alone hid the others')."""
    done = [0 if chain is None else chain.sweeps_done for chain in chains]
    if sum(0 < d < sweeps for d in done) > 1:
        return f"{len(chains)} chains at {', '.join(map(str, done))} of {sweeps} sweeps done"
    for k, chain in enumerate(chains):
        done = 0 if chain is None else chain.sweeps_done
        if done < sweeps:
            return f"chain {k + 1} of {len(chains)}, {done} of {sweeps} sweeps done"
    return f"all {len(chains)} chain(s) done ({sweeps} sweeps each)"
