"""One cell of a study: load its data, fit, score. This is the task a worker runs.

:func:`run_cell` never raises for a failing fit: the error's type and message go into the
record (``status = "error"``) and the study goes on. Only KeyboardInterrupt (and SystemExit)
pass through, so Ctrl-C stops the study.

Scores (every one that applies; the others are left empty in the table, :data:`SCORES`):

* ``ari``: adjusted Rand index of the map against the truth -- a synthetic house's, a simulated
  tour's, or a public house's region truth (:mod:`spcopyro.experiments.public_truth`); a fit on a
  coarser model grid is refined back to the map's cells first
  (:func:`spcopyro.maps.coarse.refine_labels`);
* ``matching_rate``: place estimation from the category names (synthetic houses and tours),
  on the model's grid; ``matching_rate_area``: the same with the area prior instead of pi
  (variants);
* ``top1``, ``top3``, ``mean_rank``, ``distance_m``, ``inside_rate``: held-out word prediction
  and localisation when the source holds a trial out, with the words scored
  (``scored_words``), the held-out tokens the map has never heard (``unknown_tokens``) and the
  words whose region is empty (``empty_regions``) and the mean share of the free cells in the
  regions the words name (``region_share``: a ``distance_m`` of 0 with a share of 1 is a map of
  one region, not a good localisation);
* ``concepts`` (in use), ``concepts_1pct`` (holding >= 1 % of the free cells),
  ``largest_share`` (the largest concept's share of the free cells), ``free_cells``;
* ``top_words`` (JSON text: the top 3 words of the 3 largest concepts holding an utterance)
  and ``place_top_share`` (the share of those whose top word is a place word), variants;
  a fit that did not model its words (``use_words`` off) lists none, as ``fit`` lists none
  (:func:`~spcopyro.results.concept_words.words_modelled`), and its share is nan;
* with the study's ``observations_off``, a variant is fitted again with
  ``use_images = use_words = False`` (same seed): ``ari_off`` (against the truth),
  ``ari_on_off`` (between the two maps), ``concepts_1pct_off``, ``seconds_off`` and
  ``cpu_seconds_off``;
* ``warnings``: the distinct warnings the cell gave (JSON text; empty when none):
  :mod:`spcopyro.study.cell_warnings`;
* ``source_digest``: :func:`spcopyro.study.cells.source_digest` of the process that ran the
  cell, the code that made its numbers;
* ``seconds`` (wall clock) and ``cpu_seconds`` of the fit, ``iterations``,
  ``best_objective`` (the reported state's log joint or ELBO: the best of K chains is the
  chain where it is highest) and ``objective``, which of them it is (``log joint``, ``ELBO``,
  ``Bethe ELBO``: a sampler's log joint and a variational ELBO are not on one scale);
* on a synthetic house with sentences (``sentence_fraction`` > 0: sentences as in the
  paper's Section 5, not its Table 5 setting): ``concept_words`` (JSON text: the top 3 words
  of each concept labelling at least :data:`SENTENCE_MIN_CELLS` cells, as ``fit`` lists them,
  :func:`~spcopyro.results.concept_words.listed_top_words`: none for a concept where no word
  was heard or where the fit did not model its words) and ``filler_top_share`` (the share of
  the concepts listing words whose top word is a filler,
  :data:`spcopyro.synthetic.FILLER_WORDS`; nan where none lists words);
* the trace (objective, concepts in use and seconds per iteration; with the study's
  ``ari_every``, also ``ari`` against the truth at ``ari_iterations``, paper Fig. 5), returned
  beside the record and saved by the caller as ``traces/KEY.npz``;
* the cell's label map on the map's cells with the map itself
  (:func:`~spcopyro.study.maps.label_map_arrays`: int16 labels, int8 occupancy, resolution,
  origin and the truth when there is one; comparison cells too), returned beside
  the record and saved by the caller as ``maps/KEY.npz``: the report's per-house maps are drawn
  from it, with no refit;
* ``hyperparameters`` (JSON text): with a variant's ``hyper.*`` (the Gibbs chain samples
  alpha, gamma or the concentrations), each sampled one's initial, final and posterior mean
  and sd (:func:`spcopyro.gibbs.hyperparameters.hyperparameter_summary`);
* ``details``: a study with ``scoring = "comparison"`` scores its cells as ``compare-inference``
  does (:mod:`spcopyro.study.comparison_cell`): the final scores in the columns above, the
  comparison's whole record (curve, time to 95 %, ESS, over-confidence) as JSON text here.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import time
from collections.abc import Callable

import numpy as np

from spcopyro._util.interrupts import caused_by_interrupt
from spcopyro._util.threads import torch_threads
from spcopyro.config import DEFAULT_PRESET, SpCoSettings
from spcopyro.data.model_grid import model_house
from spcopyro.experiments.ablation import concepts_over, largest_share, top_words
from spcopyro.experiments.methods import (
    METHOD_LABELS,
    SPCO_METHODS,
    RunSettings,
    fit_method,
    fit_spco,
    spco_settings,
)
from spcopyro.fit.house import fit_house
from spcopyro.metrics import (
    SpCoSemanticMap,
    adjusted_rand_index,
    heldout_localisation,
    heldout_word_prediction,
    matching_rate,
)
from spcopyro.results.concept_words import listed_top_words
from spcopyro.results.map_checks import degenerate_map_advice
from spcopyro.study.cell_warnings import captured_warnings, warnings_text
from spcopyro.study.cells import Cell, source_digest
from spcopyro.study.comparison_cell import COMPARISON, comparison_outcome
from spcopyro.study.maps import Arrays, label_map_arrays, labels_on_map
from spcopyro.study.sources import CellData, load_cell_data
from spcopyro.synthetic import FILLER_WORDS

__all__ = [
    "SCORES", "STATUS_COLUMNS", "WARNINGS", "Arrays", "advice", "label_map_arrays", "row_advice",
    "run_cell",
]  # fmt: skip

SCORES = (
    "ari", "matching_rate", "matching_rate_area", "top1", "top3", "mean_rank", "distance_m",
    "inside_rate", "region_share", "scored_words", "unknown_tokens", "empty_regions", "concepts",
    "concepts_1pct", "largest_share", "free_cells", "held_out_trial", "place_top_share",
    "top_words", "ari_off", "ari_on_off", "concepts_1pct_off", "seconds", "cpu_seconds",
    "seconds_off", "cpu_seconds_off", "iterations", "best_objective", "objective",
    "filler_top_share", "concept_words", "hyperparameters", "details",
)  # fmt: skip
"""The score columns of the table, in order."""
STATUS_COLUMNS = ("status", "error_type", "error")
"""``ok`` or ``error``, and the error's type and message."""
WARNINGS = "warnings"
"""The column of the cell's warnings: JSON text of the distinct messages, empty when none
(:func:`spcopyro.study.cell_warnings.warnings_text`)."""
SENTENCE_MIN_CELLS = 50
"""A concept counts in ``filler_top_share`` when it labels at least this many cells."""


def advice(sampled: bool) -> str:
    """The closing advice of a study cell's degenerate-map warning, in the study file's terms
    (a variant's keys), not ``fit``'s options (``--merge-moves 0.2``, ``--preset``) or
    ``GibbsOptions``, which a study does not take; ``sampled``: the cell's method samples
    (``gibbs``, ``vi-gibbs``) (:func:`spcopyro.results.map_checks.degenerate_map_advice`)."""
    return f"(in the study's variant: try {_remedies(sampled)} if the variant used another)"


def _remedies(sampled: bool) -> str:
    """The settings that may let a degenerate map's regions split, in a variant's keys: the
    remedies of :func:`advice` and :func:`row_advice`."""
    moves = "merge_moves = 0.2" if sampled else 'method = "gibbs" with merge_moves = 0.2'
    return f'a lower gamma, {moves} so that regions can split, or preset = "{DEFAULT_PRESET}"'


def row_advice(row: str) -> Callable[[bool], str]:
    """The closing advice of a degenerate-map warning of the comparison's SpCoMapping row
    ``row`` (``A-dp``, ``A-orig-g3``, ``B-dirichlet`` of :mod:`spcopyro.experiments.methods`, a
    variant named by its row's key with the row's settings in ``spcopyro experiment``'s study,
    :mod:`spcopyro.study.experiment`; :func:`_cell_advice`): its settings are the row's,
    fixed, so the advice names them and says that a study with a variant of other settings can
    be run beside it, not :func:`advice`'s "in the study's variant"."""
    label = METHOD_LABELS.get(row, "").split(") ", 1)[-1]  # without its "(A') " mark
    named = f"{row}, {label}," if label else row

    def said(sampled: bool) -> str:
        return (
            f"(the comparison's row {named} has fixed settings; a study with a variant of "
            f"other settings -- {_remedies(sampled)} -- can be run beside it)"
        )

    return said


def run_cell(cell: Cell) -> tuple[dict[str, object], Arrays | None, Arrays | None]:
    """The cell's record (status and scores, keyed by ``cell.key``), its trace (None for a
    baseline, a failed or a comparison cell) and its label map
    (:func:`~spcopyro.study.maps.label_map_arrays`; None for a failed cell). Runs torch with
    one intra-op thread. The warnings the cell gives (logger ``spcopyro``, :mod:`warnings`) are
    kept in the record's ``warnings`` (:mod:`spcopyro.study.cell_warnings`), not printed."""
    record: dict[str, object] = {"key": cell.key, "status": "ok", "error_type": "", "error": "",
                                 "source_digest": source_digest()}  # fmt: skip
    trace = label_map = None
    with captured_warnings() as said:  # kept in the record, not printed (cell_warnings)
        try:
            with torch_threads(1):
                if cell.scoring == COMPARISON:
                    scores, label_map = comparison_outcome(cell)
                else:
                    scores, trace, label_map = _fit_and_score(cell)
            record.update(scores)
        except Exception as error:  # recorded; the study goes on
            if caused_by_interrupt(error):  # Ctrl-C inside a numba call: not the cell's failure
                raise KeyboardInterrupt("interrupted inside compiled code") from error
            record.update(status="error", error_type=type(error).__name__,
                          error=str(error)[:2000])  # fmt: skip
            trace = label_map = None
    record[WARNINGS] = warnings_text(said)
    return record, trace, label_map


def _fit_and_score(cell: Cell) -> tuple[dict[str, object], Arrays | None, Arrays]:
    """:func:`_scored`: a variant cell's within its degenerate-map advice (:func:`_cell_advice`:
    its fit's and its observations-off fit's warnings, in the study file's terms)."""
    loaded = load_cell_data(cell.data, cell.seed)
    variant, categories = cell.variant, loaded.num_categories
    settings = None if variant is None else variant.spco_settings(categories)  # None: baseline
    within = (contextlib.nullcontext() if settings is None  # a row of experiments.methods
              else degenerate_map_advice(_cell_advice(cell, settings, categories)))  # fmt: skip
    with within:
        return _scored(cell, loaded, settings)


def _scored(
    cell: Cell, loaded: CellData, settings: SpCoSettings | None
) -> tuple[dict[str, object], Arrays | None, Arrays]:
    """The cell's scores, trace and label map (:func:`run_cell`); ``settings``: a variant's
    (None: a baseline row's cell, fitted by ``spcopyro.experiments.methods.fit_method``)."""
    house = loaded.house
    start, cpu = time.perf_counter(), time.process_time()
    result = None
    if settings is None:  # a baseline row of spcopyro.experiments.methods
        fitted = fit_method(
            cell.row, house, RunSettings(sweeps=cell.sweeps, spcoa_iterations=cell.spcoa_iterations,
                                         trace_every=0),
            seed=cell.seed, num_categories=loaded.num_categories, public=cell.data.kind == "public",
        )  # fmt: skip
        model, labels, scored_house = fitted.model, fitted.model.label_image(), house
    else:
        result, ari_trace = _fit(cell, house, settings, loaded.truth)
        model = SpCoSemanticMap(result)
        labels = labels_on_map(result, house, settings)
        scored_house = model_house(loaded.full, settings.data.cell_size)  # the model's grid
    scores: dict[str, object] = {
        "seconds": time.perf_counter() - start,
        "cpu_seconds": time.process_time() - cpu,
    }
    scores.update(_map_scores(labels, house.grid.free, loaded.truth))
    if loaded.categories and scored_house.truth is not None:
        scores["matching_rate"] = matching_rate(model, scored_house.truth, loaded.categories).value
        if result is not None:
            area = SpCoSemanticMap(result, prior="area")
            scores["matching_rate_area"] = matching_rate(
                area, scored_house.truth, loaded.categories
            ).value
    if result is not None:
        scores["best_objective"] = float(result.best_objective)
        scores["objective"] = result.trace.objective_name  # which one best_objective is
        sampled = result.inference.get("hyperparameters")
        if sampled:  # a variant's hyper.*: where the chain took them
            scores["hyperparameters"] = json.dumps(sampled)
        if cell.data.kind == "synthetic" and cell.data.house_spec().sentence_fraction > 0:
            scores.update(_sentence_scores(result))
        words, scores["place_top_share"] = top_words(
            result, model_house(house, settings.data.cell_size)
        )
        scores["top_words"] = json.dumps(words)
        if cell.observations_off:
            scores.update(_observations_off(cell, loaded, labels))
    if loaded.test is not None:
        words = heldout_word_prediction(model, loaded.test)
        places = heldout_localisation(model, loaded.test)
        scores.update(top1=words.top1, top3=words.top3, mean_rank=words.mean_rank,
                      distance_m=places.mean_distance, inside_rate=places.inside_rate,
                      scored_words=words.num_scored, unknown_tokens=words.unknown_tokens,
                      empty_regions=places.empty_regions,
                      region_share=places.mean_region_share,
                      held_out_trial=loaded.held_out_trial)  # fmt: skip
    label_map = label_map_arrays(labels, house, loaded.truth)
    if result is None:
        return scores, None, label_map
    trace = result.trace
    scores["concepts"] = len(result.concepts_in_use())
    scores["iterations"] = len(trace.objective)
    arrays = {
        name: np.asarray(getattr(trace, name)) for name in ("objective", "num_concepts", "seconds")
    }
    if ari_trace is not None:
        arrays["ari_iterations"], arrays["ari"] = ari_trace
    return scores, arrays, label_map


def _cell_advice(
    cell: Cell, settings: SpCoSettings, num_categories: int | None
) -> Callable[[bool], str]:
    """The closing advice of a variant cell's degenerate-map warning, in the study file's terms:
    :func:`row_advice` when the variant is a comparison row as the row fits it (named by the
    row's key, ``settings`` equal to the row's, no options or fit keywords of its own), else
    :func:`advice` -- a variant named ``A-dp`` in a user's copy of experiment.toml that changed
    its gamma has settings of its own to change."""
    variant = cell.variant
    assert variant is not None
    if cell.row not in SPCO_METHODS or variant.options or variant.fit:
        return advice
    try:
        row = spco_settings(cell.row, num_categories)
    except ValueError:  # B-dirichlet without the house's number of categories: not the row
        return advice
    return row_advice(cell.row) if settings == row else advice  # equality ignores ``chosen``


def _fit(cell: Cell, house, settings, truth: np.ndarray | None = None):
    """The variant's fit of ``house`` with ``settings``, and (iterations, ARI against
    ``truth``) every ``cell.ari_every`` iterations when asked and a truth is known (else
    None). Such a fit runs the method from random labels (:func:`fit_spco`: the same labels as
    ``fit_house``'s, checked in tests/test_experiments.py) on a variant without fit keywords
    or a coarser model grid (:func:`spcopyro.study.spec.study_from_dict` checks that), and
    its map is checked as ``fit_house`` checks every other cell's (``fit_spco`` runs
    :func:`~spcopyro.fit.house.log_degenerate_map`, with the study's advice from
    :func:`_fit_and_score`: the same house, as no model grid differs from the map's)."""
    variant = cell.variant
    assert variant is not None
    if cell.ari_every and truth is not None:
        house = dataclasses.replace(house, truth=truth)
        result, trace = fit_spco(
            house, settings, sweeps=cell.sweeps, seed=cell.seed, thin=cell.ari_every,
            method=cell.method, options=variant.method_options(), threads=1,
        )  # fmt: skip
        return result, trace
    result = fit_house(
        house, settings, method=cell.method, options=variant.method_options(),
        sweeps=cell.sweeps, seed=cell.seed, progress=False, threads=1, **variant.fit_kwargs(),
    )  # fmt: skip
    return result, None


def _observations_off(cell: Cell, loaded, labels: np.ndarray) -> dict[str, object]:
    """The same fit with images and words off: what the map is from the MRF alone, and how
    much the data moved it (``labels`` ``[H, W]``: the fit's map on the map's cells)."""
    assert cell.variant is not None
    house = loaded.house
    settings = cell.variant.spco_settings(loaded.num_categories, use_images=False, use_words=False)
    start, cpu = time.perf_counter(), time.process_time()
    off = labels_on_map(_fit(cell, house, settings)[0], house, settings)
    scores: dict[str, object] = {
        "seconds_off": time.perf_counter() - start,
        "cpu_seconds_off": time.process_time() - cpu,
        "ari_on_off": adjusted_rand_index(labels, off),
        "concepts_1pct_off": concepts_over(off[house.grid.free]),
    }
    if loaded.truth is not None:
        scores["ari_off"] = adjusted_rand_index(off, loaded.truth)
    return scores


def _sentence_scores(result) -> dict[str, object]:
    """``filler_top_share`` and ``concept_words`` of a fit (module docstring)."""
    sizes = np.bincount(result.labels, minlength=result.config.num_concepts)
    concepts = [int(c) for c in result.concepts_in_use() if sizes[c] >= SENTENCE_MIN_CELLS]
    words = [[w for w, _ in listed_top_words(result, c, 3)] for c in concepts]
    listed = [ws for ws in words if ws]  # as fit lists them: none unheard or not modelled
    share = float(np.mean([ws[0] in FILLER_WORDS for ws in listed])) if listed else float("nan")
    return {"filler_top_share": share, "concept_words": json.dumps(words)}


def _map_scores(labels: np.ndarray, free: np.ndarray, truth: np.ndarray | None) -> dict:
    """Scores of an ``[H, W]`` label map on the map's cells (``free`` ``[H, W]``)."""
    on_free = labels[free]  # [N]
    scores: dict[str, object] = {
        "free_cells": int(free.sum()),
        "concepts_1pct": concepts_over(on_free),
        "largest_share": largest_share(on_free),
    }
    if truth is not None:
        scores["ari"] = adjusted_rand_index(labels, truth)
    return scores
