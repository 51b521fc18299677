"""``spcopyro compare-inference``: the Gibbs-versus-VI comparison (issue #10), its helpers on
constructed inputs, the command end to end on a tiny synthetic house, and the comparison as a
study (issue 26) against numbers recorded from its former loop."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from fake_dataset import fake_dataset
from fit_interrupts import interrupted
from scipy.signal import lfilter
from stale_cells import check_stale_kept_then_rerun

from spcopyro.cli.main import main
from spcopyro.experiments import inference_comparison as comparison
from spcopyro.experiments.comparison_stats import (
    agreement_counts,
    effective_sample_size,
    ess_per_second,
    geometric_budgets,
    geometric_indices,
    overconfidence,
    sample_confidence,
    time_to_fraction,
    wrong_cells,
)
from spcopyro.experiments.inference_comparison import (
    VARIANTS,
    ComparisonSettings,
    Variant,
    available_variants,
    check_variants,
)
from spcopyro.study import STUDIES
from spcopyro.study.cells import cells_of
from spcopyro.study.comparison import comparison_study, run_comparison
from spcopyro.study.spec import load_study

# -- time to 95% ---------------------------------------------------------------------------------


def test_time_to_fraction_higher_is_better():
    seconds = np.array([1.0, 2.0, 3.0, 4.0])
    values = np.array([0.0, 0.5, 0.96, 1.0])
    assert time_to_fraction(seconds, values, 1.0) == 3.0
    assert time_to_fraction(seconds, values, 1.0, fraction=0.5) == 2.0
    assert time_to_fraction(seconds, values, 1.0, fraction=1.0) == 4.0
    # the first crossing counts, even if the curve drops again later
    assert time_to_fraction(seconds, np.array([0.0, 0.97, 0.2, 1.0]), 1.0) == 2.0
    # never reached (the final value lies above the curve): NaN
    assert math.isnan(time_to_fraction(seconds, values, 2.0))
    # a non-positive final quality: the target is the final value itself
    assert time_to_fraction(seconds, np.array([-0.5, -0.2, -0.1, -0.1]), -0.1) == 3.0


def test_time_to_fraction_lower_is_better():
    seconds = np.array([1.0, 2.0, 3.0, 4.0])
    distance = np.array([5.0, 2.0, 1.04, 1.0])  # target 1 / 0.95 = 1.0526
    assert time_to_fraction(seconds, distance, 1.0, higher_is_better=False) == 3.0
    assert math.isnan(time_to_fraction(seconds, distance, 0.0, higher_is_better=False))
    assert math.isnan(time_to_fraction(seconds, distance, 0.5, higher_is_better=False))


def test_time_to_fraction_rejects_bad_input():
    with pytest.raises(ValueError, match="equal"):
        time_to_fraction(np.zeros(3), np.zeros(4), 1.0)
    with pytest.raises(ValueError, match="fraction"):
        time_to_fraction(np.zeros(3), np.zeros(3), 1.0, fraction=1.5)
    assert math.isnan(time_to_fraction(np.arange(3.0), np.ones(3), math.nan))


# -- effective sample size -----------------------------------------------------------------------


def _ar1(rho: float, n: int, seed: int) -> np.ndarray:
    """x_t = rho x_{t-1} + sqrt(1 - rho^2) e_t, started in its stationary law."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=n) * math.sqrt(1 - rho**2)
    noise[0] = rng.normal()
    return lfilter([1.0], [1.0, -rho], noise)


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.9])
def test_ess_of_an_ar1_series(rho):
    """ESS of AR(1) with coefficient rho tends to n (1 - rho) / (1 + rho)."""
    n = 40_000
    expected = n * (1 - rho) / (1 + rho)
    estimates = [effective_sample_size(_ar1(rho, n, seed)) for seed in range(3)]
    assert np.mean(estimates) == pytest.approx(expected, rel=0.12)


def test_ess_agrees_with_pyro():
    """The numpy estimator is Pyro's (Geyer's initial monotone sequence), to 1% on one chain."""
    from pyro.ops.stats import effective_sample_size as pyro_ess

    for rho in (0.0, 0.7):
        x = _ar1(rho, 400, 3)
        expected = float(pyro_ess(torch.as_tensor(x)[None], chain_dim=0, sample_dim=1))
        assert effective_sample_size(x) == pytest.approx(expected, rel=0.01)


def test_ess_degenerate_series():
    assert math.isnan(effective_sample_size(np.ones(100)))
    assert math.isnan(effective_sample_size(np.arange(3.0)))
    with pytest.raises(ValueError, match="one-dimensional"):
        effective_sample_size(np.zeros((2, 5)))


def test_ess_per_second_uses_the_second_half_and_its_time():
    n = 20_000
    x = _ar1(0.5, n, 7)
    seconds = 0.002 * np.arange(1, n + 1)  # 2 ms per draw
    window_ess = effective_sample_size(x[n // 2 :])
    elapsed = seconds[-1] - seconds[n // 2 - 1]  # the second half's own time: 20 s
    assert elapsed == pytest.approx(20.0)
    assert ess_per_second(x, seconds) == pytest.approx(window_ess / elapsed)
    # about n/2 * (1 - rho)/(1 + rho) / 20 s = 166.7 per second
    assert ess_per_second(x, seconds) == pytest.approx(n / 2 / 3 / 20.0, rel=0.15)
    assert ess_per_second(x, seconds, burn_in=0.0) == pytest.approx(
        effective_sample_size(x) / seconds[-1]
    )
    with pytest.raises(ValueError, match="differ"):
        ess_per_second(x, seconds[:-1])


# -- label-map statistics ------------------------------------------------------------------------


def test_agreement_counts_on_a_two_by_two_grid():
    pairs = torch.tensor([[0, 1], [0, 2], [1, 3], [2, 3]])  # cells 0 1 / 2 3
    samples = np.array([[0, 0, 1, 1], [0, 0, 0, 0], [0, 1, 1, 0]], dtype=np.int16)
    np.testing.assert_array_equal(agreement_counts(samples, pairs), [2.0, 4.0, 0.0])


def test_wrong_cells_and_overconfidence():
    labels = np.array([0, 0, 0, 1, 1, 2])
    truth = np.array([0, 0, 1, 1, 1, 1])
    # concept 0 reads as category 0 (cell 2 is wrong); concepts 1 and 2 as category 1 (a split
    # category is not penalised)
    wrong = wrong_cells(labels, truth)
    np.testing.assert_array_equal(wrong, [False, False, True, False, False, False])
    confidence = np.array([0.5, 0.6, 0.995, 0.9, 0.8, 0.7])
    scores = overconfidence(confidence, wrong)
    assert scores["wrong_share"] == pytest.approx(1 / 6)
    assert scores["confidence_wrong"] == pytest.approx(0.995)
    assert scores["confidence_right"] == pytest.approx(np.mean([0.5, 0.6, 0.9, 0.8, 0.7]))
    assert scores["confident_wrong_share"] == 1.0
    with pytest.raises(ValueError, match="non-negative"):
        wrong_cells(np.array([0, -1]), np.array([0, 0]))


def test_sample_confidence_counts_the_second_half():
    samples = np.array([[9, 9], [9, 9], [1, 2], [1, 3], [1, 2], [0, 2]])
    np.testing.assert_allclose(sample_confidence(samples, np.array([1, 2])), [2 / 3, 2 / 3])


def test_geometric_points():
    np.testing.assert_array_equal(geometric_indices(1, 5), [0])
    indices = geometric_indices(200, 20)
    assert indices[0] == 0 and indices[-1] == 199 and np.all(np.diff(indices) > 0)
    assert len(indices) <= 20
    assert geometric_budgets(100, 7) == [1, 3, 6, 12, 25, 50, 100]
    assert geometric_budgets(4, 7) == [1, 2, 4]


# -- the method list -----------------------------------------------------------------------------


def test_unknown_method_is_an_error(tmp_path, capsys):
    with pytest.raises(ValueError, match=r"unknown method\(s\) \['nope'\].*choose from"):
        check_variants(["gibbs", "nope"])
    code = main(["compare-inference", "--out", str(tmp_path), "--methods", "gibbs", "nope"])
    assert code == 2
    assert "unknown method(s) ['nope']" in capsys.readouterr().err
    assert not (tmp_path / "comparison.json").exists()
    assert check_variants(["cavi", "gibbs"]) == ("gibbs", "cavi")  # table order


def test_a_method_missing_from_the_registry_is_skipped(monkeypatch):
    monkeypatch.setitem(VARIANTS, "fake", Variant("fake", "no-such-method", "fake", 5, 2))
    messages: list[str] = []
    kept, skipped = available_variants(["gibbs", "fake"], messages.append)
    assert kept == ["gibbs"]
    assert skipped == messages and len(messages) == 1
    assert (
        "skipped fake" in messages[0] and "'no-such-method' is not in the registry" in messages[0]
    )


def test_variant_options_change_the_defaults():
    from spcopyro.gibbs.options import GibbsOptions

    assert comparison.variant_options(VARIANTS["gibbs"]) == GibbsOptions()
    assert comparison.variant_options(VARIANTS["gibbs-sw"]) == GibbsOptions(cluster_moves=0.1)


# -- the command ---------------------------------------------------------------------------------


def _no_constant(name: str) -> None:
    raise AssertionError(f"comparison.json holds {name}: not strict JSON")


def test_iterations_take_integers_as_every_integer_option_does(tmp_path, monkeypatch, capsys):
    """--iterations gibbs=1_000 reads N as int() does, as argparse's integer options (--sweeps
    1_000) do; it was refused as 'takes METHOD=N'. What is no integer is still refused."""
    import spcopyro.study.comparison
    from spcopyro.cli.main import build_parser

    assert build_parser().parse_args(["fit", "--out", "o", "--sweeps", "1_000"]).sweeps == 1000
    taken = {}

    def run(out, settings, **kwargs):
        taken.update(settings.iterations)
        raise _Stop  # before anything runs

    monkeypatch.setattr(spcopyro.study.comparison, "run_comparison", run)
    argv = ["compare-inference", "--out", str(tmp_path / "cmp"), "--quick", "--houses",
            "synthetic", "--methods", "gibbs", "cavi", "--iterations"]  # fmt: skip
    with pytest.raises(_Stop):
        main([*argv, "gibbs=1_000", "cavi=+7"])
    assert taken == {"gibbs": 1000, "cavi": 7}
    for bad in ("gibbs=1.5", "gibbs=0", "gibbs=", "gibbs=1__0"):
        assert main([*argv, bad]) == 2
        assert "--iterations takes METHOD=N (N >= 1, METHOD one of" in capsys.readouterr().err


class _Stop(Exception):
    """Ends a command where a test has seen what it needs."""


def test_quick_command_writes_table_json_and_figure(tmp_path, capsys, monkeypatch):
    from spcopyro.experiments.comparison_figure import FINAL_NOTE

    monkeypatch.setitem(VARIANTS, "fake", Variant("fake", "no-such-method", "fake", 5, 2))
    out = tmp_path / "cmp"
    code = main([
        "compare-inference", "--out", str(out), "--quick", "--houses", "synthetic",
        "--methods", "gibbs", "cavi", "stochastic-vi", "fake",
        "--iterations", "gibbs=40", "cavi=6", "stochastic-vi=6",
    ])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert "skipped fake" in printed
    summary = json.loads((out / "comparison.json").read_text(), parse_constant=_no_constant)
    assert summary["figures"] == ["comparison_synthetic.png"]
    assert (out / "comparison_synthetic.png").stat().st_size > 10_000
    assert set(summary["records"]["synthetic"]) == {"gibbs", "cavi", "stochastic-vi"}
    assert summary["settings"]["iterations"] == {"gibbs": 40, "cavi": 6, "stochastic-vi": 6}
    assert any("skipped fake" in note for note in summary["notes"])
    gibbs = summary["records"]["synthetic"]["gibbs"][0]
    cavi = summary["records"]["synthetic"]["cavi"][0]
    memoized = summary["records"]["synthetic"]["stochastic-vi"][0]
    # every method is scored at its kept maps (memoized VI honours thin since issue 23; it was
    # scored by re-runs at budgets 1, 3, 6 before); all end at the method's own output at the
    # run's full time
    assert gibbs["curve_kind"] == cavi["curve_kind"] == memoized["curve_kind"] == "kept label maps"
    iterations = [p["iteration"] for p in memoized["curve"]]
    assert iterations == sorted(iterations) and iterations[-1] == 6
    for record in (gibbs, cavi, memoized):
        curve = record["curve"]
        seconds = [p["seconds"] for p in curve]
        assert seconds == sorted(seconds) and seconds[-1] == record["seconds"]
        assert {k: curve[-1][k] for k in ("ari", "matching_rate")} == {
            k: record["final_given_labels"][k] for k in ("ari", "matching_rate")
        }
        t95 = record["time_to_95"]["ari"]
        assert t95 is None or t95 <= record["seconds"]  # None: never reached (NaN -> null)
        assert record["concepts"] >= 1 and record["top_words"]
        assert set(record["final_given_labels"]) == set(record["final"])
        assert record["final_given_labels"]["ari"] == record["final"]["ari"]  # same labels
        assert 0 <= record["overconfidence"]["wrong_share"] <= 1
    assert set(gibbs["ess_per_second"]) == {"log_joint", "agreement"}
    assert "ess_per_second" not in cavi
    table = (out / "comparison.md").read_text()
    assert "| Gibbs (Algorithm 1) |" in table and "| CAVI (mean field" in table
    assert "## Findings" in table and "cavi against gibbs" in table
    assert "![quality against time](comparison_synthetic.png)" in table
    # under the figure: what each line's last point is (the method's reported map)
    assert "(comparison_synthetic.png)\n\n" + FINAL_NOTE + "\n" in table
    assert (out / "results.csv").is_file()  # the comparison is a study: cached in --out


def test_an_unknown_public_house_is_named_as_the_option(tmp_path, capsys):
    """--public-houses room9: the error was "room folder .../room9 does not exist"; it names the
    option and the dataset's houses, before anything runs."""
    root = fake_dataset(tmp_path / "data")
    out = tmp_path / "out"
    code = main(["compare-inference", "--out", str(out), "--quick", "--houses", "public",
                 "--data", str(root), "--public-houses", "room9"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert "--public-houses room9: not a house of" in err and "its houses: room1" in err
    assert not out.exists()


def test_findings_without_gibbs_say_why_there_are_none(tmp_path):
    """--methods cavi lbp: comparison.md's "## Findings" section was left empty (every finding
    compares a method with Gibbs)."""
    settings = ComparisonSettings(variants=("lbp",), seeds=1, house_types=("synthetic",),
                                  quick=True, iterations={"lbp": 2})  # fmt: skip
    run_comparison(tmp_path, settings)
    text = (tmp_path / "comparison.md").read_text()
    none = "## Findings (from the numbers above)\n\nNone: the findings compare each method with"
    assert none in text
    settings = dataclasses.replace(settings, variants=("gibbs",), iterations={"gibbs": 2})
    run_comparison(tmp_path / "gibbs", settings)
    text = (tmp_path / "gibbs" / "comparison.md").read_text()
    assert "\n\nNone: Gibbs (Algorithm 1) is the only method compared." in text


def test_a_score_of_minus_zero_prints_as_zero():
    """SVI's ARI at chance (-1e-5) read "-0.000" in comparison.md's table."""
    from spcopyro.experiments.comparison_report import _fmt, findings

    assert _fmt({"mean": -1e-5, "sd": 0.0, "n": 1}) == "0.000"
    assert _fmt({"mean": -2e-5, "sd": 1e-5, "n": 2}) == "0.000 ± 0.000"
    assert _fmt({"mean": 0.51, "sd": 0.0, "n": 1}, 1, False) == "0.5"

    def line(ari: float) -> dict:
        return {"final_given_labels": {"ari": {"mean": ari}}, "seconds": {"mean": 1.0}}

    (text,) = findings({"synthetic": {"gibbs": line(0.5), "svi": line(-1e-5)}})
    assert "final ARI (labels, means given them) 0.000 vs 0.500" in text, text


def test_a_budget_shorter_than_the_annealing_is_noted(tmp_path):
    """--iterations cavi=5 fitted CAVI at a quarter of gamma (its annealing runs 20 iterations);
    the method's warning went to the terminal only and the table's label still said "gamma
    annealed over 20 it.". comparison.md and the JSON's notes say so."""
    settings = ComparisonSettings(variants=("cavi", "lbp"), seeds=1, house_types=("synthetic",),
                                  quick=True, iterations={"cavi": 5, "lbp": 2})  # fmt: skip
    summary = run_comparison(tmp_path, settings)
    note = ("cavi: 5 iterations end before its annealing (anneal_iterations = 20): gamma "
            "reaches only 25% of the model's")  # fmt: skip
    assert [n for n in summary["notes"] if "annealing" in n] == [
        note + ", so its fits are of a weaker coupling"
    ]  # lbp anneals over none
    assert f"- {note}" in (tmp_path / "comparison.md").read_text()


def test_a_failed_fit_is_named_in_the_comparison(tmp_path, monkeypatch, capsys):
    """A failing fit was left out of comparison.md without a word there (the command exited
    1); its notes name it and its error."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    cavi = INFERENCE_METHODS["cavi"]
    run = type(cavi).run

    def failing(self, *args, iterations, **kwargs):
        if iterations > 2:  # the warm-up runs 2
            raise RuntimeError("no convergence")
        return run(self, *args, iterations=iterations, **kwargs)

    monkeypatch.setattr(type(cavi), "run", failing)
    out = tmp_path / "cmp"
    code = main(["compare-inference", "--out", str(out), "--quick", "--houses", "synthetic",
                 "--methods", "gibbs", "cavi", "--iterations", "gibbs=3", "cavi=20"])  # fmt: skip
    assert code == 1
    capsys.readouterr()
    line = "cavi on synthetic, seed 0, failed (RuntimeError: no convergence); left out"
    assert f"- {line}" in (out / "comparison.md").read_text()
    notes = json.loads((out / "comparison.json").read_text())["notes"]
    assert any(note.startswith(line) for note in notes)


def test_the_public_table_names_its_houses_and_trials():
    """comparison.md's public table named no house: a --quick (room1dk5, one trial) or
    --public-houses table read as the five houses' three trials."""
    from spcopyro.experiments.comparison_report import _concurrent, _public_fits

    # --workers N > 1: comparison.md did not say its times were measured beside other fits
    assert _concurrent(1) == ""
    assert _concurrent(2).startswith(" Run with --workers 2: fits may have run beside each other")

    records = {
        "gibbs": [{"house": f"room1dk5 (held-out trial {t})"} for t in (2, 0)]
        + [{"house": "room2ldk4 (held-out trial 1)"}],
        "cavi": [{"house": "room1dk5 (held-out trial 0)"}],
    }
    assert _public_fits(records) == (
        "room1dk5 (held-out trials 0, 2); room2ldk4 (held-out trial 1)"
    )
    assert _public_fits({"gibbs": []}) == "none"


def test_a_resumed_comparison_says_which_cells_it_ran_and_reruns_stale_ones(tmp_path, capsys):
    """A run that found cells finished said "Whole command: 0 s wall-clock", as if the whole
    comparison had taken no time; and the note on cells of other source said "--rerun-stale
    runs them again", an option compare-inference did not have."""
    out = tmp_path / "cmp"
    command = ["compare-inference", "--out", str(out), "--quick", "--houses", "synthetic",
               "--methods", "gibbs", "--iterations", "gibbs=5"]  # fmt: skip
    assert main(command) == 0
    capsys.readouterr()
    assert "Whole command: " in (out / "comparison.md").read_text()
    assert "## Synthetic houses (1 seed, ground truth)" in (out / "comparison.md").read_text()
    assert json.loads((out / "comparison.json").read_text())["cells_finished_before"] == 0
    assert json.loads((out / "comparison.json").read_text())["workers"] == 1
    check_stale_kept_then_rerun(
        main,
        command,
        out,
        "comparison",
        capsys,
        "compare-inference: 1 of 1 fits to run: 1 method x 1 fit each",
    )


# -- the comparison as a study (issue 26) --------------------------------------------------------

OLD_RECORDS = Path(__file__).with_name("comparison_old_records.json")
"""What the comparison's own loop gave (times left out) before it became a study."""
TIMES = ("seconds", "wall_seconds", "cpu_seconds", "time_to_95", "ess_per_second")


def _untimed(record: dict) -> dict:
    record = {k: v for k, v in record.items() if k not in TIMES}
    record["curve"] = [{k: v for k, v in p.items() if k != "seconds"} for p in record["curve"]]
    return record


def _recorded_grid(root, **changes) -> ComparisonSettings:
    values: dict = dict(
        variants=("gibbs", "gibbs-sw", "cavi", "stochastic-vi"), seeds=2, dataset_root=root,
        public_houses=("room1ldk4",), folds=1, quick=True,
        iterations={"gibbs": 40, "gibbs-sw": 40, "cavi": 6, "stochastic-vi": 6},
    )  # fmt: skip
    values.update(changes)
    return ComparisonSettings(**values)


def test_the_public_table_says_why_a_word_share_is_no_whole_count(tmp_path, dataset_root):
    """room1dk5's 500-sweep comparison listed top-1 0.205 "(15 words)": no whole number of 15,
    since a tied word scores the chance that a random tie-break ranks it first
    (metrics.heldout.rank_of_truth); comparison.md did not say so."""
    settings = _recorded_grid(dataset_root, house_types=("public",), variants=("cavi",))
    run_comparison(tmp_path, settings)
    text = " ".join((tmp_path / "comparison.md").read_text().split())
    assert (
        "A word whose probability ties with other words' counts the chance that a random "
        "tie-break ranks it first (top-3: in the first three), so a share need not be a whole "
        "number of words over the count."
    ) in text


def test_the_study_gives_the_old_loops_numbers(tmp_path, dataset_root):
    """Every score of every fit (times aside) equals what the comparison's own loop gave for the
    same grid and seeds: 4 lines on 2 synthetic houses, CAVI on a held-out trial of room1ldk4;
    a rerun fits nothing and writes the same summary."""
    old = json.loads(OLD_RECORDS.read_text())["records"]
    only_public = _recorded_grid(dataset_root, house_types=("public",), variants=("cavi",))
    only_synthetic = _recorded_grid(dataset_root, house_types=("synthetic",))
    synthetic = run_comparison(tmp_path / "s", only_synthetic)
    public = run_comparison(tmp_path / "p", only_public)
    new = {**synthetic["records"], **public["records"]}
    assert {h: list(v) for h, v in new.items()} == {h: list(v) for h, v in old.items()}
    for house_type, by_variant in old.items():
        for key, records in by_variant.items():
            assert [_untimed(r) for r in new[house_type][key]] == records, (house_type, key)
    assert synthetic["failed"] == public["failed"] == 0
    for out in (tmp_path / "s", tmp_path / "p"):
        _assert_stored_maps_are_the_scored_ones(out)
    lines: list[str] = []
    again = run_comparison(tmp_path / "p", only_public, lines.append)
    assert any("nothing to run" in line for line in lines)
    assert again["summary"] == public["summary"]


def _assert_stored_maps_are_the_scored_ones(out: Path) -> None:
    """Every comparison cell stored its final label map on the map's cells with the truth it
    was scored against (the ARI of the one against the other is the row's), and the report drew
    them."""
    from spcopyro.metrics import adjusted_rand_index
    from spcopyro.study.maps import load_label_map
    from spcopyro.study.table import read_table

    rows = read_table(out / "results.csv")
    assert rows and all(r["scoring"] == "comparison" for r in rows)
    for row in rows:
        stored = load_label_map(out, row)
        assert stored is not None and stored.truth is not None, row["label_map"]
        assert stored.labels.shape == stored.grid.shape == stored.truth.shape
        assert adjusted_rand_index(stored.labels, stored.truth) == pytest.approx(row["ari"])
    for data in {r["data"] for r in rows}:
        assert (out / f"maps_{data}.png").is_file()


@pytest.mark.parametrize("quick", [False, True])
def test_shipped_study_files_are_the_commands_grid(quick, dataset_root):
    """compare_inference(_quick).toml: the same cells, key for key, as the command's defaults
    (--quick: one public house, one held-out trial)."""
    name = "compare_inference_quick" if quick else "compare_inference"
    study = load_study(STUDIES / f"{name}.toml")
    settings = ComparisonSettings(dataset_root=dataset_root, seeds=1 if quick else 5, quick=quick,
                                  public_houses=("room1dk5",) if quick else None,
                                  folds=1 if quick else None)  # fmt: skip
    keys = [c.key for c in cells_of(study, dataset_root)]
    assert keys == [c.key for c in cells_of(comparison_study(settings))]
    assert len(keys) == (14 if quick else 140)


def test_a_method_that_keeps_no_label_maps_is_rerun_at_geometric_budgets(monkeypatch):
    """The curve of a method without kept maps (a registered method that ignores ``thin``): its
    labels re-fitted from the same seed at budgets n/2, n/4, ..., each point the score of that
    shorter run, then the full run's labels."""
    import dataclasses

    from spcopyro.config import preset
    from spcopyro.experiments.comparison_stats import geometric_budgets
    from spcopyro.fit.registry import INFERENCE_METHODS
    from spcopyro.synthetic import HouseSpec, make_house

    cavi = INFERENCE_METHODS["cavi"]
    budgets: list[int] = []

    class NoMaps:  # the protocol alone: no label maps kept
        name, objective_name = "no-maps", "ELBO"

        def default_options(self):
            return cavi.default_options()

        def run(self, data, config, *, iterations, generator, thin=0, **kwargs):
            budgets.append(iterations)
            output = cavi.run(data, config, iterations=iterations, generator=generator, **kwargs)
            return dataclasses.replace(output, label_samples=None, sample_iterations=None)

    monkeypatch.setitem(INFERENCE_METHODS, "no-maps", NoMaps())
    house = make_house(0, HouseSpec(height=40, width=50, num_rooms=3))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    problem = comparison.Problem(house, settings, seed=0, name="tiny")
    variant = Variant("no-maps", "no-maps", "no maps kept", 8, 2)
    record = comparison.fit_and_score(variant, problem, 8)
    assert record["curve_kind"] == "re-runs at geometric budgets"
    expected = geometric_budgets(8, comparison.RERUN_POINTS)[:-1]
    assert budgets == [8, *expected]  # the full run, then one re-run per budget
    assert [p["iteration"] for p in record["curve"][:-1]] == list(expected)
    assert record["curve"][-1]["iteration"] == record["iterations"]


def test_a_finite_prior_takes_a_public_houses_categories(dataset_root):
    """``--preset paper-dirichlet`` fitted every public house with L = 6 (the fallback of a
    house without categories), where a study cell, and the experiment's B-dirichlet row, take
    the paper's Table 2 count (room1ldk4: 7)."""
    from spcopyro.experiments.table import PUBLIC_CATEGORIES
    from spcopyro.study.comparison_cell import problem_of

    settings = ComparisonSettings(dataset_root=dataset_root, preset="paper-dirichlet",
                                  house_types=("public",), public_houses=("room1ldk4",),
                                  variants=("cavi",), folds=1)  # fmt: skip
    (cell,) = cells_of(comparison_study(settings), dataset_root)
    assert PUBLIC_CATEGORIES["room1ldk4"] == 7
    assert problem_of(cell).settings.model.num_concepts == 7


def test_times_to_95_percent_under_a_tenth_of_a_second_keep_their_digits():
    """A t95 of 4.9 ms read "0.00 s" beside "(37.0x slower)" (and "0.00" in the table)."""
    from spcopyro.experiments.comparison_report import _t95, findings

    assert _t95({"mean": 0.0049, "n": 1}, 1) == "0.0049"
    assert _t95({"mean": 0.18, "n": 1}, 2) == "0.2 (1/2 reached)"

    def line(t95: float) -> dict:
        return {"final_given_labels": {"top1": {"mean": 0.2}},
                "time_to_95": {"top1": {"mean": t95}}, "seconds": {"mean": 1.0},
                "concepts": {"mean": 10.0}}  # fmt: skip

    (text,) = [n for n in findings({"public": {"gibbs": line(0.0049), "cavi": line(0.18)}})
               if n.startswith("public, cavi")]  # fmt: skip
    # two significant digits below 1 s, so the times read as the ratio says (one decimal read
    # "0.2 s vs 0.0049 s (36.7x slower)", and "0.1 s vs 0.044 s (3.3x slower)" for 0.144 s)
    assert "after 0.18 s vs 0.0049 s (36.7x slower)" in text, text
    assert "whole run 1.0 s vs 1.0 s" in text, text


def test_an_interrupted_comparison_says_its_report_is_an_earlier_runs(
    tmp_path, capsys, monkeypatch
):
    """Ctrl-C left an earlier run's comparison.md beside the results.csv and report.md the
    study engine had just rewritten, without a word (a helper's QA)."""
    import spcopyro.study.comparison as comparison

    out = tmp_path / "cmp"
    out.mkdir()
    (out / "comparison.md").write_text("an earlier run\n")
    monkeypatch.setattr(comparison, "run_comparison", interrupted)
    command = ["compare-inference", "--out", str(out), "--quick", "--houses", "synthetic",
               "--methods", "gibbs", "--iterations", "gibbs=5"]  # fmt: skip
    assert main(command) == 130
    err = capsys.readouterr().err
    assert f"{out / 'comparison.md'}: an earlier run's, not rewritten" in err
    (out / "comparison.md").unlink()
    assert main(command) == 130
    assert "earlier run" not in capsys.readouterr().err


def test_a_report_replaced_before_the_stop_is_not_called_an_earlier_runs(
    tmp_path, capsys, monkeypatch
):
    """The reports are written at the end, each replaced whole: a Ctrl-C after comparison.md was
    replaced and before comparison.json was named both "an earlier run's, not rewritten"."""
    import spcopyro.study.comparison as comparison
    from spcopyro._util.outputs import replace_text

    out = tmp_path / "cmp"
    out.mkdir()
    for name in ("comparison.md", "comparison.json"):
        (out / name).write_text("an earlier run\n")

    def stopped_between_the_reports(*args, **kwargs):
        replace_text(out / "comparison.md", "this run\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(comparison, "run_comparison", stopped_between_the_reports)
    command = ["compare-inference", "--out", str(out), "--quick", "--houses", "synthetic",
               "--methods", "gibbs", "--iterations", "gibbs=5"]  # fmt: skip
    assert main(command) == 130
    err = capsys.readouterr().err
    assert f"\n{out / 'comparison.json'}: an earlier run's, not rewritten" in f"\n{err}", err
    assert str(out / "comparison.md") not in err


def test_the_table_says_how_many_iterations_each_line_ran(tmp_path):
    """comparison.md gave the budgets only ("Iterations: cavi 200, vi-gibbs 3"): a variational
    line that stopped at its tolerance long before, and vi-gibbs's CAVI start (whose time its s
    per fit includes), were not told apart from a run to the budget. A column gives the
    iterations run, vi-gibbs's with its CAVI start's; the header says what a budget counts."""
    settings = ComparisonSettings(variants=("cavi", "vi-gibbs"), seeds=1,
                                  house_types=("synthetic",), quick=True,
                                  iterations={"cavi": 200, "vi-gibbs": 3})  # fmt: skip
    summary = run_comparison(tmp_path, settings)
    cavi = summary["records"]["synthetic"]["cavi"][0]
    vi_gibbs = summary["records"]["synthetic"]["vi-gibbs"][0]
    assert cavi["iterations"] < 200  # converged first (tolerance 1e-6)
    assert vi_gibbs["iterations"] == 3 and 1 <= vi_gibbs["start_iterations"] <= 100
    text = (tmp_path / "comparison.md").read_text()
    lines = text.splitlines()
    header = next(line for line in lines if line.startswith("| method |"))
    assert "| s per fit | iterations run |" in header
    header = header.replace("\\|", "")  # "matching rate (means \\| labels)"
    column = [c.strip() for c in header.split("|")].index("iterations run")
    rows = {line.split("|")[1].strip(): line for line in lines if line.startswith("| ")}
    cavi_row = rows["CAVI (mean field; gamma annealed over 20 it.)"].replace("\\|", "")
    vi_row = rows["VI then Gibbs"].replace("\\|", "")
    assert cavi_row.count("|") == vi_row.count("|") == header.count("|")
    assert cavi_row.split("|")[column].strip() == f"{cavi['iterations']} iterations"
    assert vi_row.split("|")[column].strip() == (
        f"3 sweeps (+ {vi_gibbs['start_iterations']} CAVI iterations)"
    )
    assert ("Iteration budgets: cavi 200 iterations, vi-gibbs 3 sweeps. A budget is the sweeps "
            "of a sampler") in text  # fmt: skip
    assert "not its reported point estimate's" in text  # whose wrong cells a sampler's are


def test_svi_s_annealing_left_to_its_start_is_read_as_a_random_start_s():
    """SVIOptions.anneal_iterations defaults to None since 06e5f05 (100 for a random start, 0
    for given labels): the note read None and said nothing for --iterations svi=50, where the
    comparison's svi (full mode: no options) anneals over 100 iterations from a random start."""
    from spcopyro.experiments.comparison_report import unfinished_annealing

    settings = ComparisonSettings(variants=("svi",), seeds=1, house_types=("synthetic",))
    assert unfinished_annealing({"svi": 50}, settings) == [
        "svi: 50 steps end before its annealing (anneal_iterations = 100): gamma reaches "
        "only 50% of the model's, so its fits are of a weaker coupling"
    ]
    assert unfinished_annealing({"svi": 100}, settings) == []


def test_the_figure_names_the_parameters_its_scores_read():
    """comparison_synthetic.png's matching-rate panel is scored with the posterior means given
    each label map (module docstring), the table's "matching rate (means | labels)" column; it
    read "matching rate" beside a table whose "matching rate" is of the method's own output
    (SVI: 0.508 in the table, its curve ending at 0.306)."""
    from spcopyro.experiments.comparison_figure import curves_figure

    methods = {key: v.label for key, v in VARIANTS.items()}
    curve = [{"seconds": 1.0, "ari": 0.5, "matching_rate": 0.5, "top1": 0.2, "distance_m": 1.0}]
    labels = {}
    for house_type in ("synthetic", "public"):
        summary = {"records": {house_type: {"cavi": [{"curve": curve}]}}, "methods": methods}
        for ax in curves_figure(summary, house_type).axes:
            labels[ax.get_ylabel().split("\n")[0].split(" (")[0]] = ax.get_ylabel()
    assert labels["ARI"] == "ARI"  # the labels alone
    assert labels["matching rate"] == "matching rate\n(means | labels)"
    assert labels["held-out top-1"] == "held-out top-1\n(means | labels)"
    assert labels["localisation distance"] == (
        "localisation distance (m)\n(means | labels) (lower is better)"
    )


def test_no_axis_label_of_the_figure_runs_over_its_title():
    """comparison_public.png's distance label, "localisation distance (m) (means | labels)
    (lower is better)" on one line, was taller than its panel and ran over the figure's title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.experiments.comparison_figure import curves_figure

    methods = {key: v.label for key, v in VARIANTS.items()}
    curve = [{"seconds": 1.0, "ari": 0.5, "matching_rate": 0.5, "top1": 0.2, "distance_m": 1.0}]
    for house_type in ("synthetic", "public"):
        summary = {"records": {house_type: {"cavi": [{"curve": curve}]}}, "methods": methods}
        fig = curves_figure(summary, house_type)
        renderer = FigureCanvasAgg(fig).get_renderer()
        title = fig._suptitle.get_window_extent(renderer)
        for ax in fig.axes:
            label = ax.yaxis.label.get_window_extent(renderer)
            panel = ax.get_window_extent(renderer)
            assert label.y1 <= panel.y1 and not label.overlaps(title), ax.get_ylabel()


def test_each_curve_s_last_point_is_marked_as_the_reported_map():
    """A curve plots the label maps its method kept along the run, but its last point is the
    map the method reports (a sampler's highest-log-joint visited state, not its last one):
    Gibbs's top-1 on room1dk5 fell 0.267 -> 0.200 into that point, and nothing in the figure or
    under it said the point was another kind of map. It has its own hollow marker, one grey
    legend entry, and comparison.md says the same under the figure."""
    from matplotlib.colors import to_rgba
    from matplotlib.markers import MarkerStyle

    from spcopyro.experiments.comparison_figure import (
        FINAL_LABEL,
        FINAL_MARKER,
        FINAL_NOTE,
        curves_figure,
    )

    methods = {key: v.label for key, v in VARIANTS.items()}
    gibbs = [{"seconds": 0.1, "top1": 0.3, "distance_m": 0.5},
             {"seconds": 1.0, "top1": 0.267, "distance_m": 0.576},
             {"seconds": 1.0, "top1": 0.2, "distance_m": 0.639}]  # fmt: skip
    cavi = [{"seconds": 0.2, "top1": 0.25, "distance_m": 0.9},
            {"seconds": 2.0, "top1": 0.205, "distance_m": 0.94}]  # fmt: skip
    records = {"gibbs": [{"curve": gibbs}], "cavi": [{"curve": cavi}, {"curve": cavi}]}
    fig = curves_figure({"records": {"public": records}, "methods": methods}, "public")
    for ax, score in zip(fig.axes, ("top1", "distance_m"), strict=True):
        finals = [line for line in ax.get_lines() if line.get_marker() == FINAL_MARKER]
        points = sorted((tuple(line.get_xdata()), tuple(line.get_ydata())) for line in finals)
        assert points == sorted([((1.0,), (gibbs[-1][score],)), ((2.0,), (cavi[-1][score],)),
                                 ((2.0,), (cavi[-1][score],))]), score  # fmt: skip
        assert all(line.get_markerfacecolor() == "none" for line in finals)  # hollow
        kept = [line for line in ax.get_lines() if line not in finals]
        assert [len(line.get_xdata()) for line in kept] == [3, 2, 2]  # the lines as drawn
    (legend,) = fig.legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts == [methods["gibbs"], methods["cavi"], FINAL_LABEL]
    handle = legend.legend_handles[-1]
    assert handle.get_marker() == FINAL_MARKER and handle.get_markerfacecolor() == "none"
    assert to_rgba(handle.get_markeredgecolor()) == to_rgba("grey")
    # the note under the figure names the marker drawn, hollow as the points and the legend's
    # ("D" is matplotlib's diamond): not a word the figure does not show
    assert f"(hollow {MarkerStyle.markers[FINAL_MARKER]})" in FINAL_NOTE


def test_a_final_ari_at_chance_gets_no_time_to_95_percent():
    """An SVI quick run ended at ARI 0.006 and the findings read "95% of its own final ARI after
    0.01 s vs ...": at chance that time means nothing; the finding says the ARI is at chance."""
    from spcopyro.experiments.comparison_report import CHANCE_ARI, findings

    def line(ari: float, t95: float) -> dict:
        return {"final_given_labels": {"ari": {"mean": ari}}, "time_to_95": {"ari": {"mean": t95}},
                "seconds": {"mean": 1.0}, "concepts": {"mean": 10.0}}  # fmt: skip

    def finding(gibbs: dict, svi: dict) -> str:
        (text,) = findings({"synthetic": {"gibbs": gibbs, "svi": svi}})
        return text

    text = finding(line(0.9, 0.5), line(0.006, 0.01))
    assert "95% of its own final" not in text, text
    assert (f"its final ARI 0.006 is at chance (ARI < {CHANCE_ARI:g}), so no time to 95% of it "
            "is given (gibbs reaches 95% of its own after 0.5 s)") in text, text  # fmt: skip
    text = finding(line(0.01, 0.5), line(0.7, 0.2))
    assert ("95% of its own final ARI after 0.2 s vs none for gibbs: its final ARI 0.010 is at "
            "chance") in text, text  # fmt: skip
    text = finding(line(0.9, 0.5), line(0.7, 0.2))
    assert "95% of its own final ARI after 0.2 s vs 0.5 s (2.5x faster)" in text, text


def test_the_table_says_what_an_iteration_of_each_method_is(tmp_path):
    """comparison.md called SVI's steps and memoized VI's passes "iterations" (column iterations
    run, the budgets, the annealing notes) while their progress bars count "step" and "pass"."""
    settings = ComparisonSettings(variants=("svi", "stochastic-vi"), seeds=1,
                                  house_types=("synthetic",), quick=True,
                                  iterations={"svi": 4, "stochastic-vi": 2})  # fmt: skip
    summary = run_comparison(tmp_path, settings)
    text = (tmp_path / "comparison.md").read_text()
    assert "Iteration budgets: svi 4 steps, stochastic-vi 2 passes." in text, text
    assert "an optimiser step of svi, a pass over the tiles of stochastic-vi" in text
    lines = [line.replace("\\|", "") for line in text.splitlines() if line.startswith("| ")]
    rows = {line.split("|")[1].strip(): line.split("|") for line in lines}
    header = [c.strip() for c in next(r for k, r in rows.items() if k == "method")]
    column = header.index("iterations run")
    assert rows["SVI (Pyro guide)"][column].strip() == "4 steps"
    memoized = next(r for k, r in rows.items() if k.startswith("memoized VI"))
    assert memoized[column].strip().endswith(" passes")
    assert "svi: 4 steps end before its annealing (anneal_iterations = 10)" in " ".join(
        summary["notes"]
    )


def test_a_one_concept_map_of_a_comparison_cell_is_warned_of(dataset_root, monkeypatch):
    """compare-inference on room1dk5 (original-code, gamma 3) gave five of its seven maps one
    concept over the house with a speckle at the observed cells (ARI 0.000-0.027); comparison.md
    listed SVI's and memoized VI's flat q but no degenerate map: a comparison cell never ran the
    check ``fit_house`` runs. The cell's fit here is CAVI for 2 iterations, its map replaced by
    one concept."""
    from spcopyro.study.cell_warnings import read_warnings
    from spcopyro.study.comparison_cell import ADVICE
    from spcopyro.study.evaluate import WARNINGS, run_cell

    fit = comparison.fit_and_score_with_result

    def one_concept(variant, problem, iterations):
        record, result = fit(variant, problem, iterations)
        return record, dataclasses.replace(result, labels=np.zeros_like(result.labels))

    monkeypatch.setattr(comparison, "fit_and_score_with_result", one_concept)
    settings = ComparisonSettings(dataset_root=dataset_root, house_types=("public",),
                                  public_houses=("room1dk5",), variants=("cavi",), folds=1,
                                  iterations={"cavi": 2})  # fmt: skip
    (cell,) = cells_of(comparison_study(settings), dataset_root)
    record, _, _ = run_cell(cell)
    assert record["status"] == "ok", record["error"]
    said = read_warnings(record[WARNINGS])
    assert any("holds 100" in message for message in said), said
    # its advice fits the comparison: compare-inference takes no --method or --merge-moves
    (collapsed,) = [message for message in said if "holds 100" in message]
    assert collapsed.endswith(ADVICE) and "--merge-moves" not in collapsed, collapsed


def test_a_listed_concept_where_no_word_was_heard_says_so():
    """A concept of a disordered Gibbs map whose region heard no word has the prior's w, whose
    top words are a tie broken by vocabulary order: comparison.md listed "bedroom/shelf" for
    each of the 8 largest concepts of a 300-sweep Gibbs fit of room1dk5, as if those were its
    words."""
    from spcopyro.config import preset
    from spcopyro.experiments.comparison_report import found_words
    from spcopyro.results.concept_words import format_concept_words
    from spcopyro.synthetic import HouseSpec, make_house

    spec = HouseSpec(
        height=40, width=50, num_rooms=3, num_trials=1, utterances_per_room_per_trial=1
    )  # 3 utterances: most concepts hear none
    settings = preset("original-code", gamma=3.0, num_concepts=30)
    problem = comparison.Problem(make_house(0, spec), settings, seed=0, name="tiny")
    record, result = comparison.fit_and_score_with_result(VARIANTS["gibbs"], problem, 4)
    listed = [int(c) for c in result.concepts_in_use()[:8]]
    silent = [result.heard(c) == 0 for c in listed]
    assert any(silent) and not all(silent), [result.heard(c) for c in listed]  # both kinds
    for c, quiet, words in zip(listed, silent, record["top_words"], strict=True):
        expected = "/".join(w for w, _ in result.top_words(c, 2))
        assert words == ("" if quiet else expected), (c, words)  # data: no words, no text
    # shown in the words the fit's own listing, ``where`` and the figures use ("(no words
    # heard)" was the comparison's own)
    shown = found_words(record["top_words"]).split("; ")
    assert [s == format_concept_words([], [], 0.0) for s in shown] == silent, shown
    assert found_words(["kitchen/sink", ""]) == "kitchen/sink; (no words heard here)"


def test_a_fit_that_did_not_model_its_words_says_so_once():
    """A fit with use_words off lists no words (every w row is the prior's, the words tied:
    they were listed in tie order as if learnt); comparison.md says once that the fit did not
    model its words, as fit's listing does, not "(no words heard here)" for each concept,
    which would say that no word was heard."""
    from spcopyro.config import preset
    from spcopyro.experiments.comparison_report import summarise, table_markdown
    from spcopyro.synthetic import HouseSpec, make_house

    spec = HouseSpec(height=40, width=50, num_rooms=3, num_trials=1)
    settings = preset("original-code", gamma=3.0, num_concepts=10, use_words=False)
    problem = comparison.Problem(make_house(0, spec), settings, seed=0, name="tiny")
    record, result = comparison.fit_and_score_with_result(VARIANTS["gibbs"], problem, 4)
    assert any(result.heard(int(c)) for c in result.concepts_in_use()[:8])  # words were heard
    assert record["words_modelled"] is False
    assert record["top_words"] and set(record["top_words"]) == {""}
    compared = comparison.ComparisonSettings(house_types=("synthetic",), variants=("gibbs",))
    text = table_markdown(summarise({"synthetic": {"gibbs": [record]}}, compared, [], 1.0))
    (line,) = [line for line in text.splitlines() if line.startswith("- synthetic, gibbs:")]
    assert line == "- synthetic, gibbs: words not modelled (use_words off)", line
    heard = dataclasses.replace(problem, settings=preset("original-code", gamma=3.0,
                                                         num_concepts=10))  # fmt: skip
    record, _ = comparison.fit_and_score_with_result(VARIANTS["gibbs"], heard, 4)
    assert "words_modelled" not in record and any(record["top_words"])  # as before


def test_a_cached_record_of_an_earlier_version_reads_as_this_ones():
    """Records held the display text ("(no words heard)", then "(no words heard here)") for a
    concept that heard no word: a wording change rewrote 21 entries of the old-records fixture,
    and an earlier run's cached cells were listed in the old words beside new ones. A record
    holds "" now; an earlier run's cells read the same."""
    from spcopyro.experiments.comparison_report import found_words
    from spcopyro.study.comparison import records_of_rows

    old = ["kitchen/sink", "(no words heard)", "(no words heard here)"]
    row = {"status": "ok", "data_kind": "synthetic", "variant": "gibbs",
           "details": json.dumps({"top_words": old, "concepts": 3})}  # fmt: skip
    (record,) = records_of_rows([row])["synthetic"]["gibbs"]
    assert record == {"top_words": ["kitchen/sink", "", ""], "concepts": 3}
    assert found_words(record["top_words"]) == (
        "kitchen/sink; (no words heard here); (no words heard here)"
    )


def test_results_csv_fills_cpu_seconds_and_best_objective(tmp_path):
    """compare-inference's results.csv had columns cpu_seconds and best_objective always empty:
    a comparison cell now records the CPU time of its measured run and the objective of the
    state it reports."""
    import csv

    settings = _recorded_grid(None, house_types=("synthetic",), variants=("gibbs", "cavi"),
                              seeds=1, iterations={"gibbs": 6, "cavi": 3})  # fmt: skip
    run_comparison(tmp_path, settings)
    with open(tmp_path / "results.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert sorted(r["method"] for r in rows) == ["cavi", "gibbs"]
    # which objective each best_objective is: a log joint and an ELBO are not on one scale
    assert {r["method"]: r["objective"] for r in rows} == {"gibbs": "log joint", "cavi": "ELBO"}
    for row in rows:
        assert float(row["cpu_seconds"]) > 0, row
        assert math.isfinite(float(row["best_objective"])), row
        details = json.loads(row["details"])
        assert float(row["cpu_seconds"]) == pytest.approx(details["cpu_seconds"])


def test_the_default_comparison_says_its_scale_before_its_first_fit(
    tmp_path, monkeypatch, capsys, dataset_root
):
    """The default compare-inference plans 140 fits; it said only "140 of 140 cells to run" and
    a progress bar that predicted 4 to 17 hours on 2 cores, after it had started. It now says,
    before the first fit, the fits per method, the budgets, the predicted time and the shorter
    runs; --help says the default's scale. It says the count once: the study engine's own
    "140 of 140 cells to run" followed it (review of ee5e2fb)."""
    import spcopyro.study.run
    from spcopyro.cli.main import build_parser

    def in_process(cells):
        raise _Stop  # the first fit would start here

    monkeypatch.setattr(spcopyro.study.run, "_in_process", in_process)
    with pytest.raises(_Stop):
        main(["compare-inference", "--out", str(tmp_path / "cmp"), "--data", str(dataset_root)])
    out = capsys.readouterr().out
    assert ("compare-inference: 140 of 140 fits to run: 7 methods x 20 fits each (5 synthetic "
            "houses; 15 held-out trials of 5 public houses), at these budgets: gibbs 5000 "
            "sweeps,") in out  # fmt: skip
    assert re.search(r"vi-gibbs 5000 sweeps; predicted 1\.\d h of fits one after another "
                     r"\(times of a 2-core machine: a guide, not a promise\); cells run: "
                     r"in-process\n", out)  # fmt: skip
    assert out.count(" of 140 ") == 1, out  # the count once
    assert (
        "a shorter comparison: --quick (a smoke run: a tiny house, a few iterations), "
        "--houses synthetic --seeds 2 (2 synthetic houses a method), or a tenth of the "
        "longest budgets (--iterations gibbs=500 gibbs-sw=500 svi=200 vi-gibbs=500)"
    ) in out
    with pytest.raises(_Stop):  # a short run is not told to be shorter
        main(["compare-inference", "--out", str(tmp_path / "q"), "--quick", "--houses",
              "synthetic"])  # fmt: skip
    out = capsys.readouterr().out
    assert (
        "compare-inference: 7 of 7 fits to run: 7 methods x 1 fit each (1 synthetic house)" in out
    )
    assert "a shorter comparison" not in out
    sub = build_parser()._subparsers._group_actions[0].choices["compare-inference"]  # noqa: SLF001
    helped = " ".join(sub.format_help().split())
    assert "The default is the whole study: 140 fits (7 methods x 5 synthetic houses" in helped


def test_a_resumed_comparison_says_how_many_fits_finished_before(tmp_path):
    """compare-inference's line says the count once (the study engine's "N of M cells to run
    (K finished before)" no longer follows it), so it says the fits finished before itself."""
    from spcopyro.study.comparison import plan_lines
    from spcopyro.study.run import plan_study

    settings = ComparisonSettings(variants=("gibbs", "cavi"), seeds=2, house_types=("synthetic",),
                                  quick=True)  # fmt: skip
    study = comparison_study(settings)
    plan = plan_study(study, tmp_path / "out")
    resumed = dataclasses.replace(plan, pending=plan.pending[1:], cached=1)
    assert plan_lines(study, plan, "in-process")[0].startswith(
        "compare-inference: 4 of 4 fits to run: 2 methods x 2 fits each (2 synthetic houses)"
    )
    assert plan_lines(study, resumed, "in-process")[0].startswith(
        "compare-inference: 3 of 4 fits to run (1 finished before): 2 methods x 2 fits each"
    )


def test_run_study_says_any_describe_s_lines_one_way(tmp_path, monkeypatch):
    """run_study says describe(study, plan, where)'s lines (default _count_lines, the engine's
    count), each whole, one path for every study: it patched a describe's list in place or said
    its own line in its stead (review of 070b5fa), then appended where to a first line left
    dangling ('... (K finished before),') (review of 158dca6)."""
    import inspect

    from study_setup import one_variant_study

    from spcopyro.study import run as study_run

    def in_process(cells):
        raise _Stop  # the first fit would start here

    monkeypatch.setattr(study_run, "_in_process", in_process)
    default = inspect.signature(study_run.run_study).parameters["describe"].default
    assert default is study_run._count_lines  # noqa: SLF001
    study = one_variant_study("said", seeds=1, num_trials=1)
    for describe, expected in (
        (default, ["study 'said': 1 of 1 cells to run (0 finished before), in-process"]),
        (lambda s, plan, where: [f"{s.name}: {len(plan.pending)} to run; where: {where}", "then"],
         ["said: 1 to run; where: in-process", "then"]),
    ):  # fmt: skip
        lines: list[str] = []
        with pytest.raises(_Stop):
            study_run.run_study(study, tmp_path / "out", progress=False, report=lines.append,
                                describe=describe)  # fmt: skip
        assert lines == expected
