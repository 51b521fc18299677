"""Tests of the ablation (spcopyro.experiments.ablation*, run as a study by
spcopyro.study.ablation, issue 26) and of the sparse synthetic houses it runs on
(HouseSpec.public_like, spcopyro.synthetic.statistics)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fake_dataset import fake_dataset
from stale_cells import check_stale_kept_then_rerun

from spcopyro.cli.main import main
from spcopyro.data import load_house
from spcopyro.experiments.ablation import (
    QUICK_HOUSES,
    SYNTHETIC_HOUSES,
    AblationSettings,
    concepts_over,
    largest_share,
)
from spcopyro.experiments.ablation_report import JSON_KEYS, markdown, targets
from spcopyro.experiments.ablation_variants import (
    Variant,
    VariantError,
    make_variant,
    parse_variant,
)
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.study.ablation import (
    ABLATION,
    ABLATION_QUICK,
    ablation_settings,
    ablation_study,
    run_ablation,
)
from spcopyro.study.cells import cells_of
from spcopyro.study.spec import load_study
from spcopyro.synthetic import HouseSpec, house_statistics, make_house

OLD_RECORDS = Path(__file__).with_name("ablation_old_records.json")
"""The records (times left out) the ablation's own loop gave for :data:`OLD_GRID`, before it
became a study (issue 26)."""

# The five public houses, measured with house_statistics (min, max over the houses); the test
# against the dataset below checks these numbers when the dataset is present.
PUBLIC_RANGES = {
    "free_cells": (18026, 27746),
    "observed_cells": (58, 86),
    "density": (0.0028, 0.0043),
    "images": (142, 223),
    "utterances": (45, 76),
    "tour_m": (57.7, 74.5),
}


# ------------------------------------------------------------------------------------------
# Sparse synthetic houses
# ------------------------------------------------------------------------------------------


def test_public_ranges_match_the_dataset(dataset_root):
    stats = [house_statistics(load_house(dataset_root / name)) for name in PUBLIC_RANGES_HOUSES]
    for key, (low, high) in PUBLIC_RANGES.items():
        values = [getattr(s, key) for s in stats]
        assert min(values) == pytest.approx(low, rel=0.03), key
        assert max(values) == pytest.approx(high, rel=0.03), key


PUBLIC_RANGES_HOUSES = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_public_like_house_is_as_sparse_as_the_public_houses(seed):
    stats = house_statistics(make_house(seed=seed, spec=HouseSpec.public_like()))
    for key, (low, high) in PUBLIC_RANGES.items():
        value = getattr(stats, key)
        # within the public houses' range, with 10 % slack on either side
        assert 0.9 * low <= value <= 1.1 * high, (key, value, (low, high))
    assert stats.resolution == 0.05 and stats.trials == 3
    # and 15 times sparser than the default house
    dense = house_statistics(make_house(seed=seed))
    assert dense.density > 10 * stats.density


def test_public_like_waypoints_are_revisited_by_every_trial():
    house = make_house(seed=3, spec=HouseSpec.public_like())
    obs = house.observations
    cells_by_trial = [
        {tuple(c) for c in house.grid.world_to_cell(obs.image_xy[obs.image_trial == t])}
        for t in obs.trials
    ]
    assert cells_by_trial[0] == cells_by_trial[1] == cells_by_trial[2]
    # without revisiting, the trials draw new positions
    other = make_house(seed=3, spec=HouseSpec.public_like(revisit_waypoints=False))
    assert house_statistics(other).observed_cells > 2 * house_statistics(house).observed_cells


def test_public_like_layouts_and_errors():
    small = HouseSpec.public_like(num_rooms=3)
    assert small.num_regions == 4 and small.resolution == 0.05
    with pytest.raises(ValueError, match="waypoint_radius"):
        HouseSpec(waypoint_radius=0.0)
    with pytest.raises(ValueError, match="revisit_waypoints"):
        HouseSpec(revisit_waypoints="yes")


def test_simulate_writes_a_sparse_house(tmp_path, capsys):
    code = main(["simulate", "--out", str(tmp_path), "--density", "sparse", "--rooms", "4"])
    assert code == 0
    house = load_house(tmp_path / "synthetic")
    stats = house_statistics(house)
    assert stats.resolution == 0.05 and stats.density < 0.005
    assert len(house.category_names) == 5  # 4 rooms, one open plan


# ------------------------------------------------------------------------------------------
# Variants
# ------------------------------------------------------------------------------------------


def test_variant_routes_each_key_to_its_layer():
    v = parse_variant("mix:preset=original-code,gamma=3.5,feature_scaling=100,cluster_moves=0.2,"
                      "chains=2,init=gaussian")  # fmt: skip
    assert v.preset == "original-code"
    settings = v.spco_settings(6)
    assert settings.model.gamma == 3.5 and settings.data.feature_scaling == 100.0
    assert settings.model.alpha == 1e7  # the preset's own value stays
    assert v.method_options() == GibbsOptions(cluster_moves=0.2)
    assert v.fit_kwargs() == {"chains": 2, "init": "gaussian"}
    assert parse_variant(v.describe()) == v  # the text round-trips
    # observations off on top of the variant's own values
    off = v.spco_settings(6, use_images=False, use_words=False)
    assert not off.model.use_images and not off.model.use_words and off.model.gamma == 3.5


def test_variant_prefixes_and_nested_options():
    v = make_variant("p", {"settings.gamma": 3, "options.cluster_moves": 0.5, "fit.chains": 2})
    assert v.spco_settings().model.gamma == 3
    assert v.method_options().cluster_moves == 0.5 and v.fit_kwargs() == {"chains": 2}
    # a nested options field, by a dotted path (vi-gibbs holds its CAVI options)
    nested = parse_variant("n:method=vi-gibbs,variational.anneal_iterations=7")
    assert nested.method_options().variational.anneal_iterations == 7
    # paper-dirichlet takes L from the house's number of categories unless set
    assert parse_variant("d:preset=paper-dirichlet").spco_settings(7).model.num_concepts == 7
    assert (
        make_variant("d", {"preset": "paper-dirichlet", "num_concepts": 4})
        .spco_settings(7)
        .model.num_concepts
        == 4
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x:gama=3", "unknown key 'gama'"),
        ("x:gamma=abc", "expected a number"),
        ("x:chains=two", "expected an integer"),
        ("x:use_words=maybe", "expected true or false"),
        ("x:cluster_moves=2", "must be a probability"),
        ("x:gamma=-1", "gamma"),
        ("x:preset=paper", "choose one of"),
        ("x:method=nope", "method='nope'"),
        ("x:sweeps=10", "set by the ablation itself"),
        ("x:seed=3", "set by the ablation itself"),
        ("x:gamma", "is not KEY=VALUE"),
        ("x:gamma=3,gamma=4", "given twice"),
        ("x:options.gamma=3", "has no field"),
        ("x:settings.cluster_moves=1", "have no field"),
        ("x:fit.bogus=1", "no argument 'bogus'"),
        ("x:cluster_moves.inner=1", "unknown key"),
        ("x:options.cluster_moves.inner=1", "has no field"),
        # a misspelt prefixed key: the suggestion an unprefixed one gets, with its prefix
        ("x:settings.gama=3", r"have no field 'gama'; did you mean settings\.gamma\?"),
        ("x:options.cluster_move=0.1", r"; did you mean options\.cluster_moves\?"),
        ("x:options.hyper.log_gama_sd=2", r"; did you mean options\.hyper\.log_gamma_sd,"),
        ("x:fit.refin=auto", r"; did you mean fit\.refine\?"),
        ("x:hyper.log_gama_sd=2", r"unknown key .*; did you mean hyper\.log_gamma_sd,"),
        (":gamma=3", "must be non-empty"),
        ("x:hyper.log_gamma_sd=2", "no hyperparameter the chain samples reads log_gamma_sd"),
        ("x:point_estimate=binder", "needs marginal_samples > 0"),
        ("x:method=cavi,refine=auto", "refines a Gibbs fit, not method='cavi'"),
        ("x:method=vi-gibbs,gibbs.hyper.alpha_step=1", "reads alpha_step"),
    ],
)
def test_variant_errors_name_the_problem(text, message):
    with pytest.raises(VariantError, match=message) as info:
        parse_variant(text)
    if text.startswith("x:"):
        assert "variant 'x" in str(info.value)  # the variant is named


def test_ambiguous_key_needs_a_prefix(monkeypatch):
    import spcopyro.experiments.ablation_variants as module

    # pretend fit_house took an argument named like a model setting
    parameters = dict(module._fit_parameters())
    parameters["gamma"] = parameters["chains"]
    monkeypatch.setattr(module, "_fit_parameters", lambda: parameters)
    with pytest.raises(VariantError, match="settings.gamma or fit.gamma"):
        module.make_variant("a", {"gamma": 3})
    assert module.make_variant("a", {"settings.gamma": 3}).spco_settings().model.gamma == 3


# ------------------------------------------------------------------------------------------
# The harness
# ------------------------------------------------------------------------------------------


def _old_grid(root) -> AblationSettings:
    """The grid of :data:`OLD_RECORDS`: 2 variants and both baselines on the two quick houses
    (seeds 0-1) and room1ldk4 (seeds 0-1: trials 0 and 1 held out), 5 sweeps."""
    return AblationSettings.quick(
        variants=(parse_variant("g3:preset=original-code,gamma=3"),
                  parse_variant("dp+sw:preset=paper-dp,cluster_moves=0.2")),
        baselines=("C-spcoa", "F-geometry"), seeds=2, sweeps=5, spcoa_iterations=5,
        dataset_root=root, public_houses=("room1ldk4",), public_seeds=2,
    )  # fmt: skip


def test_the_study_covers_rows_houses_and_seeds():
    settings = AblationSettings.quick(
        variants=(parse_variant("a"), parse_variant("b:gamma=3")), seeds=3
    )
    cells = cells_of(ablation_study(settings))
    assert len(cells) == 4 * 2 * 3  # (2 variants + 2 baselines) x 2 houses x 3 seeds
    assert {(c.row, c.data.name, c.seed) for c in cells} == {
        (r, h, s) for r in ("a", "b", "C-spcoa", "F-geometry") for h in ("dense", "sparse")
        for s in range(3)
    }  # fmt: skip
    assert all(c.observations_off == (c.variant is not None) for c in cells)
    with pytest.raises(ValueError, match="unknown synthetic house"):
        ablation_study(AblationSettings.quick(synthetic=("nope",)))


@pytest.mark.parametrize("quick", [False, True])
def test_shipped_study_files_are_the_ablations_grid(quick, dataset_root):
    """ablation(_quick).toml holds the ablation's defaults: the same cells, key for key, as
    the settings the command had (AblationSettings / .quick with the dataset's houses)."""
    study = load_study(ABLATION_QUICK if quick else ABLATION)
    if quick:
        settings = AblationSettings.quick(dataset_root=dataset_root, public_houses=("room1dk5",))
    else:
        settings = AblationSettings(dataset_root=dataset_root)
    assert ablation_settings(study, dataset_root).houses == (
        QUICK_HOUSES if quick else SYNTHETIC_HOUSES
    )
    keys = [c.key for c in cells_of(study, dataset_root)]
    assert keys == [c.key for c in cells_of(ablation_study(settings))]
    again = ablation_study(ablation_settings(study, dataset_root))
    assert [c.key for c in cells_of(again)] == keys
    assert len(keys) == (25 if quick else 325)


def test_the_study_gives_the_old_loops_numbers(tmp_path, dataset_root):
    """The ablation as a study reproduces, score for score, what its own loop gave before
    issue 26 for the same grid and seeds (recorded in ablation_old_records.json); the report
    is drawn from results.csv, and rerunning fits nothing."""
    old = json.loads(OLD_RECORDS.read_text())["records"]
    report = run_ablation(tmp_path, _old_grid(dataset_root))
    times = {"seconds", "cpu_seconds", "seconds_off", "cpu_seconds_off"}
    new = [{k: v for k, v in r.items() if k not in times} for r in report["records"]]
    assert [(r["row"], r["house"], r["seed"]) for r in new] == [
        (r["row"], r["house"], r["seed"]) for r in old
    ]
    for was, now in zip(old, new, strict=True):
        assert set(now) == set(was), (was["row"], was["house"], set(now) ^ set(was))
        for key, value in was.items():
            if isinstance(value, float):
                assert now[key] == pytest.approx(value, rel=1e-9, nan_ok=True), key
            else:
                assert now[key] == value, (was["row"], was["house"], was["seed"], key)
    assert report["failed"] == 0
    lines = []
    again = run_ablation(tmp_path, _old_grid(dataset_root), report=lines.append)
    assert "nothing to run" in lines[0]
    assert again["summary"] == report["summary"]


def test_concepts_over_counts_labels_with_one_percent():
    labels = np.repeat(np.arange(4), [500, 480, 15, 5])  # 1000 cells
    assert concepts_over(labels) == 3  # 15 >= 10, 5 < 10
    assert concepts_over(labels, share=0.02) == 2


def test_largest_share_counts_labelled_cells_only():
    labels = np.repeat(np.arange(-1, 3), [500, 300, 150, 50])  # 500 unlabelled
    assert largest_share(labels) == pytest.approx(0.6)
    assert np.isnan(largest_share(np.full(4, -1)))


def test_top_words_list_none_for_a_fit_that_did_not_model_its_words():
    """The ablation's and studies' word lists follow fit's rule (``listed_top_words``,
    ``words_modelled``): a fit with ``use_words`` off lists no words (its w rows are the
    prior's, every word tied; they listed three tied words in tie order, read as what the
    concept means) and its place and filler shares are nan; a fit that modelled its words lists
    them, as fit does none for a concept where no word was heard."""
    import dataclasses
    import math

    from spcopyro.config import preset
    from spcopyro.experiments.ablation import top_words
    from spcopyro.experiments.ablation_report import _words_text
    from spcopyro.fit.house import fit_house
    from spcopyro.study.evaluate import SENTENCE_MIN_CELLS, _sentence_scores

    house = make_house(seed=0, spec=HouseSpec(sentence_fraction=0.5))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=3, progress=False)
    words, share = top_words(result, house)
    assert words and all(len(w) == 3 for w in words) and math.isfinite(share)
    sentences = _sentence_scores(result)
    sizes = np.bincount(result.labels, minlength=result.config.num_concepts)
    large = [int(c) for c in result.concepts_in_use() if sizes[c] >= SENTENCE_MIN_CELLS]
    expected = [3 if result.heard(c) else 0 for c in large]  # as fit: none where none heard
    assert [len(w) for w in json.loads(sentences["concept_words"])] == expected
    unmodelled = dataclasses.replace(result, config=result.config.replace(use_words=False))
    words, share = top_words(unmodelled, house)
    assert words and all(w == [] for w in words) and math.isnan(share)
    sentences = _sentence_scores(unmodelled)
    listed = json.loads(sentences["concept_words"])
    assert listed and all(w == [] for w in listed) and math.isnan(sentences["filler_top_share"])
    assert _words_text([[], [], []]) == "—"  # ablation.md's cell: not "; ; "


def test_targets_are_checked_against_the_baselines():
    v = Variant("v")
    settings = AblationSettings.quick(variants=(v,), synthetic=("dense",))
    spread = lambda m, s: {"mean": m, "sd": s, "n": 10}  # noqa: E731
    summary = {
        "v": {"dense": {"ari": spread(0.9, 0.01)}, "room1dk5": {"concepts_1pct": spread(7, 0)}},
        "C-spcoa": {"dense": {"ari": spread(0.8, 0.1)}},
        "F-geometry": {"dense": {"ari": spread(0.95, 0.0)}},
    }
    lines = targets(summary, settings)
    assert "beats C-spcoa" in lines[0] and "sd <= theirs" in lines[0]
    assert "does NOT beat F-geometry" in lines[0] and "sd > theirs" in lines[0]
    assert "within 2" in lines[1] and "NOT" not in lines[1]
    # one seed: its sd is undefined (0 in the JSON), so the spread is not compared; it read
    # "sd <= theirs (0.000 vs 0.000)", a target met by a single fit
    one = lambda m: {"mean": m, "sd": 0.0, "n": 1}  # noqa: E731
    summary = {"v": {"dense": {"ari": one(0.9)}}, "C-spcoa": {"dense": {"ari": one(0.8)}}}
    (line,) = targets(summary, settings)
    assert line == "v on dense: ARI beats C-spcoa (0.900 vs 0.800), sd not compared (one seed)"


def _check_outputs(out, rows, houses, seeds):
    assert {p.name for p in out.iterdir()} >= {"ablation.md", "ablation.json", "ablation.png"}
    report = json.loads((out / "ablation.json").read_text())
    assert set(report) == set(JSON_KEYS)
    assert len(report["records"]) == len(rows) * len(houses) * seeds
    for row in rows:
        for house in houses:
            scores = report["summary"][row][house]
            assert {"concepts_1pct", "seconds"} <= set(scores)
            assert set(scores["seconds"]) == {"mean", "sd", "n"}
    return report


def test_quick_run_end_to_end(tmp_path):
    settings = AblationSettings.quick(
        variants=(parse_variant("g3:preset=original-code,gamma=3"),),
        baselines=("F-geometry",), seeds=2, sweeps=5,
    )  # fmt: skip
    report = run_ablation(tmp_path, settings)
    _check_outputs(tmp_path, ["g3", "F-geometry"], ["dense", "sparse"], 2)
    assert {"results.csv", "report.md", "cells"} <= {p.name for p in tmp_path.iterdir()}
    g3 = report["summary"]["g3"]["dense"]
    for key in ("ari", "ari_off", "ari_on_off", "matching_rate", "matching_rate_area",
                "concepts", "place_top_share", "seconds_off"):  # fmt: skip
        assert key in g3, key
        assert g3[key]["n"] == 2 or key == "place_top_share"
    assert "ari_off" not in report["summary"]["F-geometry"]["dense"]
    record = report["records"][0]
    assert record["row"] == "g3" and record["top_words"] and len(record["top_words"][0]) == 3
    text = (tmp_path / "ablation.md").read_text()
    assert "## Synthetic: dense" in text and "## Synthetic: sparse" in text
    assert "`g3:preset=original-code,settings.gamma=3.0`" in text
    assert "## Targets" in text and "| house | cell (m) |" in text


def test_quick_run_on_a_public_house(tmp_path, dataset_root):
    settings = AblationSettings.quick(
        variants=(parse_variant("dp"),), baselines=("F-geometry",), synthetic=(),
        dataset_root=dataset_root, public_houses=("room1ldk4",), sweeps=3,
    )  # fmt: skip
    report = run_ablation(tmp_path, settings)
    _check_outputs(tmp_path, ["dp", "F-geometry"], ["room1ldk4"], 1)
    dp = report["summary"]["dp"]["room1ldk4"]
    assert {"top1", "top3", "distance_m", "ari_on_off", "concepts_1pct"} <= set(dp)
    assert not {"ari", "ari_off", "matching_rate"} & set(dp)  # the ablation's public columns
    assert report["records"][0]["held_out_trial"] == 0
    text = (tmp_path / "ablation.md").read_text()
    assert "| Table 2 | 7 |" in text  # room1ldk4's categories in the paper's Table 2


def test_cli_runs_and_rejects_bad_variants(tmp_path, capsys):
    out = tmp_path / "abl"
    code = main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--sweeps", "3", "--houses", "sparse", "--baselines",
                 "--variant", "sw:cluster_moves=0.5"])  # fmt: skip
    assert code == 0
    report = _check_outputs(out, ["sw"], ["sparse"], 1)
    assert report["settings"]["variants"][0]["options"] == {"cluster_moves": 0.5}
    assert report["settings"]["sweeps"] == 3 and report["settings"]["spcoa_iterations"] == 5
    assert "ablation.md" in capsys.readouterr().out
    # the alias is a study: the same command again runs nothing
    assert main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--sweeps", "3", "--houses", "sparse", "--baselines",
                 "--variant", "sw:cluster_moves=0.5"]) == 0  # fmt: skip
    assert "nothing to run: all 1 cells" in capsys.readouterr().out
    text = (out / "ablation.md").read_text()  # the default preset, left out of its text, is said
    assert "- `sw:options.cluster_moves=0.5` (preset `coarse`, the default)" in text
    assert main(["ablation", "--out", str(tmp_path / "x"), "--quick", "--variant", "x:gama=3"]) == 2
    assert "unknown key 'gama'" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_resumed_ablation_says_which_cells_it_ran_and_reruns_stale_ones(tmp_path, capsys):
    """A run that found cells finished said "Whole run: 0 s", as if the ablation had taken no
    time; the note on cells of other source said "--rerun-stale runs them again", an option
    ablation did not have; and a synthetic-only run described public houses and SpCoA."""
    out = tmp_path / "abl"
    command = ["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
               "--sweeps", "2", "--houses", "dense", "--baselines", "--no-off",
               "--variant", "g3:preset=original-code,gamma=3"]  # fmt: skip
    assert main(command) == 0
    capsys.readouterr()
    text = (out / "ablation.md").read_text()
    assert "2 Gibbs sweeps per fit; synthetic seeds 0 (house and fit). Mean" in text
    assert "public houses:" not in text and "SpCoA" not in text
    assert "Workers: 1. Whole command: " in text
    assert "- `g3:preset=original-code,settings.gamma=3.0`\n" in text
    assert "| dense (mean of 1 seed) |" in text  # "1 seeds"
    settings = AblationSettings.quick(
        variants=(parse_variant("g"), parse_variant("c:method=cavi")), baselines=()
    )
    report = {"seconds": 1.0, "summary": {}, "records": [], "statistics_md": "", "targets": []}
    header = markdown(report, settings).splitlines()[2]  # it said "30 Gibbs sweeps per fit"
    assert header.startswith("30 iterations per fit (Gibbs sweeps; c: cavi); synthetic"), header
    assert "## Targets\n\nNone checked: no synthetic house with a baseline" in markdown(
        report, settings
    )  # the section was empty
    check_stale_kept_then_rerun(main, command, out, "ablation", capsys)


def test_a_failed_cell_is_named_in_ablation_md(tmp_path, monkeypatch, capsys):
    """A failing cell was left out of ablation.md without a word there (the command exited
    1); a "Failed cells" section and the JSON's failed_cells name it and its error."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    def failing(self, *args, **kwargs):
        raise RuntimeError("no convergence")

    monkeypatch.setattr(type(INFERENCE_METHODS["cavi"]), "run", failing)
    out = tmp_path / "abl"
    code = main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--houses", "dense", "--sweeps", "2", "--no-off", "--baselines",
                 "--variant", "g:preset=original-code", "--variant", "c:method=cavi"])  # fmt: skip
    assert code == 1
    capsys.readouterr()
    text = (out / "ablation.md").read_text()
    line = "c on dense, seed 0, failed (RuntimeError: no convergence); left out of the tables"
    assert f"## Failed cells\n\n- {line}" in text
    (failed,) = json.loads((out / "ablation.json").read_text())["failed_cells"]
    assert failed.startswith(line)


def test_a_variant_named_like_a_baseline_is_refused(tmp_path, capsys):
    """--variant C-spcoa:gamma=3 ran the variant and the baseline C-spcoa and then failed drawing
    ablation.md (KeyError: 'matching_rate_area'), their records pooled under one row name."""
    out = tmp_path / "abl"
    code = main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--houses", "dense", "--sweeps", "2", "--no-off",
                 "--variant", "C-spcoa:gamma=3"])  # fmt: skip
    assert code == 2
    assert "variant 'C-spcoa': the name of a baseline row" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(ValueError, match="variant names must differ: a given twice"):
        AblationSettings(variants=(parse_variant("a"), parse_variant("a:gamma=2")))
    AblationSettings(variants=(parse_variant("C-spcoa"),), baselines=("F-geometry",))  # no clash


def test_made_by_is_a_command_that_runs_when_pasted(tmp_path, capsys):
    """ablation.md's "Made by:" joined the arguments with spaces: an --out with a space read
    as two words. It quotes them as the shell needs."""
    out = tmp_path / "my run"
    assert main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--houses", "dense", "--sweeps", "2", "--no-off", "--baselines",
                 "--variant", "g:preset=original-code"]) == 0  # fmt: skip
    capsys.readouterr()
    made_by = f"Made by: `spcopyro ablation --out '{out}' --quick --no-public"
    assert made_by in (out / "ablation.md").read_text()


def test_a_bar_in_a_variant_name_keeps_the_tables_columns(tmp_path, capsys):
    """--variant 'x|y:...' wrote '| x|y | 0.165 | ...' in ablation.md: one column more than the
    header's, every score shifted. The name is escaped, as the study report does."""
    out = tmp_path / "abl"
    assert main(["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
                 "--houses", "dense", "--sweeps", "2", "--no-off", "--baselines",
                 "--variant", "x|y:preset=original-code"]) == 0  # fmt: skip
    capsys.readouterr()
    lines = (out / "ablation.md").read_text().splitlines()
    (row,) = [line for line in lines if line.startswith("| x")]
    header = lines[lines.index(row) - 2]
    assert row.startswith("| x\\|y | ") and row.replace("\\|", "").count("|") == header.count("|")


def test_a_house_the_quick_study_lacks_says_why(tmp_path, capsys):
    """--quick --houses open-plan (a documented default setting) read "unknown --houses
    ['open-plan']; choose from ['dense', 'sparse']", not saying that --quick keeps two."""
    out = tmp_path / "abl"
    assert main(["ablation", "--out", str(out), "--quick", "--houses", "open-plan"]) == 2
    err = capsys.readouterr().err
    assert "--houses open-plan: not a synthetic setting of --quick's study" in err
    assert "choose from dense, sparse" in err and not out.exists()


def test_an_unknown_public_house_is_named_as_the_option(tmp_path, capsys):
    """--public-houses room9: the error named "<python>: [data.room9] public = ...", a study
    table the user never wrote; it names the option and the dataset's houses."""
    root = fake_dataset(tmp_path / "data")
    out = tmp_path / "out"
    code = main(["ablation", "--out", str(out), "--quick", "--data", str(root),
                 "--public-houses", "room9"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert "--public-houses room9: not a house of" in err and "its houses: room1" in err
    assert "[data." not in err
    assert not out.exists()


def test_public_only_run_with_no_synthetic_seed(tmp_path, dataset_root):
    """`--seeds 0`: the synthetic settings stay named but run no house; the report still writes
    (it once failed describing synthetic houses of no seed)."""
    settings = AblationSettings.quick(
        variants=(parse_variant("dp"),), baselines=(), seeds=0,
        dataset_root=dataset_root, public_houses=("room1ldk4",), sweeps=3,
    )  # fmt: skip
    report = run_ablation(tmp_path, settings)
    assert [s["name"] for s in report["statistics"]] == ["room1ldk4"]
    text = (tmp_path / "ablation.md").read_text()
    # it wrote "synthetic seeds 0--1" and a header-only table per synthetic setting, and drew
    # an empty synthetic panel beside the public one
    assert "## Synthetic" not in text and "synthetic seeds" not in text and "0--1" not in text
    assert "public houses: 1 seed, seed s holding out" in text and "SpCoA" not in text
    from PIL import Image

    with Image.open(tmp_path / "ablation.png") as image:
        assert image.size[0] < 13 * 110  # one panel, 11 inches cropped (two: 16 inches wide)


def test_a_single_value_is_shown_without_a_standard_deviation():
    """ablation.md printed '0.23 ± 0.00' for one seed: the sample sd of one value is undefined."""
    from spcopyro.experiments.ablation_report import _fmt, _spread

    assert _fmt(_spread([0.23])) == "0.230"
    assert _fmt(_spread([0.2, 0.4])) == "0.300 ± 0.141"
    assert _fmt(_spread([])) == "—"
    assert _fmt(_spread([-1e-4])) == "0.000"  # an ARI of chance, not "-0.000"
    assert _fmt(_spread([-0.1, 0.1 - 2e-4])) == "0.000 ± 0.141"


def test_times_under_a_tenth_of_a_second_keep_their_digits():
    """A geometry cell of 3 ms read "0.0" s per fit, the same as no time at all (ablation.md,
    table.md, comparison.md)."""
    from spcopyro._util.messages import seconds_text
    from spcopyro.experiments.ablation_report import _seconds
    from spcopyro.experiments.comparison_report import _seconds as comparison_seconds

    assert [seconds_text(x) for x in (0.0031, 0.05, 0.1, 12.34)] == ["0.0031", "0.05", "0.1",
                                                                     "12.3"]  # fmt: skip
    assert _seconds({"seconds": {"mean": 0.003}, "cpu_seconds": {"mean": 0.0029}}) == (
        "0.003 / 0.0029"
    )
    assert comparison_seconds({"mean": 0.004, "n": 2}) == "0.004"
    assert comparison_seconds(None) == "—"


def test_a_single_seed_gets_no_error_bar(tmp_path, monkeypatch):
    """ablation.png drew a zero-height error bar (sd 0) over a bar of one seed, as if its
    seeds agreed; the sd of one value is not 0 but undefined."""
    from matplotlib.axes import Axes

    from spcopyro.experiments.ablation import AblationSettings
    from spcopyro.experiments.ablation_report import figure

    errors = []
    bar = Axes.bar

    def recorded(self, *args, yerr=None, **kwargs):
        errors.append(list(yerr))
        return bar(self, *args, yerr=yerr, **kwargs)

    monkeypatch.setattr(Axes, "bar", recorded)
    settings = AblationSettings(variants=(parse_variant("a"),), baselines=(), synthetic=("dense",))
    one, two = {"mean": 0.5, "sd": 0.0, "n": 1}, {"mean": 0.5, "sd": 0.1, "n": 2}
    report = {"summary": {"a": {"dense": {"ari": one}}}, "records": []}
    figure(report, settings, tmp_path / "one.png")
    report = {"summary": {"a": {"dense": {"ari": two}}}, "records": []}
    figure(report, settings, tmp_path / "two.png")
    assert np.isnan(errors[0][0]) and errors[1] == [0.1]


def test_an_ablation_into_another_commands_folder_is_refused(tmp_path, capsys):
    """`ablation --out` a compare-inference folder replaced its results.csv, report.md and
    study.json silently (a helper's QA); a folder of the same command, quick or not, is fine."""
    out = tmp_path / "cmp"
    out.mkdir()
    (out / "study.json").write_text(json.dumps({"name": "compare-inference-quick"}))
    command = ["ablation", "--out", str(out), "--quick", "--no-public", "--seeds", "1",
               "--sweeps", "2", "--houses", "dense", "--baselines", "--no-off"]  # fmt: skip
    assert main(command) == 2
    err = capsys.readouterr().err
    assert "holds the results of `spcopyro compare-inference`" in err
    assert json.loads((out / "study.json").read_text()) == {"name": "compare-inference-quick"}
    (out / "study.json").write_text(json.dumps({"name": "ablation"}))  # the full run's folder
    assert main(command) == 0
