"""A study cell scored the way ``compare-inference`` scores a fit (``scoring = "comparison"``).

The inference comparison (issue #10, :mod:`spcopyro.experiments.inference_comparison`) runs an
inference method directly on the model's data and scores its label map *along the run* (kept
maps, or re-runs at smaller budgets), its effective sample size per second and the confidence
of its wrong cells. A cell of a study with ``scoring = "comparison"`` does exactly that
(:func:`~spcopyro.experiments.inference_comparison.fit_and_score`, after a 2-iteration warm-up
so no measured fit pays for numba's compilation), on the problem the comparison builds:

* a synthetic source: the house drawn with the cell's seed (no name), on the model's grid,
  scored against its truth;
* a public source: the house with the project's region truth (categories included) on the
  model's grid, trial ``seed mod trials`` held out, fitted with the fold's index as its seed.

The cell's record holds the final scores in the table's columns (``ari``, ``matching_rate``,
``top1``, ``top3``, ``mean_rank``, ``distance_m``, ``concepts``, ``iterations``, ``seconds``:
the inference's own time, ``cpu_seconds``: the process's CPU time over the measured run, every
thread's, so for a cell run in the study's own process while a Dask LocalCluster starts
(:func:`spcopyro.study.run._on_dask`) also the threads of the cluster's start and of its
scheduler, which run in that process; ``best_objective``: the log joint or ELBO of the state
reported, and ``objective``, which of them) and the whole comparison record (the curve, time to
95 %, ESS, over-confidence, top words) as JSON text in ``details``, from which
:mod:`spcopyro.study.comparison` draws ``comparison.md`` and its figures. Its label map is the
fit's final state on the map's cells (refined from the model's grid), with the map and the truth
it was scored against (:func:`spcopyro.study.maps.label_map_arrays`), stored as every cell's is
(``maps/KEY.npz``) so reports draw it. A degenerate final map (one concept over most of the
house) is warned of as ``fit_house`` warns
(:func:`spcopyro.results.map_checks.house_map_warning`), kept in the cell's record with its
other warnings; its advice is the comparison's (:data:`ADVICE`), not ``fit``'s options, which
``compare-inference`` does not take. Threads: as the comparison, the method runs with
:func:`spcopyro._util.threads.policy_threads` of the map.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path

from spcopyro.data import House, load_house
from spcopyro.data.model_grid import model_house
from spcopyro.experiments import inference_comparison as comparison
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES, heldout_folds, json_default
from spcopyro.results.map_checks import house_map_warning
from spcopyro.study.cells import Cell
from spcopyro.study.maps import Arrays, label_map_arrays, labels_on_map
from spcopyro.synthetic import make_house

__all__ = ["COMPARISON", "comparison_outcome", "comparison_variant", "problem_of"]

COMPARISON = "comparison"
"""The ``scoring`` of a study whose cells are scored as ``compare-inference`` scores a fit."""

ADVICE = (
    "(in a comparison, the method's map at these settings and budget, kept as it is: a lower "
    "--gamma of compare-inference may let its regions split)"
)
"""The closing advice of a comparison cell's degenerate-map warning: ``fit``'s (``--method gibbs
--merge-moves 0.2``, ``--preset``) named options ``compare-inference`` refuses."""

FINAL_SCORES = ("ari", "matching_rate", "top1", "top3", "mean_rank", "distance_m")


def comparison_variant(cell: Cell) -> comparison.Variant:
    """The comparison's line for the cell's variant: its method, its resolved options (every
    field, so nested ones count too) and the cell's budget."""
    variant = cell.variant
    assert variant is not None
    options = variant.method_options()
    fields = {f.name: getattr(options, f.name) for f in dataclasses.fields(options)}  # type: ignore[arg-type]
    known = comparison.VARIANTS.get(cell.row)
    label = known.label if known is not None else cell.row
    return comparison.Variant(cell.row, cell.method, label, cell.sweeps, cell.sweeps, fields)


def problem_of(cell: Cell) -> comparison.Problem:
    """The comparison's problem for the cell (module docstring)."""
    return _problem_and_map(cell)[0]


def _problem_and_map(cell: Cell) -> tuple[comparison.Problem, House]:
    """The comparison's problem for the cell (module docstring), and its house on the map's own
    cells with the truth the problem is scored against."""
    assert cell.variant is not None
    data = cell.data
    seed = cell.seed if data.house_seed is None else data.house_seed
    if data.kind == "synthetic":
        house = make_house(seed=seed, spec=data.house_spec())
        settings = cell.variant.spco_settings(len(house.category_names or ()) or None)
        on_model = model_house(house, settings.data.cell_size)
        return comparison.Problem(on_model, settings, cell.seed, name=f"seed {seed}"), house
    if data.kind != "public":
        raise ValueError(f"data source {data.name!r}: comparison scoring takes synthetic and "
                         f"public houses, not {data.kind}")  # fmt: skip
    house = load_house(data.target)
    truth = public_truth(house)  # scored on the project's region truth too
    house = dataclasses.replace(house, truth=truth.labels, category_names=truth.categories)
    # a finite prior's L: the house's categories in the paper's Table 2, as a study cell's
    # (spcopyro.study.sources); it was 6 for every public house
    settings = cell.variant.spco_settings(PUBLIC_CATEGORIES.get(Path(data.target).name))
    folds = list(heldout_folds(model_house(house, settings.data.cell_size)))
    fold, held, train, test = folds[cell.seed % len(folds)]
    name = f"{data.name} (held-out trial {held})"
    return comparison.Problem(train, settings, fold, test, name), house


def comparison_outcome(cell: Cell) -> tuple[dict[str, object], Arrays]:
    """Fit and score the cell as the comparison does: its record's columns (module docstring)
    and its label map (:func:`spcopyro.study.maps.label_map_arrays`)."""
    variant = comparison_variant(cell)
    if cell.variant is not None and cell.variant.fit:
        raise ValueError(f"variant {cell.row!r}: comparison scoring runs the method directly; "
                         f"it takes no fit_house arguments ({dict(cell.variant.fit)})")  # fmt: skip
    problem, house = _problem_and_map(cell)
    comparison.warm_up(variant, problem)
    record, result = comparison.fit_and_score_with_result(variant, problem, cell.sweeps)
    # a one-concept map warns as fit_house's does (the study keeps it in the cell's record):
    # comparison.md listed the flat-q warnings but not the collapse of most public maps. Its
    # advice is the comparison's: fit's "--method gibbs --merge-moves 0.2" is no option here
    snap = result.preparation.snap_distance
    warning = house_map_warning(result.labels, problem.house, snap, advice=ADVICE)
    if warning:
        logging.getLogger("spcopyro").warning(warning)
    final = record["final"]
    scores: dict[str, object] = {s: final[s] for s in FINAL_SCORES if s in final}  # type: ignore[index]
    scores.update(
        concepts=record["concepts"], iterations=record["iterations"], seconds=record["seconds"],
        cpu_seconds=record["cpu_seconds"], best_objective=result.best_objective,
        objective=result.trace.objective_name,
        details=json.dumps(record, default=json_default),
    )  # fmt: skip
    labels = labels_on_map(result, house, problem.settings)  # [H, W]
    return scores, label_map_arrays(labels, house, house.truth)
