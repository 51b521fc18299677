r"""Gibbs sampling against variational inference: quality against wall-clock time
(``spcopyro compare-inference``, issue #10's comparison; run as a study by
:func:`spcopyro.study.comparison.run_comparison`, each fit a cell scored by
:func:`fit_and_score`, written by :mod:`spcopyro.experiments.comparison_report`).

Every *variant* (:data:`VARIANTS`) is an inference method of :mod:`spcopyro.fit.registry` with its
options changed from the method's defaults (``gibbs-sw`` is ``gibbs`` with Swendsen-Wang moves)
and an iteration budget. A variant whose method the registry does not hold is skipped with a
message, so the command runs with whatever methods are installed; a name that is no variant is
an error.

Each variant fits SpCoMapping (one preset, by default the released code's values with gamma 3,
the ``A-orig-g3`` row of ``spcopyro experiment``) from random labels

* on the synthetic houses (:func:`spcopyro.synthetic.make_house`, seeds 0..n-1, method seed =
  house seed), scored against the truth: ARI and matching rate (eq. 18);
* on the public houses, one fit per held-out trial (:func:`~.table.heldout_folds`), scored on
  the held-out trial: word prediction top-1 / top-3 / mean rank and localisation distance.

**Quality along the run** is the quality of the label map a method holds at time t, scored
with the global parameters that map implies (the posterior means of pi and phi given the labels:
the Dirichlet updates of eqs. 14-17, :func:`~spcopyro.guides.factors.update_factors` of
one-hot labels), the same way for every method. A method that keeps label maps (``thin`` > 0;
Gibbs) is scored at its kept maps, at the times :attr:`~spcopyro.inference.protocol.Trace.seconds`
records for them; a method that keeps none is re-run from the same seed at budgets n/2, n/4, ...
and its labels scored at each budget's wall-clock time. The last point is the method's final
labels (Gibbs: the MAP-visited state) at the run's full time. From the curve: the time to reach
95% of that final quality (:func:`~.comparison_stats.time_to_fraction`).

**Final quality** is given twice: of the method's result (its labels with its pi and phi: a
variational method's posterior means under q; a sampler's drawn pi and phi are replaced by the
means given its labels in :func:`~spcopyro.fit.house.result_of`, so for a sampler the two agree)
and of its labels with the means given them (``final_given_labels``, the curve's last point). Scores
that read the parameters (matching rate through eq. 19, held-out word prediction) can differ a
lot between E_q and the means given the labels; ARI cannot.

**Samplers** (objective "log joint" and kept label maps): the effective sample size per second of
the log joint (every sweep) and of the Potts agreement count (the kept maps), both over the
second half of the run (:mod:`~spcopyro.experiments.comparison_stats`).

**Where each method is sure and wrong** (synthetic): a cell is wrong when its concept's majority
category is not its own (:func:`~.comparison_stats.wrong_cells`); a variational method's
confidence is q(C_i = label), a sampler's the share of its kept maps (second half) agreeing with
its last state. Over-confident regions show as wrong cells labelled with confidence >= 0.99.

Times are wall-clock on whatever machine runs it, of the inference alone (data preparation and
scoring excluded).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from spcopyro._util.threads import AUTO, resolve_threads, torch_threads
from spcopyro.config import SpCoSettings
from spcopyro.data import House, Observations
from spcopyro.experiments import comparison_stats as stats
from spcopyro.fit.house import prepare_model_data, result_of
from spcopyro.fit.registry import INFERENCE_METHODS
from spcopyro.guides.factors import mean_emissions, mean_pi, update_factors
from spcopyro.inference.protocol import InferenceOutput, Trace
from spcopyro.inference.schedule import short_runs_meant
from spcopyro.likelihood import concept_statistics
from spcopyro.metrics import (
    SpCoSemanticMap,
    adjusted_rand_index,
    heldout_localisation,
    heldout_word_prediction,
    matching_rate,
)
from spcopyro.model import ModelData
from spcopyro.results.concept_words import listed_top_words, words_modelled
from spcopyro.results.result import SpCoResult
from spcopyro.synthetic import HouseSpec


@dataclass(frozen=True)
class Variant:
    """One line of the comparison: a registry method, option changes and a budget."""

    key: str
    method: str
    """The method's name in :data:`spcopyro.fit.registry.INFERENCE_METHODS`."""
    label: str
    iterations: int
    """Iterations of a full run (Gibbs sweeps, variational updates, SVI steps)."""
    quick_iterations: int
    options: dict[str, object] = field(default_factory=dict)
    """Changes to the method's ``default_options()`` (a dataclass)."""
    quick_options: dict[str, object] = field(default_factory=dict)
    """Further changes for ``--quick`` (an annealing that its quick budget covers)."""

    def options_for(self, quick: bool) -> dict[str, object]:
        """:attr:`options`, with :attr:`quick_options` over them for a quick run."""
        return {**self.options, **self.quick_options} if quick else dict(self.options)


VARIANTS: dict[str, Variant] = {
    v.key: v
    for v in (
        Variant("gibbs", "gibbs", "Gibbs (Algorithm 1)", 5000, 60),
        Variant(
            "gibbs-sw",
            "gibbs",
            "Gibbs + Swendsen-Wang (10% of sweeps)",
            5000,
            60,
            {"cluster_moves": 0.1},
        ),  # fmt: skip
        Variant(
            "cavi",
            "cavi",
            "CAVI (mean field; gamma annealed over 20 it.)",
            100,
            20,
            {"anneal_iterations": 20, "tolerance": 1e-6},
        ),  # fmt: skip
        Variant("lbp", "lbp", "loopy BP (Bethe)", 100, 8),
        Variant(
            "svi", "svi", "SVI (Pyro guide)", 2000, 20, {}, {"anneal_iterations": 10}
        ),  # fmt: skip
        Variant(
            "stochastic-vi",
            "stochastic-vi",
            "memoized VI (spatial tiles; gamma annealed over 10 passes)",
            100,
            10,
            {"anneal_passes": 10},
        ),  # fmt: skip
        Variant("vi-gibbs", "vi-gibbs", "VI then Gibbs", 5000, 60),
    )
}
"""The comparison's lines, in table order (issue #10: Gibbs, Gibbs with Swendsen-Wang moves,
CAVI, LBP, SVI and VI-then-Gibbs, plus stochastic VI)."""

SYNTHETIC = "synthetic"
PUBLIC = "public"
HOUSE_TYPES = (SYNTHETIC, PUBLIC)
PRIMARY = {SYNTHETIC: "ari", PUBLIC: "top1"}
"""The quality whose time-to-95% the table shows first, per house type."""
SCORES = {SYNTHETIC: ("ari", "matching_rate"), PUBLIC: ("top1", "distance_m")}
"""The qualities along the run, per house type (also the figure's panels)."""
LOWER_IS_BETTER = frozenset({"distance_m", "mean_rank"})
QUICK_SPEC = HouseSpec.scaled(30, 40, num_rooms=2)
"""The tiny synthetic house of ``--quick``."""
CURVE_POINTS = 20
"""Most points scored along one run (kept maps, log-spaced)."""
RERUN_POINTS = 7
"""Budgets of a method without kept maps: n, n/2, ..., n/64."""
SAMPLES_PER_RUN = 200
"""A sampler keeps about this many label maps (thin = iterations // this)."""


@dataclass(frozen=True)
class ComparisonSettings:
    """What :func:`run_comparison` runs."""

    variants: tuple[str, ...] = tuple(VARIANTS)
    seeds: int = 5
    house_types: tuple[str, ...] = HOUSE_TYPES
    dataset_root: Path | None = None
    public_houses: tuple[str, ...] | None = None
    """None: every house of the dataset."""
    folds: int | None = None
    """Held-out folds per public house (None: one per trial)."""
    synthetic_spec: HouseSpec | None = None
    preset: str = "original-code"
    overrides: dict[str, object] = field(default_factory=lambda: {"gamma": 3.0})
    iterations: dict[str, int] = field(default_factory=dict)
    """Per variant key, a budget replacing the variant's own."""
    quick: bool = False
    command: str = ""


def check_variants(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` in table order (ValueError naming the known variants for an unknown one)."""
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        raise ValueError(
            f"unknown method(s) {unknown} for the inference comparison; choose from "
            f"{list(VARIANTS)}"
        )
    return tuple(key for key in VARIANTS if key in names)


def available_variants(
    names: Sequence[str], report: Callable[[str], None]
) -> tuple[list[str], list[str]]:
    """(the variants whose method the registry holds, messages for those skipped)."""
    kept, skipped = [], []
    for key in check_variants(names):
        method = VARIANTS[key].method
        if method in INFERENCE_METHODS:
            kept.append(key)
        else:
            message = (
                f"skipped {key}: inference method {method!r} is not in the registry "
                f"(known: {sorted(INFERENCE_METHODS)})"
            )
            report(message)
            skipped.append(message)
    return kept, skipped


def variant_options(variant: Variant) -> object:
    """The variant's options: its method's defaults with :attr:`Variant.options` changed."""
    defaults = INFERENCE_METHODS[variant.method].default_options()
    if not variant.options:
        return defaults
    if not dataclasses.is_dataclass(defaults):
        raise TypeError(f"{variant.method}'s options are not a dataclass; cannot change them")
    return dataclasses.replace(defaults, **variant.options)  # type: ignore[type-var]


def budget(variant: Variant, settings: ComparisonSettings) -> int:
    if variant.key in settings.iterations:
        return int(settings.iterations[variant.key])
    return variant.quick_iterations if settings.quick else variant.iterations


# -- one fit and its curve -----------------------------------------------------------------------


@dataclass(frozen=True)
class Problem:
    """One house to fit and how to score a fit of it."""

    house: House
    settings: SpCoSettings
    seed: int
    test: Observations | None = None
    """The held-out trial (public houses); None: scored against ``house.truth``."""
    name: str = ""


def _scores(result: SpCoResult, problem: Problem, final: bool) -> dict[str, float]:
    house = problem.house
    if problem.test is None:
        assert house.truth is not None and house.category_names is not None
        return {
            "ari": adjusted_rand_index(result.label_image(), house.truth),
            "matching_rate": matching_rate(result, house.truth, house.category_names).value,
        }
    model = SpCoSemanticMap(result)
    words = heldout_word_prediction(model, problem.test)
    scores = {"top1": words.top1}
    if house.truth is not None:  # the public houses' region truth (public_truth)
        scores["ari"] = adjusted_rand_index(result.label_image(), house.truth)
    if final:
        scores |= {"top3": words.top3, "mean_rank": words.mean_rank}
        scores["scored_words"] = float(words.num_scored)  # held-out tokens the model knows
    scores["distance_m"] = heldout_localisation(model, problem.test).mean_distance
    return scores


def _output_of_labels(labels: np.ndarray, data: ModelData, config) -> InferenceOutput:
    """An output holding ``labels`` ``[N]`` and the posterior means of the globals given them."""
    tensor = torch.as_tensor(np.asarray(labels, dtype=np.int64))  # [N]
    factors = update_factors(concept_statistics(tensor, data, config), data, config)
    empty = np.zeros(1)
    return InferenceOutput(
        labels=tensor.numpy(),
        pi=mean_pi(factors).numpy(),
        emissions=tuple(e.numpy() for e in mean_emissions(factors)),
        trace=Trace(empty, np.zeros(1, dtype=np.int64), empty),
        best_iteration=0,
    )


def fit_and_score(variant: Variant, problem: Problem, iterations: int) -> dict[str, object]:
    """Fit ``variant`` to the problem and score it along the run (see the module docstring)."""
    return fit_and_score_with_result(variant, problem, iterations)[0]


def fit_and_score_with_result(
    variant: Variant, problem: Problem, iterations: int
) -> tuple[dict[str, object], SpCoResult]:
    """:func:`fit_and_score`'s record, and the fit's final result (the state its final scores
    are of: a study keeps its label map)."""
    method = INFERENCE_METHODS[variant.method]
    options = variant_options(variant)
    counts, data = prepare_model_data(problem.house, problem.settings, method=variant.method)
    config = problem.settings.model
    threads = resolve_threads(AUTO, problem.house.grid.num_free)

    def run(budget: int, thin: int) -> InferenceOutput:
        generator = torch.Generator().manual_seed(int(problem.seed))
        with torch_threads(threads):
            return method.run(
                data, config, iterations=budget, generator=generator, options=options,
                progress=False, thin=thin,
            )  # fmt: skip

    def result(output: InferenceOutput) -> SpCoResult:
        return result_of(output, problem.house, counts, data, problem.settings, variant.method)

    thin = max(1, iterations // SAMPLES_PER_RUN)
    start, cpu = time.perf_counter(), time.process_time()
    output = run(iterations, thin)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu  # CPU: every thread's
    final_result = result(output)
    final = _scores(final_result, problem, final=True)
    # the same labels with the globals' posterior means given them: separates the label map's
    # quality from the kind of parameter estimate (a sampler hands back drawn pi and phi)
    given_labels = _scores(result(_output_of_labels(output.labels, data, config)), problem, True)
    total = float(output.trace.seconds[-1])
    curve: list[dict[str, float]] = []
    if output.label_samples is not None and len(output.label_samples):
        samples, at = output.label_samples, np.asarray(output.sample_iterations)
        for k in stats.geometric_indices(len(samples), CURVE_POINTS):
            point = _scores(result(_output_of_labels(samples[k], data, config)), problem, False)
            point |= {"seconds": float(output.trace.seconds[at[k]]), "iteration": int(at[k]) + 1}
            curve.append(point)
        curve_kind = "kept label maps"
    else:
        for b in stats.geometric_budgets(iterations, RERUN_POINTS)[:-1]:
            with short_runs_meant():  # the curve's early points: shorter than any annealing
                rerun = run(b, 0)
            point = _scores(result(_output_of_labels(rerun.labels, data, config)), problem, False)
            point |= {"seconds": float(rerun.trace.seconds[-1]), "iteration": b}
            curve.append(point)
        curve_kind = "re-runs at geometric budgets"
    house_type = SYNTHETIC if problem.test is None else PUBLIC
    last = {s: given_labels[s] for s in SCORES[house_type]}
    curve.append(last | {"seconds": total, "iteration": len(output.trace.seconds)})
    times = np.array([p["seconds"] for p in curve])
    record: dict[str, object] = {
        "variant": variant.key,
        "house": problem.name,
        "seed": problem.seed,
        "iterations": len(output.trace.seconds),
        "seconds": total,
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "final": final,
        "final_given_labels": given_labels,
        "curve": curve,
        "curve_kind": curve_kind,
        "time_to_95": {
            s: stats.time_to_fraction(
                times,
                np.array([p[s] for p in curve]),
                given_labels[s],
                higher_is_better=s not in LOWER_IS_BETTER,
            )  # fmt: skip
            for s in SCORES[house_type]
        },
        "concepts": len(final_result.concepts_in_use()),
        "top_words": [_top_words(final_result, int(c)) for c in final_result.concepts_in_use()[:8]],
        "objective": output.trace.objective_name,
    }
    if not words_modelled(final_result):  # use_words off: its top_words list none
        record["words_modelled"] = False
    if "vi_iterations_run" in output.options:  # vi-gibbs: the CAVI start before its sweeps
        record["start_iterations"] = int(output.options["vi_iterations_run"])  # type: ignore[call-overload]
    if output.trace.objective_name == "log joint" and output.label_samples is not None:
        kept_seconds = output.trace.seconds[np.asarray(output.sample_iterations)]
        agreements = stats.agreement_counts(output.label_samples, data.pairs)
        record["ess_per_second"] = {
            "log_joint": stats.ess_per_second(output.trace.objective, output.trace.seconds),
            "agreement": stats.ess_per_second(agreements, kept_seconds),
        }
    if problem.test is None:
        record["truth_categories"] = len(problem.house.category_names or ())
        confidence = _confidence(output)
        if confidence is not None:
            truth = problem.house.truth[problem.house.grid.free]  # [N]
            labels = np.asarray(output.labels if output.marginals is not None
                                else output.labels_final)  # fmt: skip
            inside = truth >= 0
            wrong = stats.wrong_cells(labels[inside], truth[inside])
            record["overconfidence"] = stats.overconfidence(confidence[inside], wrong)
    return record, final_result


HEARD_NOTHING = ""
"""A listed concept's entry in a record's ``top_words`` when no word was heard in its region (no
words, as ``"kitchen/sink"`` joins two): its w is the prior's, whose top words are a tie broken
by vocabulary order (a disordered Gibbs map of room1dk5 listed "bedroom/shelf" for each of its 8
largest concepts). comparison.md shows it as ``where``, the figures and ``concepts()`` do
(:data:`spcopyro.results.concept_words.NO_WORDS`): the record keeps data, not display text."""
OLD_HEARD_NOTHING = frozenset({"(no words heard)", "(no words heard here)"})
"""What a record's ``top_words`` held for such a concept before :data:`HEARD_NOTHING` (cells
cached by an earlier version): read as it (:func:`current_record`)."""


def current_record(record: dict) -> dict:
    """``record`` (a comparison cell's, perhaps cached by an earlier version) as this version
    writes one: its ``top_words`` entries of :data:`OLD_HEARD_NOTHING` read
    :data:`HEARD_NOTHING`."""
    words = record.get("top_words")
    if isinstance(words, list) and any(w in OLD_HEARD_NOTHING for w in words):
        record["top_words"] = [HEARD_NOTHING if w in OLD_HEARD_NOTHING else w for w in words]
    return record


def _top_words(result: SpCoResult, concept: int) -> str:
    """``"kitchen/sink"``: the concept's 2 most probable words as ``fit`` lists them
    (:func:`~spcopyro.results.concept_words.listed_top_words`), or :data:`HEARD_NOTHING` where
    it lists none: no word was heard in the concept's region, or the fit did not model its
    words (the record's ``words_modelled`` False then)."""
    return "/".join(w for w, _ in listed_top_words(result, concept, 2))


def _confidence(output: InferenceOutput) -> np.ndarray | None:
    """[N] the method's probability of each cell's label (module docstring), or None."""
    if output.marginals is not None:
        labels = np.asarray(output.labels)
        return np.asarray(output.marginals, dtype=np.float64)[np.arange(labels.size), labels]
    if output.label_samples is not None and output.labels_final is not None:
        return stats.sample_confidence(output.label_samples, output.labels_final)
    return None


# -- the whole comparison ------------------------------------------------------------------------


def warm_up(variant: Variant, problem: Problem) -> None:
    """Run ``variant`` for 2 iterations on ``problem`` and drop the result, so that no measured
    fit pays for numba compilation or cache loading."""
    counts, data = prepare_model_data(problem.house, problem.settings, method=variant.method)
    del counts
    with short_runs_meant():  # 2 iterations: shorter than any annealing, on purpose
        INFERENCE_METHODS[variant.method].run(
            data, problem.settings.model, iterations=2, generator=torch.Generator().manual_seed(0),
            options=variant_options(variant), progress=False, thin=1,
        )  # fmt: skip
