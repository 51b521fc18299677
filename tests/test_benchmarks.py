"""The benchmarks run (smoke test with --quick); their numbers are never asserted here.

They run in a subprocess that imports this checkout's ``spcopyro`` (its root first on
PYTHONPATH), whichever copy the environment has installed.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"


def run_benchmark(script: str, out: Path) -> subprocess.CompletedProcess:
    """``python benchmarks/SCRIPT --quick --out OUT`` on this checkout's package."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return subprocess.run(
        [sys.executable, str(BENCHMARKS / script), "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=600, env={**os.environ, "PYTHONPATH": path},
    )  # fmt: skip


@pytest.mark.slow
def test_gibbs_benchmark_quick(tmp_path):
    out = tmp_path / "gibbs.json"
    done = run_benchmark("gibbs.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Targets" in done.stdout
    results = json.loads(out.read_text())
    assert results["machine"]["cpu_count"] >= 1
    # Issue 15's sections: every preset's run loop against the kernel, whole fits, chains.
    for title in ("Run loop against the bare kernel", "Whole `spcopyro fit`", "Many chains"):
        assert title in done.stdout
    assert [e["preset"] for e in results["run_loop"]] == [
        "paper-dp", "paper-dirichlet", "original-code", "auto"
    ]  # fmt: skip
    assert all(e["ratio"] > 0 for e in results["run_loop"])
    assert all("error" not in e and e["ms_per_sweep"] > 0 for e in results["fits"])
    assert sorted(results["numba_warm_s"]) == ["auto", "original-code", "paper-dp"]
    assert results["chains"]["as_fits"]["ratio"] > 0
    assert len(results["chains"]["as_fits"]["pair_sweeps_s"]) == 2  # the processes' reference
    assert "two single fits at once in two processes" in done.stdout
    inside = results["chains"]["in_process"]  # threads against processes, the same chains
    assert inside["torch_threads"] == 1 and inside["processes"]["wall_s"] > 0
    assert len(inside["processes"]["per_process_s"]) == inside["processes"]["processes"]
    assert "processes (no GIL shared)" in done.stdout


@pytest.mark.slow
def test_features_benchmark_quick(tmp_path):
    out = tmp_path / "features.json"
    done = run_benchmark("features.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert out.is_file() and json.loads(out.read_text())


@pytest.mark.slow
def test_threads_benchmark_quick(tmp_path):
    out = tmp_path / "threads.json"
    done = run_benchmark("threads.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Default threads against the policy" in done.stdout
    results = json.loads(out.read_text())
    assert {row["condition"] for row in results["load"]} == {"idle", "busy"}
    assert all(row["labels_identical"] for row in results["load"])


@pytest.mark.slow
def test_prior_thread_benchmark_quick(tmp_path):
    pytest.importorskip("numba")
    out = tmp_path / "prior_thread.json"
    done = run_benchmark("prior_thread.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert set(results["conditions"]) == {"as is", "busy neighbour"}
    assert all(c["same_draws_on_and_off"] for c in results["conditions"].values())


@pytest.mark.slow
def test_background_table_benchmark_quick(tmp_path):
    pytest.importorskip("numba")
    out = tmp_path / "background_table.json"
    done = run_benchmark("background_table.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    rows = json.loads(out.read_text())["houses"]
    assert rows[0]["house"] == "synthetic"
    assert all(r["dense_ms"] > 0 and r["factored_ms"] > 0 for r in rows)
    assert all(r["max_relative_difference"] < 1e-9 for r in rows)  # the same table


@pytest.mark.slow
def test_variational_benchmark_quick(tmp_path):
    out = tmp_path / "variational.json"
    done = run_benchmark("variational.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "CAVI ms  / Gibbs" in done.stdout
    results = json.loads(out.read_text())
    assert all(row["cavi_numba"]["ratio_to_gibbs"] > 0 for row in results["iterations"])
    assert results["ordering"]


@pytest.mark.slow
def test_svi_vs_cavi_benchmark_quick(tmp_path):
    out = tmp_path / "svi.json"
    done = run_benchmark("svi_vs_cavi.py", out)
    assert done.returncode == 0, done.stderr
    record = json.loads(out.read_text())
    assert record["steps"] == 10 and len(record["rows"]) == 1
    row = record["rows"][0]
    assert math.isfinite(row["svi_elbo"]) and math.isfinite(row["cavi_elbo"])
    assert "SVI below CAVI" in done.stdout


@pytest.mark.slow
def test_word_tables_benchmark_quick(tmp_path):
    out = tmp_path / "words.json"
    done = run_benchmark("word_tables.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "| original-code, gamma 3 | mean given labels |" in done.stdout
    records = json.loads(out.read_text())["records"]
    assert set(records["paper-dp"]) == {"draw", "mean given labels", "mean over samples"}


def test_word_tables_a_fit_that_did_not_model_its_words_is_not_measured(script):
    """word_tables' top-word score is nan (not measured) where no concept lists a word."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house
    from spcopyro.synthetic import HouseSpec, make_house

    word_tables = script("word_tables")
    house = make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=3, progress=False)
    names = house.category_names
    modelled = word_tables.top_word_agreement(result, house.truth, names)
    assert 0.0 <= modelled <= 1.0
    unmodelled = dataclasses.replace(result, config=result.config.replace(use_words=False))
    assert math.isnan(word_tables.top_word_agreement(unmodelled, house.truth, names))


def test_word_tables_table_leaves_unmeasured_seeds_out_and_says_so(script):
    """... and its table says "not measured" rather than 0.000 as if every top word were wrong."""

    def row(share: float) -> dict[str, float]:
        return {"matching_rate_pi": 0.5, "matching_rate_area": 0.5,
                "top_word_names_category": share}  # fmt: skip

    nan = float("nan")
    records = {"s": {"none": [row(nan), row(nan)], "some": [row(nan), row(0.5)],
                     "all": [row(0.25), row(0.75)]}}  # fmt: skip
    lines = script("word_tables").table(records).splitlines()
    assert lines[2].endswith("| 0.500 ± 0.000 | not measured |")
    assert lines[3].endswith("| 0.500 ± 0.000 (1/2 seeds) |")
    assert lines[4].endswith("| 0.500 ± 0.250 |")


@pytest.mark.slow
def test_merge_moves_benchmark_quick(tmp_path):
    out = tmp_path / "merge.json"
    done = run_benchmark("merge_moves.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "concepts>=1%" in done.stdout
    rows = json.loads(out.read_text())["rows"]
    assert [r["merge_moves"] for r in rows] == [0.0, 0.2]


@pytest.mark.slow
def test_online_update_benchmark_quick(tmp_path):
    out = tmp_path / "online.json"
    done = run_benchmark("online_update.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Online update (trials 1-2 fitted, then trial 3 added)" in done.stdout
    record = json.loads(out.read_text())
    (house,) = record["houses"]
    assert house["house"] == "synthetic" and len(house["runs"]) == 2
    points = house["runs"][0]["update"]["points"]
    assert [p["sweeps"] for p in points] == record["checkpoints"]
    assert house["runs"][0]["update"]["new_words"] == ["kitchen", "sofa"]


def test_fixed_cost_benchmark_quick(tmp_path):
    """Two fresh ``spcopyro fit --no-figures`` runs: their phases, the fixed cost, no PNG and
    none of the optional heavy modules imported (on the dataset's room2ldk4 if present, else the
    synthetic default house)."""
    out = tmp_path / "fixed_cost.json"
    done = run_benchmark("fixed_cost.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "fixed cost paper-dp" in done.stdout
    record = json.loads(out.read_text())
    (result,) = record["results"]
    assert list(record["numba_warm_s"]) == ["paper-dp"]
    assert [run["sweeps"] for run in result["runs"]] == [1, 3]
    for run in result["runs"]:
        assert run["pngs"] == [] and not run["with_figures"]
        assert "matplotlib" not in run["imported"], run["imported"]
        assert run["wall"] >= run["startup"] > 0.0 and run["sweep_seconds"] > 0.0
    assert math.isfinite(result["fixed_cost"]) and result["fixed_cost_method"]
    # the start-up table: the questions as whole processes, none importing torch/pyro/numba
    assert "start-up of the questions as whole processes" in done.stdout
    startup = record["startup"]
    commands = {row["command"]: row for row in startup["commands"]}
    assert list(commands) == ["python -c pass", "--help", "where", "export", "show (info)"]
    assert all(row["seconds"] > 0.0 for row in commands.values())
    assert startup["no_heavy_imports"], commands
    assert all(commands[name]["heavy_imported"] == [] for name in ("--help", "where", "export"))


@pytest.mark.slow
def test_real_houses_benchmark_quick(tmp_path):
    out = tmp_path / "real_houses.json"
    done = run_benchmark("real_houses.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert {"open-plan", "sparse", "dense"} <= set(results)
    if "public" in results:  # the dataset is there: every section ran
        assert {"heldout_top1", "methods", "simulated", "longer_chain"} <= set(results)
        assert "Held-out word top-1 (each trial held out in turn)" in done.stdout
        for rows in results["heldout_top1"].values():  # every fold's words pooled, and fold 0
            for row in rows.values():
                assert 0.0 <= row["trial 1"] <= 1.0 and 0.0 <= row["all folds"] <= 1.0
                assert row["all folds"] <= row["top 3"] <= 1.0 and row["mean rank"] >= 1.0
                assert row["words"] > 0
            for name in ("coarse", "auto", "paper-dp"):  # --quick: fit seed 0 alone
                assert list(rows[name]["seeds"]) == ["0"]
                assert rows[name]["seeds"]["0"]["all folds"] == rows[name]["all folds"]
        assert results["heldout_seeds"] == [0]
        assert "| mean of houses | pooled over words |" in done.stdout
        assert "Target: held-out word top-1 of coarse not below paper-dp's" in done.stdout
        for rows in results["simulated"].values():  # --quick: fit seed 0 and the mean over seeds
            assert list(rows) == ["fit seed 0", "mean"]
            assert rows["mean"]["ari"] == pytest.approx(rows["fit seed 0"]["ari"])


def test_real_houses_heldout_words_at_several_fit_seeds(script):
    """Issue 21: the held-out words fitted every preset at fit seed 0 alone, while the seeds'
    spread (default minus paper-dp -0.044 / +0.003 / -0.050 at seeds 0 / 1 / 2) was as large as
    the gap. Now each preset gets every seed of ``seeds`` on every fold: its scores are the mean
    of the per-seed scores it reports; the baselines, drawing nothing, are fitted once."""
    from spcopyro.synthetic import make_house

    rh = script("real_houses")
    house = make_house(seed=0)  # three trials: three folds
    rows = rh.heldout_top1(house, 3, seeds=[0, 1], presets=("paper-dp",))
    assert set(rows) == {"paper-dp", "E nearest", "F geometry 2 m"}
    fitted = rows["paper-dp"]
    assert list(fitted["seeds"]) == ["0", "1"]
    for key in ("all folds", "trial 1", "top 3", "mean rank"):
        per_seed = [fitted["seeds"][s][key] for s in ("0", "1")]
        assert fitted[key] == pytest.approx(sum(per_seed) / 2), key
    assert all(row["words"] == fitted["words"] > 0 for row in fitted["seeds"].values())
    assert "seeds" not in rows["E nearest"] and rows["E nearest"]["words"] == fitted["words"]
    with pytest.raises(ValueError, match="distinct"):
        rh.heldout_top1(house, 3, seeds=[0, 0], presets=("paper-dp",))


def test_real_houses_heldout_folds_pool_as_word_prediction_scores_do(script):
    """The folds are pooled by ``WordPredictionScores.pooled`` (the benchmark summed a
    ``[folds, 4]`` array of its own), and a fold that scores no word has no score: trial 1's
    top-1 is NaN with 0 words, where it was 0.0 (every word missed), and the pooling over the
    houses' words leaves such a house out. Trial 0 of a synthetic house is given only words the
    other trials never say, so fold 0 scores none."""
    from spcopyro.metrics import WordPredictionScores, heldout_word_prediction
    from spcopyro.synthetic import make_house

    rh = script("real_houses")
    house = make_house(seed=0)
    obs = house.observations
    trials = zip(obs.utterances, obs.word_trial, strict=True)
    unheard = tuple(("unheard",) if t == 0 else u for u, t in trials)
    house = dataclasses.replace(house, observations=dataclasses.replace(obs, utterances=unheard))
    rows = rh.heldout_top1(house, 3, seeds=[0], presets=("paper-dp",))
    for name in ("paper-dp", "E nearest", "F geometry 2 m"):
        row = rows[name]
        assert row["trial 1 words"] == 0 and math.isnan(row["trial 1"]), name
        assert row["words"] > 0 and 0.0 <= row["all folds"] <= 1.0, name
    folds = [heldout_word_prediction(rh.nearest_word_map(train.grid, train.observations), test)
             for _, _, train, test in rh.heldout_folds(house)]  # fmt: skip
    every = WordPredictionScores.pooled(folds)
    assert rows["E nearest"]["all folds"] == every.top1
    assert rows["E nearest"]["mean rank"] == every.mean_rank
    assert rows["E nearest"]["words"] == every.num_scored == sum(f.num_scored for f in folds[1:])
    scored = rh.heldout_top1(make_house(seed=0), 3, seeds=[0], presets=())
    per_house = {"none": rows, "some": scored}  # the house with no trial-1 word weighs nothing
    trial1 = rh.pooled(per_house, "E nearest", "trial 1")
    assert trial1 == pytest.approx(scored["E nearest"]["trial 1"])
    assert math.isnan(rh.pooled({"none": rows}, "E nearest", "trial 1"))


def test_real_houses_doc_counts_the_words_trial_1_scores(script, dataset_root):
    """docs/real_houses.md gives how many words each fold scores on the public houses (the
    nearest utterance's model knows the training trials' words, as every fit does): it said
    trial 1 alone scored 86 words, where fold 0 scores 53 (its own pooled column fits 53)."""
    from spcopyro.data import load_house
    from spcopyro.metrics import heldout_word_prediction

    rh = script("real_houses")
    per_fold, per_house = [0, 0, 0], []  # words scored: per fold over the houses, per house
    for name in rh.PUBLIC_CATEGORIES:
        house = load_house(dataset_root / name)
        scored = [heldout_word_prediction(rh.nearest_word_map(t.grid, t.observations), test)
                  .num_scored for _, _, t, test in rh.heldout_folds(house)]  # fmt: skip
        per_fold = [a + b for a, b in zip(per_fold, scored, strict=True)]
        per_house.append(sum(scored))
    text = " ".join((ROOT / "docs" / "real_houses.md").read_text().split())
    assert f"Trial 1 alone scores {per_fold[0]} words over the five houses" in text
    assert f"scores {sum(per_fold)} words ({', '.join(map(str, per_house))} a house)" in text
    assert f"one fold's {per_fold[0]} words" in text and " 86 words" not in text


def _heldout_row(top1_per_seed: list[float], words: int) -> dict:
    seeds = {str(s): {"all folds": v, "trial 1": v, "top 3": 1.0, "mean rank": 2.0,
                      "words": words, "trial 1 words": words // 3}
             for s, v in enumerate(top1_per_seed)}  # fmt: skip
    mean = sum(top1_per_seed) / len(top1_per_seed)
    return {"all folds": mean, "trial 1": mean, "top 3": 1.0, "mean rank": 2.0,
            "words": words, "trial 1 words": words // 3, "seeds": seeds}  # fmt: skip


def test_real_houses_heldout_target_judges_the_mean_over_seeds_beside_their_spread(script):
    """The target line judges the mean over the fit seeds and prints the per-seed differences'
    range and the mean's standard error; within two standard errors of 0 it says the spread
    leaves it undecided. The tables print the mean over the houses and the pooled share over
    their words, which differ when the houses score different numbers of words."""
    rh = script("real_houses")
    per_house = {  # default minus paper-dp: seed 0 -0.1, seed 1 +0.05 (mean of the two houses)
        "a": {"coarse": _heldout_row([0.2, 0.5], 10), "paper-dp": _heldout_row([0.3, 0.4], 10)},
        "b": {"coarse": _heldout_row([0.4, 0.4], 30), "paper-dp": _heldout_row([0.5, 0.4], 30)},
    }
    line = rh.heldout_target(per_house, "coarse", "paper-dp")
    assert "0.375 against 0.400, difference -0.025" in line  # the means over seeds and houses
    assert "per seed -0.100 to +0.050, standard error 0.075" in line
    assert line.endswith("not met on the mean; undecided at this spread (within 2 standard "
                         "errors of 0)")  # fmt: skip
    assert "pooled over words 0.388 against 0.425" in line  # (10 x 0.35 + 30 x 0.4) / 40
    table = rh.heldout_table("t", per_house, "all folds", "note")
    assert "| mean of houses | pooled over words |" in table
    assert "| coarse (mean of fit seeds 0, 1) | 0.35 | 0.40 | 0.375 | 0.388 |" in table
    assert "| coarse, seed 1 | 0.50 | 0.40 | 0.450 | 0.425 |" in table
    assert "| E" not in table and "| paper-dp, seed 0 | 0.30 | 0.50 | 0.400 | 0.450 |" in table
    per_house["a"]["coarse"] = _heldout_row([0.2, 0.25], 10)  # -0.05, -0.075: 5 errors below
    per_house["b"]["paper-dp"] = _heldout_row([0.4, 0.4], 30)
    assert rh.heldout_target(per_house, "coarse", "paper-dp").endswith(": not met")
    per_house["a"]["coarse"] = _heldout_row([0.6, 0.7], 10)  # +0.15 at both seeds
    assert rh.heldout_target(per_house, "coarse", "paper-dp").endswith(": met")
    one = {h: {n: {**row, "seeds": {"0": row["seeds"]["0"]}} for n, row in rows.items()}
           for h, rows in per_house.items()}  # fmt: skip
    assert "one seed: its spread unmeasured" in rh.heldout_target(one, "coarse", "paper-dp")


@pytest.mark.slow
def test_two_stage_benchmark_quick(tmp_path):
    """Every house kind gets the four rows, and the weight is the rule's on the explained share."""
    from spcopyro.fit.image_weight import image_weight

    out = tmp_path / "two_stage.json"
    done = run_benchmark("two_stage.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    kinds = {"open-plan", "sparse", "dense"}
    if "public" in results:  # the dataset is there
        kinds |= {"public", "simulated"}
    assert kinds <= set(results)
    for kind in kinds:
        for rows in results[kind].values():
            assert {"coarse", "coarse 2x", "two-stage", "two-stage auto"} <= set(rows)
            staged = rows["two-stage"]
            assert staged["weight"] == pytest.approx(image_weight(staged["explained"]))
            assert all(0.0 <= row["largest_share"] <= 1.0 for row in rows.values())


@pytest.mark.slow
def test_collapse_terms_benchmark_quick(tmp_path):
    out = tmp_path / "collapse_terms.json"
    done = run_benchmark("collapse_terms.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    for rows in results.values():
        for terms in rows.values():
            assert math.isfinite(terms["total"])


@pytest.mark.slow
def test_coarse_losses_benchmark_quick(tmp_path):
    out = tmp_path / "coarse_losses.json"
    done = run_benchmark("coarse_losses.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    rows = json.loads(out.read_text())["houses"]
    assert {"dense 0", "sparse 0"} <= set(rows)
    for row in rows.values():
        assert 0.0 <= row["ceiling"] <= 1.0 and row["wrong"] <= row["free"]
        assert math.isfinite(row["fit_minus_region_level"]["total"])


@pytest.mark.slow
def test_navigation_benchmark_quick(tmp_path):
    out = tmp_path / "navigation.json"
    done = run_benchmark("navigation.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert results["presets"] == ["coarse", "paper-dp"]
    for row in results["synthetic"].values():
        assert row["utterances"] > 0
        for method in ("coarse", "paper-dp", "baseline"):
            assert 0.0 <= row[method]["success"] <= 1.0
        assert 0.0 <= row["coarse"]["hierarchical"] <= 1.0
    assert "paper-dp success" in done.stdout and "baseline path/shortest" in done.stdout


def test_end_to_end_benchmark_quick(tmp_path):
    """Issue 25: one default fit of the embedded house as a whole process, split into start-up,
    data, sweeps, post-processing and outputs that add up to its wall; the start-up table."""
    out = tmp_path / "end_to_end.json"
    done = run_benchmark("end_to_end.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "default fit as a whole process" in done.stdout
    record = json.loads(out.read_text())
    (house,) = record["houses"]
    fit = house["fit"]
    # the embedded house is refined on its map's cells: 200 sweeps on the model grid, then 200
    assert house["house"] == "embedded" and fit["sweep_count"] == 400
    assert list(record["numba_warm_s"]) == ["embedded"]  # kernels cached before the timed fit
    parts = ("startup", "data", "sweeps", "post", "outputs")
    assert all(fit[name] > 0.0 for name in parts)
    assert math.isclose(sum(fit[name] for name in parts), fit["wall"], rel_tol=1e-6)
    assert {"semantic_map.png", "trace.png", "house.png", "agreement.png"} <= set(fit["pngs"])
    # the figures phase: since 5ab0c44 the semantic map is drawn by the figures' child, whose
    # seconds are not in the fit's timings; the phase holds the fit's share and its wait
    assert fit["post_parts"]["point_estimate"] > 0.0 and fit["post_parts"]["figures"] > 0.0
    assert record["startup"]["commands"][1]["command"] == "--help"
    # the start-up table names the house it used: the embedded one, whether the dataset is there
    assert record["startup"]["house"] == "embedded synthetic default house"
    assert "dataset absent" not in done.stdout


@pytest.mark.slow
def test_batched_gpu_benchmark_quick(tmp_path):
    out = tmp_path / "batched.json"
    done = run_benchmark("batched_gpu.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Batched sweep of embedded" in done.stdout
    rows = json.loads(out.read_text())["rows"]
    engines = {row["engine"] for row in rows}
    assert {"torch x1", "batched x1", "batched x4"} <= engines
    assert all(row["cells_per_s"] > 0 for row in rows)


@pytest.mark.slow
def test_study_order_benchmark_quick(tmp_path):
    """Both orders on a LocalCluster, alternated, the same numbers (benchmarks/study_order.py)."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    out = tmp_path / "study_order.json"
    done = run_benchmark("study_order.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert [run["order"] for run in results["runs"]][:2] == ["table", "longest first"]
    assert results["same_numbers"] is True and "mean wall" in done.stdout


# ---------------------------------------------------------------------------------------------
# The scripts' command lines, checked without running a benchmark: the scripts are imported
# from benchmarks/ (their folder on sys.path, as when they run) and parse their arguments.
# ---------------------------------------------------------------------------------------------


@pytest.fixture
def script(monkeypatch):
    """Import a benchmark script by name (``script("gibbs")``). ``CI=1`` as the scripts' own
    ``os.environ.setdefault("CI", "1")`` would set it (online_update.py, stochastic_vi.py: no bars
    in them or their children), but through monkeypatch, so that it ends with the test."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setenv("CI", "1")
    return importlib.import_module


class _Parsed(Exception):
    """Raised with a script's parsed arguments, before it measures anything."""


@pytest.fixture
def parse(script, monkeypatch):
    """``parse("gibbs", [...])``: the namespace the script's main() parses from the argv (the
    parser's own usage errors are SystemExit(2), as on the command line)."""
    original = argparse.ArgumentParser.parse_args

    def capture(self, args=None, namespace=None):
        raise _Parsed(original(self, args, namespace))

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)

    def parsed(name: str, argv: list[str]) -> argparse.Namespace:
        with pytest.raises(_Parsed) as got:
            script(name).main(argv)
        return got.value.args[0]

    return parsed


def test_dataset_root_note_or_one_line_error(script, tmp_path, monkeypatch, capsys):
    """An empty $SPCOPYRO_DATA: a note and None where the script can go on without the dataset,
    a one-line error (exit 2) where it cannot or where --dataset names a folder that is none."""
    bench_cli = script("bench_cli")
    monkeypatch.setenv("SPCOPYRO_DATA", str(tmp_path))
    assert bench_cli.dataset_root(without="the public houses are skipped") is None
    assert "holds no map/ folder; the public houses are skipped" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        bench_cli.dataset_root()
    assert stop.value.code == 2 and "error: dataset folder" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        bench_cli.dataset_root(tmp_path / "none", without="skipped")
    assert stop.value.code == 2


def test_a_quick_run_never_overwrites_the_full_runs_json(script, tmp_path):
    """--quick wrote its smoke numbers over benchmarks/NAME.json, the full run's results (an
    hour's work on some scripts): every script with --quick writes NAME_quick.json instead,
    through bench_cli.results_path (or names its _quick.json itself); --out still wins."""
    bench_cli = script("bench_cli")
    assert bench_cli.results_path(None, "x", quick=True) == BENCHMARKS / "x_quick.json"
    assert bench_cli.results_path(None, "x", quick=False) == BENCHMARKS / "x.json"
    assert bench_cli.results_path(tmp_path / "o.json", "x", quick=True) == tmp_path / "o.json"
    overwriting = [
        path.name
        for path in sorted(BENCHMARKS.glob("*.py"))
        if '"--quick"' in (text := path.read_text())
        and "results_path(" not in text
        and "_quick.json" not in text
        and path.name != "bench_cli.py"
    ]
    assert overwriting == []


def test_scripts_find_the_dataset_through_bench_cli():
    """find_dataset_root raises on an empty $SPCOPYRO_DATA: every script goes through
    bench_cli.dataset_root, which turns that into a note or a one-line error."""
    call = re.compile(r"(=|else|return)\s+find_dataset_root\(")
    calls = [
        path.name
        for path in BENCHMARKS.glob("*.py")
        if path.name != "bench_cli.py" and call.search(path.read_text())
    ]
    assert calls == []


def test_an_out_in_a_missing_folder_gets_its_folder_before_the_run(script, tmp_path, capsys):
    """A script whose --out named a folder that did not exist ran its measurements, then
    failed with a traceback when it wrote the JSON."""
    bench_cli = script("bench_cli")
    bench_cli.prepare_out_folder(["--quick", "--out", str(tmp_path / "a" / "b" / "r.json")])
    bench_cli.prepare_out_folder([f"--out={tmp_path / 'c' / 'r.json'}"])
    assert (tmp_path / "a" / "b").is_dir() and (tmp_path / "c").is_dir()
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit) as stop:
        bench_cli.prepare_out_folder(["--out", str(tmp_path / "file" / "r.json")])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "cannot make its folder" in err and "Traceback" not in err


@pytest.mark.parametrize("how", ["existing", "slash"])
def test_an_out_that_is_a_folder_is_an_error_before_the_run(script, tmp_path, capsys, how):
    """``--out /tmp`` ran the whole benchmark, then failed writing the JSON with an
    IsADirectoryError traceback (and ``--out new/`` made the folder to fail the same way)."""
    bench_cli = script("bench_cli")
    value = str(tmp_path) if how == "existing" else f"{tmp_path / 'new'}/"
    with pytest.raises(SystemExit) as stop:
        bench_cli.prepare_out_folder(["--out", value])
    err = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and len(err.splitlines()) == 1, err
    assert f"error: --out {value}: is a folder" in err
    assert not (tmp_path / "new").exists()


def test_run_main_interrupted_one_line_and_130(script, tmp_path, capsys):
    """Ctrl-C: no traceback, one line saying what was (not) written, exit status 130."""
    bench_cli = script("bench_cli")

    def interrupted() -> int:
        raise KeyboardInterrupt

    with pytest.raises(SystemExit) as stop:
        bench_cli.run_main(interrupted)
    assert stop.value.code == 130
    assert capsys.readouterr().err.strip() == "interrupted: no JSON written"
    partial = tmp_path / "x.partial.json"
    partial.write_text("[]")
    bench_cli.WRITTEN.append(partial)
    try:
        with pytest.raises(SystemExit):
            bench_cli.run_main(interrupted)
    finally:
        bench_cli.WRITTEN.remove(partial)
    assert f"interrupted: {partial} holds the results so far" in capsys.readouterr().err


CTRL_C_AT_EXIT = """
import atexit, os, signal, sys, time
sys.path.insert(0, sys.argv[1])
from bench_cli import run_main


def ctrl_c_during_shutdown():  # a Ctrl-C while torch's exit callbacks run, after "wrote ..."
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(5)


def main():
    atexit.register(ctrl_c_during_shutdown)
    print("wrote results.json", file=sys.stderr)
    return {code}


run_main(main)
"""


@pytest.mark.parametrize("code", [0, "KeyboardInterrupt()"])
def test_ctrl_c_during_the_exit_is_no_traceback(tmp_path, code):
    """A Ctrl-C once main is done (its JSON written, or the interrupt reported), while the
    interpreter shuts down: the script ends quietly with main's status; it printed a
    KeyboardInterrupt traceback from an atexit callback after "wrote ..."."""
    source = CTRL_C_AT_EXIT.format(code=code)
    if code != 0:
        source = source.replace("    return KeyboardInterrupt()", "    raise KeyboardInterrupt")
    script = tmp_path / "ctrl_c_at_exit.py"
    script.write_text(source)
    done = subprocess.run([sys.executable, str(script), str(BENCHMARKS)], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, done.stderr
    if code == 0:
        assert (done.returncode, done.stderr) == (0, "wrote results.json\n")
    else:
        assert done.returncode == 130
        assert done.stderr.strip().endswith("interrupted: no JSON written")


def test_every_script_runs_main_through_run_main():
    """Each runnable script ends in bench_cli.run_main(main), not sys.exit(main())."""
    runnable = [p for p in BENCHMARKS.glob("*.py") if '__name__ == "__main__"' in p.read_text()]
    assert len(runnable) >= 20
    assert [p.name for p in runnable if "    run_main(main)\n" not in p.read_text()] == []


@pytest.mark.slow
def test_footprint_quick_leaves_no_partial_file(tmp_path):
    out = tmp_path / "footprint.json"
    done = run_benchmark("footprint.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(out.read_text())["rows"]
    assert not (tmp_path / "footprint.partial.json").exists()


@pytest.mark.parametrize("name", ["coarse_losses", "collapse_terms", "navigation", "real_houses",
                                  "study_dask", "study_order", "two_stage"])  # fmt: skip
def test_default_out_is_beside_the_script(parse, script, name, tmp_path, monkeypatch):
    """The default --out is benchmarks/NAME.json wherever the script is run from (it was
    relative to the current folder: the run failed at the end, writing the JSON)."""
    monkeypatch.chdir(tmp_path)
    args = parse(name, [])
    assert args.out is None  # bench_cli.results_path's: NAME.json, or NAME_quick.json
    assert script("bench_cli").results_path(args.out, name, args.quick) == (
        BENCHMARKS / f"{name}.json"
    )


@pytest.fixture
def keep_torch_threads():
    """Some scripts set torch's thread count before they check their houses: restore it."""
    import torch

    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)


BAD_VALUES = [
    ("study_order", ["--quick", "--repeats", "0"], "--repeats"),
    ("merge_moves", ["--sweeps", "-5"], "--sweeps"),
    ("merge_moves", ["--quick", "--merge-moves", "-1"], "--merge-moves"),
    ("hyperparameters", ["--sweeps", "-1"], "--sweeps"),
    ("features", ["--quick", "--batch-sizes", "-1", "--no-dataset"], "--batch-sizes"),
    ("variational", ["--quick", "--torch-threads", "0"], "--torch-threads"),
    ("end_to_end", ["--quick", "--sweeps", "-5", "--no-startup"], "--sweeps"),
    ("prior_thread", ["--quick", "--busy-cores", "-1"], "--busy-cores"),
    ("study_dask", ["--quick", "--pairs", "0"], "--pairs"),
    ("fixed_cost", ["--repeats", "-1"], "--repeats"),
    ("fixed_cost", ["--sweeps", "3", "1"], "--sweeps"),
    ("batched_gpu", ["--seconds", "-1"], "--seconds"),
    ("batched_gpu", ["--torch-threads", "0"], "--torch-threads"),
    ("word_tables", ["--quick", "--seeds", "-1"], "--seeds"),
    ("svi_vs_cavi", ["--quick", "--steps", "-1"], "--steps"),
    ("real_houses", ["--quick", "--sweeps", "-1"], "--sweeps"),
    ("footprint", ["--quick", "--radii", "-1"], "--radii"),
    ("gibbs", ["--quick", "--wait-idle", "-1"], "--wait-idle"),
    # A preset or gamma the model refuses: a usage error, not its ValueError after the setup.
    ("merge_moves", ["--quick", "--preset", "bogus"], "--preset"),
    ("merge_moves", ["--quick", "--gamma", "-1"], "--gamma"),
    ("online_update", ["--quick", "--preset", "bogus"], "--preset"),
    ("online_update", ["--quick", "--gamma", "nan"], "--gamma"),
    ("variational", ["--quick", "--presets", "paper-dp,bogus"], "--presets"),
    ("fixed_cost", ["--quick", "--presets", "bogus"], "--presets"),
    # A map too small for HouseSpec.scaled: was a HouseSpecError traceback from the first child.
    ("stochastic_vi", ["--quick", "--side", "19"], "--side"),
]


@pytest.mark.parametrize(("name", "argv", "option"), BAD_VALUES)
def test_bad_values_are_usage_errors_naming_the_option(script, capsys, name, argv, option):
    """A count below 1 (or a share outside [0, 1], a negative time) is an argparse usage error
    naming the option (exit 2), also under --quick: no traceback, nothing run, no silent -1."""
    with pytest.raises(SystemExit) as stop:
        script(name).main(argv)
    assert stop.value.code == 2
    assert f"argument {option}" in capsys.readouterr().err


BAD_NAMES = [
    ("threads", ["--quick", "--backends", "torch,bogus"], "--backends"),
    ("features", ["--quick", "--no-dataset", "--devices", "bogus"], "--devices"),
    ("features", ["--quick", "--no-dataset", "--weights", "/nonexistent/alexnet.pt"], "--weights"),
    # No house at all: end_to_end.py fitted none and printed "... on every house: PASS".
    ("end_to_end", ["--houses", ",", "--no-startup"], "--houses"),
]


@pytest.mark.parametrize(("name", "argv", "option"), BAD_NAMES)
def test_bad_names_are_one_line_errors(script, capsys, name, argv, option):
    """A backend, device or weights file that is not there: a one-line error naming the option
    (exit 2) before anything is measured; threads.py measured the other backend with a note,
    features.py failed with torch's (or the loader's) traceback after loading the model."""
    with pytest.raises(SystemExit) as stop:
        script(name).main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert f"error: {option}" in err.splitlines()[-1], err
    assert "Traceback" not in err, err


def test_an_option_given_explicitly_wins_over_quick(script):
    """The rule of every script (benchmarks/README.md): --quick only changes the defaults."""
    fixed_cost, batched_gpu = script("fixed_cost"), script("batched_gpu")
    assert fixed_cost.parse_args(["--quick"]).repeats == 1
    assert fixed_cost.parse_args(["--quick", "--repeats", "2"]).repeats == 2
    assert fixed_cost.parse_args(["--quick", "--sweeps", "2", "5"]).sweeps == (2, 5)
    assert fixed_cost.parse_args([]).sweeps == fixed_cost.SWEEPS
    assert batched_gpu.parse_args(["--quick"]).seconds == 0.2
    assert batched_gpu.parse_args(["--quick", "--seconds", "1"]).seconds == 1.0
    assert script("bench_cli").quick_or(None, True, 1, 2) == 1


@pytest.mark.skipif(sys.version_info < (3, 11), reason="PYTHONSAFEPATH is Python 3.11's")
def test_fixed_cost_times_its_own_checkout_from_any_working_directory(tmp_path, script):
    """fixed_cost.py's timed processes import the script's own checkout's ``spcopyro`` from a
    working directory that holds another (the root of another checkout): ``python -m spcopyro``
    and ``python -c`` put the working directory before ``PYTHONPATH``, so a worktree's script of
    the code before a change, run from this checkout's root, timed this checkout's package."""
    decoy = tmp_path / "spcopyro"
    decoy.mkdir()
    (decoy / "__init__.py").write_text('raise ImportError("the working directory\'s copy")\n')
    env = script("fixed_cost")._environment()
    done = {}
    for program in (["-c", "import spcopyro; print(spcopyro.__file__)"],
                    ["-m", "spcopyro", "--help"]):  # fmt: skip
        done[program[0]] = subprocess.run([sys.executable, *program], cwd=tmp_path, env=env,
                                          capture_output=True, text=True, timeout=120)  # fmt: skip
    for run in done.values():  # the decoy's ImportError fails either
        assert run.returncode == 0, run.stderr
    assert Path(done["-c"].stdout.strip()) == ROOT / "spcopyro" / "__init__.py"


UNKNOWN_HOUSES = [
    ("end_to_end", ["--houses", "bogus", "--sweeps", "5", "--no-startup"]),
    ("merge_moves", ["--public", "bogus", "--sweeps", "4"]),
    ("navigation", ["--quick", "--houses", "bogus"]),
    ("footprint", ["--houses", "bogus", "--presets", "paper-dp", "--seeds", "0", "--sweeps", "5"]),
    ("fixed_cost", ["--quick", "--house", "bogus"]),
    ("online_update", ["--quick", "--houses", "bogus"]),
]


@pytest.mark.parametrize(("name", "argv"), UNKNOWN_HOUSES)
def test_an_unknown_house_is_a_one_line_error(script, capsys, keep_torch_threads, name, argv):
    """A house asked for by name that the dataset lacks: one line naming it and the houses
    there, exit 2 (fixed_cost fitted the synthetic house instead and exited 0)."""
    with pytest.raises(SystemExit) as stop:
        script(name).main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "error: --house" in err or "error: --public" in err, err
    assert "bogus" in err, err
    assert len(err.splitlines()) == 1, err


def test_merge_moves_warms_up_before_the_timed_chains(script, tmp_path, keep_torch_threads):
    """The baseline chain ran first, cold: numba's compilation was charged to it (26.6 ms a
    sweep against 3.4 with moves). Now a short untimed chain of each setting runs first."""
    merge_moves = script("merge_moves")
    calls = []
    original = merge_moves.run_chain

    def recording(house, preset_name, share, sweeps, *args, **kwargs):
        calls.append((share, sweeps))
        return original(house, preset_name, share, sweeps, *args, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(merge_moves, "run_chain", recording)
        assert merge_moves.main(["--quick", "--out", str(tmp_path / "m.json")]) == 0
    warm = merge_moves.WARMUP_SWEEPS
    assert calls == [(0.0, warm), (1.0, warm), (0.0, 12), (0.2, 12)]
    # --merge-moves 0: the baseline alone, once (it ran and printed two identical rows).
    calls.clear()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(merge_moves, "run_chain", recording)
        argv = ["--quick", "--merge-moves", "0", "--out", str(tmp_path / "m0.json")]
        assert merge_moves.main(argv) == 0
    assert calls == [(0.0, warm), (0.0, 12)]


def test_merge_moves_estimates_join_specks_as_fit_does(script, keep_torch_threads):
    """The VI / Binder estimates are those ``spcopyro fit`` reports: its specks joined to other
    clusters, told by the words heard at each cell (``words_per_cell``, as fit's
    ``with_posterior_means`` passes). The benchmark called the raw point estimate without them,
    so its estimates kept the speck concepts that fit's ``vi`` joins."""
    import numpy as np

    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.results.posterior_means import words_per_cell
    from spcopyro.synthetic import make_house

    merge_moves = script("merge_moves")
    house = make_house(seed=0)
    settings = preset("paper-dp")
    expected = words_per_cell(prepare_model_data(house, settings)[1], settings.data.word_scaling)
    calls = []
    original = merge_moves.point_estimate

    def recording(samples, loss, **kwargs):
        calls.append((loss, kwargs.get("cell_words")))
        return original(samples, loss, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(merge_moves, "point_estimate", recording)
        row = merge_moves.run_chain(house, "paper-dp", 0.0, 4, 0, 2, quiet=True)
    assert [loss for loss, _ in calls] == ["vi", "binder"]
    for _, cell_words in calls:
        assert cell_words is not None
        np.testing.assert_array_equal(cell_words, expected)
    assert set(row["specks_joined"]) == {"vi", "binder"}
    assert all(v["cells"] >= v["specks"] >= 0 for v in row["specks_joined"].values())


def test_study_tables_name_the_cells_and_columns_that_differ(script):
    """study_order.py judged 'same numbers' by the whole tables and once said False with no
    word of where; the timing columns of observations-off runs were compared too."""
    study_dask = script("study_dask")
    row = {"key": "a" * 20, "ari": 0.5, "source_digest": "x"}
    assert study_dask.differences([row], [dict(row)]) == []
    found = study_dask.differences([row], [{**row, "source_digest": "y"}])
    assert found == ["aaaaaaaaaaaa source_digest: 'x' != 'y'"]
    assert study_dask.differences([row], []) == [f"{'a' * 20}: missing from the other table"]
    assert {"seconds_off", "cpu_seconds_off"} <= set(study_dask.TIMING)


def test_coarse_losses_table_cells_are_text_not_python_reprs(script):
    """coarse_losses.py printed its split regions, wrong cells by distance and log-joint terms
    as Python reprs ("{1: 0.47}", "[7, 7, 7]", "{'labels': 0.0, ...}") in a markdown table."""
    coarse_losses = script("coarse_losses")
    errors = {"region_level_ari": 0.876, "split": {1: 0.47, 3: 0.2}, "specks": 0, "wrong": 7,
              "free": 3600, "wrong_within_0.3_0.6_1m": [5, 6, 7]}  # fmt: skip
    joint = {"labels": -0.5, "potts": -42.0, "images": 1.25, "words": 3.0, "total": -38.25}
    row = coarse_losses.table_row("dense 0", 0.8731, 0.995, errors, joint)
    assert len(row) == len(coarse_losses.HEADERS)
    assert row[4:] == ["1: 47 %, 3: 20 %", "0", "7 of 3600", "5 / 6 / 7",
                       "-38.2 (-0.5, -42.0, +1.2, +3.0)"]  # fmt: skip
    empty = coarse_losses.table_row("d", 1.0, 1.0, {**errors, "split": {}}, joint)
    assert empty[4] == "-"


def test_gibbs_whole_fit_speedup_is_against_the_house_the_fit_fitted(script, monkeypatch):
    """Without the dataset `spcopyro fit` fits the embedded default house (3600 cells): the
    per-cell loop its speed-up divides by was timed on the headline house's ~28k-cell stand-in,
    so the ">= 600x the per-cell loop" verdict compared two different houses."""
    gibbs, bench_setup = script("gibbs"), script("bench_setup")
    from spcopyro.synthetic import HouseSpec, make_house

    timed = []
    monkeypatch.setattr(gibbs, "whole_fit", lambda path, name, sweeps: {"ms_per_sweep": 1.0})
    monkeypatch.setattr(gibbs, "time_per_cell", lambda problem, sweeps: timed.append(
        (problem.name, problem.data.num_free)) or {"seconds_per_iteration": 1.0})  # fmt: skip
    stand_in = make_house(seed=0, spec=HouseSpec.scaled(30, 30), name="stand-in")
    fits = gibbs.bench_fits(None, stand_in, gibbs.QUICK, skip_baseline=False)
    embedded = bench_setup.embedded_default_house()
    assert [f["house"] for f in fits] == [None] * len(gibbs.FIT_PRESETS)
    assert {name for name, _ in timed} == {embedded.name} != {"stand-in"}
    assert {cells for _, cells in timed} == {int(embedded.grid.num_free)}


def test_variational_targets_line_counts_the_rows_that_pass(script):
    """variational.py's verdict line read "FAIL (2 of 4 rows)" for 2 rows passing of 4."""
    line = script("variational").targets_line([False, False, True, True])
    assert line.endswith(": FAIL (2 of 4 rows pass)"), line


def test_quick_tables_say_what_min_rise_and_reached_measure(script):
    """stochastic_vi.py's 'min rise', footprint.py's 'reached' and online_update.py's
    'reached' rows did not say of what (the ELBO per pass at full gamma; the share of free
    cells the data reach; the first update length at the scratch fit's log joint)."""
    small = {"house": "h", "method": "m", "free_cells": 10, "passes": 3, "final_elbo": -1.0,
             "ari": 1.0, "concepts": 2, "seconds": 1.0, "seconds_per_pass": 0.3,
             "min_elbo_rise_at_full_gamma": -0.5}  # fmt: skip
    header = script("stochastic_vi").render({"small": [small]}).splitlines()[1]
    assert header.endswith("min ELBO rise per pass at full gamma"), header
    row = {"preset": "p", "house": "h", "fit": "f", "ari_truth": 1.0, "ari_between_seeds": None,
           "ari_vs_no_observations": 1.0, "concepts_1pct": 2, "cells_reached": 5,
           "free_cells": 10, "seconds": 1.0}  # fmt: skip
    header = script("footprint").summary_table({"rows": [row]}).splitlines()[0]
    assert "share of cells reached" in header, header
    point = {"sweeps": 0, "best_log_joint": 0.0, "typical_log_joint": 0.0, "seconds": 1.0,
             "ari_vs_scratch": 1.0, "concepts": 2}  # fmt: skip
    run = {"scratch": {"wall_seconds": 1.0, "best_log_joint": 0.0, "typical_log_joint": 0.0,
                       "concepts": 2}, "update": {"points": [point]},
           "reached": 0, "reached_typical": None}  # fmt: skip
    text = script("online_update").table([{"house": "h", "runs": [run],
                                           "scratch_vs_scratch_ari": []}], 10)  # fmt: skip
    assert "first sweeps: best LJ >= scratch" in text, text
    assert "first sweeps: typical LJ >= scratch" in text, text


def test_prior_thread_warms_every_setting_before_timing(script, monkeypatch):
    """The warm-up chain ran the default setting (one-pass) only: the first timed block of
    'worker off' loaded the two-part draw's kernels, and a --quick run printed it at 765 ms a
    sweep (105x one-pass) against 9 ms next to a busy neighbour. One untimed sweep of each
    setting now comes first."""
    import torch

    from spcopyro.gibbs import numba_globals

    prior_thread = script("prior_thread")
    modes = []
    monkeypatch.setattr(prior_thread, "make_sweep_plan", lambda data: None)

    def sweep(state, *_):
        modes.append(numba_globals.prior_thread())
        return state

    monkeypatch.setattr(prior_thread, "gibbs_sweep_numba", sweep)
    state = argparse.Namespace(labels=torch.zeros(3), log_emissions=(torch.zeros(2),))
    problem = argparse.Namespace(data=argparse.Namespace(num_free=3), config=None)
    record = prior_thread.time_condition(problem, state, blocks=2, block=3)
    assert modes[:3] == ["one-pass", "off", "on"], modes[:3]
    assert len(modes) == 3 + 2 * 3 * 3 and record["same_draws_on_and_off"]


def test_readme_names_the_json_each_quick_run_writes():
    """benchmarks/README.md said svi_vs_cavi.py, word_tables.py and hyperparameters.py write
    their NAME.json "also with --quick": they write NAME_quick.json (bench_cli.results_path),
    as their --help says. Every NAME_quick.json the README names is one a script writes."""
    readme = (BENCHMARKS / "README.md").read_text()
    assert "also with `--quick`" not in readme
    written = {"NAME_quick.json"}
    for path in BENCHMARKS.glob("*.py"):
        source = path.read_text()
        calls = [line for line in source.splitlines() if "results_path(" in line]
        written |= {f"{n}_quick.json" for line in calls for n in re.findall(r'"(\w+)"', line)}
        written |= set(re.findall(r'"(\w+_quick\.json)"', source))
    named = set(re.findall(r"(?<![/\w])(\w+_quick\.json)", readme))  # not an --out /tmp/... example
    assert named and named <= written, sorted(named - written)


def test_variational_judges_cavi_over_gibbs_with_the_other_targets(script):
    """Issue 20's target, CAVI / Gibbs <= 2 (benchmarks/README.md), was judged "yes" / "no" in
    its column and left out of the Targets line: a run whose every CAVI row missed it still
    printed "Targets: ... PASS"."""
    variational = script("variational")
    cavi = {"seconds": 3e-3, "ratio_to_gibbs": 3.0, "mean_support": 2.0, "first_seconds": [3e-3],
            "first_ratio": 1.0, "warmup_excess_iterations": 0.0, "elbo_decreases": 0,
            "largest_elbo_decrease": 0.0, "elbo": -1.0}  # fmt: skip
    row = {"house": "h", "preset": "paper-dp", "L": 10, "cells": 9,
           "gibbs_numba": {"seconds": 1e-3}, "cavi_numba": cavi,
           "lbp_numba": {"seconds": 3e-3, "ratio_to_cavi": 1.0}}  # fmt: skip
    results = {"iterations": [row], "lbp_backend": "numba", "first_calls_s": {"cavi": 1, "lbp": 1},
               "ordering": [], "total_s": 1.0, "out": "x.json"}  # fmt: skip
    text = variational.render(results)
    first_row = text.splitlines()[4]
    assert first_row.split()[7] == "FAIL", first_row
    assert "CAVI / Gibbs <= 2" in text and text.count(": FAIL (2 of 3 rows pass)") == 1, text


def test_stochastic_vi_warms_every_variant_before_the_timed_runs(script, monkeypatch):
    """The small houses' table timed each variant cold: the first memoized row of each dtype
    paid numba's compilation (a --quick run on a fresh checkout: 0.78 s against 0.03 s for the
    next variant, 0.84 s for the first float64 one). Each runs untimed first."""
    import numpy as np
    import torch

    from spcopyro.guides import memoized, run

    stochastic_vi = script("stochastic_vi")
    calls = []

    def fake(kind):
        def fit(data, config, passes, **kwargs):
            calls.append((kind, passes))
            return argparse.Namespace(
                objective=np.zeros(passes), gammas=np.full(passes, config.gamma),
                labels=torch.zeros(data.num_free, dtype=torch.long),
                num_concepts=np.ones(passes), seconds=np.ones(passes),
            )  # fmt: skip

        return fit

    monkeypatch.setattr(run, "run_variational", fake("cavi"))
    monkeypatch.setattr(memoized, "run_stochastic", fake("memoized"))
    rows = stochastic_vi.bench_small(passes=6, anneal=2)
    warm = getattr(stochastic_vi, "WARMUP_PASSES", 2)
    assert calls[:6] == [("cavi", warm)] + [("memoized", warm)] * 5, calls[:6]
    assert calls[6:] == ([("cavi", 6)] + [("memoized", 6)] * 5) * 2 and len(rows) == 12


def test_fixed_cost_quick_startup_only_keeps_the_full_runs_startup_json(script, tmp_path):
    """fixed_cost.py --quick --startup-only wrote its one repeat over benchmarks/startup.json,
    the full --startup-only run's results."""
    fixed_cost = script("fixed_cost")

    def out(*argv):
        return fixed_cost.results_file(fixed_cost.parse_args(list(argv)))

    assert out("--quick", "--startup-only") == BENCHMARKS / "startup_quick.json"
    assert out("--startup-only") == BENCHMARKS / "startup.json"
    assert out("--quick") == BENCHMARKS / "fixed_cost_quick.json"
    assert out() == BENCHMARKS / "fixed_cost.json"
    given = tmp_path / "s.json"
    assert out("--quick", "--startup-only", "--out", str(given)) == given


def test_study_dask_judges_one_pair_too(script):
    """study_dask.py --quick (and --pairs 1, a README command line) printed the ratio and
    'target <= 0.6' but no PASS/FAIL: the verdict came only with two pairs or more."""
    study_dask = script("study_dask")
    one = study_dask.verdict_lines(2.8, True, [(1.3, 3.6)])
    assert one[-1].startswith("one pair, ratio 2.77 (target <= 0.6): FAIL"), one
    many = study_dask.verdict_lines(0.5, True, [(10.0, 5.0), (10.0, 7.0), (10.0, 5.5)])
    assert many[-1] == "median ratio 0.55 (target <= 0.6): PASS", many


class _Measuring(Exception):
    """Raised where a script would start measuring."""


@pytest.mark.parametrize(("name", "argv", "first_measure"), [
    ("end_to_end", ["--sweeps", "2", "--no-startup"], "fit_default"),
    ("hyperparameters", ["--sweeps", "2", "--public-sweeps", "2"], "run_variant"),
])  # fmt: skip
def test_no_dataset_is_one_note_line(script, monkeypatch, capsys, name, argv, first_measure):
    """Without the dataset (benchmarks/README.md: one `note: ...` line on stderr and the run
    goes on), end_to_end.py and hyperparameters.py printed a second note saying it again."""
    module = script(name)
    monkeypatch.setenv("SPCOPYRO_DATA", "/nonexistent")

    def measuring(*args, **kwargs):
        raise _Measuring

    monkeypatch.setattr(module, first_measure, measuring)
    with pytest.raises(_Measuring):
        module.main(argv)
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "/nonexistent" in notes[0], notes


def test_gibbs_memory_target_names_its_run(script):
    """gibbs.py's memory target read "peak memory of that run < 1 GiB"; under --quick the line
    before it is the per-cell speed-up, not the 5000-sweep run it meant."""
    report = script("gibbs_report")
    headline = {"sweeps": 20, "synthetic_stand_in": False, "wall_s": 1.0, "backend": "numba",
                "peak_rss_bytes": 700 << 20}  # fmt: skip
    targets = report.evaluate_targets({"houses": [], "headline": headline, "backends": []})
    memory = [t for t in targets if "GiB" in t["target"]]
    assert len(memory) == 1 and memory[0]["ok"], targets
    assert memory[0]["target"].startswith("peak memory of the headline run_gibbs (20 sweeps, ")


def test_footprint_warms_up_before_the_first_timed_fit(script, monkeypatch):
    """footprint.py's first fit (the first house's 'no observations') paid numba's load in its
    seconds: a --quick run printed 1.5 s a fit against 0.1 s for the fits with observations.
    Untimed short fits, without and with observations, come first."""
    footprint = script("footprint")
    calls = []

    def fit(house, settings, sweeps, seed):
        calls.append((settings.model.use_images, sweeps))
        if sweeps == 7:  # the first timed fit
            raise _Measuring

    monkeypatch.setattr(footprint, "fit_spco", fit)
    args = argparse.Namespace(presets=["paper-dp"], houses=["synthetic"], seeds=[0], sweeps=7,
                              radii=[0.0])  # fmt: skip
    with pytest.raises(_Measuring):
        footprint.run(args)
    warm = getattr(footprint, "WARMUP_SWEEPS", 2)
    assert calls == [(False, warm), (True, warm), (False, 7)], calls


def test_stochastic_vi_cavi_baseline_leaves_out_the_kernels_load(script, monkeypatch):
    """The large map's baseline, seconds a CAVI iteration, was the whole run over its 2-3
    iterations, the first of which loads the compiled kernels, while the memoized run's pass
    was a median: the ratio 'time per pass / CAVI iteration' charged the load to CAVI only."""
    import numpy as np
    import torch

    from spcopyro.guides import run

    stochastic_vi = script("stochastic_vi")

    def fit(data, config, iterations, **kwargs):
        return argparse.Namespace(seconds=np.array([5.0, 6.0, 7.5]), objective=np.zeros(3),
                                  labels=torch.zeros(data.num_free, dtype=torch.long))  # fmt: skip

    monkeypatch.setattr(run, "run_variational", fit)
    record = stochastic_vi.child_cavi(stochastic_vi.MIN_SIDE, 3)
    assert record["seconds_per_iteration"] == 1.25, record
    assert record["first_iteration_s"] == 5.0 and record["backend"] in ("numba", "torch")


def test_stochastic_vi_cavi_baseline_times_its_setup_apart(script, monkeypatch):
    """docs/variational.md quoted 9.9 s a CAVI iteration at 10^6 cells: the whole
    run_variational call over its iterations, its own setup included. The child now records
    the model data's time and run_variational's setup before its first iteration apart."""
    import numpy as np
    import torch

    from spcopyro.guides import run

    stochastic_vi = script("stochastic_vi")
    clock = iter([100.0, 102.0, 110.0, 120.0])  # data built in 2 s; the run call takes 10 s

    def fit(data, config, iterations, **kwargs):
        return argparse.Namespace(seconds=np.array([5.0, 6.0, 7.5]), objective=np.zeros(3),
                                  labels=torch.zeros(data.num_free, dtype=torch.long))  # fmt: skip

    monkeypatch.setattr(run, "run_variational", fit)
    monkeypatch.setattr(stochastic_vi, "time", argparse.Namespace(perf_counter=lambda: next(clock)))
    record = stochastic_vi.child_cavi(stochastic_vi.MIN_SIDE, 3)
    assert record["data_s"] == 2.0, record
    assert record["run_s"] == 10.0 and record["setup_s"] == 2.5, record
    assert record["seconds_per_iteration"] == 1.25, record
    memory = {"peak_rss_bytes": 0, "rss_after_data_bytes": 0, "q_bytes": 0}
    text = stochastic_vi.render({"small": [], "large_cavi": {**record, **memory}})
    assert "model data 2.0 s" in text and "first iteration 2.5 s" in text, text


QUICK_SIZES = {"threads.py": {"sweeps", "repeats", "sides"}}
"""Options whose default --quick changes through a sizes record, not bench_cli.quick_or."""


def _script_parsers(script, monkeypatch):
    """(path, source, argument parser) of every benchmark script that runs a main, its parser
    caught as main parses its arguments."""

    def capture(self, args=None, namespace=None):
        raise _Parsed(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    for path in sorted(BENCHMARKS.glob("*.py")):
        source = path.read_text()
        if "    run_main(main)\n" not in source or path.name == "bench_cli.py":
            continue
        with pytest.raises(_Parsed) as got:
            script(path.stem).main([])
        yield path, source, got.value.args[0]


def test_every_option_quick_changes_says_both_defaults_in_its_help(script, monkeypatch):
    """benchmarks/README.md: each option's --help gives both defaults. real_houses.py's
    --sweeps, --seeds, --open-plan-seeds, --method-iterations and --fit-seeds gave neither
    --quick's value (60, 1, 1, 5, 0) nor, for three of them, the full run's; threads.py's
    --sweeps, --repeats and --sides neither."""
    parsers = {}
    silent = []
    for path, source, parser in _script_parsers(script, monkeypatch):
        parsers[path.name] = parser
        quick = set(re.findall(r"quick_or\(\s*args\.(\w+)", source))
        quick |= QUICK_SIZES.get(path.name, set())
        for action in parser._actions:
            words = set(re.findall(r"\w+", action.help or ""))
            if action.dest in quick and not {"default", "quick"} <= words:
                silent.append(f"{path.name} {action.option_strings[0]}")
    assert len(parsers) >= 20 and silent == [], silent


def test_every_out_help_names_the_json_files_the_script_writes(script, monkeypatch):
    """The brief of benchmarks/README.md: a script writes its JSON where --help says. The --out
    of batched_gpu, features ('features_*.json'), footprint, merge_moves, prior_thread,
    stochastic_vi and variational named no default file."""
    wrong = []
    for path, source, parser in _script_parsers(script, monkeypatch):
        (out,) = [a for a in parser._actions if a.dest == "out"]
        named = set(re.findall(r"(?<![.\w])(\w+\.json)", out.help or ""))
        calls = [line for line in source.splitlines() if "results_path(" in line]
        written = set(re.findall(r'"(\w+\.json)"', source)) | {
            f"{n}{suffix}.json" for line in calls for n in re.findall(r'"(\w+)"', line)
            for suffix in ("", "_quick")
        }  # fmt: skip
        quick = {n for n in named if n.endswith("_quick.json")}
        if not quick or not named - quick or not named <= written:
            wrong.append(f"{path.name}: {out.help!r}")
    assert wrong == [], wrong


def test_readme_lists_every_script_with_command_lines_that_parse(script, monkeypatch):
    """Every runnable script has a `python benchmarks/NAME.py ...` line in benchmarks/README.md
    (rendered as docs/benchmarks.md), and each such line's options parse."""
    readme = (BENCHMARKS / "README.md").read_text()
    lines = re.findall(r"^python benchmarks/(\w+)\.py([^#\n]*)", readme, flags=re.M)
    runnable = {p.stem for p in BENCHMARKS.glob("*.py") if "    run_main(main)\n" in p.read_text()}
    assert runnable - {"bench_cli"} <= {name for name, _ in lines}

    def capture(self, args=None, namespace=None):
        raise _Parsed(self.parse_known_args(args, namespace))

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    for name, rest in lines:
        with pytest.raises(_Parsed) as got:
            script(name).main(rest.split())
        assert got.value.args[0][1] == [], (name, rest)


def test_gibbs_scaling_and_quality_rows_run_under_fits_thread_policy(script, monkeypatch):
    """gibbs.py's scaling and quality rows ran with torch's default thread count (one a core:
    noisy next to other work on a 2-core machine) while its whole fits and chains ran under
    fit's policy (one thread below 50,000 free cells); each row now runs under the policy and
    records and prints its count."""
    import torch

    gibbs = script("gibbs")
    scaling = script("gibbs_scaling")
    seen = []

    def timed(problem, backend, **kwargs):
        seen.append(torch.get_num_threads())
        return {"ms_per_iteration": 1.0, "ns_per_cell": 1.0}

    def run(*args, **kwargs):
        seen.append(torch.get_num_threads())
        raise _Measuring

    monkeypatch.setattr(scaling, "time_backend", timed)
    monkeypatch.setattr(scaling, "run_gibbs", run)
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        series = scaling.bench_scaling(None, ["torch"], gibbs.QUICK)
        assert torch.get_num_threads() == 2  # restored after each map
        with pytest.raises(_Measuring):
            scaling.bench_quality("torch", gibbs.QUICK)
        assert seen == [1] * (
            len(gibbs.QUICK.scaling_sides) + len(gibbs.QUICK.scaling_num_concepts) + 1
        ), seen
        assert [e["torch_threads"] for e in series["cells"]] == [1, 1], series
        assert (
            scaling.bench_scaling(None, ["torch"], gibbs.QUICK, 2)["cells"][0]["torch_threads"] == 2
        )
    finally:
        torch.set_num_threads(previous)
    machine = {"date": "-", "cpu_model": "-", "cpus_usable": 2, "torch": "-", "torch_threads": 2,
               "numba": "-"}  # fmt: skip
    results = {"machine": machine, "backends": ["torch"], "backend_notes": {}, "quick": True,
               "dataset": None, "houses": [], "scaling": series, "scaling_threads": "auto",
               "total_s": 1.0, "out": "-"}  # fmt: skip
    text = script("gibbs_report").render(results)
    assert "spcopyro fit's policy" in text and "torch threads" in text, text


def test_start_up_benchmarks_time_their_processes_with_the_bytecode_cache(script, monkeypatch):
    """With PYTHONDONTWRITEBYTECODE=1 in the environment (as on the project's machine) every
    timed process compiled all of spcopyro again, which a user's Python does once: `where` took
    0.51 s against 0.22 s with the .pyc. The processes' environment clears it, spcopyro is
    compiled before anything is timed, and the JSON and the report say so."""
    fixed_cost = script("fixed_cost")
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    env = fixed_cost._environment()
    assert "PYTHONDONTWRITEBYTECODE" not in env and env["CI"] == "1", sorted(env)
    calls = []

    def run(command, **kwargs):
        calls.append((command, kwargs["env"]))
        return argparse.Namespace(returncode=0)

    monkeypatch.setattr(fixed_cost.subprocess, "run", run)
    record = fixed_cost.warm_bytecode()
    [(command, child_env)] = calls
    assert command[1:4] == ["-m", "compileall", "-q"] and command[-1].endswith("spcopyro")
    assert "PYTHONDONTWRITEBYTECODE" not in child_env
    assert record["parent_PYTHONDONTWRITEBYTECODE"] == "1" and record["compileall_ok"], record
    assert "PYTHONDONTWRITEBYTECODE=1 here, cleared" in fixed_cost.bytecode_note(record)
    assert script("end_to_end").warm_bytecode is fixed_cost.warm_bytecode


def test_timed_fits_find_numba_kernels_cached(script, monkeypatch):
    """A kernel is compiled by the first process that calls it: in a fresh checkout the
    split-merge kernels compiled inside gibbs.py's timed `auto` fit (first sweep 2.1 s, not 0.2)
    and counted as fixed cost. Each configuration is fitted once, untimed, first, for enough
    sweeps that a fifth-of-the-sweeps move runs, and the benchmarks record it."""
    fixed_cost = script("fixed_cost")
    calls = []
    monkeypatch.setattr(fixed_cost, "run_fit_process", lambda a, timeout: calls.append(a))
    data = Path("/data/room2ldk4")
    warm = fixed_cost.warm_kernels({p: fixed_cost.preset_arguments(data, p)
                                    for p in ("paper-dp", "auto")})  # fmt: skip
    assert sorted(warm) == ["auto", "paper-dp"] and all(s >= 0.0 for s in warm.values())
    sweeps = str(fixed_cost.WARM_SWEEPS)
    assert calls == [[str(data), "--preset", p, "--seed", "0", "--sweeps", sweeps, "--no-figures"]
                     for p in ("paper-dp", "auto")]  # fmt: skip
    assert 0.8**fixed_cost.WARM_SWEEPS < 1e-4  # merge_moves = region_moves = 0.2 a sweep
    assert "untimed 50-sweep fit" in fixed_cost.warm_note(warm)
    assert script("gibbs").warm_kernels is fixed_cost.warm_kernels
    assert script("end_to_end").warm_kernels is fixed_cost.warm_kernels


def test_fixed_limit_targets_print_their_same_run_baseline(script):
    """The targets that are fixed limits of the issues, not ratios (kernel ns a cell, a whole
    fit's ms a sweep, the fixed cost, the 5000-sweep run's seconds, its peak memory) printed
    the measured value alone: on a loaded machine nothing said whether a FAIL was the code or
    the machine. Each now prints a baseline timed in the same run beside it."""
    report = script("gibbs_report")
    per_cell = {"seconds_per_iteration": 0.5}
    results = {
        "backends": [],
        "houses": [{"house": "room2ldk4", "per_cell": per_cell, "speedup": {"numba": 400.0}}],
        "run_loop": [{"preset": "paper-dp", "num_concepts": 120, "house": "room2ldk4",
                      "sweeps": 5000, "ratio": 1.1, "run_gibbs_ms_per_sweep": 1.1,
                      "kernel_ms_per_sweep": 1.0, "kernel_ns_per_cell": 36.0,
                      "free_cells": 27746}],
        "fits": [{"preset": "paper-dp", "house": "room2ldk4", "sweeps": 5000,
                  "ms_per_sweep": 0.8, "per_cell": per_cell, "speedup_vs_per_cell": 625.0,
                  "fixed_direct": 2.5}],
        "headline": {"house": "room2ldk4", "free_cells": 27746, "sweeps": 5000,
                     "synthetic_stand_in": False, "wall_s": 9.0, "backend": "numba",
                     "peak_rss_bytes": 700 << 20, "rss_after_import_bytes": 500 << 20},
        "import_floor": {"pass": 0.02, "torch": 1.5},
    }  # fmt: skip
    measured = {t["target"].split(" ")[0]: t["measured"] for t in report.evaluate_targets(results)}
    assert "per-cell loop, same run: 18021 ns/cell" in measured["kernel"], measured
    assert "per-cell loop, same run: 500 ms/it" in measured["whole"], measured
    assert "import torch alone 1.50 s" in measured["fixed"], measured
    assert "per-cell loop, same run: 2500 s projected" in measured["5000"], measured
    assert "after the imports: 500 MiB" in measured["peak"], measured
    fixed_cost = script("fixed_cost")
    row = {"preset": "paper-dp", "figures": False, "fixed_cost": 2.5, "meets_target": False,
           "fixed_cost_extrapolated": 2.6, "seconds_per_sweep": 1e-3, "target_seconds": 2.0,
           "runs": [], "house": "room2ldk4", "repeats": 1}  # fmt: skip
    text = fixed_cost.render([row], {"pass": 0.02, "torch": 1.5})
    assert "FAIL (same run: import torch alone 1.50 s, python -c pass 0.02 s)" in text, text


def test_gibbs_per_house_and_headline_rows_run_under_fits_thread_policy(script, monkeypatch):
    """The per-house rows and the headline subprocess ran with torch's default count too (the
    parent passed its own count, two here, to the headline child); on room2ldk4 at load 3 a
    sweep took 0.98 ms with one thread against 9-24 ms with two."""
    import numpy as np
    import torch

    gibbs = script("gibbs")
    seen = []
    data = argparse.Namespace(num_free=27746, obs_cells=torch.zeros(86, 1))
    monkeypatch.setattr(gibbs, "list_houses", lambda root: ["room2ldk4"])
    monkeypatch.setattr(gibbs, "load_house", lambda path: None)
    monkeypatch.setattr(gibbs, "load_headline_house", lambda root: None)
    monkeypatch.setattr(gibbs, "make_problem", lambda house, settings: argparse.Namespace(
        data=data, config=None, name="room2ldk4"))  # fmt: skip

    def timed(problem, backend, **kwargs):
        seen.append(torch.get_num_threads())
        return {"ms_per_iteration": 1.0}

    def run(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return argparse.Namespace(seconds=np.array([1.0]), num_concepts=np.array([3]),
                                  log_joint=np.array([0.0]))  # fmt: skip

    monkeypatch.setattr(gibbs, "time_backend", timed)
    monkeypatch.setattr(gibbs, "run_gibbs", run)
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        [row] = gibbs.bench_houses(Path("/data"), ["numba"], gibbs.QUICK, skip_baseline=True)
        record = gibbs.child_run(None, "numba", 1)
        assert seen == [1, 1] and row["torch_threads"] == record["torch_threads"] == 1, seen
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(previous)
    commands = []

    def child(command, **kwargs):
        commands.append(command)
        raise _Measuring

    monkeypatch.setattr(gibbs.subprocess, "run", child)
    for threads in ("auto", 3):
        with pytest.raises(_Measuring):
            gibbs.bench_headline(None, "numba", 1, threads)
    assert "--torch-threads" not in commands[0], commands  # the child applies the policy
    assert commands[1][-3:] == ["--torch-threads", "3", "--no-dataset"], commands


def test_gibbs_run_loop_rows_run_under_fits_thread_policy(script, monkeypatch):
    """The run loop against the kernel (and the kernel's ns-a-cell target) ran with torch's
    default count: a --quick run at load 3 timed paper-dp's kernel at 53 ms a sweep on room2ldk4
    against ~1 ms with one thread. It now runs under fit's policy and records the count."""
    import torch

    run_loop = script("gibbs_run_loop")
    seen = []

    def timed(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return {"ratio": 1.0}

    monkeypatch.setattr(run_loop, "_kernel_and_run", timed)
    data = argparse.Namespace(num_free=27746)
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        row = run_loop.kernel_and_run(data, None, 10)
        assert seen == [1] and row["torch_threads"] == 1, (seen, row)
        assert run_loop.kernel_and_run(data, None, 10, threads=2)["torch_threads"] == 2
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(previous)


@pytest.mark.slow
def test_coarse_variants_quick_scores_each_variant_and_resumes(tmp_path, dataset_root):
    """coarse_variants.py --quick: each variant's public and held-out scores on one house, in a
    JSON written as it goes; a rerun with the same --out fits nothing again (same JSON)."""
    out = tmp_path / "coarse_variants.json"
    done = run_benchmark("coarse_variants.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert results["sweeps"] == 20 and results["houses"] == ["room1dk5"]
    assert list(results["variants"]) == ["coarse", "footprint 0.5 m"]
    for seeds in results["variants"].values():
        row = seeds["seed 0"]
        held = row["houses"]["room1dk5"]["heldout"]
        assert 0.0 <= held["all folds"] <= held["top 3"] <= 1.0 and held["words"] > 0
        assert row["summary"]["top1"] == held["all folds"]
        assert row["summary"]["ari"] == row["houses"]["room1dk5"]["public"]["ari"]
    assert "| coarse (seed 0) |" in done.stdout
    again = run_benchmark("coarse_variants.py", out)
    assert again.returncode == 0 and "seed 0 room1dk5" not in again.stderr, again.stderr[-3000:]
    assert json.loads(out.read_text()) == results


def _variant_house(ari, share, count, top1=0.3, words=10):
    public = {"ari": ari, "largest_share": share, "concepts_1pct": count, "refined": False}
    held = {"all folds": top1, "top 3": 0.6, "mean rank": 3.0, "words": words}
    return {"public": public, "heldout": held}


def test_coarse_variants_judges_the_ari_targets_on_every_house(script):
    """A variant meets the ARI targets only with the mean above (E)'s (0.510 on the public
    houses; the bar given, no longer a 0.510 of the script's own), no concept over 60 % and
    every house's concept count within 2 of Table 2."""
    cv = script("coarse_variants")
    house = _variant_house
    table2 = dict(cv.PUBLIC_CATEGORIES)
    good = {h: house(0.6, 0.5, n) for h, n in table2.items()}
    assert cv.summary(good, 0.510)["ari_targets"] is True
    assert cv.summary(good, 0.610)["ari_targets"] is False  # the bar is the one measured
    assert cv.summary(good, 0.510)["top1"] == pytest.approx(0.3)
    assert cv.summary({**good, "room1dk5": house(0.6, 0.61, 6)}, 0.510)["ari_targets"] is False
    assert cv.summary({**good, "room1dk5": house(0.6, 0.5, 9)}, 0.510)["ari_targets"] is False
    low = {h: house(0.5, 0.5, n) for h, n in table2.items()}
    assert cv.summary(low, 0.510)["ari_targets"] is False


def test_coarse_variants_pools_held_out_words_as_real_houses_does(script):
    """The held-out summary is real_houses.py's: the mean of houses, and the pooling over the
    houses' words (``real_houses.pooled``: a house weighs by its words, one scoring none
    weighs nothing, where the script's own dot product made the pooled score NaN)."""
    cv = script("coarse_variants")
    per_house = {"room1dk5": _variant_house(0.6, 0.5, 6, top1=0.2, words=30),
                 "room1dk6": _variant_house(0.6, 0.5, 5, top1=0.6, words=10)}  # fmt: skip
    scored = cv.summary(per_house, 0.510)
    assert scored["top1"] == pytest.approx(0.4)
    assert scored["top1_pooled"] == pytest.approx((0.2 * 30 + 0.6 * 10) / 40)
    none = {**per_house, "room1ldk4": _variant_house(0.6, 0.5, 7, top1=float("nan"), words=0)}
    assert cv.summary(none, 0.510)["top1_pooled"] == pytest.approx(scored["top1_pooled"])


def test_coarse_variants_scores_held_out_words_as_real_houses_does(script):
    """coarse_variants.py's held-out scores of ``coarse`` are real_houses.py's at the same fit
    seed (one fold loop, ``real_houses.heldout_fold_scores``, where it had a copy)."""
    from spcopyro.synthetic import make_house

    cv, rh = script("coarse_variants"), script("real_houses")
    house = make_house(seed=0)
    ours = cv.heldout_scores(house, "coarse", 3, 0)
    theirs = rh.heldout_top1(house, 3, seeds=[0], presets=("coarse",))["coarse"]["seeds"]["0"]
    assert ours == theirs and ours["words"] > 0


def test_coarse_variants_ari_bar_is_the_nearest_utterances_public_mean(script, dataset_root):
    """The ARI target's bar is measured as real_houses.py scores (E) nearest utterance, over
    the five public houses: docs/real_houses.md's 0.510 (the script kept its own 0.510)."""
    from spcopyro.data import load_house

    cv = script("coarse_variants")
    houses = {h: load_house(dataset_root / h) for h in cv.PUBLIC_CATEGORIES}
    truths = {h: cv.public_truth(house).labels for h, house in houses.items()}
    bar = cv.nearest_ari(houses, truths)
    assert f"{bar:.3f}" == "0.510"


def test_coarse_variants_fits_held_out_words_with_real_houses_preset_model(script, monkeypatch):
    """A variant's held-out model is ``real_houses.preset_model`` of its preset and overrides
    (not a lambda of the script's own around the same fit)."""
    from spcopyro.synthetic import make_house

    cv, rh = script("coarse_variants"), script("real_houses")
    calls = []

    def preset_model(*args, **overrides):
        calls.append((args, overrides))
        return lambda train: rh.nearest_word_map(train.grid, train.observations)

    monkeypatch.setattr(rh, "preset_model", preset_model)
    assert cv.heldout_scores(make_house(seed=0), "footprint 0.5 m", 3, 0)["words"] > 0
    assert calls == [(("coarse", 3, 0), {"footprint_reach_share": 0.0, "footprint_radius": 0.5})]


def _stub_coarse_variants(cv, monkeypatch, dataset_root) -> dict[str, list]:
    """Stubs coarse_variants.py's loading, truths, fits and ARI bar; name -> what each was
    called with."""
    seen: dict[str, list] = {"load": [], "truth": [], "nearest": []}
    monkeypatch.setenv("SPCOPYRO_DATA", str(dataset_root))
    monkeypatch.setattr(cv, "load_house", lambda path: seen["load"].append(path.name) or path.name)

    def public_truth(house):
        seen["truth"].append(house)
        return argparse.Namespace(labels=house)

    def nearest_ari(houses, truths):
        seen["nearest"].append((list(houses), list(truths.values())))
        return 0.5

    monkeypatch.setattr(cv, "public_truth", public_truth)
    monkeypatch.setattr(cv, "nearest_ari", nearest_ari)
    public = {"ari": 0.6, "largest_share": 0.5, "concepts_1pct": 6, "refined": False}
    monkeypatch.setattr(cv, "public_scores", lambda house, truth, *_: dict(public))
    held = {"all folds": 0.3, "top 3": 0.6, "mean rank": 3.0, "words": 10}
    monkeypatch.setattr(cv, "heldout_scores", lambda house, *_: dict(held))
    return seen


def test_coarse_variants_rerun_on_a_finished_json_loads_no_house(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """The ARI bar (all five public houses, their truths and nearest-word maps: ~6 s) is
    measured when a summary is first judged, not before the resume check: a rerun on a finished
    JSON loads no house and fits nothing; the first run loads each house once and judges with
    the five houses' bar (--quick too, one house fitted)."""
    cv = script("coarse_variants")
    seen = _stub_coarse_variants(cv, monkeypatch, dataset_root)
    out = tmp_path / "cv.json"
    assert cv.main(["--quick", "--out", str(out)]) == 0
    five = list(cv.PUBLIC_CATEGORIES)
    assert seen["load"] == ["room1dk5", *five[1:]] and seen["truth"] == seen["load"]
    assert seen["nearest"] == [(five, five)]  # once, for both variants
    first, printed = out.read_text(), capsys.readouterr().out
    assert "| coarse (seed 0) |" in printed and "| footprint 0.5 m (seed 0) |" in printed
    for calls in seen.values():
        calls.clear()
    assert cv.main(["--quick", "--out", str(out)]) == 0
    assert seen == {"load": [], "truth": [], "nearest": []}
    assert out.read_text() == first and capsys.readouterr().out == printed


def test_coarse_variants_synthetic_scores_the_houses_not_tuned_on(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """Issue 21: before a variant could become the default it must pass on the houses it was
    not tuned on, as real_houses.py checks the default. --synthetic fits each variant through
    real_houses.fit_preset (its preset and overrides; stubbed here: the truth for ``coarse``,
    one concept for ``footprint 0.5 m``) on real_houses.py's synthetic houses (house seed S at
    fit seed S + f) and, through real_houses.simulated_on, on simulate --map of a public map;
    its results go under "synthetic" of the variant and seed, the public results beside them
    untouched; a rerun fits nothing; the table judges every target PASS or FAIL."""
    import numpy as np

    from spcopyro.data import load_house

    cv, rh = script("coarse_variants"), script("real_houses")
    out = tmp_path / "cv.json"
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    assert cv.main(["--quick", "--out", str(out)]) == 0  # the public results first
    public = json.loads(out.read_text())
    capsys.readouterr()
    monkeypatch.setattr(cv, "load_house", load_house)
    calls = []

    def fit_preset(house, name, sweeps, seed, **overrides):
        calls.append((house.name, name, sweeps, seed, overrides))
        return (np.zeros_like(house.truth) if overrides else house.truth), 0.0

    monkeypatch.setattr(rh, "fit_preset", fit_preset)
    built = _count_calls(monkeypatch, rh, "baseline_scores", "map_simulation")
    argv = ["--quick", "--synthetic", "--open-plan-seeds", "2", "--seeds", "1", "--out", str(out)]
    assert cv.main(argv) == 0
    kinds = [("synthetic", 1), ("synthetic", 2), ("synthetic", 1), ("synthetic", 1),
             ("room1dk5", 1)]  # open-plan seeds 0 and 1, sparse, dense; simulate --map  # fmt: skip
    assert calls == [(h, "coarse", 20, seed, {}) for h, seed in kinds] + [
        (h, "coarse", 20, seed, {"footprint_reach_share": 0.0, "footprint_radius": 0.5})
        for h, seed in kinds
    ]
    results = json.loads(out.read_text())
    houses = ["open-plan seed 0", "open-plan seed 1", "sparse seed 0", "dense seed 0"]
    # the baselines and the simulation draw nothing: once a house and a map, not a variant
    assert built == {"baseline_scores": houses, "map_simulation": ["room1dk5"]}
    baselines = results.pop("synthetic_baselines")
    assert list(baselines) == houses and rh.ORACLE in baselines["open-plan seed 0"]
    for name, seeds in results["variants"].items():
        record = seeds.pop("seed 1")["synthetic"]
        assert all(list(row) == ["variant"] for k, row in record["houses"].items()
                   if not k.startswith("simulated "))  # fmt: skip
        assert list(record["houses"]) == ["open-plan seed 0", "open-plan seed 1", "sparse seed 0",
                                          "dense seed 0", "simulated room1dk5"]  # fmt: skip
        summary = record["summary"]
        assert summary["open-plan"]["houses"] == 2 and summary["dense"]["houses"] == 1
        assert summary["dense"]["ari"] == (1.0 if name == "coarse" else 0.0)
        assert summary["simulated"] == {"room1dk5": 1.0 if name == "coarse" else 0.0}
        assert 0.0 < summary["open-plan"]["F"] < summary["open-plan"]["oracle"] <= 1.0
    assert results == public  # the public results and their keys as they were
    printed = capsys.readouterr().out
    rows = {line.split(" | ")[0]: line for line in printed.splitlines() if line.startswith("| ")}
    assert rows["| coarse (1)"].count("PASS") == 4 and "FAIL" not in rows["| coarse (1)"]
    assert rows["| footprint 0.5 m (1)"].count("FAIL") == 4
    assert "room1dk5 1.00" in rows["| coarse (1)"] and "| 1.000 (2) |" in rows["| coarse (1)"]
    calls.clear()
    first = out.read_text()
    assert cv.main(argv) == 0  # finished: skipped
    assert calls == [] and out.read_text() == first and capsys.readouterr().out == printed
    assert len(built["baseline_scores"]) == 4


def _count_calls(monkeypatch, module, *names: str) -> dict[str, list]:
    """Wraps ``module``'s functions ``names`` (a house first): name -> the key of each call's
    house (its name, or ``"KIND seed S"`` of a synthetic house made by ``synthetic_house``)."""
    seen: dict[str, list] = {name: [] for name in names}
    keys: dict[int, str] = {}
    synthetic_house = module.synthetic_house

    def made(kind, seed):
        house = synthetic_house(kind, seed)
        keys[id(house)] = f"{kind} seed {seed}"
        return house

    monkeypatch.setattr(module, "synthetic_house", made)
    for name in names:
        wrapped = getattr(module, name)

        def counted(house, *args, _name=name, _wrapped=wrapped, **kwargs):
            seen[_name].append(keys.get(id(house), house.name))
            return _wrapped(house, *args, **kwargs)

        monkeypatch.setattr(module, name, counted)
    return seen


def test_coarse_variants_synthetic_reads_a_json_with_the_baselines_in_every_entry(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """A JSON written before the baselines had their own slot kept each synthetic house's
    baselines and oracle beside the variant's row of every variant and seed: --synthetic takes
    them from there (computing only a house's missing), resumes, and prints the same table as
    from the new layout."""
    import numpy as np

    from spcopyro.data import load_house

    cv, rh = script("coarse_variants"), script("real_houses")
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    monkeypatch.setattr(cv, "load_house", load_house)
    monkeypatch.setattr(rh, "fit_preset", lambda house, name, sweeps, seed, **overrides: (
        np.zeros_like(house.truth) if overrides else house.truth, 0.0))  # fmt: skip
    new, old = tmp_path / "new.json", tmp_path / "old.json"
    argv = ["--quick", "--synthetic", "--open-plan-seeds", "2", "--seeds", "1", "--out"]
    assert cv.main([*argv, str(new)]) == 0
    printed = capsys.readouterr().out.replace(str(new), "OUT")
    report = json.loads(new.read_text())
    baselines = report.pop("synthetic_baselines")
    for seeds in report["variants"].values():  # the earlier layout
        for key, row in seeds["seed 1"]["synthetic"]["houses"].items():
            row |= baselines.get(key, {})
    records = [seeds["seed 1"]["synthetic"] for seeds in report["variants"].values()]
    del records[1]["summary"], records[1]["houses"]["sparse seed 0"]  # cut short: resumed
    del records[0]["houses"]["open-plan seed 1"][rh.ORACLE]  # not its slot: read from the other
    old.write_text(json.dumps(report, indent=1))
    built = _count_calls(monkeypatch, rh, "baseline_scores", "map_simulation")
    assert cv.main([*argv, str(old)]) == 0
    assert capsys.readouterr().out.replace(str(old), "OUT") == printed
    assert built == {"baseline_scores": [], "map_simulation": []}  # all were in the JSON
    assert json.loads(old.read_text())["synthetic_baselines"] == baselines
    report = json.loads(old.read_text())
    del report["synthetic_baselines"]
    for seeds in report["variants"].values():  # only the baselines: a house's slot computed
        seeds["seed 1"]["synthetic"].pop("summary")
        for row in seeds["seed 1"]["synthetic"]["houses"].values():
            row.pop(rh.ORACLE, None)
    old.write_text(json.dumps(report, indent=1))
    assert cv.main([*argv, str(old)]) == 0
    assert capsys.readouterr().out.replace(str(old), "OUT") == printed
    assert sorted(built["baseline_scores"]) == sorted(baselines)
    assert json.loads(old.read_text())["synthetic_baselines"] == baselines


def test_coarse_variants_synthetic_kinds_add_houses_and_stage_two_patches_the_refinement(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """--kinds fits only those kinds of house; a later run with other kinds adds them to the
    same variant and seed (the summary over every house it has, a kind without houses shown
    as '-'). A variant's STAGE_TWO settings are the refinement's own for its fits only
    (refine.refined_settings patched while it fits, restored after)."""
    import numpy as np

    from spcopyro.data import load_house
    from spcopyro.fit import refine

    cv, rh = script("coarse_variants"), script("real_houses")
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    monkeypatch.setattr(cv, "load_house", load_house)
    original = refine.refined_settings
    calls = []

    def fit_preset(house, name, sweeps, seed, **overrides):
        stage_two = refine.refined_settings(rh.settings_of("coarse", **overrides), 1, 4)
        calls.append((name, overrides, stage_two.data.footprint_reach_share))
        return house.truth, 0.0

    monkeypatch.setattr(rh, "fit_preset", fit_preset)
    out = tmp_path / "cv.json"
    variants = ["--variants", "reach 0.25, stage two too", "reach 0.5, --refine never"]
    argv = ["--quick", "--synthetic", "--open-plan-seeds", "2", "--seeds", "1", *variants,
            "--out", str(out)]  # fmt: skip
    assert cv.main([*argv, "--kinds", "open-plan"]) == 0
    uncut = {"footprint_reach_door_width": None}  # UNCUT: set by real_houses.settings_of
    assert calls == [("coarse", {"footprint_reach_share": 0.25, **uncut}, 0.25)] * 2 + [
        (rh.UNREFINED, {"footprint_reach_share": 0.5, **uncut}, 0.0)] * 2  # fmt: skip
    assert refine.refined_settings is original
    record = json.loads(out.read_text())["variants"]["reach 0.25, stage two too"]["seed 1"]
    assert list(record["synthetic"]["houses"]) == ["open-plan seed 0", "open-plan seed 1"]
    assert list(record["synthetic"]["summary"]) == ["open-plan", "simulated"]
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| reach")]
    assert len(rows) == 2 and all("| - | - |" in row and "PASS" in row for row in rows)
    calls.clear()
    assert cv.main([*argv, "--kinds", "dense"]) == 0
    assert [c[0] for c in calls] == ["coarse", rh.UNREFINED]  # dense seed 0 alone
    summary = json.loads(out.read_text())["variants"]["reach 0.25, stage two too"]["seed 1"][
        "synthetic"]["summary"]  # fmt: skip
    assert summary["open-plan"]["houses"] == 2 and summary["dense"]["ari"] == 1.0
    assert np.isclose(summary["open-plan"]["ari"], 1.0)
    with pytest.raises(SystemExit):
        cv.main(["--quick", "--kinds", "dense", "--out", str(out)])  # only with --synthetic


def test_coarse_variants_keep_what_their_stored_results_measured(script):
    """Since 86d6df4 ``coarse`` carries a reach share of 0.2 in rooms (1 m doors). Every variant
    measured before it, on ``coarse`` with share 0, resolves (through the script's own
    ``variant_settings``) to share 0 and no door cut, the reach shares without "in rooms" to
    their share and radius without a door cut; ``reach 0.2 in rooms`` and ``coarse`` to the
    current preset's preparation, ``coarse before the reach share`` to share 0. Every variant
    is listed here: one added must say what it means."""
    from spcopyro.config import preset

    cvs = script("coarse_variant_settings")
    now, before = preset("coarse").data, preset("coarse", footprint_reach_share=0.0).data
    assert (now.footprint_reach_share, now.footprint_reach_door_width) == (0.2, 1.0)
    current = ["coarse", "coarse, --refine never", "reach 0.2 in rooms"]
    in_rooms = {"reach 0.25 in rooms": 0.25, "reach 0.25 in rooms, stage two too": 0.25,
                "reach 0.2 in rooms, stage two too": 0.2}  # fmt: skip
    reach = {"reach 0.25": (0.25, None), "reach 0.5": (0.5, None),
             "reach 0.25, --refine never": (0.25, None), "reach 0.5, --refine never": (0.5, None),
             "reach 0.25, stage two too": (0.25, None), "reach 0.1": (0.1, None),
             "reach 0.1, --refine never": (0.1, None), "reach 0.2": (0.2, None),
             "reach 0.25 within 2 m": (0.25, 2.0),
             "reach 0.25 within 3 m": (0.25, 3.0)}  # fmt: skip
    old = [n for n in cvs.VARIANTS if n not in [*current, *in_rooms, *reach]]
    assert len(old) == 18 and "coarse before the reach share" in old and "paper-dp" in old
    for name in old:
        data = cvs.variant_settings(name).data
        assert (data.footprint_reach_share, data.footprint_reach_door_width) == (0.0, None), name
    assert cvs.variant_settings("coarse before the reach share").data == before
    for name, (share, radius) in reach.items():
        data = cvs.variant_settings(name).data
        cut = (data.footprint_reach_share, data.footprint_reach_radius)
        assert (*cut, data.footprint_reach_door_width) == (share, radius, None), name
    for name, share in in_rooms.items():
        data = cvs.variant_settings(name).data
        assert (data.footprint_reach_share, data.footprint_reach_door_width) == (share, 1.0)
    for name in current:
        assert cvs.variant_settings(name).data == now, name
    assert cvs.variant_settings("reach 0.2 in rooms").model == preset("coarse").model
    assert cvs.preparation("reach 0.2 in rooms, stage two too")["stage two"] == {
        "footprint_reach_share": 0.2, "footprint_reach_door_width": 1.0}  # fmt: skip


def test_coarse_variants_fit_with_the_settings_they_record(script, monkeypatch):
    """The settings a variant's fits get (public and held-out, through real_houses.fit_result:
    fit_house stubbed) are ``variant_settings``' (what its records store), and a None override
    (:data:`UNCUT`: no door cut) reaches the fit though ``preset`` ignores None: the reach
    shares without "in rooms" are fitted with no door width, literally (fails where fit_result
    builds its settings with ``preset`` alone, dropping the None)."""
    from spcopyro.synthetic import make_house

    cv, rh = script("coarse_variants"), script("real_houses")
    cvs = script("coarse_variant_settings")
    house, fitted, doors = make_house(seed=0), [], {}

    class Fitted(Exception):
        pass

    def fit_house(house, settings, **kwargs):
        fitted.append((settings, kwargs.get("refine")))
        raise Fitted

    monkeypatch.setattr(rh, "fit_house", fit_house)
    for name in cvs.VARIANTS:
        for call in (cv.public_scores, cv.heldout_scores):
            fitted.clear()
            with pytest.raises(Fitted):
                call(house, *([house.truth] if call is cv.public_scores else []), name, 3, 0)
            settings, refine = fitted[0]
            want = cvs.variant_settings(name)
            assert (settings.data, settings.model) == (want.data, want.model), name
            assert refine == "never" or not name.endswith("--refine never"), name
            doors[name] = (settings.data.footprint_reach_share,
                           settings.data.footprint_reach_door_width)  # fmt: skip
    assert doors["coarse"] == doors["coarse, --refine never"] == (0.2, 1.0)
    assert doors["reach 0.25"] == doors["reach 0.25, stage two too"] == (0.25, None)
    assert doors["reach 0.5, --refine never"] == (0.5, None)
    assert doors["reach 0.2"] == (0.2, None) and doors["reach 0.25 in rooms"] == (0.25, 1.0)
    recorded = cvs.preparation("reach 0.25, stage two too")
    assert recorded["footprint_reach_door_width"] is None and recorded["stage two"] == {
        "footprint_reach_share": 0.25}  # fmt: skip


def test_coarse_variants_refuse_to_resume_a_record_prepared_otherwise(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """Each new record stores its data preparation; a resume refuses, before fitting, a record
    whose stored preparation differs from what the variant now resolves to (here: the variant
    defined as before 86d6df4's default changed, which then silently inherited the reach
    share), naming the variant, seed, field and both values. A record without one (older) is
    trusted."""
    from spcopyro.data import load_house

    cv, rh = script("coarse_variants"), script("real_houses")
    cvs = script("coarse_variant_settings")
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    out = tmp_path / "cv.json"
    assert cv.main(["--quick", "--out", str(out)]) == 0
    monkeypatch.setattr(cv, "load_house", load_house)
    monkeypatch.setattr(rh, "fit_preset", lambda house, *_, **__: (house.truth, 0.0))
    argv = ["--quick", "--synthetic", "--kinds", "dense", "--out", str(out)]
    assert cv.main(argv) == 0
    report = json.loads(out.read_text())
    for name, seeds in report["variants"].items():
        row = seeds["seed 0"]
        assert row["preparation"] == row["synthetic"]["preparation"] == cvs.preparation(name)
    assert report["variants"]["coarse"]["seed 0"]["preparation"]["footprint_reach_share"] == 0.2
    first = out.read_text()
    capsys.readouterr()
    fits = []
    monkeypatch.setattr(cv, "public_scores", lambda *args: fits.append(args))
    monkeypatch.setattr(rh, "fit_preset", lambda *args, **kwargs: fits.append(args))
    changed = {**cvs.VARIANTS, "footprint 0.5 m": ("coarse", {"footprint_radius": 0.5})}
    monkeypatch.setattr(cvs, "VARIANTS", changed)  # as it was: now with the reach share
    for run in (["--quick", "--variants", "coarse", "--out", str(out)], argv):
        with pytest.raises(SystemExit) as refused:
            cv.main(run)
        assert refused.value.code == 2
        message = capsys.readouterr().err.strip().splitlines()[-1]
        assert message.endswith(
            f"error: {out}: 'footprint 0.5 m' seed 0's public results were fitted with "
            "footprint_reach_share = 0.0, the variant now resolves to 0.2; give another --out, "
            "or rename the variant's entry in the JSON to what it measured"
        )
    assert fits == [] and out.read_text() == first
    for row in report["variants"]["footprint 0.5 m"].values():  # an older JSON: none recorded
        del row["preparation"], row["synthetic"]["preparation"]
    out.write_text(json.dumps(report, indent=1))
    assert cv.main(argv) == 0 and fits == []  # trusted, as before; nothing refitted
    synthetic = report["variants"]["coarse"]["seed 0"]["synthetic"]
    synthetic["preparation"]["footprint_reach_door_width"] = None
    out.write_text(json.dumps(report, indent=1))
    with pytest.raises(SystemExit):
        cv.main(argv)
    message = capsys.readouterr().err.strip().splitlines()[-1]
    assert (
        "'coarse' seed 0's synthetic results were fitted with footprint_reach_door_width = "
        "None, the variant now resolves to 1.0;" in message
    )
    assert fits == []
