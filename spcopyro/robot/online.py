r"""Online updates: continue a saved fit with new observations (the paper's future work, Sec. 6).

A robot that has mapped a house and then records another trial need not refit from scratch:
:func:`fit_update` takes a finished fit (a :class:`~spcopyro.results.result.SpCoResult`, e.g.
``SpCoResult.load(OUT)``) and the house with *all* its observations (the old trials and the new
ones together), and runs a few hundred Gibbs sweeps (or iterations of any method of
:mod:`spcopyro.fit.registry`) from the saved state instead of thousands from random labels
(``spcopyro fit DATA --update OUT``).

What carries over:

* **Labels**: the saved point estimate of every free cell's concept. The map must be the same
  (shape, resolution, origin and free cells; :func:`check_compatible`).
* **Vocabulary** (:func:`merge_vocabulary`): the union. The saved words keep their columns
  0..V-1, in the saved order; words first heard in the new data get columns V..V'-1, in order of
  first appearance. A saved word the new data no longer holds keeps its column with zero counts.
  A fit saved by an older spcopyro may hold words the tokenizer now folds or strips (``TV``,
  ``stove.``, a byte-order mark in front), which the new data's words never equal: they are read
  as :func:`~spcopyro.data.text.tokenize` reads them now (:func:`renormalise_vocabulary`; two that
  become one word add their probabilities), with a warning naming them; one that is no single
  word now (punctuation alone) keeps its column and is named as matching no word of the data.
  Image classes and the items of every further modality must be the same (ValueError otherwise).
* **Globals** (Gibbs): pi and every modality's distributions of the saved point estimate are the
  chain's state at sweep 0, so the first label sweep (eq. 13) places the new observations under
  what the old ones taught. Each word distribution is extended to the new words by
  :func:`extend_emission`, a draw from the Dirichlet conditional (eq. 17) in which the new words
  have no counts yet:

  .. math::

      w'_l \sim \mathrm{Dir}(\beta + n_{l1}, \ldots, \beta + n_{lV}, \beta, \ldots, \beta)
      \iff w'_l = (S_l\, w_l,\; (1 - S_l)\, u_l),\quad
      S_l \sim \mathrm{Beta}(\beta V + n_l,\; \beta V_{new}),\quad
      u_l \sim \mathrm{Dir}(\beta \mathbf 1_{V_{new}})

  (the Dirichlet's aggregation and neutrality properties), where the saved w_l stands for the
  draw from Dir(beta + n_l) over the old words and n_l is concept l's word total. The saved fit
  does not store n_l: it is counted from the saved labels and the given data's counts of the
  saved words (old and new trials together: an over-estimate by the new trial's share, which only
  keeps a little more mass on the old words for one sweep). Without a generator the mean is used
  (S_l = E[S_l], u_l uniform). A variational method starts from the saved labels only
  (``init_labels``): it derives its global factors from them.
* **Concept numbers**: the result's concepts are renumbered after the sweeps to match the saved
  fit's on the same cells (:mod:`spcopyro.results.renumber`), so that a place keeps its number
  (colours, ``show``, the concepts table) although the sampler may have moved it to another.
  ``update_of.renumbered`` records the numbers that moved (new number -> the sampler's), so
  that its raw samples can be read in the result's numbers.

The saved settings (model hyperparameters and data preparation) must equal the new run's:
:func:`check_compatible` names every field that differs. Everything after sweep 0 is the
ordinary sampler on the whole data, so the result is a fit of the old and new observations
together; the trace and the best state cover the update's sweeps only.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from spcopyro._util.messages import echo, listed, warn_once
from spcopyro._util.number_checks import is_integer
from spcopyro._util.random_draws import sample_log_dirichlet
from spcopyro._util.threads import AUTO, resolve_threads, torch_threads
from spcopyro.config import IMAGES, WORDS, SpCoSettings
from spcopyro.data import CellCounts, House
from spcopyro.data.word_weighting import keeping_word_weighting
from spcopyro.fit import gibbs_chains  # with_sample_marginals through it: a test's patch reaches
from spcopyro.fit.gibbs_chains import FitInterrupted, marginal_thin
from spcopyro.fit.house import prepare_model_data, provenance, result_of
from spcopyro.fit.registry import DEFAULT_METHOD, get_method
from spcopyro.gibbs.method import GibbsInference, gibbs_record, output_from_run
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsChain, advance, start_chain
from spcopyro.inference.driver import DriveInterrupted
from spcopyro.inference.protocol import method_options
from spcopyro.maps.grid import frame_differences
from spcopyro.model import DTYPE, ModelData
from spcopyro.results.renumber import matching_permutation, moved_numbers, renumbered
from spcopyro.results.result import SpCoResult
from spcopyro.results.saved_vocabulary import (
    SavedVocabulary,
    renormalise_vocabulary,
    renormalised_result,
)
from spcopyro.robot.update_history import UPDATE_INIT, update_record

__all__ = [
    "DEFAULT_UPDATE_SWEEPS",
    "SavedVocabulary",
    "UpdateMismatchError",
    "UpdateStart",
    "VocabularyMerge",
    "check_compatible",
    "extend_emission",
    "fit_update",
    "merge_vocabulary",
    "renormalise_vocabulary",
    "settings_of",
    "start_update",
    "start_update_chain",
]

DEFAULT_UPDATE_SWEEPS = 300
"""Sweeps (or iterations) of an update when none are given. Measured (benchmarks/online_update.py,
trials 1-2 fitted with 5000 sweeps, updated with trial 3): 300 sweeps cost 2.5-10% of a 5000-sweep
refit, and their mean log joint over the last 100 sweeps was, in median over 3 seeds, within the
refits' seed-to-seed spread on the five public houses and the synthetic one (paper-dp); with
original-code and gamma 3 the synthetic house's ARI was 0.975 against the refit's 0.980."""

_TINY = np.finfo(np.float64).tiny
"""Probabilities of the saved globals are floored here before their log: a Gibbs draw with a
small concentration can underflow to 0, and log 0 times a zero count is NaN in the sweep."""


@dataclass(frozen=True)
class VocabularyMerge:
    """The vocabulary of an update: the saved words first, in their columns, then the new ones."""

    vocabulary: tuple[str, ...]
    """[V'] the union: ``vocabulary[:old_size]`` is the saved vocabulary, unchanged."""
    old_size: int
    """V, the saved vocabulary's size."""
    new_words: tuple[str, ...]
    """[V' - V] words of the new data the saved fit never heard, in order of first appearance."""
    unheard_words: tuple[str, ...]
    """Saved words the new data does not hold (kept, with zero counts)."""

    def column(self, word: str) -> int:
        """The column of ``word`` in :attr:`vocabulary` (KeyError if it is in neither)."""
        return self.vocabulary.index(word)


def merge_vocabulary(saved: Sequence[str], observed: Sequence[str]) -> VocabularyMerge:
    """The union of a saved fit's vocabulary and the words ``observed`` in the new data.

    Saved word v keeps column v; a new word gets the next free column, in ``observed``'s order.
    """
    saved = tuple(saved)
    if len(set(saved)) != len(saved):
        raise ValueError("the saved fit's vocabulary lists a word twice")
    known = set(saved)
    new = tuple(word for word in dict.fromkeys(observed) if word not in known)
    heard = set(observed)
    return VocabularyMerge(
        vocabulary=saved + new,
        old_size=len(saved),
        new_words=new,
        unheard_words=tuple(word for word in saved if word not in heard),
    )


UNMATCHABLE_SHOWN = 10
"""Saved words no token can match that an update's warning names (then '... (N more)')."""


def _warn_renormalised(saved: SavedVocabulary, where: str) -> None:
    """Warn (once per saved fit and vocabulary) of what :func:`renormalise_vocabulary` changed."""
    said = [note] if (note := saved.renamed_note()) else []
    if saved.unmatchable:
        names = listed([echo(word) for word in saved.unmatchable], UNMATCHABLE_SHOWN)
        said.append(f"{len(saved.unmatchable)} word(s) of its vocabulary are no word the "
                    f"tokenizer makes now and can match no word of the data (kept, without "
                    f"counts): {names}")  # fmt: skip
    if said:
        warn_once(("renormalised vocabulary", where, saved.columns.tobytes(), saved.vocabulary),
                  f"update of {where}: " + "; ".join(said))  # fmt: skip


def settings_of(saved: SpCoResult) -> SpCoSettings:
    """The saved fit's settings: its model hyperparameters and data preparation."""
    return SpCoSettings(model=saved.config, data=saved.preparation)


def _differences(saved: dict[str, object], new: dict[str, object]) -> list[str]:
    def said(name: str, value: object) -> str:  # cell_size None: no model grid
        return (
            "None (the map's own cells)" if name == "cell_size" and value is None else repr(value)
        )

    return [
        f"{name}: saved fit {said(name, saved[name])}, this run {said(name, new.get(name))}"
        for name in saved
        if saved[name] != new.get(name)
    ]


class UpdateMismatchError(ValueError):
    """:func:`check_compatible`'s refusal: this run may not continue the saved fit. A
    ValueError (what it raised before it had a type of its own); ``problems``: each difference,
    as the message names them, so that a caller (``spcopyro fit --update``'s hint of the flag
    that mends it) tells the refusal by its type, not by its message's words."""

    def __init__(self, message: str, problems: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.problems: tuple[str, ...] = tuple(problems)


def check_compatible(
    saved: SpCoResult, house: House, settings: SpCoSettings, where: str = "the saved fit"
) -> None:
    """:class:`UpdateMismatchError` (a ValueError), naming every difference, unless ``house`` and
    ``settings`` may continue ``saved``: the same map (shape, resolution, origin, free cells),
    the same model hyperparameters and data preparation, the same number of image classes and
    the same modalities with the same items. ``where`` names the saved fit in the message (its
    folder)."""
    problems = []
    old, grid = saved.grid, house.grid
    if old.shape != grid.shape:
        problems.append(f"map: saved fit {old.shape[0]} x {old.shape[1]} cells, this run "
                        f"{grid.shape[0]} x {grid.shape[1]}")  # fmt: skip
    else:
        resolution, origin = frame_differences(old, grid)  # maps' one rule, as same_frame's
        if resolution:
            problems.append(f"map resolution: saved fit {old.resolution:g} m, this run "
                            f"{grid.resolution:g} m")  # fmt: skip
        if origin:  # in the finer map's cells (in the saved fit's, a --init start refused it)
            problems.append(f"map origin: saved fit {list(old.origin)}, this run "
                            f"{list(grid.origin)}")  # fmt: skip
        if not np.array_equal(old.free, grid.free):
            moved = int((old.free != grid.free).sum())
            problems.append(f"map: {moved} cells differ in being free (saved fit "
                            f"{old.num_free} free cells, this run {grid.num_free})")  # fmt: skip
    settings = keeping_word_weighting(saved.preparation.word_weighting, settings, where)
    problems += _differences(saved.config.to_json(), settings.model.to_json())
    problems += _differences(
        dataclasses.asdict(saved.preparation), dataclasses.asdict(settings.data)
    )
    obs = house.observations
    classes = saved.emission(IMAGES).probabilities.shape[1]
    if classes != obs.num_feature_classes:
        problems.append(f"image classes: saved fit {classes}, this run's Ft.csv "
                        f"{obs.num_feature_classes} (the features must come from the same "
                        "network and head)")  # fmt: skip
    further = {t.name: t.items for t in saved.emissions if t.name not in (IMAGES, WORDS)}
    present = {m.name: m.items for m in obs.modalities}
    for name in sorted(set(further) | set(present)):
        if name not in present:
            problems.append(f"modality {name!r}: in the saved fit, not in this run's data")
        elif name not in further:
            problems.append(f"modality {name!r}: in this run's data, not in the saved fit")
        elif tuple(further[name]) != tuple(present[name]):
            problems.append(f"modality {name!r}: items differ (saved fit {list(further[name])}, "
                            f"this run {list(present[name])})")  # fmt: skip
    if problems:
        refined = (saved.inference.get("refine") or {}).get("refine")
        hint = (
            " (a refined fit is saved with its second stage's settings, on the map's own "
            "cells, not the preset's: leave them out to continue with the saved fit's, "
            "settings=None in fit_update, no model or data options after --update)"
            if refined
            else " (an update needs the saved fit's map and settings: see its config.json)"
        )
        message = f"cannot update {where} with this run: " + "; ".join(problems) + hint
        raise UpdateMismatchError(message, problems)


def extend_emission(
    probabilities: np.ndarray,
    totals: np.ndarray,
    concentration: float,
    num_new: int,
    generator: torch.Generator | None = None,
) -> np.ndarray:
    """[L, V + num_new] each concept's distribution over the old items extended to ``num_new``
    new ones under the prior (the module docstring's construction).

    Args:
        probabilities: [L, V] the saved distributions (rows sum to 1); V = 0 (a fit of a
            house without words): the new items take all the mass, S_l = 0.
        totals: [L] n_l, each concept's count total over the old items.
        concentration: the symmetric Dirichlet concentration (beta for words).
        num_new: the new items.
        generator: draw S_l and u_l (None: their means).
    """
    probabilities = np.asarray(probabilities, dtype=np.float64)  # [L, V]
    if num_new == 0:
        return probabilities.copy()
    num_concepts, num_old = probabilities.shape
    totals = np.asarray(totals, dtype=np.float64)  # [L]
    old_mass = concentration * num_old + totals  # [L] Beta's first parameter
    new_mass = concentration * num_new  # Beta's second parameter
    if generator is None:
        share = old_mass / (old_mass + new_mass)  # [L] E[S_l]
        spread = np.full((num_concepts, num_new), 1.0 / num_new)  # [L, V_new] E[u_l]
    else:
        # S_l ~ Beta(a, b) as the first part of Dir(a, b); u_l ~ Dir(concentration). No old
        # items (a fit of a house without words): a = 0, and Beta(0, b) is the point at 0.
        share = np.zeros(num_concepts)  # [L]
        if num_old:
            pair = torch.stack(
                [torch.as_tensor(old_mass, dtype=DTYPE), torch.full((num_concepts,), new_mass)],
                -1,
            )  # [L, 2]
            share = sample_log_dirichlet(pair, generator)[:, 0].exp().numpy()  # [L]
        flat = torch.full((num_concepts, num_new), float(concentration), dtype=DTYPE)
        spread = sample_log_dirichlet(flat, generator).exp().numpy()  # [L, V_new]
    return np.concatenate(
        [share[:, None] * probabilities, (1.0 - share)[:, None] * spread], axis=1
    )  # [L, V + V_new]


@dataclass
class UpdateStart:
    """What an update starts from: the data of all observations, and the state at sweep 0."""

    counts: CellCounts
    data: ModelData
    settings: SpCoSettings
    merge: VocabularyMerge
    labels: torch.Tensor
    """[N] the saved labels."""
    log_pi: torch.Tensor
    """[L] log of the saved pi."""
    log_emissions: tuple[torch.Tensor, ...]
    """Per modality of ``data``, [L, K_m]: the saved distributions, words extended."""


def _log(probabilities: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(np.log(np.maximum(probabilities, _TINY)), dtype=DTYPE)


def start_update(
    saved: SpCoResult,
    house: House,
    settings: SpCoSettings | None = None,
    *,
    generator: torch.Generator | None = None,
    where: str = "the saved fit",
    method: str | None = None,
) -> UpdateStart:
    """Check ``house`` and ``settings`` against ``saved`` (:func:`check_compatible`), build the
    per-cell counts of all observations over the merged vocabulary, and the starting state.
    ``settings`` None: the saved fit's (a word weighting ``"auto"``: the saved fit's too,
    :func:`~spcopyro.data.word_weighting.keeping_word_weighting`, which refuses a saved
    ``"auto"``); ``generator`` None: new word columns at their mean; ``method``: the update's
    (its setting warnings, :func:`prepare_model_data`)."""
    asked = settings_of(saved) if settings is None else settings
    settings = keeping_word_weighting(saved.preparation.word_weighting, asked, where)
    check_compatible(saved, house, settings, where)
    saved, renormalised = renormalised_result(saved)  # its words as the tokenizer reads them
    _warn_renormalised(renormalised, where)
    merge = merge_vocabulary(saved.vocabulary, house.observations.vocabulary)
    counts, data = prepare_model_data(house, settings, vocabulary=merge.vocabulary, method=method)
    labels = torch.as_tensor(np.asarray(saved.labels), dtype=torch.long)  # [N]
    config = settings.model
    log_emissions = []
    for modality in data.modalities:
        table = saved.emission(modality.name).probabilities  # [L, K_m]
        if modality.name == WORDS:
            rows = labels[data.obs_cells]  # [M] concepts of the observed cells
            old_counts = modality.counts[:, : merge.old_size]  # [M, V]
            totals = torch.zeros(config.num_concepts, dtype=DTYPE)  # [L]
            totals.index_add_(0, rows, old_counts.sum(dim=1))
            table = extend_emission(
                table, totals.numpy(), config.beta, len(merge.new_words), generator
            )  # [L, V']
        log_emissions.append(_log(table))
    return UpdateStart(
        counts, data, settings, merge, labels, _log(np.asarray(saved.pi)), tuple(log_emissions)
    )


def start_update_chain(
    saved: SpCoResult,
    house: House,
    settings: SpCoSettings | None = None,
    *,
    options: GibbsOptions | None = None,
    seed: int = 0,
    where: str = "the saved fit",
) -> tuple[GibbsChain, UpdateStart]:
    """A Gibbs chain at sweep 0 of an update: the saved labels and the saved globals (words
    extended with draws), ready for :func:`~spcopyro.gibbs.run.advance`."""
    options = method_options(options, GibbsOptions, "Gibbs sampling")
    generator = torch.Generator().manual_seed(int(seed))
    start = start_update(saved, house, settings, generator=generator, where=where)
    chain = start_chain(
        start.data, start.settings.model, options=options, generator=generator,
        init_labels=start.labels,
    )  # fmt: skip
    chain.state = chain.state._replace(
        labels=start.labels.clone(), log_pi=start.log_pi, log_emissions=start.log_emissions
    )
    return chain, start


def fit_update(
    saved: SpCoResult,
    house: House,
    settings: SpCoSettings | None = None,
    *,
    method: str = DEFAULT_METHOD,
    options: object | None = None,
    sweeps: int = DEFAULT_UPDATE_SWEEPS,
    seeds: Sequence[int] = (0,),
    progress: bool | None = None,
    source: str | None = None,
    threads: int | str | None = AUTO,
    marginal_samples: int = 0,
    point_estimate: str = "map-visited",
    where: str | os.PathLike[str] = "the saved fit",
) -> list[SpCoResult]:
    """One :class:`SpCoResult` per seed: ``sweeps`` iterations of ``method`` on all of
    ``house``'s observations, starting from ``saved`` (see the module docstring).

    Args:
        saved: the fit to continue (``SpCoResult.load(OUT)``).
        house: the same house with the old and the new observations.
        settings: must equal the saved fit's (None: take them from it).
        where: the saved fit's folder, for messages and ``config.json``.
        Others (``marginal_samples``, ``point_estimate``, ...): as for
            :func:`spcopyro.fit.house.fit_house_chains`.

    Raises:
        FitInterrupted: Ctrl-C stopped the sweeps or iterations; its ``where`` says how far
            (e.g. ``"chain 1 of 2, 120 of 300 sweeps done"``), and nothing is kept.
    """
    if not is_integer(sweeps) or sweeps < 1:
        raise ValueError(f"sweeps must be a positive integer, got {sweeps!r}")
    if len(seeds) == 0:
        raise ValueError("seeds must name at least one chain")
    where = str(where)
    inference = get_method(method)
    thin = marginal_thin(int(sweeps), marginal_samples)
    results = []
    with torch_threads(resolve_threads(threads, house.grid.num_free)) as used:
        for k, seed in enumerate(seeds):
            try:
                if isinstance(inference, GibbsInference):
                    gibbs_options = method_options(options, GibbsOptions, "Gibbs sampling")
                    chain, start = start_update_chain(
                        saved, house, settings, options=gibbs_options, seed=int(seed),
                        where=where,
                    )  # fmt: skip
                    advance(chain, int(sweeps), thin=thin, progress=progress)
                    entry = gibbs_record(gibbs_options, int(sweeps), chain.backend.name)
                    output = output_from_run(chain.to_run(), entry)
                else:
                    generator = torch.Generator().manual_seed(int(seed))
                    start = start_update(saved, house, settings, where=where, method=method)
                    output = inference.run(
                        start.data, start.settings.model, iterations=int(sweeps),
                        generator=generator, init_labels=start.labels, options=options,
                        progress=progress, thin=thin,
                    )  # fmt: skip
            except DriveInterrupted as stop:  # said as every fit's interruption is: how far
                done, count = len(stop.trajectory.objective), f"{k + 1} of {len(seeds)}"
                where_stopped = (
                    f"chain {count}, {done} of {sweeps} sweeps done"
                    if isinstance(inference, GibbsInference)
                    else f"{method} fit {count}, "
                    + (stop.progress or f"{done} of {sweeps} iterations done")
                )
                raise FitInterrupted(where_stopped) from None
            if output.marginals is None:  # a sampler: its label frequencies; a variational
                area = house.grid.cell_area  # m^2 of a cell: the saved fit's (checked)
                output = gibbs_chains.with_sample_marginals(  # method's marginals: its q(C)
                    output, int(sweeps), start.data, start.settings, point_estimate,
                    cell_area=area,
                )  # fmt: skip
            merge = start.merge
            output.options.update(
                seed=int(seed), init=UPDATE_INIT,  # the fit's folder once: update_of.fit
                update_of=update_record(saved, (merge.new_words, merge.unheard_words), where,
                                        start.counts),
            )  # fmt: skip
            if saved.inference.get("refine"):  # a refined fit's update is one: updated again
                output.options["refine"] = saved.inference["refine"]  # as refined (config.json)
            record = {**provenance(house, start.data, source, start.counts), "threads": used}
            result = result_of(
                output, house, start.counts, start.data, start.settings, method, record
            )
            # the saved fit's numbers for the same places (a sampler renumbers concepts freely)
            perm = matching_permutation(saved.labels, result.labels, len(result.pi))  # [L]
            result.inference["update_of"]["renumbered"] = moved_numbers(perm)
            results.append(renumbered(result, perm))
    return results
